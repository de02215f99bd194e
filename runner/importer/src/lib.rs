//! The FMU importer: unpacks any `.fmu` safely ([`archive`]), reads its description into one
//! model whatever its FMI version ([`model`]), loads its binary and drives instances of it
//! through the FMI bindings ([`fmi1`], [`fmi2`], [`fmi3`]), and integrates Model Exchange FMUs of
//! any version with the toolkit's solvers ([`exchange`]). One [`Instance`] type runs an FMU whatever
//! its version and interface. It depends on the FMI C interface and schema only, never on our
//! exporter.
//!
//! # Example
//!
//! Load an FMU (any FMI 1.0, 2.0 or 3.0 FMU; Co-Simulation when it offers it, else Model Exchange,
//! which the toolkit's solvers integrate), run it on a grid and read a variable:
//!
//! ```no_run
//! use std::path::Path;
//! use fmi_importer::{Fmu, Reader, Step};
//!
//! let fmu = Fmu::load(Path::new("target/fmu/pendulum.fmu"))?;
//! let theta = fmu.description.variable("theta").ok_or("no variable theta")?;
//! let mut reader = Reader::new(fmu.description.fmi_version, &[theta])?;
//! let mut instance = fmu.instantiate("pendulum", false)?;
//! instance.setup_experiment(Some(1e-8), 0.0, 5.0)?;
//! instance.enter_initialization_mode()?;
//! instance.exit_initialization_mode()?;
//! let (h, mut value) = (0.01, [0.0]);
//! for k in 0..500 {
//!     if let Step::Ended { reason, .. } = instance.do_step(k as f64 * h, h)? {
//!         println!("the FMU ended the run: {reason}");
//!         break;
//!     }
//!     instance.read(&mut reader, &mut value)?;
//! }
//! println!("theta(5 s) = {} rad", value[0]);
//! # Ok::<(), String>(())
//! ```

pub mod archive;
pub mod call_log;
pub mod exchange;
pub mod fmi1;
pub mod fmi2;
pub mod fmi3;
mod logging;
pub mod model;
pub mod number_text;
mod reader;
pub mod scratch;
pub mod state;
pub mod trace;

use std::ffi::CString;
use std::path::{Path, PathBuf};

pub use logging::{print_line, set_log_printer};

/// Whether binaries loaded from now on stay loaded until the process ends ([`keep_binaries_loaded`]).
static RESIDENT: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// From now on, FMU binaries are never unloaded: dropping an [`Fmu`] leaves its binary in the
/// process until it exits. For a process that ends after its runs (the runner's commands and
/// workers): an FMU may leave code behind that runs at exit (an exit handler registered for the
/// whole process, threads of a library it brought, as a PythonFMU's libpython and numpy do),
/// and unloading its binary first makes the exit crash. A long-lived process that loads many
/// FMUs (the Python package) unloads them, as fmpy does.
pub fn keep_binaries_loaded() {
    RESIDENT.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// Opens an FMU's binary, resident if [`keep_binaries_loaded`] was called.
///
/// # Safety
/// As [`fmi_c::Library::open`].
unsafe fn open_binary(path: &Path) -> Result<fmi_c::Library, String> {
    let opened = match RESIDENT.load(std::sync::atomic::Ordering::Relaxed) {
        true => fmi_c::Library::open_resident(path),
        false => fmi_c::Library::open(path),
    };
    opened.map_err(|e| explain_load_error(e, &LIBRARY_DIRS))
}

/// Where [`explain_load_error`] looks for a libpython to suggest.
const LIBRARY_DIRS: [&str; 4] = ["/usr/lib/x86_64-linux-gnu", "/usr/lib64", "/usr/lib", "/usr/local/lib"];

/// The loader's message, with what to do about the usual causes: a dependency the system cannot
/// find (named), or Python's symbols undefined (an FMU made with PythonFMU expects the host to
/// have loaded libpython: preload one, found in `dirs` when there is one).
fn explain_load_error(error: String, dirs: &[&str]) -> String {
    if let Some(i) = error.find(": cannot open shared object file") {
        let needed = error[..i].rsplit(": ").next().unwrap_or("");
        if !needed.is_empty() && !needed.contains('/') {
            return format!(
                "{error}\nthe binary needs the library {needed}, which this system does not have where the loader looks: install it, or add its directory to LD_LIBRARY_PATH"
            );
        }
    }
    if let Some(i) = error.find("undefined symbol: _Py") {
        let symbol = error[i + "undefined symbol: ".len()..].split_whitespace().next().unwrap_or("");
        let libpython = dirs
            .iter()
            .filter_map(|d| std::fs::read_dir(d).ok())
            .flat_map(|entries| entries.flatten())
            .map(|e| e.path())
            .filter(|p| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("libpython3") && n.ends_with(".so")))
            .min()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "libpython3.X.so".to_owned());
        return format!(
            "{error}\n{symbol} is Python's: the FMU (made with PythonFMU?) expects the program that loads it to have loaded libpython; run with LD_PRELOAD={libpython} (the Python version the FMU was built for)"
        );
    }
    error
}
pub use model::{Causality, Description, FmiVersion, Interface, Kind, Variability, Variable};

