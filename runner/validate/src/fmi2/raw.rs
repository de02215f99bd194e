//! Raw FMI 2.0 calls for the probes: every one of the 44 functions resolved (or found missing),
//! and an instance that makes any call in any state, with any arguments (NULL arrays
//! included), recording each call in the progress file before making it. This is the child
//! side; nothing here is safe to run in the validator's own process.

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;
use std::sync::Mutex;
use std::time::Duration;

use fmi_c::fmi2 as c;
use libloading::os::unix::{Library, RTLD_LOCAL, RTLD_NOW};

use super::model::Model;
use super::table::{Function, Interface, State};
use crate::isolation::{CallRecord, Progress};

macro_rules! api {
    ($($field:ident: $ty:ident = $name:literal,)*) => {
        /// The binary's fmi2 functions, each `None` when not exported.
        pub(crate) struct Api {
            $(pub(crate) $field: Option<c::$ty>,)*
            _library: Library,
        }

        impl Api {
            fn resolve(library: Library) -> Api {
                // SAFETY: each name is an FMI 2.0 function whose C signature the standard fixes
                // as the type it is read as.
                unsafe {
                    Api {
                        $($field: library.get::<c::$ty>(concat!($name, "\0").as_bytes()).ok().map(|s| *s),)*
                        _library: library,
                    }
                }
            }

            /// Whether the binary exports the function called `name`.
            pub(crate) fn exports(&self, name: &str) -> bool {
                match name {
                    $($name => self.$field.is_some(),)*
                    _ => false,
                }
            }
        }
    };
}

api! {
    get_types_platform: GetTypesPlatform = "fmi2GetTypesPlatform",
    get_version: GetVersion = "fmi2GetVersion",
    set_debug_logging: SetDebugLogging = "fmi2SetDebugLogging",
    instantiate: Instantiate = "fmi2Instantiate",
    free_instance: FreeInstance = "fmi2FreeInstance",
    setup_experiment: SetupExperiment = "fmi2SetupExperiment",
    enter_initialization_mode: EnterInitializationMode = "fmi2EnterInitializationMode",
    exit_initialization_mode: ExitInitializationMode = "fmi2ExitInitializationMode",
    terminate: Terminate = "fmi2Terminate",
    reset: Reset = "fmi2Reset",
    get_real: GetReal = "fmi2GetReal",
    get_integer: GetInteger = "fmi2GetInteger",
    get_boolean: GetBoolean = "fmi2GetBoolean",
    get_string: GetString = "fmi2GetString",
    set_real: SetReal = "fmi2SetReal",
    set_integer: SetInteger = "fmi2SetInteger",
    set_boolean: SetBoolean = "fmi2SetBoolean",
    set_string: SetString = "fmi2SetString",
    get_fmu_state: GetFmuState = "fmi2GetFMUstate",
    set_fmu_state: SetFmuState = "fmi2SetFMUstate",
    free_fmu_state: FreeFmuState = "fmi2FreeFMUstate",
    serialized_fmu_state_size: SerializedFmuStateSize = "fmi2SerializedFMUstateSize",
    serialize_fmu_state: SerializeFmuState = "fmi2SerializeFMUstate",
    de_serialize_fmu_state: DeSerializeFmuState = "fmi2DeSerializeFMUstate",
    get_directional_derivative: GetDirectionalDerivative = "fmi2GetDirectionalDerivative",
    enter_event_mode: EnterEventMode = "fmi2EnterEventMode",
    new_discrete_states: NewDiscreteStates = "fmi2NewDiscreteStates",
    enter_continuous_time_mode: EnterContinuousTimeMode = "fmi2EnterContinuousTimeMode",
    completed_integrator_step: CompletedIntegratorStep = "fmi2CompletedIntegratorStep",
    set_time: SetTime = "fmi2SetTime",
    set_continuous_states: SetContinuousStates = "fmi2SetContinuousStates",
    get_derivatives: GetDerivatives = "fmi2GetDerivatives",
    get_event_indicators: GetEventIndicators = "fmi2GetEventIndicators",
    get_continuous_states: GetContinuousStates = "fmi2GetContinuousStates",
    get_nominals_of_continuous_states: GetNominalsOfContinuousStates = "fmi2GetNominalsOfContinuousStates",
    set_real_input_derivatives: SetRealInputDerivatives = "fmi2SetRealInputDerivatives",
    get_real_output_derivatives: GetRealOutputDerivatives = "fmi2GetRealOutputDerivatives",
    do_step: DoStep = "fmi2DoStep",
    cancel_step: CancelStep = "fmi2CancelStep",
    get_status: GetStatus = "fmi2GetStatus",
    get_real_status: GetRealStatus = "fmi2GetRealStatus",
    get_integer_status: GetIntegerStatus = "fmi2GetIntegerStatus",
    get_boolean_status: GetBooleanStatus = "fmi2GetBooleanStatus",
    get_string_status: GetStringStatus = "fmi2GetStringStatus",
}

