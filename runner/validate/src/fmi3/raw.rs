//! Raw FMI 3.0 calls for the probes: the functions the probes call resolved (each `None` when
//! not exported), any of the 75 names looked up for the exports check, and an instance that
//! makes any call in any state, recording each call in the progress file before making it.
//! This is the child side; nothing here is safe to run in the validator's own process.

use std::cell::RefCell;
use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::sync::Mutex;
use std::time::Duration;

use fmi_c::fmi3 as c;
use libloading::os::unix::{Library, RTLD_LOCAL, RTLD_NOW};

use crate::isolation::{CallRecord, Progress};

macro_rules! api {
    ($($field:ident: $ty:ident = $name:literal,)*) => {
        /// The binary's fmi3 functions the probes call, each `None` when not exported.
        pub(crate) struct Api {
            $(pub(crate) $field: Option<c::$ty>,)*
            library: Library,
        }

        impl Api {
            fn resolve(library: Library) -> Api {
                // SAFETY: each name is an FMI 3.0 function whose C signature the standard fixes
                // as the type it is read as.
                unsafe {
                    Api {
                        $($field: library.get::<c::$ty>(concat!($name, "\0").as_bytes()).ok().map(|s| *s),)*
                        library,
                    }
                }
            }
        }
    };
}

api! {
    get_version: GetVersion = "fmi3GetVersion",
    instantiate_model_exchange: InstantiateModelExchange = "fmi3InstantiateModelExchange",
    instantiate_co_simulation: InstantiateCoSimulation = "fmi3InstantiateCoSimulation",
    free_instance: FreeInstance = "fmi3FreeInstance",
    enter_initialization_mode: EnterInitializationMode = "fmi3EnterInitializationMode",
    exit_initialization_mode: ExitInitializationMode = "fmi3ExitInitializationMode",
    enter_event_mode: EnterEventMode = "fmi3EnterEventMode",
    terminate: Terminate = "fmi3Terminate",
    reset: Reset = "fmi3Reset",
    get_float64: GetFloat64 = "fmi3GetFloat64",
    set_float64: SetFloat64 = "fmi3SetFloat64",
    update_discrete_states: UpdateDiscreteStates = "fmi3UpdateDiscreteStates",
    enter_continuous_time_mode: EnterContinuousTimeMode = "fmi3EnterContinuousTimeMode",
    completed_integrator_step: CompletedIntegratorStep = "fmi3CompletedIntegratorStep",
    set_time: SetTime = "fmi3SetTime",
    set_continuous_states: SetContinuousStates = "fmi3SetContinuousStates",
    get_continuous_state_derivatives: GetContinuousStateDerivatives = "fmi3GetContinuousStateDerivatives",
    get_event_indicators: GetEventIndicators = "fmi3GetEventIndicators",
    get_continuous_states: GetContinuousStates = "fmi3GetContinuousStates",
    get_number_of_event_indicators: GetNumberOfEventIndicators = "fmi3GetNumberOfEventIndicators",
    get_number_of_continuous_states: GetNumberOfContinuousStates = "fmi3GetNumberOfContinuousStates",
    enter_step_mode: EnterStepMode = "fmi3EnterStepMode",
    do_step: DoStep = "fmi3DoStep",
    get_int32: GetInt32 = "fmi3GetInt32",
    set_int32: SetInt32 = "fmi3SetInt32",
    get_boolean: GetBoolean = "fmi3GetBoolean",
    set_boolean: SetBoolean = "fmi3SetBoolean",
    get_string: GetString = "fmi3GetString",
    set_string: SetString = "fmi3SetString",
    get_fmu_state: GetFmuState = "fmi3GetFMUState",
    set_fmu_state: SetFmuState = "fmi3SetFMUState",
    free_fmu_state: FreeFmuState = "fmi3FreeFMUState",
    serialized_fmu_state_size: SerializedFmuStateSize = "fmi3SerializedFMUStateSize",
    serialize_fmu_state: SerializeFmuState = "fmi3SerializeFMUState",
    deserialize_fmu_state: DeserializeFmuState = "fmi3DeserializeFMUState",
}