/// Why a model ended the run at `when` (`t = 2.79`): its logged `reason` after "the model ended
/// the simulation at `when`", or the reason alone when it already says when (this toolkit's
/// FMUs log "the simulation ended at t = 2.79 s: ...": the time once is enough).
pub fn model_ended(when: &str, reason: &str) -> String {
    if reason.contains(when) {
        reason.to_owned()
    } else {
        format!("the model ended the simulation at {when}: {reason}")
    }
}
/// The error for an optional FMI function `function` that instance `instance`'s binary does not
/// export; out of line, so the calls that check for it stay small enough to inline.
#[cold]
#[inline(never)]
pub(crate) fn not_exported(instance: &str, function: &str) -> String {
    format!("{instance}: the FMU does not export {function}")
}

pub use reader::Reader;
pub use solvers::Method;

/// How the runner integrates a Model Exchange FMU (a Co-Simulation FMU integrates itself); the
/// relative tolerance is the run's (`fmi2SetupExperiment`'s).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Solver {
    /// The method: Euler, RK4, DOPRI5, BS23 or DOP853 (the toolkit's solvers).
    pub method: Method,
    /// The step of the fixed-step methods (s).
    pub fixed_step: f64,
    /// DOPRI5's absolute tolerance.
    pub abs_tol: f64,
}

impl Default for Solver {
    /// The defaults of the toolkit's FMUs' own solver controls.
    fn default() -> Self {
        let c = solvers::controls::Controls::default();
        Solver { method: Method::from_code(c.solver).unwrap_or(Method::Dopri5), fixed_step: c.fixed_step, abs_tol: c.abs_tol }
    }
}

/// An FMU archive unpacked into a temporary directory and checked up to the point of loading its
/// binary: everything the importer reads from a file it did not write, before running any of it.
pub struct Unpacked {
    /// The description, in the importer's model.
    pub description: Description,
    /// The FMI 1.0 description as written (for checks that need the raw schema).
    pub fmi1: Option<fmi_schema::fmi1::ModelDescription>,
    /// The FMI 2.0 description as written.
    pub fmi2: Option<fmi_schema::fmi2::ModelDescription>,
    /// The FMI 3.0 description as written.
    pub fmi3: Option<fmi_schema::fmi3::ModelDescription>,
    /// The interface the binary will be driven through.
    pub interface: Interface,
    /// The modelIdentifier of that interface.
    pub identifier: String,
    /// The shared library for this platform inside `dir`.
    pub binary: PathBuf,
    /// The directory the archive was extracted into (deleted on drop): see [`scratch`].
    pub dir: tempfile::TempDir,
    /// The ModelStructure's continuous states (Model Exchange's implicit methods use them).
    pub states: Option<exchange::StateStructure>,
}

impl Unpacked {
    /// Extracts `path` safely, parses its modelDescription.xml and finds the binary for this
    /// platform, for Co-Simulation when the FMU offers it, else Model Exchange.
    pub fn open(path: &Path) -> Result<Unpacked, String> {
        Self::open_as(path, None)
    }

    /// [`Unpacked::open`] for `interface` (`None`: Co-Simulation when offered, else Model
    /// Exchange). An interface the FMU does not offer, or one that needs an external tool, is
    /// refused.
    pub fn open_as(path: &Path, interface: Option<Interface>) -> Result<Unpacked, String> {
        if !path.is_file() {
            return Err(format!("FMU file {} does not exist", path.display()));
        }
        // Checked first: a refused archive creates no directory, and its size picks the place.
        let mut checked = archive::check_zip(path, archive::Limits::FMU)?;
        let dir = scratch::unpack_dir(checked.total_bytes())?;
        // The description is read while the rest (the binary: most of the bytes) unpacks on
        // another core.
        checked.extract_first("modelDescription.xml", dir.path())?;
        let (extracted, read) = std::thread::scope(|scope| {
            let rest = scope.spawn(|| checked.extract(dir.path()));
            let read = read_description(path, dir.path(), interface);
            (rest.join().unwrap_or_else(|_| Err(format!("{}: unpacking failed", path.display()))), read)
        });
        extracted?;
        let found = read?;
        let binary = find_binary(&found, path, dir.path())?;
        Ok(Unpacked {
            description: found.description,
            fmi1: found.fmi1,
            fmi2: found.fmi2,
            fmi3: found.fmi3,
            interface: found.interface,
            identifier: found.identifier,
            binary,
            dir,
            states: found.states,
        })
    }
}

/// Reads the description of the FMU `path` unpacked in `dir`, chooses `interface` (`None`:
/// Co-Simulation when offered, else Model Exchange) and finds the binary for this platform.
fn inspect(path: &Path, dir: &Path, interface: Option<Interface>) -> Result<(Described, PathBuf), String> {
    let described = read_description(path, dir, interface)?;
    let binary = find_binary(&described, path, dir)?;
    Ok((described, binary))
}

/// What [`read_description`] reads of an unpacked FMU's description.
struct Described {
    states: Option<exchange::StateStructure>,
    description: Description,
    fmi1: Option<fmi_schema::fmi1::ModelDescription>,
    fmi2: Option<fmi_schema::fmi2::ModelDescription>,
    fmi3: Option<fmi_schema::fmi3::ModelDescription>,
    interface: Interface,
    identifier: String,
}

