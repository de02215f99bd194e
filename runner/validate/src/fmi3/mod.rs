//! FMI 3.0: its state table, its description, and its C calls behind the probes' [`Binary`]
//! and [`Instance`] traits (any call in any state, with any arguments, NULL arrays included).
//! Co-Simulation instances are made with Event Mode and early return where the FMU offers
//! them; Scheduled Execution is not probed.

pub(crate) mod description;
mod rules;
pub(crate) mod table;

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;

use fmi_c::fmi3 as c;
use fmi_c::Library;

use crate::fmi::{Code, Fmi, Interface, Op, Outcome, Type};
use crate::instance::{Binary, Core, EventUpdate, Exports, FmuState, Instance, Log, StepResult, Tracer};
use crate::isolation::CallRecord;
use crate::model::{Grid, Model};
use crate::table::Table;

/// FMI 3.0's platform folder for this machine (the importer's).
pub(crate) const PLATFORM: &str = fmi_importer::fmi3::PLATFORM;

/// A loaded FMI 3.0 binary.
pub(crate) struct Fmi3 {
    api: c::Functions,
    /// Keeps the binary loaded while its functions are called.
    _library: Library,
    model: &'static Model,
    tracer: Tracer,
    /// The resources directory as FMI 3.0 passes it: an absolute path ending in '/'.
    resources: CString,
}

impl Fmi3 {
    /// The binary `library` of the FMU unpacked in `dir`, described by `model`, with its FMI
    /// 3.0 functions.
    pub(crate) fn new(library: Library, model: &'static Model, dir: &Path, tracer: Tracer) -> Result<Fmi3, String> {
        let resources = CString::new(format!("{}/", dir.join("resources").display()))
            .map_err(|_| "the temporary directory's path contains a NUL byte".to_owned())?;
        Ok(Fmi3 { api: c::Functions::resolve(&library), _library: library, model, tracer, resources })
    }
}

/// fmi3LogMessageCallback: hands the message to the instance's [`Log`].
unsafe extern "C" fn log_message(env: *mut c_void, status: c_int, category: *const c_char, message: *const c_char) {
    // Inside the FMU's call: must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        if env.is_null() {
            return;
        }
        let text = |p: *const c_char| if p.is_null() { String::new() } else { unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned() };
        let message = text(message);
        let line = fmi_schema::printable(format!("[{}] {}: {message}", c::status_name(status), text(category)));
        // SAFETY: the environment is the Log the instance was made with, alive until freed.
        let log = unsafe { &*(env as *const Log) };
        log.receive(&line, &message);
    });
}

impl Binary for Fmi3 {
    fn fmi(&self) -> Fmi {
        Fmi::Fmi3
    }