impl Api {
    /// Loads the shared library at `path` (running its initializers: the child's risk) and
    /// resolves the functions.
    pub(crate) fn load(path: &Path) -> Result<Api, String> {
        // SAFETY: loading runs the library's initializers, which is what this process is for.
        let library = unsafe { Library::open(Some(path), RTLD_NOW | RTLD_LOCAL) }.map_err(|e| e.to_string())?;
        Ok(Api::resolve(library))
    }

    /// Whether the binary exports the function called `name`.
    pub(crate) fn exports(&self, name: &str) -> bool {
        let Ok(symbol) = CString::new(name) else { return false };
        // SAFETY: only the address is looked up, never called through this type.
        unsafe { self.library.get::<*const c_void>(symbol.as_bytes_with_nul()).is_ok() }
    }
}

/// The largest serialized FMU state the validator allocates (1 GiB): a larger size is taken
/// for garbage.
const MAX_SERIALIZED: usize = 1 << 30;

/// A status code as returned, including values the standard does not define.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Code(pub c_int);

impl Code {
    pub(crate) const OK: Code = Code(c::Status::Ok as c_int);
    pub(crate) const WARNING: Code = Code(c::Status::Warning as c_int);
    pub(crate) const ERROR: Code = Code(c::Status::Error as c_int);
    /// The function is not exported, so it was not called.
    pub(crate) const MISSING: Code = Code(-1000);

    /// fmi3OK or fmi3Warning: the call succeeded.
    pub(crate) fn ok(self) -> bool {
        self == Code::OK || self == Code::WARNING
    }

    /// The standard's name.
    pub(crate) fn name(self) -> &'static str {
        if self == Code::MISSING {
            "nothing (the function is not exported)"
        } else {
            c::status_name(self.0)
        }
    }
}

/// What the FMU logged since the last [`Log::take`].
#[derive(Default)]
pub(crate) struct Log {
    lines: Mutex<Vec<String>>,
}

impl Log {
    /// The lines logged since the last call, joined, if any.
    pub(crate) fn take(&self) -> Option<String> {
        let mut lines = self.lines.lock().ok()?;
        let text = lines.join("\n");
        lines.clear();
        (!text.is_empty()).then_some(text)
    }
}

/// fmi3LogMessageCallback: keeps the message (the last few) and echoes it to stderr, whose tail
/// the parent attaches to a crash.
unsafe extern "C" fn log_message(env: *mut c_void, status: c_int, category: *const c_char, message: *const c_char) {
    // Inside the FMU's call: must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        if env.is_null() {
            return;
        }
        let text = |p: *const c_char| if p.is_null() { String::new() } else { unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned() };
        let line = format!("[{}] {}: {}", c::status_name(status), text(category), text(message));
        eprintln!("{line}");
        // SAFETY: the environment is the Log the instance was created with, alive until freed.
        let log = unsafe { &*(env as *const Log) };
        if let Ok(mut lines) = log.lines.lock() {
            if lines.len() >= 8 {
                lines.remove(0);
            }
            lines.push(fmi_schema::escaped_and_cut(&line, 400, "..."));
        }
    });
}

/// The interface an instance is created for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) enum Interface {
    CoSimulation,
    ModelExchange,
}

impl Interface {
    /// As the report names it.
    pub(crate) fn title(self) -> &'static str {
        match self {
            Interface::CoSimulation => "Co-Simulation",
            Interface::ModelExchange => "Model Exchange",
        }
    }

    /// As the probe's command line names it.
    pub(crate) fn arg(self) -> &'static str {
        match self {
            Interface::CoSimulation => "cs",
            Interface::ModelExchange => "me",
        }
    }

    pub(crate) fn from_arg(arg: &str) -> Option<Interface> {
        match arg {
            "cs" => Some(Interface::CoSimulation),
            "me" => Some(Interface::ModelExchange),
            _ => None,
        }
    }
}

/// How a Co-Simulation instance is made: Event Mode and early return asked for or not.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct CsOptions {
    pub event_mode_used: bool,
    pub early_return_allowed: bool,
}

/// One live instance, its calls recorded in the progress file before they are made.
pub(crate) struct Instance<'a> {
    pub api: &'a Api,
    pub raw: c::Instance,
    /// The FMU's log messages (its instance environment: boxed, so it stays put).
    pub log: Box<Log>,
    progress: &'a Progress,
    /// The progress file's slot of the thread that uses the instance.
    slot: usize,
    timeout: Duration,
    /// The standard's name of the state the validator believes the instance is in.
    pub state: &'static str,
    /// The variable and the arguments the next call records (see [`Instance::note`]).
    note: RefCell<(Option<String>, Option<String>)>,
    freed: bool,
}