/// Reads the description of the FMU `path` from `dir` (where at least its
/// modelDescription.xml is unpacked) and chooses `interface`.
fn read_description(path: &Path, dir: &Path, interface: Option<Interface>) -> Result<Described, String> {
    let xml_path = dir.join("modelDescription.xml");
    let xml = std::fs::read_to_string(&xml_path).map_err(|e| format!("{}: no readable modelDescription.xml: {e}", path.display()))?;
    let at = |e: &dyn std::fmt::Display| format!("{}: modelDescription.xml: {e}", path.display());
    let version = fmi_schema::fmi_version(&xml).map_err(|e| at(&e))?;
    let (description, fmi1, fmi2, fmi3) = if version.starts_with("3.") {
        let raw = fmi_schema::fmi3::ModelDescription::from_xml(&xml).map_err(|e| at(&e))?;
        refuse_unsupported_fmi3(&raw).map_err(|e| format!("{}: {e}", path.display()))?;
        (fmi3::describe(&raw), None, None, Some(raw))
    } else if version.starts_with("1.") {
        let raw = fmi_schema::fmi1::ModelDescription::from_xml(&xml).map_err(|e| at(&e))?;
        (fmi1::describe(&raw), Some(raw), None, None)
    } else {
        let raw = fmi_schema::fmi2::ModelDescription::from_xml(&xml).map_err(|e| at(&e))?;
        (fmi2::describe(&raw), None, Some(raw), None)
    };
    let offered: Vec<Interface> =
        [Interface::CoSimulation, Interface::ModelExchange].into_iter().filter(|&i| description.interface(i).is_some()).collect();
    let interface = match interface {
        Some(asked) if offered.contains(&asked) => asked,
        Some(asked) => {
            let has = match offered.first() {
                Some(other) => format!("it offers {other} only (--interface {})", other.name()),
                None => "it declares neither interface".to_owned(),
            };
            return Err(format!("{}: this FMU does not support {asked}: {has}", path.display()));
        }
        None => {
            *offered.first().ok_or_else(|| format!("{}: this FMU declares neither Co-Simulation nor Model Exchange", path.display()))?
        }
    };
    let caps = description.interface(interface).expect("offered");
    if description.fmi_version == FmiVersion::Fmi1 && caps.needs_execution_tool {
        return Err(format!(
            "{}: this FMI 1.0 Co-Simulation FMU wraps a simulation tool (CoSimulation_Tool): its binary only talks to that tool, which the runner cannot provide",
            path.display()
        ));
    }
    if interface == Interface::ModelExchange && caps.needs_execution_tool {
        return Err(format!(
            "{}: this Model Exchange FMU needs an external simulation tool (needsExecutionTool=\"true\"): its binary only talks to that tool, which the runner cannot provide",
            path.display()
        ));
    }
    let identifier = caps.model_identifier.clone();
    // The identifier names the binary to load: with a '/' it could name any library on disk.
    if identifier.is_empty() || identifier.contains(['/', '\0']) {
        return Err(format!("{}: modelIdentifier {identifier:?} is not a file name (FMI requires a C identifier)", path.display()));
    }
    let states = match (&fmi2, &fmi3) {
        (Some(md), _) => fmi2::state_structure(md),
        (_, Some(md)) => fmi3::state_structure(md),
        _ => None,
    };
    Ok(Described { states, description, fmi1, fmi2, fmi3, interface, identifier })
}

/// The binary for this platform of the FMU `path` unpacked in `dir`, as `described` names it.
fn find_binary(described: &Described, path: &Path, dir: &Path) -> Result<PathBuf, String> {
    let Described { description, identifier, .. } = described;
    let platform = match description.fmi_version {
        FmiVersion::Fmi1 => fmi1::PLATFORM,
        FmiVersion::Fmi2 => fmi2::PLATFORM,
        FmiVersion::Fmi3 => fmi3::PLATFORM,
    };
    let binary = dir.join("binaries").join(platform).join(format!("{identifier}.so"));
    if !binary.is_file() {
        return Err(format!(
            "{}: no binary for this platform: binaries/{platform}/{identifier}.so is missing (the FMU has binaries for: {})",
            path.display(),
            platforms(&dir.join("binaries"))
        ));
    }
    Ok(binary)
}

/// Refuses the FMI 3.0 features the runner does not simulate, naming them: Scheduled Execution
/// (an FMU offering nothing else) and clocks.
fn refuse_unsupported_fmi3(md: &fmi_schema::fmi3::ModelDescription) -> Result<(), String> {
    if md.co_simulation.is_none() && md.model_exchange.is_none() && md.scheduled_execution.is_some() {
        return Err(
            "this FMU offers only Scheduled Execution, which the runner does not support (it runs Co-Simulation and Model Exchange)"
                .to_owned(),
        );
    }
    if let Some(clock) = md.model_variables.iter().find(|v| matches!(v.kind, fmi_schema::fmi3::VariableKind::Clock(_))) {
        return Err(format!("the FMU has clocks (variable '{}' is a Clock), which the runner does not support", clock.name));
    }
    Ok(())
}

/// The platform folders in an FMU's `binaries` folder, for messages (`none` if there are none).
pub fn platforms(binaries: &Path) -> String {
    let mut found: Vec<String> = std::fs::read_dir(binaries)
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    found.sort();
    if found.is_empty() {
        "none".to_owned()
    } else {
        found.join(", ")
    }
}

/// The loaded binary of an FMU, by FMI version (boxed: each holds its version's whole table of
/// functions).
enum Binding {
    Fmi1(Box<fmi1::Binary>),
    Fmi2(Box<fmi2::Binary>),
    Fmi3(Box<fmi3::Binary>),
}