impl Api {
    /// Loads the shared library at `path` (running its initializers: the child's risk) and
    /// resolves every function.
    pub(crate) fn load(path: &Path) -> Result<Api, String> {
        // SAFETY: loading runs the library's initializers, which is what this process is for.
        let library = unsafe { Library::open(Some(path), RTLD_NOW | RTLD_LOCAL) }.map_err(|e| e.to_string())?;
        Ok(Api::resolve(library))
    }
}

/// A status code as returned, including values the standard does not define.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Code(pub c_int);

impl Code {
    pub(crate) const OK: Code = Code(c::Status::Ok as c_int);
    pub(crate) const WARNING: Code = Code(c::Status::Warning as c_int);
    pub(crate) const DISCARD: Code = Code(c::Status::Discard as c_int);
    pub(crate) const ERROR: Code = Code(c::Status::Error as c_int);
    pub(crate) const FATAL: Code = Code(c::Status::Fatal as c_int);
    /// The function is not exported, so it was not called.
    pub(crate) const MISSING: Code = Code(-1000);

    /// fmi2OK or fmi2Warning: the call succeeded.
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

/// Receives the FMU's log messages, already formatted by the C shim.
unsafe extern "C" fn forward(context: *mut c_void, instance: *const c_char, status: c_int, category: *const c_char, text: *const c_char) {
    // Inside the FMU's call: must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        if context.is_null() {
            return;
        }
        let log = &*(context as *const Log);
        let text_of = |p: *const c_char| if p.is_null() { String::new() } else { CStr::from_ptr(p).to_string_lossy().into_owned() };
        log.receive(&text_of(instance), status, &text_of(category), &text_of(text));
    });
}

/// The messages an instance logged since they were last taken.
#[derive(Default)]
pub(crate) struct Log {
    messages: Mutex<Vec<String>>,
}

impl Log {
    fn receive(&self, instance: &str, status: c_int, category: &str, text: &str) {
        let line = fmi_schema::printable(format!("[{instance}] {} ({category}): {text}", Code(status).name()));
        // The child's stderr is the tail a crash report quotes.
        eprintln!("{line}");
        if let Ok(mut messages) = self.messages.lock() {
            if messages.len() >= 20 {
                messages.remove(0);
            }
            messages.push(fmi_schema::escaped_and_cut(text, 300, "..."));
        }
    }

    /// The messages logged since the last take, joined; `None` if there were none.
    pub(crate) fn take(&self) -> Option<String> {
        let mut messages = self.messages.lock().ok()?;
        if messages.is_empty() {
            return None;
        }
        let joined = messages[messages.len().saturating_sub(3)..].join(" | ");
        messages.clear();
        Some(joined)
    }
}

/// The callbacks of one instance, at a fixed address while it lives.
pub(crate) struct Callbacks {
    functions: c::CallbackFunctions,
    _forwarder: Box<c::LogForwarder>,
    pub(crate) log: Box<Log>,
}

impl Callbacks {
    fn new() -> Box<Callbacks> {
        let log = Box::new(Log::default());
        let forwarder = Box::new(c::LogForwarder { forward, context: &*log as *const Log as *mut c_void });
        let functions = c::CallbackFunctions {
            logger: Some(c::logger_shim()),
            allocate_memory: Some(libc::calloc),
            free_memory: Some(libc::free),
            step_finished: None,
            component_environment: &*forwarder as *const c::LogForwarder as *mut c_void,
        };
        Box::new(Callbacks { functions, _forwarder: forwarder, log })
    }
}