impl<'a> Instance<'a> {
    /// fmi3Instantiate<interface> with `token`; `Err` with the log when it returns NULL (or the
    /// function is missing).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn new(
        api: &'a Api,
        interface: Interface,
        name: &str,
        token: &str,
        resource_path: &str,
        cs: CsOptions,
        (progress, slot): (&'a Progress, usize),
        timeout: Duration,
    ) -> Result<Instance<'a>, (Code, Option<String>)> {
        let log = Box::new(Log::default());
        let env = &*log as *const Log as *mut c_void;
        let (name, token, resources) = (
            CString::new(name).unwrap_or_default(),
            CString::new(token).unwrap_or_default(),
            CString::new(resource_path).unwrap_or_default(),
        );
        let record = CallRecord {
            call: match interface {
                Interface::CoSimulation => "fmi3InstantiateCoSimulation".into(),
                Interface::ModelExchange => "fmi3InstantiateModelExchange".into(),
            },
            state: "(no instance)".into(),
            variable: None,
            value: None,
        };
        progress.begin(slot, &record, timeout);
        // SAFETY: every pointer is valid for the call; the log outlives the instance.
        let raw = unsafe {
            match interface {
                Interface::CoSimulation => api.instantiate_co_simulation.map(|f| {
                    f(
                        name.as_ptr(),
                        token.as_ptr(),
                        resources.as_ptr(),
                        false,
                        false,
                        cs.event_mode_used,
                        cs.early_return_allowed,
                        std::ptr::null(),
                        0,
                        env,
                        Some(log_message),
                        None,
                    )
                }),
                Interface::ModelExchange => api
                    .instantiate_model_exchange
                    .map(|f| f(name.as_ptr(), token.as_ptr(), resources.as_ptr(), false, false, env, Some(log_message))),
            }
        };
        progress.end(slot);
        match raw {
            None => Err((Code::MISSING, None)),
            Some(p) if p.is_null() => Err((Code::ERROR, log.take())),
            Some(raw) => {
                Ok(Instance { api, raw, log, progress, slot, timeout, state: "Instantiated", note: RefCell::default(), freed: false })
            }
        }
    }

    /// Has the next call recorded with `variable` and `value` (what its arguments are), which
    /// a crash in it then reports.
    pub(crate) fn note(&self, variable: Option<String>, value: Option<String>) {
        *self.note.borrow_mut() = (variable, value);
    }

    /// Makes `call` (the C name, for the record), through `f` when exported.
    pub(crate) fn call<F>(&self, name: &str, f: Option<F>, make: impl FnOnce(F, c::Instance) -> c_int) -> Code {
        let (variable, value) = self.note.take();
        let Some(f) = f else { return Code::MISSING };
        let record = CallRecord { call: name.into(), state: self.state.into(), variable, value };
        self.progress.begin(self.slot, &record, self.timeout);
        let code = Code(make(f, self.raw));
        self.progress.end(self.slot);
        code
    }

    /// A call of an `fmi3<F>(instance)` function.
    pub(crate) fn plain(&self, name: &str, f: Option<unsafe extern "C" fn(c::Instance) -> c_int>) -> Code {
        // SAFETY: a live instance.
        self.call(name, f, |f, raw| unsafe { f(raw) })
    }

    /// fmi3EnterInitializationMode with the tolerance (if any), start and stop time.
    pub(crate) fn enter_initialization_mode(&self, tolerance: Option<f64>, start: f64, stop: f64) -> Code {
        // SAFETY: scalar arguments.
        self.call("fmi3EnterInitializationMode", self.api.enter_initialization_mode, |f, raw| unsafe {
            f(raw, tolerance.is_some(), tolerance.unwrap_or(0.0), start, true, stop)
        })
    }

    /// fmi3UpdateDiscreteStates: the status, discreteStatesNeedUpdate, terminateSimulation and
    /// nextEventTime (when defined).
    pub(crate) fn update_discrete_states(&self) -> (Code, bool, bool, Option<f64>) {
        let (mut again, mut terminate, mut nominals, mut values, mut defined, mut next) = (false, false, false, false, false, 0.0);
        // SAFETY: valid out pointers.
        let code = self.call("fmi3UpdateDiscreteStates", self.api.update_discrete_states, |f, raw| unsafe {
            f(raw, &mut again, &mut terminate, &mut nominals, &mut values, &mut defined, &mut next)
        });
        (code, again, terminate, defined.then_some(next))
    }

    /// fmi3DoStep from `t` over `h`: the status, eventHandlingNeeded, terminateSimulation,
    /// earlyReturn and lastSuccessfulTime.
    pub(crate) fn do_step(&self, t: f64, h: f64) -> (Code, bool, bool, bool, f64) {
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, f64::NAN);
        // SAFETY: valid out pointers.
        let code = self.call("fmi3DoStep", self.api.do_step, |f, raw| unsafe {
            f(raw, t, h, true, &mut event, &mut terminate, &mut early, &mut last)
        });
        (code, event, terminate, early, last)
    }

    /// fmi3CompletedIntegratorStep: the status, enterEventMode and terminateSimulation.
    pub(crate) fn completed_integrator_step(&self) -> (Code, bool, bool) {
        let (mut enter, mut terminate) = (false, false);
        // SAFETY: valid out pointers.
        let code = self.call("fmi3CompletedIntegratorStep", self.api.completed_integrator_step, |f, raw| unsafe {
            f(raw, true, &mut enter, &mut terminate)
        });
        (code, enter, terminate)
    }

    /// fmi3SetTime.
    pub(crate) fn set_time(&self, t: f64) -> Code {
        // SAFETY: a scalar argument.
        self.call("fmi3SetTime", self.api.set_time, |f, raw| unsafe { f(raw, t) })
    }

    /// One of the array calls of Model Exchange (states, derivatives, indicators).
    pub(crate) fn array(
        &self,
        name: &str,
        f: Option<unsafe extern "C" fn(c::Instance, *mut f64, usize) -> c_int>,
        values: &mut [f64],
    ) -> Code {
        // SAFETY: an array of values.len() elements (a dangling but aligned pointer for none).
        self.call(name, f, |f, raw| unsafe { f(raw, values.as_mut_ptr(), values.len()) })
    }

    /// fmi3SetContinuousStates.
    pub(crate) fn set_continuous_states(&self, x: &[f64]) -> Code {
        // SAFETY: an array of x.len() states.
        self.call("fmi3SetContinuousStates", self.api.set_continuous_states, |f, raw| unsafe { f(raw, x.as_ptr(), x.len()) })
    }

    /// The number fmi3GetNumberOf<what> reports.
    pub(crate) fn number_of(&self, name: &str, f: Option<unsafe extern "C" fn(c::Instance, *mut usize) -> c_int>) -> (Code, usize) {
        let mut n = 0usize;
        // SAFETY: a valid out pointer.
        let code = self.call(name, f, |f, raw| unsafe { f(raw, &mut n) });
        (code, n)
    }

    /// fmi3GetFloat64 of `vrs` into `values` (one element each).
    pub(crate) fn get_float64(&self, vrs: &[u32], values: &mut [f64]) -> Code {
        // SAFETY: vrs.len() references and as many values.
        self.call("fmi3GetFloat64", self.api.get_float64, |f, raw| unsafe {
            f(raw, vrs.as_ptr(), vrs.len(), values.as_mut_ptr(), values.len())
        })
    }

    /// fmi3SetFloat64 of one scalar.
    pub(crate) fn set_float64(&self, vr: u32, value: f64) -> Code {
        // SAFETY: one reference and one value.
        self.call("fmi3SetFloat64", self.api.set_float64, |f, raw| unsafe { f(raw, &vr, 1, &value, 1) })
    }

    /// fmi3GetFMUState into `state` (NULL on entry: a new copy; else the copy is overwritten).
    pub(crate) fn get_fmu_state(&self, state: &mut c::FmuState) -> Code {
        // SAFETY: a valid out pointer.
        self.call("fmi3GetFMUState", self.api.get_fmu_state, |f, raw| unsafe { f(raw, state) })
    }

    /// fmi3SetFMUState.
    pub(crate) fn set_fmu_state(&self, state: c::FmuState) -> Code {
        // SAFETY: a state this instance's FMU returned.
        self.call("fmi3SetFMUState", self.api.set_fmu_state, |f, raw| unsafe { f(raw, state) })
    }

    /// fmi3FreeFMUState, which must set `*state` to NULL.
    pub(crate) fn free_fmu_state(&self, state: &mut c::FmuState) -> Code {
        // SAFETY: a state this instance's FMU returned, and a valid pointer to it.
        self.call("fmi3FreeFMUState", self.api.free_fmu_state, |f, raw| unsafe { f(raw, state) })
    }

    /// fmi3SerializedFMUStateSize then fmi3SerializeFMUState: the bytes of `state`, or the
    /// failing call and what went wrong.
    pub(crate) fn serialize(&self, state: c::FmuState) -> Result<Vec<u8>, (&'static str, String)> {
        let mut n = 0usize;
        // SAFETY: a valid out pointer.
        let code = self.call("fmi3SerializedFMUStateSize", self.api.serialized_fmu_state_size, |f, raw| unsafe { f(raw, state, &mut n) });
        if !code.ok() {
            return Err(("fmi3SerializedFMUStateSize", format!("returned {}", code.name())));
        }
        if n > MAX_SERIALIZED {
            return Err(("fmi3SerializedFMUStateSize", format!("reported {n} bytes, more than the validator's limit of {MAX_SERIALIZED}")));
        }
        let mut bytes = vec![0u8; n];
        // SAFETY: a buffer of the size the FMU asked for.
        let code = self.call("fmi3SerializeFMUState", self.api.serialize_fmu_state, |f, raw| unsafe {
            f(raw, state, bytes.as_mut_ptr(), bytes.len())
        });
        if code.ok() {
            Ok(bytes)
        } else {
            Err((
                "fmi3SerializeFMUState",
                format!("returned {} for a buffer of the {n} bytes fmi3SerializedFMUStateSize asked for", code.name()),
            ))
        }
    }

    /// fmi3DeserializeFMUState of `bytes`: the status and the new state.
    pub(crate) fn deserialize(&self, bytes: &[u8]) -> (Code, c::FmuState) {
        let mut state: c::FmuState = std::ptr::null_mut();
        // SAFETY: the bytes the FMU serialized, and a valid out pointer.
        let code = self.call("fmi3DeserializeFMUState", self.api.deserialize_fmu_state, |f, raw| unsafe {
            f(raw, bytes.as_ptr(), bytes.len(), &mut state)
        });
        (code, state)
    }

    /// fmi3GetString of `vrs`: the status and the texts (`None` for a NULL pointer), copied
    /// at once (the FMU's pointers are valid only until its next call).
    pub(crate) fn get_string(&self, vrs: &[u32]) -> (Code, Vec<Option<String>>) {
        let mut values: Vec<c::FmiString> = vec![std::ptr::null(); vrs.len()];
        // SAFETY: vrs.len() references and as many values.
        let code = self.call("fmi3GetString", self.api.get_string, |f, raw| unsafe {
            f(raw, vrs.as_ptr(), vrs.len(), values.as_mut_ptr(), values.len())
        });
        let texts = values
            .iter()
            // SAFETY: a non-NULL pointer the FMU returned points at a NUL-terminated text.
            .map(|p| (!p.is_null()).then(|| unsafe { CStr::from_ptr(*p) }.to_string_lossy().into_owned()))
            .collect();
        (code, texts)
    }

    /// fmi3SetString of one scalar.
    pub(crate) fn set_string(&self, vr: u32, text: &CStr) -> Code {
        let value = text.as_ptr();
        // SAFETY: one reference and one valid text.
        self.call("fmi3SetString", self.api.set_string, |f, raw| unsafe { f(raw, &vr, 1, &value, 1) })
    }

    /// fmi3FreeInstance (once).
    pub(crate) fn free(&mut self) {
        if !self.freed {
            self.freed = true;
            let raw = self.raw;
            if let Some(f) = self.api.free_instance {
                let record = CallRecord { call: "fmi3FreeInstance".into(), state: self.state.into(), variable: None, value: None };
                self.progress.begin(self.slot, &record, self.timeout);
                // SAFETY: a live instance, freed once.
                unsafe { f(raw) };
                self.progress.end(self.slot);
            }
        }
    }
}

impl Drop for Instance<'_> {
    fn drop(&mut self) {
        self.free();
    }
}