    fn model(&self) -> &'static Model {
        self.model
    }

    fn table(&self) -> &'static Table {
        &table::TABLE
    }

    fn tracer(&self) -> Tracer {
        self.tracer
    }

    fn instantiate(
        &'static self,
        name: &str,
        interface: Interface,
        token: &str,
        slot: usize,
    ) -> Result<Box<dyn Instance>, (Code, Option<String>)> {
        let log = Box::new(Log::default());
        let env = &*log as *const Log as *mut c_void;
        let nul = |what: &str| (Code::error_of(Fmi::Fmi3), Some(format!("the {what} contains a NUL byte")));
        let c_name = CString::new(name).map_err(|_| nul("instance name"))?;
        let c_token = CString::new(token).map_err(|_| nul("instantiationToken"))?;
        let record = CallRecord {
            call: table::TABLE.name(Op::Instantiate, interface).to_owned(),
            state: "(no instance)".to_owned(),
            variable: None,
            value: Some(format!("instanceName {name:?}, instantiationToken {token}")),
        };
        let cs = self.model.co_simulation.clone().unwrap_or_default();
        let tracer = self.tracer.in_slot(slot);
        let resources = self.resources.as_ptr();
        // SAFETY: every pointer is valid for the call; the log outlives the instance.
        let handle = tracer.traced(&record, || unsafe {
            match interface {
                Interface::CoSimulation => self.api.instantiate_co_simulation.map(|f| {
                    f(
                        c_name.as_ptr(),
                        c_token.as_ptr(),
                        resources,
                        false,
                        false,
                        cs.event_mode,
                        cs.early_return,
                        std::ptr::null(),
                        0,
                        env,
                        Some(log_message),
                        None,
                    )
                }),
                Interface::ModelExchange => self
                    .api
                    .instantiate_model_exchange
                    .map(|f| f(c_name.as_ptr(), c_token.as_ptr(), resources, false, false, env, Some(log_message))),
            }
        });
        match handle {
            None => Err((Code::missing(Fmi::Fmi3), None)),
            Some(p) if p.is_null() => Err((Code::error_of(Fmi::Fmi3), log.take())),
            Some(handle) => Ok(Box::new(Fmi3Instance { core: Core::new(self, interface, handle, log, tracer), api: &self.api })),
        }
    }

    fn exports(&self, name: &str) -> bool {
        self.api.exports(name)
    }

    /// Section 2.5: "The FMU must implement all API functions declared in fmi3Functions.h, even
    /// if they are only needed for interface types or optional capabilities that the FMU does
    /// not support".
    fn required_exports(&self, _interfaces: &[Interface]) -> Exports {
        let all: Vec<&'static str> = c::COMMON_FUNCTIONS
            .iter()
            .chain(&c::MODEL_EXCHANGE_FUNCTIONS)
            .chain(&c::CO_SIMULATION_FUNCTIONS)
            .chain(&c::SCHEDULED_EXECUTION_FUNCTIONS)
            .copied()
            .collect();
        let n = all.len();
        let why = format!(": FMI 3.0 requires all {n} functions of fmi3Functions.h, even for interfaces and capabilities the FMU lacks");
        Exports {
            required: all.into_iter().map(|f| (f, why.clone())).collect(),
            passed: format!("all {n} functions of fmi3Functions.h exported"),
        }
    }

    fn query(&self, op: Op) -> Option<Option<String>> {
        let getter = if op == Op::GetVersion { self.api.get_version } else { None }?;
        // SAFETY: returns a static C string per the standard (NULL is checked).
        Some(unsafe {
            let p = getter();
            (!p.is_null()).then(|| CStr::from_ptr(p).to_string_lossy().into_owned())
        })
    }
}

/// One live FMI 3.0 instance.
struct Fmi3Instance {
    core: Core,
    api: &'static c::Functions,
}

impl Drop for Fmi3Instance {
    fn drop(&mut self) {
        if !self.core.is_fatal() {
            self.free();
        }
    }
}

/// The type of FMI 3.0's vector getters.
type VectorGetter = Option<unsafe extern "C" fn(c::Instance, *mut f64, usize) -> c_int>;

impl Fmi3Instance {
    fn vector_function(&self, op: Op) -> VectorGetter {
        match op {
            Op::GetDerivatives => self.api.get_continuous_state_derivatives,
            Op::GetEventIndicators => self.api.get_event_indicators,
            Op::GetContinuousStates => self.api.get_continuous_states,
            Op::GetNominalsOfContinuousStates => self.api.get_nominals_of_continuous_states,
            _ => unreachable!("{op:?} does not fill a vector"),
        }
    }
}

impl Instance for Fmi3Instance {
    fn core(&self) -> &Core {
        &self.core
    }

    fn core_mut(&mut self) -> &mut Core {
        &mut self.core
    }

    fn setup_experiment(&mut self, _grid: &Grid) -> Option<Outcome<()>> {
        None
    }

    fn enter_initialization_mode(&mut self, grid: &Grid) -> Outcome<()> {
        let (tolerance, start, stop) = (grid.tolerance, grid.start, grid.stop);
        let value = format!("tolerance {}, start {start}, stop {stop}", tolerance.map_or("undefined".to_owned(), |t| t.to_string()));
        let api = self.api;
        self.core.status(Op::EnterInitializationMode, None, Some(value), |h| {
            // SAFETY: scalar arguments.
            api.enter_initialization_mode.map(|f| unsafe { f(h, tolerance.is_some(), tolerance.unwrap_or(0.0), start, true, stop) })
        })
    }

    fn simple(&mut self, op: Op) -> Outcome<()> {
        let api = self.api;
        if op == Op::FreeInstance {
            // Only with a NULL instance, which the FMU must ignore: a real free goes through free().
            assert!(self.core.null_instance, "FreeInstance of a live instance goes through free()");
            let ok = Code::ok_of(Fmi::Fmi3).status;
            // SAFETY: a NULL instance.
            return self.core.status(op, None, None, |h| api.free_instance.map(|f| unsafe { f(h) }).map(|()| ok));
        }
        let f = match op {
            Op::ExitInitializationMode => api.exit_initialization_mode,
            Op::Terminate => api.terminate,
            Op::Reset => api.reset,
            Op::EnterEventMode => api.enter_event_mode,
            Op::EnterContinuousTimeMode => api.enter_continuous_time_mode,
            Op::EnterStepMode => api.enter_step_mode,
            _ => unreachable!("{op:?} is not an FMI 3.0 call on the instance alone"),
        };
        self.core.plain(op, f)
    }