/// One loaded FMU in the child: its functions, description and progress file.
pub(crate) struct Fmu {
    pub api: Api,
    pub model: Model,
    pub interface: Interface,
    pub guid: CString,
    resource_uri: CString,
    progress: Progress,
    pub timeout: Duration,
}

impl Fmu {
    /// An FMU unpacked in `dir`, whose `interface` binary is `api`.
    pub(crate) fn new(
        api: Api,
        model: Model,
        interface: Interface,
        dir: &Path,
        progress: Progress,
        timeout: Duration,
    ) -> Result<Fmu, String> {
        let guid = CString::new(model.md.guid.clone()).map_err(|_| "the GUID contains a NUL byte".to_owned())?;
        let resource_uri = CString::new(format!("file://{}/", dir.join("resources").display()))
            .map_err(|_| "the temporary directory's path contains a NUL byte".to_owned())?;
        Ok(Fmu { api, model, interface, guid, resource_uri, progress, timeout })
    }

    /// Runs `body` (one FMI call) with its record in `slot`: the parent can then name it if it
    /// crashes or overruns the timeout.
    pub(crate) fn traced<R>(&self, slot: usize, record: &CallRecord, body: impl FnOnce() -> R) -> R {
        self.progress.begin(slot, record, self.timeout);
        let result = body();
        self.progress.end(slot);
        result
    }

    /// fmi2Instantiate for `interface` with `guid`; `Err` carries what the FMU logged.
    pub(crate) fn instantiate_as(
        &self,
        name: &str,
        interface: Interface,
        guid: &CStr,
        slot: usize,
    ) -> Result<Instance<'_>, (Code, Option<String>)> {
        let Some(instantiate) = self.api.instantiate else { return Err((Code::MISSING, None)) };
        let callbacks = Callbacks::new();
        let c_name = CString::new(name).expect("instance names are ours, without NUL");
        let record = CallRecord {
            call: Function::Instantiate.name().to_owned(),
            state: "(no instance)".to_owned(),
            variable: None,
            value: Some(format!("instanceName {name:?}, fmuType {}, GUID {}", interface.title(), guid.to_string_lossy())),
        };
        // SAFETY: every pointer is valid for the call; the callbacks outlive the component.
        let component = self.traced(slot, &record, || unsafe {
            instantiate(
                c_name.as_ptr(),
                interface.fmi_type(),
                guid.as_ptr(),
                self.resource_uri.as_ptr(),
                &callbacks.functions,
                c::FALSE,
                c::FALSE,
            )
        });
        if component.is_null() {
            return Err((Code::ERROR, callbacks.log.take()));
        }
        Ok(Instance {
            fmu: self,
            c: component,
            state: State::Instantiated,
            callbacks,
            slot,
            fatal: false,
            interface,
            null_component: false,
        })
    }

    /// fmi2Instantiate for this FMU's interface with its own GUID.
    pub(crate) fn instantiate(&self, name: &str, slot: usize) -> Result<Instance<'_>, (Code, Option<String>)> {
        self.instantiate_as(name, self.interface, &self.guid, slot)
    }
}

/// What a call returned, with what the FMU logged during it.
pub(crate) struct Outcome<T> {
    pub code: Code,
    pub value: T,
    pub log: Option<String>,
}

/// One live instance, driven call by call. `state` is where the validator believes it is
/// (the state the standard's state machine puts it in after the calls made).
pub(crate) struct Instance<'f> {
    pub fmu: &'f Fmu,
    pub c: c::Component,
    pub state: State,
    callbacks: Box<Callbacks>,
    slot: usize,
    fatal: bool,
    interface: Interface,
    /// While set, every call passes a NULL fmi2Component instead of `c` (the NULL-instance
    /// probes): the instance itself is not addressed, so its believed state does not move.
    pub null_component: bool,
}

/// The value a record shows for a call made with a NULL fmi2Component.
pub(crate) const NULL_COMPONENT: &str = "a NULL fmi2Component";

// An instance is used by one thread at a time (the threads probe moves each to its own).
unsafe impl Send for Instance<'_> {}

/// `value` of a call as its record shows it: short, and printable.
fn shown(text: String) -> String {
    fmi_schema::escaped_and_cut(&text, 200, "...")
}