/// A loaded FMU: its description, its open binary and the directory it was unpacked into
/// (deleted when the `Fmu` is dropped, after the binary is closed, unless someone else unpacked it:
/// [`Fmu::load_unpacked`]).
pub struct Fmu {
    /// The description, in the importer's model.
    pub description: Description,
    /// The modelIdentifier (name of the binary and of the model).
    pub identifier: String,
    /// The interface instances are created for.
    pub interface: Interface,
    /// Where the FMU's resources are, as instantiation wants it: a `file://` URI for FMI 2.0,
    /// a directory path with a trailing separator for FMI 3.0, the unpacked FMU's `file://` URI
    /// for FMI 1.0 (fmuLocation).
    pub(crate) resource_uri: CString,
    /// GUID (FMI 2.0) or instantiation token (FMI 3.0), as instantiation wants it.
    pub(crate) token: CString,
    /// The ModelStructure's continuous states, for the implicit methods' Jacobian.
    pub(crate) states: Option<exchange::StateStructure>,
    // Field order is drop order: close the library before deleting the files it came from.
    binding: Binding,
    _dir: Option<tempfile::TempDir>,
}

impl Fmu {
    /// Unpacks and loads the `.fmu` at `path`, for Co-Simulation when it offers it.
    pub fn load(path: &Path) -> Result<Fmu, String> {
        Self::load_as(path, None)
    }

    /// Unpacks and loads the `.fmu` at `path` for `interface` (`None`: Co-Simulation when
    /// offered, else Model Exchange).
    pub fn load_as(path: &Path, interface: Option<Interface>) -> Result<Fmu, String> {
        let Unpacked { description, interface, identifier, binary, dir, states, .. } = Unpacked::open_as(path, interface)?;
        let root = dir.path().to_path_buf();
        Fmu::assemble(path, (description, states), interface, identifier, &binary, &root, Some(dir))
    }

    /// Loads the FMU `path` from `dir`, where [`Unpacked::open_as`] unpacked it (possibly in
    /// another process, which keeps and deletes the directory: this `Fmu` never does), for
    /// `interface`. A worker process loads its supervisor's copy so: it unpacks nothing and, if
    /// it dies, leaves nothing behind.
    pub fn load_unpacked(path: &Path, dir: &Path, interface: Option<Interface>) -> Result<Fmu, String> {
        let (found, binary) = inspect(path, dir, interface)?;
        Fmu::assemble(path, (found.description, found.states), found.interface, found.identifier, &binary, dir, None)
    }

    /// Loads `binary` of the FMU `path` unpacked in `dir` (deleted with the `Fmu` if `owned`).
    fn assemble(
        path: &Path,
        (description, states): (Description, Option<exchange::StateStructure>),
        interface: Interface,
        identifier: String,
        binary: &Path,
        dir: &Path,
        owned: Option<tempfile::TempDir>,
    ) -> Result<Fmu, String> {
        let loaded = match description.fmi_version {
            FmiVersion::Fmi1 => {
                Binding::Fmi1(Box::new(fmi1::Binary::load(binary, interface, &identifier).map_err(|e| format!("{}: {e}", path.display()))?))
            }
            FmiVersion::Fmi2 => {
                Binding::Fmi2(Box::new(fmi2::Binary::load(binary, interface).map_err(|e| format!("{}: {e}", path.display()))?))
            }
            FmiVersion::Fmi3 => {
                Binding::Fmi3(Box::new(fmi3::Binary::load(binary, interface).map_err(|e| format!("{}: {e}", path.display()))?))
            }
        };
        let resources = dir.join("resources");
        let resource_uri = match description.fmi_version {
            // FMI 1.0's fmuLocation: the unpacked FMU itself, not its resources.
            FmiVersion::Fmi1 => format!("file://{}", dir.display()),
            FmiVersion::Fmi2 => format!("file://{}/", resources.display()),
            FmiVersion::Fmi3 => format!("{}/", resources.display()),
        };
        let resource_uri = CString::new(resource_uri).map_err(|_| "temporary path contains a NUL byte".to_owned())?;
        let token = CString::new(description.instantiation_token.clone())
            .map_err(|_| format!("{}: the GUID contains a NUL byte", path.display()))?;
        Ok(Fmu { description, identifier, interface, resource_uri, token, states, binding: loaded, _dir: owned })
    }

    /// Who this FMU's saved states belong to ([`state::SavedState::to_bytes`]).
    pub fn state_identity(&self) -> state::Identity<'_> {
        state::Identity::of(&self.description, self.interface)
    }

    /// A new instance named `name`; `debug_logging` turns the FMU's debug logging on.
    pub fn instantiate(&self, name: &str, debug_logging: bool) -> Result<Instance<'_>, String> {
        match &self.binding {
            Binding::Fmi1(binary) => Ok(match self.interface {
                Interface::CoSimulation => Instance::Fmi1Cs(fmi1::CoSimulation::new(self, binary, name, debug_logging)?),
                Interface::ModelExchange => {
                    Instance::Fmi1Me(Box::new(fmi1::instantiate_model_exchange(self, binary, name, debug_logging)?))
                }
            }),
            Binding::Fmi2(binary) => Ok(match self.interface {
                Interface::CoSimulation => Instance::Fmi2Cs(fmi2::CoSimulation::new(self, binary, name, debug_logging)?),
                Interface::ModelExchange => {
                    Instance::Fmi2Me(Box::new(fmi2::instantiate_model_exchange(self, binary, name, debug_logging)?))
                }
            }),
            Binding::Fmi3(binary) => Ok(match self.interface {
                Interface::CoSimulation => Instance::Fmi3Cs(fmi3::CoSimulation::new(self, binary, name, debug_logging)?),
                Interface::ModelExchange => {
                    Instance::Fmi3Me(Box::new(fmi3::instantiate_model_exchange(self, binary, name, debug_logging)?))
                }
            }),
        }
    }
}