    fn set_debug_logging(&mut self, on: bool) -> Outcome<()> {
        let api = self.api;
        self.core.status(Op::SetDebugLogging, None, Some(format!("loggingOn {on}, no categories")), |h| {
            // SAFETY: no categories: a NULL array of length 0, as the standard asks.
            api.set_debug_logging.map(|f| unsafe { f(h, on, 0, std::ptr::null()) })
        })
    }

    fn free(&mut self) {
        self.core.free(self.api.free_instance);
    }

    fn get_numbers(&mut self, ty: Type, vrs: &[u32], names: &str) -> Outcome<Vec<f64>> {
        let (api, n) = (self.api, vrs.len());
        let value = Some(format!("{n} value reference(s)"));
        // SAFETY (each arm): n references and as many values.
        match ty {
            Type::Real => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![0.0f64; n];
                    api.get_float64.map(|f| (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr(), n) }, out))
                },
                Vec::new(),
            ),
            Type::Integer => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![0i32; n];
                    api.get_int32
                        .map(|f| (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr(), n) }, out.iter().map(|&v| f64::from(v)).collect()))
                },
                Vec::new(),
            ),
            Type::Boolean => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![false; n];
                    api.get_boolean
                        .map(|f| (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr(), n) }, out.iter().map(|&v| v as i32 as f64).collect()))
                },
                Vec::new(),
            ),
            Type::String => unreachable!("strings are read with get_strings"),
        }
    }

    fn get_strings(&mut self, vrs: &[u32], names: &str) -> Outcome<Vec<Option<String>>> {
        let (api, n) = (self.api, vrs.len());
        self.core.call(
            Op::Get(Type::String),
            Some(names),
            Some(format!("{n} value reference(s)")),
            |h| {
                let mut out: Vec<c::FmiString> = vec![std::ptr::null(); n];
                // SAFETY: n references and as many values; the texts are copied before the
                // next call.
                api.get_string.map(|f| {
                    let code = unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr(), n) };
                    let texts =
                        out.iter().map(|p| (!p.is_null()).then(|| unsafe { CStr::from_ptr(*p) }.to_string_lossy().into_owned())).collect();
                    (code, texts)
                })
            },
            Vec::new(),
        )
    }

    fn set_numbers(&mut self, ty: Type, vrs: &[u32], values: &[f64], names: &str) -> Outcome<()> {
        let (api, n) = (self.api, vrs.len());
        let shown = values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ");
        // SAFETY (each arm): n references and as many values.
        match ty {
            Type::Real => self.core.status(Op::Set(ty), Some(names), Some(shown), |h| {
                api.set_float64.map(|f| unsafe { f(h, vrs.as_ptr(), n, values.as_ptr(), n) })
            }),
            Type::Integer => {
                let ints: Vec<i32> = values.iter().map(|&v| v as i32).collect();
                self.core.status(Op::Set(ty), Some(names), Some(shown), |h| {
                    api.set_int32.map(|f| unsafe { f(h, vrs.as_ptr(), n, ints.as_ptr(), n) })
                })
            }
            Type::Boolean => {
                let bools: Vec<bool> = values.iter().map(|&v| v != 0.0).collect();
                let shown = bools.iter().map(|b| b.to_string()).collect::<Vec<_>>().join(", ");
                self.core.status(Op::Set(ty), Some(names), Some(shown), |h| {
                    api.set_boolean.map(|f| unsafe { f(h, vrs.as_ptr(), n, bools.as_ptr(), n) })
                })
            }
            Type::String => unreachable!("strings are set with set_strings"),
        }
    }

    fn set_strings(&mut self, vrs: &[u32], values: &[String], names: &str) -> Outcome<()> {
        let texts: Vec<CString> = values.iter().map(|v| CString::new(v.replace('\0', " ")).expect("NUL removed")).collect();
        let pointers: Vec<c::FmiString> = texts.iter().map(|t| t.as_ptr()).collect();
        let (api, n) = (self.api, vrs.len());
        self.core.status(Op::Set(Type::String), Some(names), Some(format!("{values:?}")), |h| {
            // SAFETY: n references and as many NUL-terminated texts, alive for the call.
            api.set_string.map(|f| unsafe { f(h, vrs.as_ptr(), n, pointers.as_ptr(), n) })
        })
    }

    fn raw_access(
        &mut self,
        op: Op,
        null_vrs: bool,
        null_values: bool,
        n: usize,
        vr: u32,
        variable: Option<&str>,
        value: Option<String>,
    ) -> Outcome<()> {
        let (ty, get) = op.access().expect("a get or a set");
        let vrs = [vr];
        let vr_ptr = if null_vrs { std::ptr::null() } else { vrs.as_ptr() };
        // An 8-byte buffer holds one value of any of the four types; the String one points at
        // a valid text.
        let text = CString::new("runner validate").expect("no NUL");
        let mut buffer: [u64; 1] = match ty {
            Type::Real => [1.5f64.to_bits()],
            Type::String => [text.as_ptr() as u64],
            _ => [1],
        };
        let values: *mut c_void = if null_values { std::ptr::null_mut() } else { buffer.as_mut_ptr() as *mut c_void };
        let api = self.api;
        self.core.status(op, variable, value, |h| {
            // SAFETY: the arrays are either NULL (what is being probed) or valid for n <= 1.
            unsafe {
                match (ty, get) {
                    (Type::Real, true) => api.get_float64.map(|g| g(h, vr_ptr, n, values as *mut f64, n)),
                    (Type::Integer, true) => api.get_int32.map(|g| g(h, vr_ptr, n, values as *mut i32, n)),
                    (Type::Boolean, true) => api.get_boolean.map(|g| g(h, vr_ptr, n, values as *mut bool, n)),
                    (Type::String, true) => api.get_string.map(|g| g(h, vr_ptr, n, values as *mut c::FmiString, n)),
                    (Type::Real, false) => api.set_float64.map(|g| g(h, vr_ptr, n, values as *const f64, n)),
                    (Type::Integer, false) => api.set_int32.map(|g| g(h, vr_ptr, n, values as *const i32, n)),
                    (Type::Boolean, false) => api.set_boolean.map(|g| g(h, vr_ptr, n, values as *const bool, n)),
                    (Type::String, false) => api.set_string.map(|g| g(h, vr_ptr, n, values as *const c::FmiString, n)),
                }
            }
        })
    }

    fn set_string_pointer(&mut self, vr: u32, text: *const c_char, variable: &str, value: String) -> Outcome<()> {
        let (api, vrs, texts) = (self.api, [vr], [text]);
        self.core.status(Op::Set(Type::String), Some(variable), Some(value), |h| {
            // SAFETY: one reference and one text, the caller's (or a NULL being probed).
            api.set_string.map(|f| unsafe { f(h, vrs.as_ptr(), 1, texts.as_ptr(), 1) })
        })
    }

    fn get_string_pointer(&mut self, vr: u32, variable: &str) -> Outcome<(*const c_char, Option<String>)> {
        let (api, vrs) = (self.api, [vr]);
        self.core.call(
            Op::Get(Type::String),
            Some(variable),
            Some("1 value reference".to_owned()),
            |h| {
                let mut out: [c::FmiString; 1] = [std::ptr::null()];
                // SAFETY: one reference and one value; the text is read before the next call.
                api.get_string.map(|f| {
                    let code = unsafe { f(h, vrs.as_ptr(), 1, out.as_mut_ptr(), 1) };
                    let text = (!out[0].is_null()).then(|| unsafe { CStr::from_ptr(out[0]) }.to_string_lossy().into_owned());
                    (code, (out[0], text))
                })
            },
            (std::ptr::null(), None),
        )
    }

    fn get_fmu_state(&mut self) -> Outcome<FmuState> {
        self.core.get_fmu_state(self.api.get_fmu_state)
    }

    fn get_fmu_state_into_null(&mut self) -> Outcome<()> {
        self.core.get_fmu_state_into_null(self.api.get_fmu_state)
    }

    fn set_fmu_state(&mut self, state: FmuState) -> Outcome<()> {
        self.core.set_fmu_state(self.api.set_fmu_state, state)
    }

    fn free_fmu_state(&mut self, state: &mut FmuState) -> Outcome<()> {
        self.core.free_fmu_state(self.api.free_fmu_state, state)
    }

    fn serialized_fmu_state_size(&mut self, state: FmuState) -> Outcome<usize> {
        self.core.serialized_fmu_state_size(self.api.serialized_fmu_state_size, state)
    }

    fn serialize_fmu_state(&mut self, state: FmuState, bytes: &mut [u8]) -> Outcome<()> {
        let api = self.api;
        self.core.status(Op::SerializeFmuState, None, Some(format!("{} bytes", bytes.len())), |h| {
            // SAFETY: a buffer of the size the FMU asked for.
            api.serialize_fmu_state.map(|f| unsafe { f(h, state, bytes.as_mut_ptr(), bytes.len()) })
        })
    }

    fn deserialize_fmu_state(&mut self, bytes: &[u8]) -> Outcome<FmuState> {
        let api = self.api;
        self.core.call(
            Op::DeserializeFmuState,
            None,
            Some(format!("{} bytes", bytes.len())),
            |h| {
                let mut state: c::FmuState = std::ptr::null_mut();
                // SAFETY: the bytes the FMU serialized, and a valid out pointer.
                api.deserialize_fmu_state.map(|f| (unsafe { f(h, bytes.as_ptr(), bytes.len(), &mut state) }, state))
            },
            std::ptr::null_mut(),
        )
    }

    fn do_step(&mut self, t: f64, h: f64) -> Outcome<StepResult> {
        let api = self.api;
        self.core.call(
            Op::DoStep,
            None,
            Some(format!("currentCommunicationPoint {t}, communicationStepSize {h}")),
            |i| {
                let (mut event, mut terminate, mut early, mut last) = (false, false, false, f64::NAN);
                // SAFETY: valid out pointers.
                api.do_step.map(|f| {
                    let code = unsafe { f(i, t, h, true, &mut event, &mut terminate, &mut early, &mut last) };
                    (code, StepResult { event, terminate, early, last })
                })
            },
            StepResult::default(),
        )
    }

    fn terminated(&mut self) -> Outcome<bool> {
        // fmi3DoStep says so itself (terminateSimulation).
        Outcome { code: Code::missing(Fmi::Fmi3), value: false, log: None }
    }

    fn set_time(&mut self, t: f64) -> Outcome<()> {
        self.core.set_time(self.api.set_time, t)
    }

    fn set_continuous_states(&mut self, x: &[f64]) -> Outcome<()> {
        self.core.set_continuous_states(self.api.set_continuous_states, x)
    }

    fn get_vector(&mut self, op: Op, n: usize) -> Outcome<Vec<f64>> {
        let f = self.vector_function(op);
        self.core.get_vector(op, f, n)
    }

    fn null_vector(&mut self, op: Op, n: usize) -> Outcome<()> {
        let get = (op != Op::SetContinuousStates).then(|| self.vector_function(op)).flatten();
        self.core.null_vector(op, get, self.api.set_continuous_states, n)
    }

    fn update_discrete_states(&mut self) -> Outcome<EventUpdate> {
        let api = self.api;
        self.core.call(
            Op::UpdateDiscreteStates,
            None,
            None,
            |h| {
                let (mut again, mut terminate, mut nominals, mut values, mut defined, mut next) = (false, false, false, false, false, 0.0);
                // SAFETY: valid out pointers.
                api.update_discrete_states.map(|f| {
                    let code = unsafe { f(h, &mut again, &mut terminate, &mut nominals, &mut values, &mut defined, &mut next) };
                    (code, EventUpdate { again, terminate, values_changed: values, next_event_time: defined.then_some(next) })
                })
            },
            EventUpdate::default(),
        )
    }

    fn completed_integrator_step(&mut self) -> Outcome<(bool, bool)> {
        let api = self.api;
        self.core.call(
            Op::CompletedIntegratorStep,
            None,
            None,
            |h| {
                let (mut enter, mut terminate) = (false, false);
                // SAFETY: valid out pointers.
                api.completed_integrator_step.map(|f| (unsafe { f(h, true, &mut enter, &mut terminate) }, (enter, terminate)))
            },
            (false, false),
        )
    }

    fn number_of(&mut self, op: Op, null: bool) -> Outcome<usize> {
        let f = match op {
            Op::GetNumberOfContinuousStates => self.api.get_number_of_continuous_states,
            Op::GetNumberOfEventIndicators => self.api.get_number_of_event_indicators,
            _ => unreachable!("{op:?} is not a size query"),
        };
        let value = null.then(|| "a NULL pointer for the number".to_owned());
        self.core.call(
            op,
            None,
            value,
            |h| {
                let mut n = 0usize;
                let out: *mut usize = if null { std::ptr::null_mut() } else { &mut n };
                // SAFETY: a valid out pointer, or a NULL being probed.
                f.map(|f| (unsafe { f(h, out) }, n))
            },
            0,
        )
    }

    fn other(&mut self, op: Op) -> Outcome<()> {
        unreachable!("FMI 3.0's probes make no call {op:?}")
    }
}
