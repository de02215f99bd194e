//! FMI 2.0: its state table, its description, and its C calls behind the probes' [`Binary`]
//! and [`Instance`] traits (any call in any state, with any arguments, NULL arrays included).

pub(crate) mod description;
mod rules;
pub(crate) mod table;

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::Path;

use fmi_c::fmi2 as c;
use fmi_c::Library;

use crate::fmi::{Code, Fmi, Interface, Op, Outcome, Type};
use crate::instance::{Binary, Core, EventUpdate, Exports, FmuState, Instance, Log, StepResult, Tracer};
use crate::isolation::CallRecord;
use crate::model::{Grid, Model};
use crate::table::Table;

/// FMI 2.0's platform folder for this machine (the importer's).
pub(crate) const PLATFORM: &str = fmi_importer::fmi2::PLATFORM;

/// A loaded FMI 2.0 binary.
pub(crate) struct Fmi2 {
    api: c::Functions,
    /// Keeps the binary loaded while its functions are called.
    _library: Library,
    model: &'static Model,
    tracer: Tracer,
    resource_uri: CString,
}

impl Fmi2 {
    /// The binary `library` of the FMU unpacked in `dir`, described by `model`, with its FMI
    /// 2.0 functions.
    pub(crate) fn new(library: Library, model: &'static Model, dir: &Path, tracer: Tracer) -> Result<Fmi2, String> {
        let resource_uri = CString::new(format!("file://{}/", dir.join("resources").display()))
            .map_err(|_| "the temporary directory's path contains a NUL byte".to_owned())?;
        Ok(Fmi2 { api: c::Functions::resolve(&library), _library: library, model, tracer, resource_uri })
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
        let text = text_of(text);
        let line = fmi_schema::printable(format!("[{}] {} ({}): {text}", text_of(instance), c::status_name(status), text_of(category)));
        log.receive(&line, &text);
    });
}

/// The callbacks of one instance, at a fixed address while it lives.
struct Callbacks {
    functions: c::CallbackFunctions,
    _forwarder: Box<c::LogForwarder>,
}

// The callbacks point at the instance's own log; they move with the instance to the thread
// that uses it (the threads probe), one thread at a time.
unsafe impl Send for Callbacks {}

impl Callbacks {
    fn new(log: &Log) -> Box<Callbacks> {
        let forwarder = Box::new(c::LogForwarder { forward, context: log as *const Log as *mut c_void });
        let functions = c::CallbackFunctions::forwarding_to(&forwarder);
        Box::new(Callbacks { functions, _forwarder: forwarder })
    }
}

impl Binary for Fmi2 {
    fn fmi(&self) -> Fmi {
        Fmi::Fmi2
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
        let Some(instantiate) = self.api.instantiate else { return Err((Code::missing(Fmi::Fmi2), None)) };
        let log = Box::new(Log::default());
        let callbacks = Callbacks::new(&log);
        let c_name = CString::new(name).expect("instance names are ours, without NUL");
        let guid = CString::new(token).map_err(|_| (Code::error_of(Fmi::Fmi2), Some("the GUID contains a NUL byte".to_owned())))?;
        let record = CallRecord {
            call: "fmi2Instantiate".to_owned(),
            state: "(no instance)".to_owned(),
            variable: None,
            value: Some(format!("instanceName {name:?}, fmuType {}, GUID {token}", interface.title())),
        };
        let fmu_type = match interface {
            Interface::CoSimulation => c::CO_SIMULATION,
            Interface::ModelExchange => c::MODEL_EXCHANGE,
        };
        let tracer = self.tracer.in_slot(slot);
        // SAFETY: every pointer is valid for the call; the callbacks outlive the component.
        let component = tracer.traced(&record, || unsafe {
            instantiate(c_name.as_ptr(), fmu_type, guid.as_ptr(), self.resource_uri.as_ptr(), &callbacks.functions, c::FALSE, c::FALSE)
        });
        if component.is_null() {
            return Err((Code::error_of(Fmi::Fmi2), log.take()));
        }
        Ok(Box::new(Fmi2Instance { core: Core::new(self, interface, component, log, tracer), api: &self.api, _callbacks: callbacks }))
    }

    fn exports(&self, name: &str) -> bool {
        self.api.exports(name)
    }

