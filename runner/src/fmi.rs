//! The FMI 2.0 Co-Simulation importer: unpacks an `.fmu`, reads its description, loads its
//! binary, resolves the `fmi2*` functions and drives instances of it. It assumes nothing about
//! who exported the FMU beyond the standard.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use fmu::description::{ModelDescription, ScalarVariable, TypeKind};
use fmu::ffi::{CallbackFunctions, LoggerFn, TERMINATED};

use crate::archive;
use crate::library::Library;
use crate::package::PLATFORM;
use crate::progress;

/// fmi2Status values.
const OK: c_int = 0;
const WARNING: c_int = 1;
const DISCARD: c_int = 2;
const ERROR: c_int = 3;
const FATAL: c_int = 4;
/// fmi2StatusKind fmi2LastSuccessfulTime.
const LAST_SUCCESSFUL_TIME: c_int = 2;

fn status_name(status: c_int) -> &'static str {
    match status {
        OK => "fmi2OK",
        WARNING => "fmi2Warning",
        DISCARD => "fmi2Discard",
        ERROR => "fmi2Error",
        FATAL => "fmi2Fatal",
        5 => "fmi2Pending",
        _ => "an unknown fmi2Status",
    }
}

extern "C" {
    /// The variadic logger of `logger.c`; it formats and forwards to [`runner_log_message`].
    fn runner_fmi_logger(env: *mut c_void, instance: *const c_char, status: c_int, category: *const c_char, message: *const c_char, ...);
}

/// What the logger knows about one instance: the last problem it reported, for error messages.
struct LogContext {
    last_problem: Mutex<Option<String>>,
}

unsafe fn c_text<'a>(p: *const c_char) -> std::borrow::Cow<'a, str> {
    if p.is_null() {
        "".into()
    } else {
        CStr::from_ptr(p).to_string_lossy()
    }
}

/// Receives every FMU log message, already formatted by `logger.c`: prints it with the instance
/// name on stderr and remembers problems (discard and worse) for the call's error message.
#[no_mangle]
pub unsafe extern "C" fn runner_log_message(env: *mut c_void, instance: *const c_char, status: c_int, category: *const c_char, text: *const c_char) {
    let (instance, category, text) = (c_text(instance), c_text(category), c_text(text));
    let level = match status {
        OK => "info",
        WARNING => "warning",
        DISCARD => "discard",
        ERROR => "error",
        FATAL => "fatal",
        _ => "log",
    };
    // Above the progress bar, if one is drawn; this never panics (it must not unwind into C).
    progress::eprint_line(&format!("[{instance}] {level} ({category}): {text}"));
    if status >= DISCARD && !env.is_null() {
        let context = &*(env as *const LogContext);
        if let Ok(mut last) = context.last_problem.lock() {
            *last = Some(text.into_owned());
        }
    }
}

type Component = *mut c_void;

/// The FMI functions the importer calls, resolved once per loaded binary.
struct Api {
    get_version: unsafe extern "C" fn() -> *const c_char,
    get_types_platform: unsafe extern "C" fn() -> *const c_char,
    instantiate: unsafe extern "C" fn(*const c_char, c_int, *const c_char, *const c_char, *const CallbackFunctions, c_int, c_int) -> Component,
    free_instance: unsafe extern "C" fn(Component),
    setup_experiment: unsafe extern "C" fn(Component, c_int, f64, f64, c_int, f64) -> c_int,
    enter_initialization_mode: unsafe extern "C" fn(Component) -> c_int,
    exit_initialization_mode: unsafe extern "C" fn(Component) -> c_int,
    terminate: unsafe extern "C" fn(Component) -> c_int,
    get_real: unsafe extern "C" fn(Component, *const u32, usize, *mut f64) -> c_int,
    get_integer: unsafe extern "C" fn(Component, *const u32, usize, *mut c_int) -> c_int,
    get_boolean: unsafe extern "C" fn(Component, *const u32, usize, *mut c_int) -> c_int,
    set_real: unsafe extern "C" fn(Component, *const u32, usize, *const f64) -> c_int,
    set_integer: unsafe extern "C" fn(Component, *const u32, usize, *const c_int) -> c_int,
    set_boolean: unsafe extern "C" fn(Component, *const u32, usize, *const c_int) -> c_int,
    set_string: unsafe extern "C" fn(Component, *const u32, usize, *const *const c_char) -> c_int,
    do_step: unsafe extern "C" fn(Component, f64, f64, c_int) -> c_int,
    get_boolean_status: unsafe extern "C" fn(Component, c_int, *mut c_int) -> c_int,
    get_real_status: unsafe extern "C" fn(Component, c_int, *mut f64) -> c_int,
}