impl<'f> Instance<'f> {
    /// The interface it was instantiated for.
    pub(crate) fn interface(&self) -> Interface {
        self.interface
    }

    /// What the FMU logged since the last take.
    pub(crate) fn take_log(&self) -> Option<String> {
        self.callbacks.log.take()
    }

    /// Makes one call: records it (function, state, variable, value), runs `body` with the
    /// component, takes the log, and moves the believed state on after an error or fatal
    /// status. A function the binary does not export returns [`Code::MISSING`] uncalled.
    pub(crate) fn call<T>(
        &mut self,
        function: Function,
        variable: Option<&str>,
        value: Option<String>,
        body: impl FnOnce(&Api, c::Component) -> Option<(Code, T)>,
        missing: T,
    ) -> Outcome<T> {
        let value = match (self.null_component, value) {
            (false, value) => value,
            (true, None) => Some(NULL_COMPONENT.to_owned()),
            (true, Some(v)) => Some(format!("{NULL_COMPONENT}; {v}")),
        };
        let record = CallRecord {
            call: function.name().to_owned(),
            state: self.state.name().to_owned(),
            variable: variable.map(|v| shown(v.to_owned())),
            value: value.map(shown),
        };
        let component = if self.null_component { std::ptr::null_mut() } else { self.c };
        let api = &self.fmu.api;
        let result = self.fmu.traced(self.slot, &record, || body(api, component));
        let log = self.take_log();
        let (code, value) = result.unwrap_or((Code::MISSING, missing));
        if self.null_component {
            return Outcome { code, value, log };
        }
        if code == Code::ERROR && self.state != State::Gone {
            self.state = State::Error;
        }
        if code == Code::FATAL {
            self.fatal = true;
            self.state = State::Gone;
        }
        Outcome { code, value, log }
    }

    /// A call that returns only a status.
    pub(crate) fn status(
        &mut self,
        function: Function,
        variable: Option<&str>,
        value: Option<String>,
        body: impl FnOnce(&Api, c::Component) -> Option<c_int>,
    ) -> Outcome<()> {
        self.call(function, variable, value, |api, c| body(api, c).map(|code| (Code(code), ())), ())
    }

    /// fmi2SetupExperiment over the grid's times.
    pub(crate) fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Outcome<()> {
        let value = format!("tolerance {}, start {start}, stop {stop}", tolerance.map_or("undefined".to_owned(), |t| t.to_string()));
        self.status(Function::SetupExperiment, None, Some(value), |api, c| {
            // SAFETY: scalar arguments only.
            api.setup_experiment.map(|f| unsafe { f(c, tolerance.is_some() as c_int, tolerance.unwrap_or(0.0), start, c::TRUE, stop) })
        })
    }

    /// A call on the component alone (fmi2EnterInitializationMode, fmi2Terminate, ...).
    pub(crate) fn simple(&mut self, function: Function) -> Outcome<()> {
        self.status(function, None, None, |api, c| {
            let f = match function {
                Function::EnterInitializationMode => api.enter_initialization_mode,
                Function::ExitInitializationMode => api.exit_initialization_mode,
                Function::Terminate => api.terminate,
                Function::Reset => api.reset,
                Function::EnterEventMode => api.enter_event_mode,
                Function::EnterContinuousTimeMode => api.enter_continuous_time_mode,
                Function::CancelStep => api.cancel_step,
                _ => unreachable!("{} takes more arguments", function.name()),
            };
            // SAFETY: these functions take the component only.
            f.map(|f| unsafe { f(c) })
        })
    }