    /// Every function of each declared interface, even for capabilities it lacks.
    fn required_exports(&self, interfaces: &[Interface]) -> Exports {
        let mut required: Vec<(&'static str, String)> = Vec::new();
        for &interface in interfaces {
            for op in table::TABLE.functions(interface) {
                let name = table::TABLE.name(op, interface);
                if !required.iter().any(|(n, _)| *n == name) {
                    let why = format!(
                        ", which {} requires (FMI 2.0: every function of a declared interface, even for capabilities it lacks)",
                        interface.title()
                    );
                    required.push((name, why));
                }
            }
        }
        let titles = interfaces.iter().map(|i| i.title()).collect::<Vec<_>>().join(" and ");
        Exports { passed: format!("all {} functions of {titles} exported", required.len()), required }
    }

    fn query(&self, op: Op) -> Option<Option<String>> {
        let getter = match op {
            Op::GetVersion => self.api.get_version,
            Op::GetTypesPlatform => self.api.get_types_platform,
            _ => None,
        }?;
        // SAFETY: both return a static C string per the standard (NULL is checked).
        Some(unsafe {
            let p = getter();
            (!p.is_null()).then(|| CStr::from_ptr(p).to_string_lossy().into_owned())
        })
    }
}

/// One live FMI 2.0 instance.
struct Fmi2Instance {
    core: Core,
    api: &'static c::Functions,
    _callbacks: Box<Callbacks>,
}

impl Drop for Fmi2Instance {
    fn drop(&mut self) {
        if !self.core.is_fatal() {
            self.free();
        }
    }
}

/// `values` as a record shows them.
fn listed(values: &[f64]) -> String {
    values.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ")
}

impl Instance for Fmi2Instance {
    fn core(&self) -> &Core {
        &self.core
    }

    fn core_mut(&mut self) -> &mut Core {
        &mut self.core
    }

    fn setup_experiment(&mut self, grid: &Grid) -> Option<Outcome<()>> {
        let (tolerance, start, stop) = (grid.tolerance, grid.start, grid.stop);
        let value = format!("tolerance {}, start {start}, stop {stop}", tolerance.map_or("undefined".to_owned(), |t| t.to_string()));
        let api = self.api;
        Some(self.core.status(Op::SetupExperiment, None, Some(value), |h| {
            // SAFETY: scalar arguments only.
            api.setup_experiment.map(|f| unsafe { f(h, tolerance.is_some() as c_int, tolerance.unwrap_or(0.0), start, c::TRUE, stop) })
        }))
    }

    fn enter_initialization_mode(&mut self, _grid: &Grid) -> Outcome<()> {
        self.simple(Op::EnterInitializationMode)
    }

    fn simple(&mut self, op: Op) -> Outcome<()> {
        let api = self.api;
        if op == Op::FreeInstance {
            // Only with a NULL component, which the FMU must ignore: a real free goes through free().
            assert!(self.core.null_instance, "FreeInstance of a live instance goes through free()");
            let ok = Code::ok_of(Fmi::Fmi2).status;
            // SAFETY: a NULL component.
            return self.core.status(op, None, None, |h| api.free_instance.map(|f| unsafe { f(h) }).map(|()| ok));
        }
        let f = match op {
            Op::EnterInitializationMode => api.enter_initialization_mode,
            Op::ExitInitializationMode => api.exit_initialization_mode,
            Op::Terminate => api.terminate,
            Op::Reset => api.reset,
            Op::EnterEventMode => api.enter_event_mode,
            Op::EnterContinuousTimeMode => api.enter_continuous_time_mode,
            Op::CancelStep => api.cancel_step,
            _ => unreachable!("{op:?} is not an FMI 2.0 call on the component alone"),
        };
        self.core.plain(op, f)
    }

    fn set_debug_logging(&mut self, on: bool) -> Outcome<()> {
        let api = self.api;
        self.core.status(Op::SetDebugLogging, None, Some(format!("loggingOn {on}, no categories")), |h| {
            // SAFETY: no categories: a NULL array of length 0.
            api.set_debug_logging.map(|f| unsafe { f(h, on as c::Boolean, 0, std::ptr::null()) })
        })
    }

    fn free(&mut self) {
        self.core.free(self.api.free_instance);
    }