/// A value to set, already converted to the variable's type.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Real, Float64 and Float32 (rounded to single precision when set).
    Real(f64),
    /// Integer (Int32, and FMI 2.0's Enumeration).
    Integer(i32),
    /// The other integer types and FMI 3.0's Enumeration, checked against the type's range.
    Int(i128),
    Boolean(bool),
    String(String),
    /// FMI 3.0 Binary.
    Binary(Vec<u8>),
    /// The elements of an FMI 3.0 array, row-major, set whole.
    List(Vec<Value>),
}

impl Value {
    /// The value as a number, where it is one (Booleans as 0/1).
    pub fn as_number(&self) -> Option<f64> {
        match self {
            Value::Real(x) => Some(*x),
            Value::Integer(i) => Some(f64::from(*i)),
            Value::Int(i) => Some(*i as f64),
            Value::Boolean(b) => Some(f64::from(u8::from(*b))),
            Value::String(_) | Value::Binary(_) | Value::List(_) => None,
        }
    }
}

/// How a step ended.
pub enum Step {
    /// The step reached its end.
    Done,
    /// The FMU refused to continue (it terminated the simulation): why, and the last time it
    /// reached when it reports one.
    Ended { reason: String, last_time: Option<f64> },
    /// The step stopped at an event at `time` (FMI 3.0 Event Mode or early return), before
    /// handling it: call [`Instance::handle_event`], then step on from `time`.
    Event { time: f64 },
}