    /// fmi2GetReal/Integer/Boolean of `vrs` as f64 (Booleans 0/1); `names` for the record.
    pub(crate) fn get_numbers(&mut self, base: super::model::Base, vrs: &[u32], names: &str) -> Outcome<Vec<f64>> {
        use super::model::Base;
        let n = vrs.len();
        let value = Some(format!("{n} value reference(s)"));
        match base {
            Base::Real => self.call(
                Function::GetReal,
                Some(names),
                value,
                |api, c| {
                    let mut out = vec![0.0f64; n];
                    // SAFETY: arrays of n elements.
                    api.get_real.map(|f| (Code(unsafe { f(c, vrs.as_ptr(), n, out.as_mut_ptr()) }), out))
                },
                Vec::new(),
            ),
            Base::Integer => self.call(
                Function::GetInteger,
                Some(names),
                value,
                |api, c| {
                    let mut out = vec![0 as c::Integer; n];
                    // SAFETY: arrays of n elements.
                    api.get_integer
                        .map(|f| (Code(unsafe { f(c, vrs.as_ptr(), n, out.as_mut_ptr()) }), out.iter().map(|&v| f64::from(v)).collect()))
                },
                Vec::new(),
            ),
            Base::Boolean => self.call(
                Function::GetBoolean,
                Some(names),
                value,
                |api, c| {
                    let mut out = vec![0 as c::Boolean; n];
                    // SAFETY: arrays of n elements.
                    api.get_boolean.map(|f| {
                        (Code(unsafe { f(c, vrs.as_ptr(), n, out.as_mut_ptr()) }), out.iter().map(|&v| (v != 0) as i32 as f64).collect())
                    })
                },
                Vec::new(),
            ),
            Base::String => unreachable!("strings are read with get_strings"),
        }
    }

    /// fmi2GetString of `vrs`, copied at once (the FMU may reuse its buffers).
    pub(crate) fn get_strings(&mut self, vrs: &[u32], names: &str) -> Outcome<Vec<Option<String>>> {
        let n = vrs.len();
        self.call(
            Function::GetString,
            Some(names),
            Some(format!("{n} value reference(s)")),
            |api, c| {
                let mut out: Vec<c::FmiString> = vec![std::ptr::null(); n];
                // SAFETY: arrays of n elements; the returned strings are read before the next call.
                api.get_string.map(|f| {
                    let code = Code(unsafe { f(c, vrs.as_ptr(), n, out.as_mut_ptr()) });
                    let texts = out
                        .iter()
                        .map(|&p| if p.is_null() { None } else { Some(unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()) })
                        .collect();
                    (code, texts)
                })
            },
            Vec::new(),
        )
    }

    /// fmi2SetReal/Integer/Boolean of `vrs` to `values`.
    pub(crate) fn set_numbers(&mut self, base: super::model::Base, vrs: &[u32], values: &[f64], names: &str) -> Outcome<()> {
        use super::model::Base;
        let n = vrs.len();
        let shown_values = values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ");
        match base {
            Base::Real => self.status(Function::SetReal, Some(names), Some(shown_values), |api, c| {
                // SAFETY: arrays of n elements.
                api.set_real.map(|f| unsafe { f(c, vrs.as_ptr(), n, values.as_ptr()) })
            }),
            Base::Integer => {
                let ints: Vec<c::Integer> = values.iter().map(|&v| v as c::Integer).collect();
                self.status(Function::SetInteger, Some(names), Some(shown_values), |api, c| {
                    // SAFETY: arrays of n elements.
                    api.set_integer.map(|f| unsafe { f(c, vrs.as_ptr(), n, ints.as_ptr()) })
                })
            }
            Base::Boolean => {
                let bools: Vec<c::Boolean> = values.iter().map(|&v| (v != 0.0) as c::Boolean).collect();
                let shown_bools = bools.iter().map(|&b| if b != 0 { "true" } else { "false" }).collect::<Vec<_>>().join(", ");
                self.status(Function::SetBoolean, Some(names), Some(shown_bools), |api, c| {
                    // SAFETY: arrays of n elements.
                    api.set_boolean.map(|f| unsafe { f(c, vrs.as_ptr(), n, bools.as_ptr()) })
                })
            }
            Base::String => unreachable!("strings are set with set_strings"),
        }
    }

    /// fmi2SetString of `vrs` to `values`.
    pub(crate) fn set_strings(&mut self, vrs: &[u32], values: &[String], names: &str) -> Outcome<()> {
        let texts: Vec<CString> = values.iter().map(|v| CString::new(v.replace('\0', " ")).expect("NUL removed")).collect();
        let pointers: Vec<c::FmiString> = texts.iter().map(|t| t.as_ptr()).collect();
        let n = vrs.len();
        self.status(Function::SetString, Some(names), Some(format!("{values:?}")), |api, c| {
            // SAFETY: arrays of n elements of NUL-terminated strings alive for the call.
            api.set_string.map(|f| unsafe { f(c, vrs.as_ptr(), n, pointers.as_ptr()) })
        })
    }

