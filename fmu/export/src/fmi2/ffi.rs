//! FMI 2.0's C functions: `export_fmi2!` writes the 44 `extern "C"` functions of a model, each
//! a thin call of the front end's generic body (`crate::frontend::ffi`); the bodies here are
//! FMI 2.0's own: instantiation (one function for both interfaces, by `fmuType`, with the
//! logger's C signature and the resources as a URI), the step and its status queries, and
//! `fmi2NewDiscreteStates`' result struct.

#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, c_int, c_void, CString};

pub use fmi_c::fmi2::{CallbackFunctions, CallbackLogger as LoggerFn, EventInfo, CO_SIMULATION as FMI2_COSIMULATION};
use fmi_c::fmi2::{DO_STEP_STATUS, LAST_SUCCESSFUL_TIME, MODEL_EXCHANGE, TERMINATED};

use super::Fmi2;
use crate::core::{CallResult, Failure};
use crate::frontend::ffi::{self as fr, c_message, opt_str, with_instance, Request};
use crate::frontend::{Call, Interface, Setup, Version};
use crate::logging::{Logger, Sink, Status};
use crate::model::Model;

/// The raw pointers the logger needs, sendable because the importer owns their thread safety
/// (FMI requires the logger to be callable from any thread that calls the instance).
struct RawLogger {
    logger: LoggerFn,
    env: *mut c_void,
    name: CString,
}
unsafe impl Send for RawLogger {}

impl RawLogger {
    fn send(&self, status: Status, category: &str, message: &str) {
        let category = c_message(category);
        let message = c_message(message);
        // SAFETY: the importer gave this logger and environment for the instance's lifetime.
        unsafe { (self.logger)(self.env, self.name.as_ptr(), status as c_int, category.as_ptr(), message.as_ptr()) }
    }
}

