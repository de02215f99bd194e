//! The FMU importer: unpacks any `.fmu` safely ([`archive`]), reads its description into one
//! model whatever its FMI version ([`model`]), loads its binary and drives instances of it
//! through the FMI bindings ([`fmi2`]). One [`Instance`] type runs an FMU whatever its version
//! and interface. It depends on the FMI C interface and schema only, never on our exporter.

pub mod archive;
pub mod fmi2;
mod logging;
pub mod model;
pub mod trace;

use std::ffi::CString;
use std::path::{Path, PathBuf};

pub use logging::{print_line, set_log_printer};
pub use model::{Causality, Description, FmiVersion, Interface, Kind, Variability, Variable};

/// An FMU archive unpacked into a temporary directory and checked up to the point of loading its
/// binary: everything the importer reads from a file it did not write, before running any of it.
pub struct Unpacked {
    /// The description, in the importer's model.
    pub description: Description,
    /// The FMI 2.0 description as written (for checks that need the raw schema).
    pub fmi2: Option<fmi_schema::fmi2::ModelDescription>,
    /// The interface the binary will be driven through.
    pub interface: Interface,
    /// The modelIdentifier of that interface.
    pub identifier: String,
    /// The shared library for this platform inside `dir`.
    pub binary: PathBuf,
    /// The directory the archive was extracted into (deleted on drop).
    pub dir: tempfile::TempDir,
}

impl Unpacked {
    /// Extracts `path` safely, parses its modelDescription.xml and finds the binary for this
    /// platform.
    pub fn open(path: &Path) -> Result<Unpacked, String> {
        if !path.is_file() {
            return Err(format!("FMU file {} does not exist", path.display()));
        }
        let dir =
            tempfile::Builder::new().prefix("runner-fmu-").tempdir().map_err(|e| format!("cannot create a temporary directory: {e}"))?;
        archive::extract_zip(path, dir.path())?;
        let (description, raw, interface, identifier, binary) = inspect(path, dir.path())?;
        Ok(Unpacked { description, fmi2: Some(raw), interface, identifier, binary, dir })
    }
}

/// What [`Unpacked::open`] reads from the directory `dir` that the FMU `path` was unpacked into.
#[allow(clippy::type_complexity)]
fn inspect(path: &Path, dir: &Path) -> Result<(Description, fmi_schema::fmi2::ModelDescription, Interface, String, PathBuf), String> {
    let xml_path = dir.join("modelDescription.xml");
    let xml = std::fs::read_to_string(&xml_path).map_err(|e| format!("{}: no readable modelDescription.xml: {e}", path.display()))?;
    let raw = fmi_schema::fmi2::ModelDescription::from_xml(&xml).map_err(|e| format!("{}: modelDescription.xml: {e}", path.display()))?;
    let description = fmi2::describe(&raw);
    let interface = Interface::CoSimulation;
    let identifier = match description.interface(interface) {
        Some(caps) => caps.model_identifier.clone(),
        None => return Err(format!("{}: this FMU does not support Co-Simulation", path.display())),
    };
    // The identifier names the binary to load: with a '/' it could name any library on disk.
    if identifier.is_empty() || identifier.contains(['/', '\0']) {
        return Err(format!("{}: modelIdentifier {identifier:?} is not a file name (FMI requires a C identifier)", path.display()));
    }
    let platform = fmi2::PLATFORM;
    let binary = dir.join("binaries").join(platform).join(format!("{identifier}.so"));
    if !binary.is_file() {
        return Err(format!(
            "{}: no binary for this platform: binaries/{platform}/{identifier}.so is missing (the FMU has binaries for: {})",
            path.display(),
            platforms(&dir.join("binaries"))
        ));
    }
    Ok((description, raw, interface, identifier, binary))
}

fn platforms(binaries: &Path) -> String {
    let mut found: Vec<String> = std::fs::read_dir(binaries)
        .map(|d| d.filter_map(|e| e.ok()).filter_map(|e| e.file_name().to_str().map(str::to_owned)).collect())
        .unwrap_or_default();
    found.sort();
    if found.is_empty() {
        "none".to_owned()
    } else {
        found.join(", ")
    }
}

/// The loaded binary of an FMU, by FMI version.
enum Binding {
    Fmi2(fmi2::Binary),
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
    pub(crate) resource_uri: CString,
    /// GUID (FMI 2.0) or instantiation token (FMI 3.0), as instantiation wants it.
    pub(crate) token: CString,
    // Field order is drop order: close the library before deleting the files it came from.
    binding: Binding,
    _dir: Option<tempfile::TempDir>,
}

impl Fmu {
    /// Unpacks and loads the `.fmu` at `path`.
    pub fn load(path: &Path) -> Result<Fmu, String> {
        let Unpacked { description, interface, identifier, binary, dir, .. } = Unpacked::open(path)?;
        let root = dir.path().to_path_buf();
        Fmu::assemble(path, description, interface, identifier, &binary, &root, Some(dir))
    }