    /// fmi2DoStep from `t` over `h`.
    pub(crate) fn do_step(&mut self, t: f64, h: f64) -> Outcome<()> {
        self.status(Function::DoStep, None, Some(format!("currentCommunicationPoint {t}, communicationStepSize {h}")), |api, c| {
            // SAFETY: scalar arguments.
            api.do_step.map(|f| unsafe { f(c, t, h, c::TRUE) })
        })
    }

    /// fmi2GetBooleanStatus(fmi2Terminated).
    pub(crate) fn terminated_status(&mut self) -> Outcome<bool> {
        self.call(
            Function::GetBooleanStatus,
            None,
            Some("fmi2Terminated".to_owned()),
            |api, c| {
                let mut value: c::Boolean = 0;
                // SAFETY: a valid out pointer.
                api.get_boolean_status.map(|f| (Code(unsafe { f(c, c::TERMINATED, &mut value) }), value != 0))
            },
            false,
        )
    }

    /// fmi2GetFMUstate into a new state.
    pub(crate) fn get_fmu_state(&mut self) -> Outcome<c::FmuState> {
        self.call(
            Function::GetFmuState,
            None,
            None,
            |api, c| {
                let mut state: c::FmuState = std::ptr::null_mut();
                // SAFETY: a valid out pointer.
                api.get_fmu_state.map(|f| (Code(unsafe { f(c, &mut state) }), state))
            },
            std::ptr::null_mut(),
        )
    }

    /// fmi2SetFMUstate.
    pub(crate) fn set_fmu_state(&mut self, state: c::FmuState) -> Outcome<()> {
        self.status(Function::SetFmuState, None, None, |api, c| {
            // SAFETY: a state this instance's FMU returned.
            api.set_fmu_state.map(|f| unsafe { f(c, state) })
        })
    }

    /// fmi2FreeFMUstate.
    pub(crate) fn free_fmu_state(&mut self, state: &mut c::FmuState) -> Outcome<()> {
        self.status(Function::FreeFmuState, None, None, |api, c| {
            // SAFETY: a state this instance's FMU returned.
            api.free_fmu_state.map(|f| unsafe { f(c, state) })
        })
    }

    /// fmi2SerializedFMUstateSize then fmi2SerializeFMUstate: the bytes of `state`.
    pub(crate) fn serialize(&mut self, state: c::FmuState) -> Outcome<Vec<u8>> {
        let size = self.call(
            Function::SerializedFmuStateSize,
            None,
            None,
            |api, c| {
                let mut n = 0usize;
                // SAFETY: a valid out pointer.
                api.serialized_fmu_state_size.map(|f| (Code(unsafe { f(c, state, &mut n) }), n))
            },
            0,
        );
        if !size.code.ok() {
            return Outcome { code: size.code, value: Vec::new(), log: size.log };
        }
        let n = size.value;
        self.call(
            Function::SerializeFmuState,
            None,
            Some(format!("{n} bytes")),
            |api, c| {
                let mut bytes = vec![0u8; n];
                // SAFETY: a buffer of the size the FMU asked for.
                api.serialize_fmu_state.map(|f| (Code(unsafe { f(c, state, bytes.as_mut_ptr() as *mut c::Byte, n) }), bytes))
            },
            Vec::new(),
        )
    }

    /// fmi2DeSerializeFMUstate of `bytes` into a new state.
    pub(crate) fn deserialize(&mut self, bytes: &[u8]) -> Outcome<c::FmuState> {
        self.call(
            Function::DeSerializeFmuState,
            None,
            Some(format!("{} bytes", bytes.len())),
            |api, c| {
                let mut state: c::FmuState = std::ptr::null_mut();
                // SAFETY: the bytes the FMU serialized, and a valid out pointer.
                api.de_serialize_fmu_state
                    .map(|f| (Code(unsafe { f(c, bytes.as_ptr() as *const c::Byte, bytes.len(), &mut state) }), state))
            },
            std::ptr::null_mut(),
        )
    }