/// One instance of an FMU, whatever its version and interface: the calls of a simulation run.
/// An enum rather than a trait object: the run loop calls `do_step` and `read` once per
/// communication point, and a match inlines where a virtual call cannot.
pub enum Instance<'a> {
    Fmi2Cs(fmi2::CoSimulation<'a>),
    /// Integrated by the runner (see [`exchange::ModelExchange`]); boxed, as it carries the
    /// integrator.
    Fmi2Me(Box<fmi2::ModelExchange<'a>>),
    Fmi3Cs(fmi3::CoSimulation<'a>),
    /// Integrated by the runner, as FMI 2.0's.
    Fmi3Me(Box<fmi3::ModelExchange<'a>>),
    Fmi1Cs(fmi1::CoSimulation<'a>),
    /// Integrated by the runner, as FMI 2.0's.
    Fmi1Me(Box<fmi1::ModelExchange<'a>>),
}

impl Instance<'_> {
    /// The runner's integrator for a Model Exchange instance (before initialization ends);
    /// a Co-Simulation FMU integrates itself and ignores it.
    pub fn set_solver(&mut self, solver: Solver) {
        match self {
            Instance::Fmi2Cs(_) | Instance::Fmi1Cs(_) | Instance::Fmi3Cs(_) => {}
            Instance::Fmi2Me(i) => i.set_solver(solver),
            Instance::Fmi1Me(i) => i.set_solver(solver),
            Instance::Fmi3Me(i) => i.set_solver(solver),
        }
    }

    /// Sets up the experiment: an optional relative tolerance, the start and stop time.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.setup_experiment(tolerance, start, stop),
            Instance::Fmi1Cs(i) => i.setup_experiment(tolerance, start, stop),
            Instance::Fmi3Cs(i) => i.setup_experiment(tolerance, start, stop),
            Instance::Fmi2Me(i) => i.setup_experiment(tolerance, start, stop),
            Instance::Fmi1Me(i) => i.setup_experiment(tolerance, start, stop),
            Instance::Fmi3Me(i) => i.setup_experiment(tolerance, start, stop),
        }
    }

    /// Enters initialization mode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.enter_initialization_mode(),
            Instance::Fmi1Cs(i) => i.enter_initialization_mode(),
            Instance::Fmi3Cs(i) => i.enter_initialization_mode(),
            Instance::Fmi2Me(i) => i.enter_initialization_mode(),
            Instance::Fmi1Me(i) => i.enter_initialization_mode(),
            Instance::Fmi3Me(i) => i.enter_initialization_mode(),
        }
    }

    /// Leaves initialization mode: the instance is ready to step.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.exit_initialization_mode(),
            Instance::Fmi1Cs(i) => i.exit_initialization_mode(),
            Instance::Fmi3Cs(i) => i.exit_initialization_mode(),
            Instance::Fmi2Me(i) => i.exit_initialization_mode(),
            Instance::Fmi1Me(i) => i.exit_initialization_mode(),
            Instance::Fmi3Me(i) => i.exit_initialization_mode(),
        }
    }

    /// Sets one variable.
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set(variable, value),
            Instance::Fmi1Cs(i) => i.set(variable, value),
            Instance::Fmi3Cs(i) => i.set(variable, value),
            Instance::Fmi2Me(i) => i.set(variable, value),
            Instance::Fmi1Me(i) => i.set(variable, value),
            Instance::Fmi3Me(i) => i.set(variable, value),
        }
    }

    /// Reads a String variable: its text, each element's for an FMI 3.0 array (after
    /// initialization has begun, as FMI allows).
    pub fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String> {
        match self {
            Instance::Fmi2Cs(i) => i.get_string(variable).map(|text| vec![text]),
            Instance::Fmi1Cs(i) => i.get_string(variable).map(|text| vec![text]),
            Instance::Fmi3Cs(i) => i.get_string(variable),
            Instance::Fmi2Me(i) => i.get_string(variable),
            Instance::Fmi1Me(i) => i.get_string(variable),
            Instance::Fmi3Me(i) => i.get_string(variable),
        }
    }

    /// Sets the first time derivative of the Real input `variable` (FMI 2.0 Co-Simulation FMUs
    /// that declare `canInterpolateInputs`; the others are refused).
    pub fn set_input_derivative(&mut self, variable: &Variable, derivative: f64) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set_input_derivative(variable, derivative),
            Instance::Fmi1Cs(i) => i
                .set_input_derivatives(&[variable.value_reference], &[1], &[derivative])
                .map_err(|e| format!("{e} (the derivative of {})", variable.name)),
            Instance::Fmi2Me(_) | Instance::Fmi1Me(_) | Instance::Fmi3Cs(_) | Instance::Fmi3Me(_) => {
                Err(format!("{}: input derivatives are passed to FMI 1.0 and 2.0 Co-Simulation FMUs only", variable.name))
            }
        }
    }

    /// Sets time derivatives of Real inputs, `values[k]` the `orders[k]`-th of `vrs[k]` (FMI 2.0
    /// Co-Simulation FMUs that declare `canInterpolateInputs`; FMI 3.0 has no such call).
    /// Inlined, as [`Instance::read`]: a system's master calls it at every communication step.
    #[inline(always)]
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set_input_derivatives(vrs, orders, values),
            Instance::Fmi1Cs(i) => i.set_input_derivatives(vrs, orders, values),
            Instance::Fmi2Me(_) | Instance::Fmi1Me(_) | Instance::Fmi3Cs(_) | Instance::Fmi3Me(_) => {
                Err("input derivatives are passed to FMI 1.0 and 2.0 Co-Simulation FMUs only".to_owned())
            }
        }
    }

    /// Reads time derivatives of Real outputs, `out[k]` the `orders[k]`-th of `vrs[k]`
    /// (Co-Simulation FMUs that declare `maxOutputDerivativeOrder`). Inlined, as
    /// [`Instance::read`]: a system's master calls it at every communication step.
    #[inline(always)]
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], out: &mut [f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.get_output_derivatives(vrs, orders, out),
            Instance::Fmi1Cs(i) => i.get_output_derivatives(vrs, orders, out),
            Instance::Fmi3Cs(i) => i.get_output_derivatives(vrs, orders, out),
            Instance::Fmi2Me(_) | Instance::Fmi1Me(_) | Instance::Fmi3Me(_) => {
                Err("output derivatives come from Co-Simulation FMUs only".to_owned())
            }
        }
    }

    /// Reads the variables of `reader` into `out`, one f64 per variable (Booleans as 0/1).
    /// Always inlined, like [`Instance::do_step`]: a run calls both at every communication
    /// point, and as calls of their own they cost a frame each (about 20 instructions).
    #[inline(always)]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.read(reader, out),
            Instance::Fmi1Cs(i) => i.read(reader, out),
            Instance::Fmi3Cs(i) => i.read(reader, out),
            Instance::Fmi2Me(i) => i.read(reader, out),
            Instance::Fmi1Me(i) => i.read(reader, out),
            Instance::Fmi3Me(i) => i.read(reader, out),
        }
    }

    /// Sets Real (Float64) scalars, `values[k]` to `vrs[k]`, in one call without allocating:
    /// a master's inputs at every step. The caller checks that each is a settable Real.
    #[inline]
    pub fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set_reals(vrs, values),
            Instance::Fmi1Cs(i) => i.set_reals(vrs, values),
            Instance::Fmi3Cs(i) => i.set_reals(vrs, values),
            Instance::Fmi2Me(i) => i.set_reals(vrs, values),
            Instance::Fmi1Me(i) => i.set_reals(vrs, values),
            Instance::Fmi3Me(i) => i.set_reals(vrs, values),
        }
    }

    /// Advances from the communication point `t` over `h`.
    #[inline(always)]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        match self {
            Instance::Fmi2Cs(i) => i.do_step(t, h),
            Instance::Fmi1Cs(i) => i.do_step(t, h),
            Instance::Fmi2Me(i) => i.do_step(t, h),
            Instance::Fmi1Me(i) => i.do_step(t, h),
            Instance::Fmi3Me(i) => i.do_step(t, h),
            Instance::Fmi3Cs(i) => i.do_step(t, h),
        }
    }

    /// The work of the runner's integrator (steps, evaluations, the implicit methods'
    /// Jacobians and Newton failures), for a Model Exchange instance (`None` for
    /// Co-Simulation, whose FMU does the integration).
    pub fn counters(&self) -> Option<exchange::Counters> {
        match self {
            Instance::Fmi2Cs(_) | Instance::Fmi1Cs(_) | Instance::Fmi3Cs(_) => None,
            Instance::Fmi2Me(i) => Some(i.solver_counters()),
            Instance::Fmi1Me(i) => Some(i.solver_counters()),
            Instance::Fmi3Me(i) => Some(i.solver_counters()),
        }
    }

    /// Sets an input or a tunable parameter between steps, where the interface wants it (Model
    /// Exchange: a parameter in event mode, and the integrator restarted).
    pub fn set_between_steps(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set(variable, value),
            Instance::Fmi1Cs(i) => i.set(variable, value),
            Instance::Fmi3Cs(i) => i.set(variable, value),
            Instance::Fmi2Me(i) => i.set_between_steps(variable, value),
            Instance::Fmi1Me(i) => i.set_between_steps(variable, value),
            Instance::Fmi3Me(i) => i.set_between_steps(variable, value),
        }
    }

    /// Reset (fmi2Reset, fmi3Reset): back to the state right after instantiation, to set up and
    /// initialize again without a new instance.
    pub fn reset(&mut self) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.reset(),
            Instance::Fmi1Cs(i) => i.reset(),
            Instance::Fmi3Cs(i) => i.reset(),
            Instance::Fmi2Me(i) => i.reset(),
            Instance::Fmi1Me(i) => i.reset(),
            Instance::Fmi3Me(i) => i.reset(),
        }
    }

    /// The instance's state at `time` (the time a Co-Simulation instance reached; a Model
    /// Exchange instance knows its own): the FMU's serialized state and what the runner keeps.
    pub fn save_state(&mut self, time: f64) -> Result<state::SavedState, String> {
        let (time, next_event_time, fmu) = match self {
            Instance::Fmi2Cs(i) => (time, None, i.get_state()?),
            Instance::Fmi1Cs(i) => (time, None, i.get_state()?),
            Instance::Fmi3Cs(i) => (time, None, i.get_state()?),
            Instance::Fmi2Me(i) => i.get_state()?,
            Instance::Fmi1Me(i) => i.get_state()?,
            Instance::Fmi3Me(i) => i.get_state()?,
        };
        Ok(state::SavedState { time, next_event_time, fmu })
    }

    /// Restores a state of [`Instance::save_state`] taken from an instance of the same FMU.
    pub fn restore_state(&mut self, saved: &state::SavedState) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set_state(&saved.fmu),
            Instance::Fmi1Cs(i) => i.set_state(&saved.fmu),
            Instance::Fmi3Cs(i) => i.set_state(&saved.fmu),
            Instance::Fmi2Me(i) => i.set_state(saved.time, saved.next_event_time, &saved.fmu),
            Instance::Fmi1Me(i) => i.set_state(saved.time, saved.next_event_time, &saved.fmu),
            Instance::Fmi3Me(i) => i.set_state(saved.time, saved.next_event_time, &saved.fmu),
        }
    }

    /// Moves a Model Exchange instance's states to `x` (see `ModelExchange::move_states`).
    pub fn move_states(&mut self, x: &[f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Me(i) => i.move_states(x),
            Instance::Fmi1Me(i) => i.move_states(x),
            Instance::Fmi3Me(i) => i.move_states(x),
            Instance::Fmi2Cs(_) | Instance::Fmi1Cs(_) | Instance::Fmi3Cs(_) => {
                Err("a Co-Simulation FMU integrates its states itself: they cannot be moved".to_owned())
            }
        }
    }

    /// For tests/bench/jacobian only (the `bench-hooks` feature): see
    /// `ModelExchange::bench_solver_jacobian`.
    #[cfg(feature = "bench-hooks")]
    pub fn bench_solver_jacobian(&mut self, x: &[f64], directional: bool, jacobian: &mut [f64], work: &mut [f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Me(i) => i.bench_solver_jacobian(x, directional, jacobian, work),
            Instance::Fmi1Me(i) => i.bench_solver_jacobian(x, directional, jacobian, work),
            Instance::Fmi3Me(i) => i.bench_solver_jacobian(x, directional, jacobian, work),
            Instance::Fmi2Cs(_) | Instance::Fmi1Cs(_) | Instance::Fmi3Cs(_) => {
                Err("the runner's integrator needs Model Exchange".to_owned())
            }
        }
    }

    /// The linearization at the instance's current time and states over `ports` (see
    /// [`exchange::Jacobians`]): a Model Exchange instance only.
    pub fn linearize(&mut self, ports: exchange::Ports, prefer: exchange::JacobianSource) -> Result<exchange::Jacobians, String> {
        match self {
            Instance::Fmi2Me(i) => i.linearize(ports, prefer),
            Instance::Fmi1Me(i) => i.linearize(ports, prefer),
            Instance::Fmi3Me(i) => i.linearize(ports, prefer),
            Instance::Fmi2Cs(_) | Instance::Fmi1Cs(_) | Instance::Fmi3Cs(_) => {
                Err("linearization needs the FMU's Model Exchange interface (the states and their derivatives)".to_owned())
            }
        }
    }

    /// Handles the event a [`Step::Event`] stopped at: `Ok(Some(reason))` when the FMU ends
    /// the simulation there.
    pub fn handle_event(&mut self, time: f64) -> Result<Option<String>, String> {
        match self {
            Instance::Fmi2Cs(_) | Instance::Fmi2Me(_) | Instance::Fmi1Cs(_) | Instance::Fmi1Me(_) | Instance::Fmi3Me(_) => Ok(None),
            Instance::Fmi3Cs(i) => i.handle_event(time),
        }
    }
}