    fn get_numbers(&mut self, ty: Type, vrs: &[u32], names: &str) -> Outcome<Vec<f64>> {
        let (api, n) = (self.api, vrs.len());
        let value = Some(format!("{n} value reference(s)"));
        // SAFETY (each arm): arrays of n elements.
        match ty {
            Type::Real => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![0.0f64; n];
                    api.get_real.map(|f| (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr()) }, out))
                },
                Vec::new(),
            ),
            Type::Integer => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![0 as c::Integer; n];
                    api.get_integer
                        .map(|f| (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr()) }, out.iter().map(|&v| f64::from(v)).collect()))
                },
                Vec::new(),
            ),
            Type::Boolean => self.core.call(
                Op::Get(ty),
                Some(names),
                value,
                |h| {
                    let mut out = vec![0 as c::Boolean; n];
                    api.get_boolean.map(|f| {
                        (unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr()) }, out.iter().map(|&v| (v != 0) as i32 as f64).collect())
                    })
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
                // SAFETY: arrays of n elements; the returned strings are read before the next call.
                api.get_string.map(|f| {
                    let code = unsafe { f(h, vrs.as_ptr(), n, out.as_mut_ptr()) };
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

    fn set_numbers(&mut self, ty: Type, vrs: &[u32], values: &[f64], names: &str) -> Outcome<()> {
        let (api, n) = (self.api, vrs.len());
        // SAFETY (each arm): arrays of n elements.
        match ty {
            Type::Real => self.core.status(Op::Set(ty), Some(names), Some(listed(values)), |h| {
                api.set_real.map(|f| unsafe { f(h, vrs.as_ptr(), n, values.as_ptr()) })
            }),
            Type::Integer => {
                let ints: Vec<c::Integer> = values.iter().map(|&v| v as c::Integer).collect();
                self.core.status(Op::Set(ty), Some(names), Some(listed(values)), |h| {
                    api.set_integer.map(|f| unsafe { f(h, vrs.as_ptr(), n, ints.as_ptr()) })
                })
            }
            Type::Boolean => {
                let bools: Vec<c::Boolean> = values.iter().map(|&v| (v != 0.0) as c::Boolean).collect();
                let shown = bools.iter().map(|&b| if b != 0 { "true" } else { "false" }).collect::<Vec<_>>().join(", ");
                self.core.status(Op::Set(ty), Some(names), Some(shown), |h| {
                    api.set_boolean.map(|f| unsafe { f(h, vrs.as_ptr(), n, bools.as_ptr()) })
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
            // SAFETY: arrays of n elements of NUL-terminated strings alive for the call.
            api.set_string.map(|f| unsafe { f(h, vrs.as_ptr(), n, pointers.as_ptr()) })
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
        // An 8-byte buffer holds one value of any type; the String one points at a valid text.
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
                    (Type::Real, true) => api.get_real.map(|g| g(h, vr_ptr, n, values as *mut f64)),
                    (Type::Integer, true) => api.get_integer.map(|g| g(h, vr_ptr, n, values as *mut c::Integer)),
                    (Type::Boolean, true) => api.get_boolean.map(|g| g(h, vr_ptr, n, values as *mut c::Boolean)),
                    (Type::String, true) => api.get_string.map(|g| g(h, vr_ptr, n, values as *mut c::FmiString)),
                    (Type::Real, false) => api.set_real.map(|g| g(h, vr_ptr, n, values as *const f64)),
                    (Type::Integer, false) => api.set_integer.map(|g| g(h, vr_ptr, n, values as *const c::Integer)),
                    (Type::Boolean, false) => api.set_boolean.map(|g| g(h, vr_ptr, n, values as *const c::Boolean)),
                    (Type::String, false) => api.set_string.map(|g| g(h, vr_ptr, n, values as *const c::FmiString)),
                }
            }
        })
    }

    fn set_string_pointer(&mut self, vr: u32, text: *const c_char, variable: &str, value: String) -> Outcome<()> {
        let (api, vrs, texts) = (self.api, [vr], [text]);
        self.core.status(Op::Set(Type::String), Some(variable), Some(value), |h| {
            // SAFETY: arrays of one element; the text is the caller's (or a NULL being probed).
            api.set_string.map(|f| unsafe { f(h, vrs.as_ptr(), 1, texts.as_ptr()) })
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
                // SAFETY: arrays of one element; the text is read before the next call.
                api.get_string.map(|f| {
                    let code = unsafe { f(h, vrs.as_ptr(), 1, out.as_mut_ptr()) };
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
            api.serialize_fmu_state.map(|f| unsafe { f(h, state, bytes.as_mut_ptr() as *mut c::Byte, bytes.len()) })
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
                api.de_serialize_fmu_state.map(|f| (unsafe { f(h, bytes.as_ptr() as *const c::Byte, bytes.len(), &mut state) }, state))
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
            // SAFETY: scalar arguments.
            |c| api.do_step.map(|f| (unsafe { f(c, t, h, c::TRUE) }, StepResult::default())),
            StepResult::default(),
        )
    }

    fn terminated(&mut self) -> Outcome<bool> {
        let api = self.api;
        self.core.call(
            Op::Status(Some(Type::Boolean)),
            None,
            Some("fmi2Terminated".to_owned()),
            |h| {
                let mut value: c::Boolean = 0;
                // SAFETY: a valid out pointer.
                api.get_boolean_status.map(|f| (unsafe { f(h, c::TERMINATED, &mut value) }, value != 0))
            },
            false,
        )
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
        let got = self.core.call(
            Op::UpdateDiscreteStates,
            None,
            None,
            |h| {
                let mut info = c::EventInfo::default();
                // SAFETY: a valid out pointer.
                api.new_discrete_states.map(|f| (unsafe { f(h, &mut info) }, info))
            },
            c::EventInfo::default(),
        );
        let info = got.value;
        Outcome {
            code: got.code,
            value: EventUpdate {
                again: info.new_discrete_states_needed != 0,
                terminate: info.terminate_simulation != 0,
                values_changed: info.values_of_continuous_states_changed != 0,
                next_event_time: (info.next_event_time_defined != 0).then_some(info.next_event_time),
            },
            log: got.log,
        }
    }

    fn completed_integrator_step(&mut self) -> Outcome<(bool, bool)> {
        let api = self.api;
        self.core.call(
            Op::CompletedIntegratorStep,
            None,
            None,
            |h| {
                let (mut enter, mut terminate): (c::Boolean, c::Boolean) = (0, 0);
                // SAFETY: valid out pointers.
                api.completed_integrator_step.map(|f| (unsafe { f(h, c::TRUE, &mut enter, &mut terminate) }, (enter != 0, terminate != 0)))
            },
            (false, false),
        )
    }

    fn number_of(&mut self, _op: Op, _null: bool) -> Outcome<usize> {
        // FMI 2.0 has no size queries: the description's sizes hold.
        Outcome { code: Code::missing(Fmi::Fmi2), value: 0, log: None }
    }

    fn other(&mut self, op: Op) -> Outcome<()> {
        let api = self.api;
        let no_variables = Some("no variables".to_owned());
        match op {
            Op::GetDirectionalDerivative => self.core.status(op, None, Some("no unknowns, no knowns".to_owned()), |h| {
                // SAFETY: zero-length arrays: the FMU reads no element.
                api.get_directional_derivative.map(|g| unsafe { g(h, [].as_ptr(), 0, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) })
            }),
            Op::SetInputDerivatives => self.core.status(op, None, no_variables, |h| {
                // SAFETY: zero-length arrays.
                api.set_real_input_derivatives.map(|g| unsafe { g(h, [].as_ptr(), 0, [].as_ptr(), [].as_ptr()) })
            }),
            Op::GetOutputDerivatives => self.core.status(op, None, no_variables, |h| {
                // SAFETY: zero-length arrays.
                api.get_real_output_derivatives.map(|g| unsafe { g(h, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) })
            }),
            Op::Status(ty) => {
                // The status kind that fits each type.
                let (kind, name) = match ty {
                    Some(Type::Real) => (c::LAST_SUCCESSFUL_TIME, "fmi2LastSuccessfulTime"),
                    Some(Type::Boolean) => (c::TERMINATED, "fmi2Terminated"),
                    Some(Type::String) => (c::PENDING_STATUS, "fmi2PendingStatus"),
                    _ => (c::DO_STEP_STATUS, "fmi2DoStepStatus"),
                };
                self.core.status(op, None, Some(name.to_owned()), |h| {
                    let mut buffer = [0u64; 1];
                    let out = buffer.as_mut_ptr() as *mut c_void;
                    // SAFETY: an 8-byte, 8-aligned buffer holds any of the five value types.
                    unsafe {
                        match ty {
                            None => api.get_status.map(|g| g(h, kind, out as *mut c_int)),
                            Some(Type::Real) => api.get_real_status.map(|g| g(h, kind, out as *mut f64)),
                            Some(Type::Integer) => api.get_integer_status.map(|g| g(h, kind, out as *mut c::Integer)),
                            Some(Type::Boolean) => api.get_boolean_status.map(|g| g(h, kind, out as *mut c::Boolean)),
                            Some(Type::String) => api.get_string_status.map(|g| g(h, kind, out as *mut c::FmiString)),
                        }
                    }
                })
            }
            _ => unreachable!("{op:?} is not among FMI 2.0's other calls"),
        }
    }
}

/// The type of FMI 2.0's vector getters.
type VectorGetter = Option<unsafe extern "C" fn(c::Component, *mut f64, usize) -> c_int>;

impl Fmi2Instance {
    fn vector_function(&self, op: Op) -> VectorGetter {
        match op {
            Op::GetDerivatives => self.api.get_derivatives,
            Op::GetEventIndicators => self.api.get_event_indicators,
            Op::GetContinuousStates => self.api.get_continuous_states,
            Op::GetNominalsOfContinuousStates => self.api.get_nominals_of_continuous_states,
            _ => unreachable!("{op:?} does not fill a vector"),
        }
    }
}