    /// fmi2NewDiscreteStates.
    pub(crate) fn new_discrete_states(&mut self) -> Outcome<c::EventInfo> {
        self.call(
            Function::NewDiscreteStates,
            None,
            None,
            |api, c| {
                let mut info = c::EventInfo::default();
                // SAFETY: a valid out pointer.
                api.new_discrete_states.map(|f| (Code(unsafe { f(c, &mut info) }), info))
            },
            c::EventInfo::default(),
        )
    }

    /// fmi2CompletedIntegratorStep: (enterEventMode, terminateSimulation).
    pub(crate) fn completed_integrator_step(&mut self) -> Outcome<(bool, bool)> {
        self.call(
            Function::CompletedIntegratorStep,
            None,
            None,
            |api, c| {
                let (mut enter, mut terminate): (c::Boolean, c::Boolean) = (0, 0);
                // SAFETY: valid out pointers.
                api.completed_integrator_step
                    .map(|f| (Code(unsafe { f(c, c::TRUE, &mut enter, &mut terminate) }), (enter != 0, terminate != 0)))
            },
            (false, false),
        )
    }

    /// fmi2SetTime.
    pub(crate) fn set_time(&mut self, t: f64) -> Outcome<()> {
        self.status(Function::SetTime, None, Some(format!("time {t}")), |api, c| {
            // SAFETY: a scalar argument.
            api.set_time.map(|f| unsafe { f(c, t) })
        })
    }

    /// fmi2SetContinuousStates.
    pub(crate) fn set_continuous_states(&mut self, x: &[f64]) -> Outcome<()> {
        self.status(Function::SetContinuousStates, None, Some(numbers(x)), |api, c| {
            // SAFETY: an array of x.len() elements.
            api.set_continuous_states.map(|f| unsafe { f(c, x.as_ptr(), x.len()) })
        })
    }

    /// fmi2GetDerivatives, fmi2GetEventIndicators, fmi2GetContinuousStates or
    /// fmi2GetNominalsOfContinuousStates into `n` values.
    pub(crate) fn get_vector(&mut self, function: Function, n: usize) -> Outcome<Vec<f64>> {
        self.call(
            function,
            None,
            Some(format!("{n} values")),
            |api, c| {
                let f = match function {
                    Function::GetDerivatives => api.get_derivatives,
                    Function::GetEventIndicators => api.get_event_indicators,
                    Function::GetContinuousStates => api.get_continuous_states,
                    Function::GetNominalsOfContinuousStates => api.get_nominals_of_continuous_states,
                    _ => unreachable!("{} does not fill a vector", function.name()),
                };
                let mut out = vec![0.0f64; n];
                // SAFETY: an array of n elements.
                f.map(|f| (Code(unsafe { f(c, out.as_mut_ptr(), n) }), out))
            },
            Vec::new(),
        )
    }

    /// fmi2SetDebugLogging for all categories.
    pub(crate) fn set_debug_logging(&mut self, on: bool) -> Outcome<()> {
        self.status(Function::SetDebugLogging, None, Some(format!("loggingOn {on}, no categories")), |api, c| {
            // SAFETY: no categories: a NULL array of length 0.
            api.set_debug_logging.map(|f| unsafe { f(c, on as c::Boolean, 0, std::ptr::null()) })
        })
    }

    /// fmi2FreeInstance; the instance is gone afterwards.
    pub(crate) fn free(&mut self) {
        if self.state == State::Gone {
            return;
        }
        self.null_component = false;
        let _ = self.status(Function::FreeInstance, None, None, |api, c| {
            // SAFETY: the live component, freed once.
            api.free_instance.map(|f| unsafe { f(c) }).map(|()| Code::OK.0)
        });
        self.state = State::Gone;
    }
}

impl Drop for Instance<'_> {
    fn drop(&mut self) {
        // After fmi2Fatal the standard allows no call at all, not even fmi2FreeInstance.
        if !self.fatal {
            self.free();
        }
    }
}

/// A list of numbers as a record or message shows it.
pub(crate) fn numbers(values: &[f64]) -> String {
    let mut text: Vec<String> = values.iter().take(6).map(|v| v.to_string()).collect();
    if values.len() > 6 {
        text.push(format!("... ({} values)", values.len()));
    }
    text.join(", ")
}