/// The text of a string the FMU returned for `name` from `call`: NULL and invalid UTF-8 are
/// the FMU's faults, reported as such.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string valid for the call.
pub(crate) unsafe fn text_of(p: *const std::ffi::c_char, name: &str, call: &str) -> Result<String, String> {
    if p.is_null() {
        return Err(format!("{call} of {name}: the FMU returned a NULL string"));
    }
    std::ffi::CStr::from_ptr(p)
        .to_str()
        .map(str::to_owned)
        .map_err(|e| format!("{call} of {name}: the FMU returned text that is not UTF-8 ({e})"))
}

#[cfg(test)]
mod tests {
    /// dlopen's messages as glibc words them, each with its advice.
    #[test]
    fn loading_errors_say_what_to_do() {
        let missing =
            explain_load_error("cannot load /x/f.so: libfoo.so.2: cannot open shared object file: No such file or directory".into(), &[]);
        assert!(missing.contains("needs the library libfoo.so.2") && missing.contains("LD_LIBRARY_PATH"), "{missing}");
        let python = explain_load_error("cannot load /x/f.so: /x/f.so: undefined symbol: _Py_NoneStruct".into(), &[]);
        assert!(python.contains("_Py_NoneStruct is Python's") && python.contains("LD_PRELOAD=libpython3.X.so"), "{python}");
        let other = "cannot load /x/f.so: /x/f.so: undefined symbol: my_helper";
        assert_eq!(explain_load_error(other.into(), &[]), other, "other messages stay as they are");
    }