impl Api {
    // Each transmute's target type is the field it initializes, which spells the C signature.
    #[allow(clippy::missing_transmute_annotations)]
    fn resolve(lib: &Library) -> Result<Api, String> {
        macro_rules! get {
            ($name:literal) => {
                // SAFETY: the FMI 2.0 standard fixes this symbol's C signature, which the field's type spells.
                unsafe { std::mem::transmute::<*mut c_void, _>(lib.symbol($name)?) }
            };
        }
        Ok(Api {
            get_version: get!("fmi2GetVersion"),
            get_types_platform: get!("fmi2GetTypesPlatform"),
            instantiate: get!("fmi2Instantiate"),
            free_instance: get!("fmi2FreeInstance"),
            setup_experiment: get!("fmi2SetupExperiment"),
            enter_initialization_mode: get!("fmi2EnterInitializationMode"),
            exit_initialization_mode: get!("fmi2ExitInitializationMode"),
            terminate: get!("fmi2Terminate"),
            get_real: get!("fmi2GetReal"),
            get_integer: get!("fmi2GetInteger"),
            get_boolean: get!("fmi2GetBoolean"),
            set_real: get!("fmi2SetReal"),
            set_integer: get!("fmi2SetInteger"),
            set_boolean: get!("fmi2SetBoolean"),
            set_string: get!("fmi2SetString"),
            do_step: get!("fmi2DoStep"),
            get_boolean_status: get!("fmi2GetBooleanStatus"),
            get_real_status: get!("fmi2GetRealStatus"),
        })
    }
}

/// A loaded FMU: its description, its open binary and the directory it was unpacked into
/// (deleted when the `Fmu` is dropped, after the binary is closed).
pub struct Fmu {
    /// The parsed modelDescription.xml.
    pub description: ModelDescription,
    /// The Co-Simulation modelIdentifier (name of the binary and of the model).
    pub identifier: String,
    api: Api,
    resource_uri: CString,
    guid: CString,
    // Field order is drop order: close the library before deleting the files it came from.
    _library: Library,
    _dir: tempfile::TempDir,
}

/// An FMU archive unpacked into a temporary directory and checked up to the point of loading its
/// binary: everything the runner reads from a file it did not write, before running any of it.
pub struct Unpacked {
    /// The parsed modelDescription.xml.
    pub description: ModelDescription,
    /// The Co-Simulation modelIdentifier.
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
        let dir = tempfile::Builder::new().prefix("runner-fmu-").tempdir().map_err(|e| format!("cannot create a temporary directory: {e}"))?;
        archive::extract_zip(path, dir.path())?;
        let xml_path = dir.path().join("modelDescription.xml");
        let xml = std::fs::read_to_string(&xml_path).map_err(|e| format!("{}: no readable modelDescription.xml: {e}", path.display()))?;
        let description = ModelDescription::from_xml(&xml).map_err(|e| format!("{}: modelDescription.xml: {e}", path.display()))?;
        let identifier = description.co_simulation().map_err(|e| format!("{}: {e}", path.display()))?.model_identifier.clone();
        // The identifier names the binary to load: with a '/' it could name any library on disk.
        if identifier.is_empty() || identifier.contains(['/', '\0']) {
            return Err(format!("{}: modelIdentifier {identifier:?} is not a file name (FMI requires a C identifier)", path.display()));
        }
        let binary = dir.path().join("binaries").join(PLATFORM).join(format!("{identifier}.so"));
        if !binary.is_file() {
            return Err(format!(
                "{}: no binary for this platform: binaries/{PLATFORM}/{identifier}.so is missing (the FMU has binaries for: {})",
                path.display(),
                platforms(&dir.path().join("binaries"))
            ));
        }
        Ok(Unpacked { description, identifier, binary, dir })
    }
}