    /// Loads the FMU `path` from `dir`, where [`Unpacked::open`] unpacked it (possibly in another
    /// process, which keeps and deletes the directory: this `Fmu` never does). A worker process
    /// loads its supervisor's copy so: it unpacks nothing and, if it dies, leaves nothing behind.
    pub fn load_unpacked(path: &Path, dir: &Path) -> Result<Fmu, String> {
        let (description, _, interface, identifier, binary) = inspect(path, dir)?;
        Fmu::assemble(path, description, interface, identifier, &binary, dir, None)
    }

    /// Loads `binary` of the FMU `path` unpacked in `dir` (deleted with the `Fmu` if `owned`).
    fn assemble(
        path: &Path,
        description: Description,
        interface: Interface,
        identifier: String,
        binary: &Path,
        dir: &Path,
        owned: Option<tempfile::TempDir>,
    ) -> Result<Fmu, String> {
        let loaded = fmi2::Binary::load(binary, interface == Interface::CoSimulation).map_err(|e| format!("{}: {e}", path.display()))?;
        let resource_uri = CString::new(format!("file://{}/", dir.join("resources").display()))
            .map_err(|_| "temporary path contains a NUL byte".to_owned())?;
        let token = CString::new(description.instantiation_token.clone())
            .map_err(|_| format!("{}: the GUID contains a NUL byte", path.display()))?;
        Ok(Fmu { description, identifier, interface, resource_uri, token, binding: Binding::Fmi2(loaded), _dir: owned })
    }

    /// A new instance named `name`; `debug_logging` turns the FMU's debug logging on.
    pub fn instantiate(&self, name: &str, debug_logging: bool) -> Result<Instance<'_>, String> {
        match &self.binding {
            Binding::Fmi2(binary) => Ok(Instance::Fmi2Cs(fmi2::CoSimulation::new(self, binary, name, debug_logging)?)),
        }
    }
}

/// A value to set, already converted to the variable's type.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// Real (Float64).
    Real(f64),
    /// Integer (also Enumeration).
    Integer(i32),
    Boolean(bool),
    String(String),
}

/// How a step ended.
pub enum Step {
    /// The step reached its end.
    Done,
    /// The FMU refused to continue (it terminated the simulation): why, and the last time it
    /// reached when it reports one.
    Ended { reason: String, last_time: Option<f64> },
}

/// One instance of an FMU, whatever its version and interface: the calls of a simulation run.
/// An enum rather than a trait object: the run loop calls `do_step` and `read` once per
/// communication point, and a match inlines where a virtual call cannot.
pub enum Instance<'a> {
    Fmi2Cs(fmi2::CoSimulation<'a>),
}

impl Instance<'_> {
    /// Sets up the experiment: an optional relative tolerance, the start and stop time.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.setup_experiment(tolerance, start, stop),
        }
    }

    /// Enters initialization mode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.enter_initialization_mode(),
        }
    }

    /// Leaves initialization mode: the instance is ready to step.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.exit_initialization_mode(),
        }
    }

    /// Sets one variable.
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.set(variable, value),
        }
    }

    /// Reads the variables of `reader` into `out`, one f64 per variable (Booleans as 0/1).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        match self {
            Instance::Fmi2Cs(i) => i.read(reader, out),
        }
    }

    /// Advances from the communication point `t` over `h`.
    #[inline]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        match self {
            Instance::Fmi2Cs(i) => i.do_step(t, h),
        }
    }
}

/// Reads a fixed list of numeric variables in one get call per type.
pub struct Reader {
    layout: Vec<(Kind, usize)>,
    pub(crate) real_vrs: Vec<u32>,
    pub(crate) real_buf: Vec<f64>,
    pub(crate) integer_vrs: Vec<u32>,
    pub(crate) integer_buf: Vec<i32>,
    pub(crate) boolean_vrs: Vec<u32>,
    pub(crate) boolean_buf: Vec<i32>,
}

impl Reader {
    /// A reader for `variables`, in order; String variables are refused.
    pub fn new(variables: &[&Variable]) -> Result<Reader, String> {
        let mut r = Reader {
            layout: Vec::new(),
            real_vrs: Vec::new(),
            real_buf: Vec::new(),
            integer_vrs: Vec::new(),
            integer_buf: Vec::new(),
            boolean_vrs: Vec::new(),
            boolean_buf: Vec::new(),
        };
        for v in variables {
            let list = match v.kind {
                Kind::Real => &mut r.real_vrs,
                Kind::Integer | Kind::Enumeration => &mut r.integer_vrs,
                Kind::Boolean => &mut r.boolean_vrs,
                Kind::String => return Err(format!("{} is a String variable; only numbers can be recorded", v.name)),
            };
            r.layout.push((v.kind, list.len()));
            list.push(v.value_reference);
        }
        r.real_buf = vec![0.0; r.real_vrs.len()];
        r.integer_buf = vec![0; r.integer_vrs.len()];
        r.boolean_buf = vec![0; r.boolean_vrs.len()];
        Ok(r)
    }

    /// Copies the per-type buffers into `out` in the reader's order.
    pub(crate) fn gather(&self, out: &mut [f64]) {
        for (slot, &(kind, i)) in out.iter_mut().zip(&self.layout) {
            *slot = match kind {
                Kind::Real => self.real_buf[i],
                Kind::Boolean => (self.boolean_buf[i] != 0) as i32 as f64,
                _ => self.integer_buf[i] as f64,
            };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::archive::{write_zip, Entry};

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