    use super::*;

    /// A third-party FMU's reason gets the time; this toolkit's, which says it, does not twice.
    #[test]
    fn an_early_end_says_when_once() {
        assert_eq!(model_ended("t = 2.5", "landed"), "the model ended the simulation at t = 2.5: landed");
        let ours = "the simulation ended at t = 2.5 s: the projectile landed";
        assert_eq!(model_ended("t = 2.5", ours), ours);
    }
    use crate::archive::{write_zip, Entry};

    /// The implicit methods' finite-difference Jacobian groups the columns that share no row of
    /// the ModelStructure `Derivatives` dependencies (issue 33): the description's 1-based
    /// variable indices become state indices, dependencies on other variables (a parameter)
    /// drop out, and a derivative without `dependencies` (it may depend on every state) makes
    /// the pattern dense. Here der(x1) <- x1, k; der(x2) <- x1, x2; der(x3) <- x3: columns x1
    /// and x3 share no row, so two evaluations give the three columns.
    #[test]
    fn model_structure_dependencies_group_the_jacobian_columns() {
        let xml = |x3_dependencies: &str| {
            format!(
                r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g">
  <ModelExchange modelIdentifier="m"/>
  <ModelVariables>
    <ScalarVariable name="x1" valueReference="10" causality="local" variability="continuous" initial="exact"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="der(x1)" valueReference="11" causality="local" variability="continuous"><Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="x2" valueReference="12" causality="local" variability="continuous" initial="exact"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="der(x2)" valueReference="13" causality="local" variability="continuous"><Real derivative="3"/></ScalarVariable>
    <ScalarVariable name="x3" valueReference="14" causality="local" variability="continuous" initial="exact"><Real start="1"/></ScalarVariable>
    <ScalarVariable name="der(x3)" valueReference="15" causality="local" variability="continuous"><Real derivative="5"/></ScalarVariable>
    <ScalarVariable name="k" valueReference="16" causality="parameter" variability="fixed"><Real start="1"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Derivatives>
      <Unknown index="2" dependencies="1 7"/>
      <Unknown index="4" dependencies="1 3"/>
      <Unknown index="6" {x3_dependencies}/>
    </Derivatives>
  </ModelStructure>
</fmiModelDescription>"#
            )
        };
        let md = fmi_schema::fmi2::ModelDescription::from_xml(&xml(r#"dependencies="5""#)).unwrap();
        let structure = fmi2::state_structure(&md).unwrap();
        assert_eq!((structure.states.as_slice(), structure.derivatives.as_slice()), ([10, 12, 14].as_slice(), [11, 13, 15].as_slice()));
        let pattern = structure.pattern.expect("every derivative declares its dependencies");
        assert_eq!(pattern, [vec![0], vec![0, 1], vec![2]]);
        let (groups, _) = solvers::implicit::column_groups(3, Some(&pattern));
        assert_eq!(groups, [vec![0, 2], vec![1]]);
        // der(x3) without dependencies: it may depend on every state, so one column a call.
        let md = fmi_schema::fmi2::ModelDescription::from_xml(&xml("")).unwrap();
        let pattern = fmi2::state_structure(&md).unwrap().pattern;
        assert_eq!(pattern, None);
        assert_eq!(solvers::implicit::column_groups(3, pattern.as_deref()).0.len(), 3);
    }

    #[test]
    fn a_model_identifier_with_a_path_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let fmu = dir.path().join("traversal.fmu");
        let xml = r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="g">
  <CoSimulation modelIdentifier="../../m"/>
  <ModelVariables/>
  <ModelStructure/>
</fmiModelDescription>"#;
        // Without the check, binaries/linux64/../../m.so would resolve to the archive's m.so.
        let entries = [
            Entry { path: "modelDescription.xml", bytes: xml.as_bytes() },
            Entry { path: "binaries/linux64/other.so", bytes: b"\x7fELF" },
            Entry { path: "m.so", bytes: b"\x7fELF" },
        ];
        write_zip(std::fs::File::create(&fmu).unwrap(), &entries).unwrap();
        let error = Unpacked::open(&fmu).err().expect("the FMU must be refused");
        assert!(error.contains("traversal.fmu") && error.contains("modelIdentifier \"../../m\" is not a file name"), "{error}");
    }
}