impl Fmu {
    /// Unpacks and loads the `.fmu` at `path`.
    pub fn load(path: &Path) -> Result<Fmu, String> {
        let Unpacked { description, identifier, binary, dir } = Unpacked::open(path)?;
        let library = Library::open(&binary)?;
        let api = Api::resolve(&library).map_err(|e| format!("{}: {e} (FMI 2.0 requires it)", path.display()))?;
        // SAFETY: both return static C strings per the standard.
        let version = unsafe { c_text((api.get_version)()).into_owned() };
        if version != "2.0" {
            return Err(format!("{}: fmi2GetVersion returned {version:?}, not \"2.0\"", path.display()));
        }
        let types = unsafe { c_text((api.get_types_platform)()).into_owned() };
        if types != "default" {
            return Err(format!("{}: fmi2GetTypesPlatform returned {types:?}; only \"default\" types are supported", path.display()));
        }
        let resource_uri = CString::new(format!("file://{}/", dir.path().join("resources").display())).map_err(|_| "temporary path contains a NUL byte".to_owned())?;
        let guid = CString::new(description.guid.clone()).map_err(|_| format!("{}: the GUID contains a NUL byte", path.display()))?;
        Ok(Fmu { description, identifier, api, resource_uri, guid, _library: library, _dir: dir })
    }
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

/// A value to set, already converted to the variable's type.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// fmi2Real.
    Real(f64),
    /// fmi2Integer (also Enumeration).
    Integer(i32),
    /// fmi2Boolean.
    Boolean(bool),
    /// fmi2String.
    String(String),
}

/// How a `do_step` ended.
pub enum Step {
    /// The step reached its end.
    Done,
    /// The FMU refused to continue (fmi2Discard with fmi2Terminated): why, and the last time
    /// it reached (fmi2LastSuccessfulTime) when it reports one.
    Ended { reason: String, last_time: Option<f64> },
}

/// One instance of an FMU (fmi2Instantiate .. fmi2FreeInstance).
pub struct Instance<'a> {
    fmu: &'a Fmu,
    name: String,
    component: Component,
    // Both must stay at fixed addresses for the instance's lifetime: the FMU keeps pointers.
    _callbacks: Box<CallbackFunctions>,
    log: Box<LogContext>,
    /// fmi2Terminate is allowed now: the instance left initialization (stepComplete or
    /// stepFailed) and no call has since returned fmi2Error, after which only fmi2Reset and
    /// fmi2FreeInstance are.
    terminate_allowed: bool,
    fatal: bool,
}

impl<'a> Instance<'a> {
    /// fmi2Instantiate as Co-Simulation; `debug_logging` sets loggingOn.
    pub fn new(fmu: &'a Fmu, name: &str, debug_logging: bool) -> Result<Instance<'a>, String> {
        let log = Box::new(LogContext { last_problem: Mutex::new(None) });
        let callbacks = Box::new(CallbackFunctions {
            // SAFETY (of the cast): runner_fmi_logger has exactly fmi2CallbackLogger's C signature.
            logger: Some(runner_fmi_logger as LoggerFn),
            allocate_memory: Some(libc::calloc),
            free_memory: Some(libc::free),
            step_finished: None,
            component_environment: &*log as *const LogContext as *mut c_void,
        });
        let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
        // SAFETY: every pointer is valid for the call; callbacks and log outlive the component.
        let component = unsafe {
            (fmu.api.instantiate)(c_name.as_ptr(), fmu::ffi::FMI2_COSIMULATION, fmu.guid.as_ptr(), fmu.resource_uri.as_ptr(), &*callbacks, 0, debug_logging as c_int)
        };
        let instance = Instance { fmu, name: name.to_owned(), component, _callbacks: callbacks, log, terminate_allowed: false, fatal: false };
        if component.is_null() {
            return Err(instance.failure("fmi2Instantiate", "returned NULL"));
        }
        Ok(instance)
    }

    /// An error message for a failed call, with the last problem the FMU logged.
    fn failure(&self, call: &str, what: &str) -> String {
        let logged = self.log.last_problem.lock().ok().and_then(|mut l| l.take());
        match logged {
            Some(message) => format!("{}: {call} {what}: {message}", self.name),
            None => format!("{}: {call} {what} (the FMU logged no reason)", self.name),
        }
    }

    /// Ok for fmi2OK and fmi2Warning, else the failure with the FMU's logged reason. Inlined
    /// (it follows every doStep and read), with the failure path kept out of line.
    #[inline]
    fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        match status {
            OK | WARNING => Ok(()),
            _ => Err(self.refused(call, status)),
        }
    }