fn sink_for(functions: &CallbackFunctions, name: &str) -> Option<Sink> {
    let raw = RawLogger { logger: functions.logger?, env: functions.component_environment, name: c_message(name) };
    Some(Box::new(move |status: Status, category: &'static str, message: &str| raw.send(status, category, message)))
}

/// `fmi2GetTypesPlatform`.
pub fn get_types_platform() -> *const c_char {
    c"default".as_ptr()
}

/// `fmi2GetVersion`.
pub fn get_version() -> *const c_char {
    c"2.0".as_ptr()
}

/// `fmi2Instantiate`: an instance for the interface `fmuType` asks for (Model Exchange or
/// Co-Simulation, the same binary); checks the GUID; NULL with a logged reason on refusal.
pub unsafe fn instantiate<M: Model>(
    instance_name: *const c_char,
    fmu_type: c_int,
    guid: *const c_char,
    resource_location: *const c_char,
    functions: *const CallbackFunctions,
    _visible: c_int,
    logging_on: c_int,
) -> *mut c_void {
    fr::instantiate::<Fmi2, M>(|| {
        let functions = functions.as_ref()?;
        let name = opt_str(instance_name);
        let logged_name = name.filter(|n| !n.is_empty()).unwrap_or("?");
        let setup = match fmu_type {
            FMI2_COSIMULATION => Ok(Setup::plain(Interface::CoSimulation)),
            MODEL_EXCHANGE => Ok(Setup::plain(Interface::ModelExchange)),
            _ => Err(format!("fmuType = {fmu_type} is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)")),
        };
        Some(Request {
            call: "fmi2Instantiate",
            logger: Logger::new(sink_for(functions, logged_name), logging_on != 0),
            name,
            setup,
            token: opt_str(guid),
            resources: opt_str(resource_location).and_then(resource_dir),
        })
    })
}

/// The directory of a `fmuResourceLocation` URI (`file:///dir/`, `file:/dir`, percent-encoded
/// bytes decoded); `None` for other schemes.
pub fn resource_dir(uri: &str) -> Option<std::path::PathBuf> {
    use std::os::unix::ffi::OsStringExt;
    let rest = uri.strip_prefix("file:")?;
    let path = match rest.strip_prefix("//") {
        Some(after) => after.strip_prefix("localhost").unwrap_or(after),
        None => rest,
    };
    if !path.starts_with('/') {
        return None;
    }
    let bytes = path.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        match (bytes[i], bytes.get(i + 1).copied().and_then(hex), bytes.get(i + 2).copied().and_then(hex)) {
            (b'%', Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (b, _, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    Some(std::path::PathBuf::from(std::ffi::OsString::from_vec(out)))
}

/// `fmi2SetupExperiment`.
pub unsafe fn setup_experiment<M: Model>(
    c: *mut c_void,
    tol_defined: c_int,
    tol: f64,
    start: f64,
    stop_defined: c_int,
    stop: f64,
) -> c_int {
    let call = Call::SetupExperiment;
    with_instance::<Fmi2, M>(c, call, |inst| {
        fr::trace_experiment(inst, call, (tol_defined, tol, start, stop_defined, stop));
        fr::ok(inst.setup_experiment((tol_defined != 0).then_some(tol), start, (stop_defined != 0).then_some(stop)))
    })
}

/// `fmi2DoStep`.
pub unsafe fn do_step<M: Model>(c: *mut c_void, current: f64, h: f64, _no_set_prior: c_int) -> c_int {
    with_instance::<Fmi2, M>(c, Call::DoStep, |inst| {
        inst.trace(Call::DoStep, || format!("currentCommunicationPoint={current}, communicationStepSize={h}"));
        inst.do_step(current, h)
    })
}

fn unsupported_kind(call: Call, kind: c_int) -> Failure {
    Failure {
        status: Status::Discard,
        message: format!("{}: status kind {kind} is not available from this FMU", Fmi2::name(call)),
        broken: false,
    }
}

/// The status query `call` of `kind`: `answer` gives the value of the one kind it has
/// (`known`), written to `value`; another kind is Discard.
unsafe fn status_query<M: Model, T>(
    c: *mut c_void,
    call: Call,
    kind: c_int,
    value: *mut T,
    known: c_int,
    answer: impl FnOnce(&super::Instance<M>) -> CallResult<T>,
) -> c_int {
    with_instance::<Fmi2, M>(c, call, |inst| {
        if value.is_null() {
            return Err(Failure::error(format!("{}: value is NULL", Fmi2::name(call))));
        }
        if kind != known {
            inst.check(call)?;
            return Err(unsupported_kind(call, kind));
        }
        *value = answer(inst)?;
        Ok(Status::Ok)
    })
}

/// `fmi2GetStatus`: `fmi2DoStepStatus` gives the last step's status.
pub unsafe fn get_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut c_int) -> c_int {
    status_query::<M, c_int>(c, Call::GetStatus, kind, value, DO_STEP_STATUS, |inst| Ok(inst.do_step_status()? as c_int))
}

/// `fmi2GetRealStatus`: `fmi2LastSuccessfulTime`.
pub unsafe fn get_real_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut f64) -> c_int {
    status_query::<M, f64>(c, Call::GetRealStatus, kind, value, LAST_SUCCESSFUL_TIME, |inst| inst.last_successful_time())
}

/// A status query of which FMI 2.0 has no kind these FMUs answer.
unsafe fn no_status_kind<M: Model>(c: *mut c_void, call: Call, kind: c_int) -> c_int {
    with_instance::<Fmi2, M>(c, call, |inst| {
        inst.check(call)?;
        Err(unsupported_kind(call, kind))
    })
}

/// `fmi2GetIntegerStatus`: no integer status kinds exist in FMI 2.0.
pub unsafe fn get_integer_status<M: Model>(c: *mut c_void, kind: c_int, _value: *mut c_int) -> c_int {
    no_status_kind::<M>(c, Call::GetIntegerStatus, kind)
}

/// `fmi2GetBooleanStatus`: `fmi2Terminated`, true once the model ended the experiment.
pub unsafe fn get_boolean_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut c_int) -> c_int {
    status_query::<M, c_int>(c, Call::GetBooleanStatus, kind, value, TERMINATED, |inst| Ok(inst.terminated()? as c_int))
}

/// `fmi2GetStringStatus`: `fmi2PendingStatus` is meaningless for synchronous steps.
pub unsafe fn get_string_status<M: Model>(c: *mut c_void, kind: c_int, _value: *mut *const c_char) -> c_int {
    no_status_kind::<M>(c, Call::GetStringStatus, kind)
}

/// `fmi2NewDiscreteStates`: fills `*info`.
pub unsafe fn new_discrete_states<M: Model>(c: *mut c_void, info: *mut EventInfo) -> c_int {
    let call = Call::UpdateDiscreteStates;
    with_instance::<Fmi2, M>(c, call, |inst| {
        inst.check(call)?;
        if info.is_null() {
            return Err(Failure::error("fmi2NewDiscreteStates: eventInfo is NULL"));
        }
        let update = inst.update_discrete_states()?;
        *info = EventInfo {
            new_discrete_states_needed: update.discrete_states_need_update as c_int,
            terminate_simulation: update.terminate_simulation as c_int,
            nominals_of_continuous_states_changed: update.nominals_of_continuous_states_changed as c_int,
            values_of_continuous_states_changed: update.values_of_continuous_states_changed as c_int,
            next_event_time_defined: update.next_event_time.is_some() as c_int,
            next_event_time: update.next_event_time.unwrap_or(0.0),
        };
        Ok(Status::Ok)
    })
}

/// Exports all 44 FMI 2.0 functions for `$model` (the 25 common ones, the 9 of Co-Simulation
/// and the 10 of Model Exchange: one binary serves both interfaces), plus
/// `fmu_model_description` (used by `runner build` to write the `.fmu`'s XML from the compiled
/// table). Expanded by [`export_fmu!`](crate::export_fmu); not for direct use.
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi2 {
    ($model:ty) => {
        /// The FMI 2.0 C ABI of this FMU (generated by `fmu_export::export_fmu!`).
        #[allow(unsafe_code, non_snake_case, clippy::missing_safety_doc, clippy::too_many_arguments)]
        pub mod fmi2_exports {
            #[allow(unused_imports)]
            use super::*;
            use ::std::ffi::{c_char, c_int, c_uint, c_void};
            use $crate::fmi2::ffi as f;
            use $crate::frontend::ffi as fr;
            use $crate::frontend::Call;
            type V = $crate::fmi2::Fmi2;
            type M = $model;

            #[no_mangle]
            pub extern "C" fn fmi2GetTypesPlatform() -> *const c_char {
                f::get_types_platform()
            }
            #[no_mangle]
            pub extern "C" fn fmi2GetVersion() -> *const c_char {
                f::get_version()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetDebugLogging(c: *mut c_void, on: c_int, n: usize, cats: *const *const c_char) -> c_int {
                fr::set_debug_logging::<V, M>(c, on != 0, n, cats)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Instantiate(
                name: *const c_char,
                ty: c_int,
                guid: *const c_char,
                res: *const c_char,
                fns: *const f::CallbackFunctions,
                visible: c_int,
                logging: c_int,
            ) -> *mut c_void {
                f::instantiate::<M>(name, ty, guid, res, fns, visible, logging)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeInstance(c: *mut c_void) {
                fr::free_instance::<V, M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetupExperiment(
                c: *mut c_void,
                tol_defined: c_int,
                tol: f64,
                start: f64,
                stop_defined: c_int,
                stop: f64,
            ) -> c_int {
                f::setup_experiment::<M>(c, tol_defined, tol, start, stop_defined, stop)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterInitializationMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterInitializationMode, |i| i.enter_initialization_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::Terminate, |i| i.terminate())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::Reset, |i| i.reset())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut f64) -> c_int {
                fr::get_real::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut c_int) -> c_int {
                fr::get_integer::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut c_int) -> c_int {
                fr::get_boolean::<V, M, c_int>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut *const c_char) -> c_int {
                fr::get_string::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(c: *mut c_void, vr: *const c_uint, n: usize, v: *const f64) -> c_int {
                fr::set_real::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(c: *mut c_void, vr: *const c_uint, n: usize, v: *const c_int) -> c_int {
                fr::set_integer::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(c: *mut c_void, vr: *const c_uint, n: usize, v: *const c_int) -> c_int {
                fr::set_boolean::<V, M, c_int>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(c: *mut c_void, vr: *const c_uint, n: usize, v: *const *const c_char) -> c_int {
                fr::set_string::<V, M>(c, vr, n, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                fr::get_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, s: *mut c_void) -> c_int {
                fr::set_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                fr::free_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(c: *mut c_void, s: *mut c_void, size: *mut usize) -> c_int {
                fr::serialized_fmu_state_size::<V, M>(c, s, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(c: *mut c_void, s: *mut c_void, buf: *mut c_char, size: usize) -> c_int {
                fr::serialize_fmu_state::<V, M>(c, s, buf as *mut u8, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: *mut c_void,
                buf: *const c_char,
                size: usize,
                s: *mut *mut c_void,
            ) -> c_int {
                fr::deserialize_fmu_state::<V, M>(c, buf as *const u8, size, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: *mut c_void,
                unknowns: *const c_uint,
                n_unknowns: usize,
                knowns: *const c_uint,
                n_knowns: usize,
                seed: *const f64,
                sensitivity: *mut f64,
            ) -> c_int {
                fr::get_directional_derivative::<V, M>(
                    c,
                    (unknowns, n_unknowns),
                    (knowns, n_knowns),
                    (seed, n_knowns),
                    (sensitivity, n_unknowns),
                )
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: *mut c_void,
                vr: *const c_uint,
                n: usize,
                order: *const c_int,
                v: *const f64,
            ) -> c_int {
                fr::set_input_derivatives::<V, M>(c, vr, n, order, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: *mut c_void,
                vr: *const c_uint,
                n: usize,
                order: *const c_int,
                v: *mut f64,
            ) -> c_int {
                fr::get_output_derivatives::<V, M>(c, vr, n, order, v, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(c: *mut c_void, t: f64, h: f64, no_set_prior: c_int) -> c_int {
                f::do_step::<M>(c, t, h, no_set_prior)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> c_int {
                // Never allowed: steps are synchronous.
                fr::simple::<V, M>(c, Call::CancelStep, |i| i.check(Call::CancelStep))
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStatus(c: *mut c_void, kind: c_int, v: *mut c_int) -> c_int {
                f::get_status::<M>(c, kind, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealStatus(c: *mut c_void, kind: c_int, v: *mut f64) -> c_int {
                f::get_real_status::<M>(c, kind, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetIntegerStatus(c: *mut c_void, kind: c_int, v: *mut c_int) -> c_int {
                f::get_integer_status::<M>(c, kind, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBooleanStatus(c: *mut c_void, kind: c_int, v: *mut c_int) -> c_int {
                f::get_boolean_status::<M>(c, kind, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetStringStatus(c: *mut c_void, kind: c_int, v: *mut *const c_char) -> c_int {
                f::get_string_status::<M>(c, kind, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterEventMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterEventMode, |i| i.enter_event_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2NewDiscreteStates(c: *mut c_void, info: *mut f::EventInfo) -> c_int {
                f::new_discrete_states::<M>(c, info)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterContinuousTimeMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterContinuousTimeMode, |i| i.enter_continuous_time_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
                c: *mut c_void,
                _no_set_prior: c_int,
                enter: *mut c_int,
                terminate: *mut c_int,
            ) -> c_int {
                fr::completed_integrator_step::<V, M, c_int>(c, enter, terminate)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetTime(c: *mut c_void, time: f64) -> c_int {
                fr::set_time::<V, M>(c, time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetContinuousStates(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
                fr::set_continuous_states::<V, M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDerivatives(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
                fr::get_derivatives::<V, M>(c, dx, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetEventIndicators(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
                fr::get_event_indicators::<V, M>(c, z, ni)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                fr::get_continuous_states::<V, M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetNominalsOfContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                fr::get_nominals_of_continuous_states::<V, M>(c, x, nx)
            }

            /// Writes this FMU's modelDescription.xml into `buf`; returns the size needed.
            #[no_mangle]
            pub unsafe extern "C" fn fmu_model_description(buf: *mut c_char, size: usize) -> usize {
                match ::std::panic::catch_unwind(|| $crate::fmi2::describe::model_description_xml::<M>()) {
                    Ok(Ok(xml)) => fr::copy_out(&xml, buf, size),
                    _ => 0,
                }
            }
        }
    };
}

#[cfg(test)]
mod resource_tests {
    use super::resource_dir;
    use std::path::Path;

    /// The spellings importers pass: fmpy and the runner `file:///dir/`, some `file:/dir`, the
    /// host `localhost`, spaces percent-encoded; another scheme has no directory.
    #[test]
    fn resource_locations_become_directories() {
        assert_eq!(resource_dir("file:///tmp/fmu/resources/").as_deref(), Some(Path::new("/tmp/fmu/resources/")));
        assert_eq!(resource_dir("file:/tmp/r").as_deref(), Some(Path::new("/tmp/r")));
        assert_eq!(resource_dir("file://localhost/tmp/r").as_deref(), Some(Path::new("/tmp/r")));
        assert_eq!(resource_dir("file:///tmp/a%20b/r%2").as_deref(), Some(Path::new("/tmp/a b/r%2")));
        assert_eq!(resource_dir("http://example/r"), None);
        assert_eq!(resource_dir("file:relative"), None);
    }
}