    #[cold]
    fn refused(&mut self, call: &str, status: c_int) -> String {
        if status == FATAL {
            self.fatal = true;
        }
        if status == ERROR || status == FATAL {
            self.terminate_allowed = false;
        }
        self.failure(call, &format!("returned {}", status_name(status)))
    }

    /// fmi2SetupExperiment with an optional relative tolerance and a defined stop time.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        let status = unsafe { (self.fmu.api.setup_experiment)(self.component, tolerance.is_some() as c_int, tolerance.unwrap_or(0.0), start, 1, stop) };
        self.check("fmi2SetupExperiment", status)
    }

    /// fmi2EnterInitializationMode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        let status = unsafe { (self.fmu.api.enter_initialization_mode)(self.component) };
        self.check("fmi2EnterInitializationMode", status)
    }

    /// fmi2ExitInitializationMode.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        let status = unsafe { (self.fmu.api.exit_initialization_mode)(self.component) };
        self.check("fmi2ExitInitializationMode", status)?;
        self.terminate_allowed = true;
        Ok(())
    }

    /// Sets one variable (fmi2Set<Type> with one value reference).
    pub fn set(&mut self, variable: &ScalarVariable, value: &Value) -> Result<(), String> {
        let vr = variable.value_reference;
        let c = self.component;
        let api = &self.fmu.api;
        // SAFETY: one value reference and one value, both valid for the call.
        let status = unsafe {
            match value {
                Value::Real(v) => (api.set_real)(c, &vr, 1, v),
                Value::Integer(v) => (api.set_integer)(c, &vr, 1, v),
                Value::Boolean(v) => (api.set_boolean)(c, &vr, 1, &(*v as c_int)),
                Value::String(v) => {
                    let s = CString::new(v.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))?;
                    (api.set_string)(c, &vr, 1, &s.as_ptr())
                }
            }
        };
        self.check(&format!("fmi2Set{} of {}", kind_name(variable.type_kind()), variable.name), status)
    }

    /// Reads the variables of `reader` into `out` (one f64 per variable, Booleans as 0/1).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        if reader.integer_vrs.is_empty() && reader.boolean_vrs.is_empty() && out.len() == reader.real_vrs.len() {
            // Only Reals (the usual sweep): they are in `out`'s order, so read straight into it.
            if !out.is_empty() {
                let status = unsafe { (self.fmu.api.get_real)(self.component, reader.real_vrs.as_ptr(), out.len(), out.as_mut_ptr()) };
                self.check("fmi2GetReal", status)?;
            }
            return Ok(());
        }
        self.read_mixed(reader, out)
    }

    /// [`Instance::read`] for variables of several types, through the reader's buffers.
    fn read_mixed(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        let c = self.component;
        let api = &self.fmu.api;
        if !reader.real_vrs.is_empty() {
            let status = unsafe { (api.get_real)(c, reader.real_vrs.as_ptr(), reader.real_vrs.len(), reader.real_buf.as_mut_ptr()) };
            self.check("fmi2GetReal", status)?;
        }
        if !reader.integer_vrs.is_empty() {
            let status = unsafe { (api.get_integer)(c, reader.integer_vrs.as_ptr(), reader.integer_vrs.len(), reader.integer_buf.as_mut_ptr()) };
            self.check("fmi2GetInteger", status)?;
        }
        if !reader.boolean_vrs.is_empty() {
            let status = unsafe { (api.get_boolean)(c, reader.boolean_vrs.as_ptr(), reader.boolean_vrs.len(), reader.boolean_buf.as_mut_ptr()) };
            self.check("fmi2GetBoolean", status)?;
        }
        for (slot, &(kind, i)) in out.iter_mut().zip(&reader.layout) {
            *slot = match kind {
                TypeKind::Real => reader.real_buf[i],
                TypeKind::Boolean => (reader.boolean_buf[i] != 0) as i32 as f64,
                _ => reader.integer_buf[i] as f64,
            };
        }
        Ok(())
    }

    /// fmi2DoStep from `t` over `h`; a discard with fmi2Terminated becomes [`Step::Ended`].
    /// Inlined into the run loop, with the discard handling out of line.
    #[inline]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        let status = unsafe { (self.fmu.api.do_step)(self.component, t, h, 1) };
        if status == DISCARD {
            return self.discarded(t);
        }
        self.check("fmi2DoStep", status)?;
        Ok(Step::Done)
    }

    /// After fmi2Discard from the step at `t`: [`Step::Ended`] if the model terminated.
    #[cold]
    fn discarded(&mut self, t: f64) -> Result<Step, String> {
        let mut terminated: c_int = 0;
        let s = unsafe { (self.fmu.api.get_boolean_status)(self.component, TERMINATED, &mut terminated) };
        self.check("fmi2GetBooleanStatus(fmi2Terminated)", s)?;
        let reason = self.log.last_problem.lock().ok().and_then(|mut l| l.take()).unwrap_or_else(|| "no reason logged".to_owned());
        if terminated == 0 {
            return Err(format!("{}: fmi2DoStep at t = {t} returned fmi2Discard without terminating: {reason}", self.name));
        }
        let mut last = f64::NAN;
        let s = unsafe { (self.fmu.api.get_real_status)(self.component, LAST_SUCCESSFUL_TIME, &mut last) };
        let last_time = (s == OK || s == WARNING).then_some(last).filter(|t| t.is_finite());
        let when = match last_time {
            Some(last) => format!("t = {last}"),
            None => format!("the step from t = {t}"),
        };
        Ok(Step::Ended { reason: format!("the model ended the simulation at {when}: {reason}"), last_time })
    }
}

impl Drop for Instance<'_> {
    fn drop(&mut self) {
        // After fmi2Fatal the standard allows no further call, not even fmi2FreeInstance.
        if self.fatal {
            return;
        }
        // SAFETY: the component is live; fmi2Terminate only where the standard allows it (a
        // call it refuses would log an "illegal call sequence" of ours), and fmi2FreeInstance
        // is the last call.
        unsafe {
            if self.terminate_allowed {
                (self.fmu.api.terminate)(self.component);
            }
            (self.fmu.api.free_instance)(self.component);
        }
    }
}

fn kind_name(kind: TypeKind) -> &'static str {
    match kind.base_type() {
        TypeKind::Real => "Real",
        TypeKind::Boolean => "Boolean",
        TypeKind::String => "String",
        _ => "Integer",
    }
}

/// Reads a fixed list of numeric variables in one fmi2Get call per type.
pub struct Reader {
    layout: Vec<(TypeKind, usize)>,
    real_vrs: Vec<u32>,
    real_buf: Vec<f64>,
    integer_vrs: Vec<u32>,
    integer_buf: Vec<c_int>,
    boolean_vrs: Vec<u32>,
    boolean_buf: Vec<c_int>,
}

impl Reader {
    /// A reader for `variables`, in order; String variables are refused.
    pub fn new(variables: &[&ScalarVariable]) -> Result<Reader, String> {
        let mut r = Reader { layout: Vec::new(), real_vrs: Vec::new(), real_buf: Vec::new(), integer_vrs: Vec::new(), integer_buf: Vec::new(), boolean_vrs: Vec::new(), boolean_buf: Vec::new() };
        for v in variables {
            let kind = v.type_kind().base_type();
            let list = match kind {
                TypeKind::Real => &mut r.real_vrs,
                TypeKind::Integer => &mut r.integer_vrs,
                TypeKind::Boolean => &mut r.boolean_vrs,
                _ => return Err(format!("{} is a String variable; only numbers can be recorded", v.name)),
            };
            r.layout.push((kind, list.len()));
            list.push(v.value_reference);
        }
        r.real_buf = vec![0.0; r.real_vrs.len()];
        r.integer_buf = vec![0; r.integer_vrs.len()];
        r.boolean_buf = vec![0; r.boolean_vrs.len()];
        Ok(r)
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
        write_zip(&fmu, &entries).unwrap();
        let error = Unpacked::open(&fmu).err().expect("the FMU must be refused");
        assert!(error.contains("traversal.fmu") && error.contains("modelIdentifier \"../../m\" is not a file name"), "{error}");
    }
}
