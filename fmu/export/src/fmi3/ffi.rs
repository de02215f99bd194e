//! FMI 3.0's C functions: `export_fmi3!` writes the 75 `extern "C"` functions of a model, each
//! a thin call of the front end's generic body (`crate::frontend::ffi`); the bodies here are
//! FMI 3.0's own: the three instantiations (the logger's C signature, the resources as a
//! path), `fmi3EnterInitializationMode` with the experiment, and the calls that return their
//! results through several pointers (the step, the discrete update, the sizes). The functions
//! that do not apply to these FMUs (Scheduled Execution, clocks, Configuration Mode, types no
//! variable has, derivatives they do not provide) check the state machine, log the table's
//! reason, and return `fmi3Error`.

#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, c_int, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use fmi_c::fmi3::LogMessageCallback;

use super::Fmi3;
use crate::core::Failure;
use crate::frontend::ffi::{self as fr, c_message, opt_str, with_instance, Request};
use crate::frontend::{Call, Interface, Setup, Version};
use crate::logging::{Logger, Sink, Status};
use crate::model::Model;

/// The importer's logger, sendable because the importer owns its thread safety.
struct RawLogger {
    callback: LogMessageCallback,
    env: *mut c_void,
}
unsafe impl Send for RawLogger {}

impl RawLogger {
    fn send(&self, status: Status, category: &str, message: &str) {
        let category = c_message(category);
        // FMI 3.0's logger takes the message as it is (no format): no escaping of '%'.
        let message = std::ffi::CString::new(message.replace('\0', " ")).expect("NULs removed");
        // SAFETY: the importer gave this logger and environment for the instance's lifetime.
        unsafe { (self.callback)(self.env, status as c_int, category.as_ptr(), message.as_ptr()) }
    }
}

fn sink_for(callback: Option<LogMessageCallback>, env: *mut c_void) -> Option<Sink> {
    let raw = RawLogger { callback: callback?, env };
    Some(Box::new(move |status: Status, category: &'static str, message: &str| raw.send(status, category, message)))
}

/// `fmi3GetVersion`.
pub fn get_version() -> *const c_char {
    c"3.0".as_ptr()
}

/// What both instantiations read of the importer's arguments.
// The arguments of fmi3Instantiate*, passed on as the standard lists them.
#[allow(clippy::too_many_arguments)]
unsafe fn instantiate<M: Model>(
    call: &'static str,
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    logging_on: bool,
    env: *mut c_void,
    log: Option<LogMessageCallback>,
    setup: Setup,
) -> *mut c_void {
    fr::instantiate::<Fmi3, M>(|| {
        Some(Request {
            call,
            logger: Logger::new(sink_for(log, env), logging_on),
            name: opt_str(instance_name),
            setup: Ok(setup),
            token: opt_str(token),
            // FMI 3.0 passes the resources folder as a plain path (FMI 2.0: a file URI); NULL
            // or empty when the importer has none, and then the model keeps its defaults.
            resources: opt_str(resource_path).filter(|p| !p.is_empty()).map(std::path::PathBuf::from),
        })
    })
}

/// `fmi3InstantiateModelExchange`.
pub unsafe fn instantiate_model_exchange<M: Model>(
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    logging_on: bool,
    env: *mut c_void,
    log: Option<LogMessageCallback>,
) -> *mut c_void {
    let setup = Setup::plain(Interface::ModelExchange);
    instantiate::<M>("fmi3InstantiateModelExchange", instance_name, token, resource_path, logging_on, env, log, setup)
}

/// `fmi3InstantiateCoSimulation`: `eventModeUsed` and `earlyReturnAllowed` choose how steps
/// meet events (see the front end). No intermediate update is ever made, so the required
/// intermediate variables need nothing.
#[allow(clippy::too_many_arguments)] // fmi3InstantiateCoSimulation's own arguments
pub unsafe fn instantiate_co_simulation<M: Model>(
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    logging_on: bool,
    event_mode_used: bool,
    early_return_allowed: bool,
    env: *mut c_void,
    log: Option<LogMessageCallback>,
) -> *mut c_void {
    let setup = Setup { interface: Interface::CoSimulation, event_mode_used, early_return_allowed };
    instantiate::<M>("fmi3InstantiateCoSimulation", instance_name, token, resource_path, logging_on, env, log, setup)
}

/// `fmi3InstantiateScheduledExecution`: not offered; logs why and returns NULL.
pub unsafe fn instantiate_scheduled_execution(env: *mut c_void, log: Option<LogMessageCallback>) -> *mut c_void {
    if let Some(mut sink) = sink_for(log, env) {
        let _ = catch_unwind(AssertUnwindSafe(|| {
            sink(
                Status::Error,
                crate::logging::LOG_ERROR.name,
                "fmi3InstantiateScheduledExecution: this FMU does not offer Scheduled Execution (only Model Exchange and Co-Simulation)",
            )
        }));
    }
    std::ptr::null_mut()
}

/// `fmi3EnterInitializationMode`.
pub unsafe fn enter_initialization_mode<M: Model>(
    c: *mut c_void,
    tol_defined: bool,
    tol: f64,
    start: f64,
    stop_defined: bool,
    stop: f64,
) -> c_int {
    let call = Call::EnterInitializationMode;
    with_instance::<Fmi3, M>(c, call, |inst| {
        fr::trace_experiment(inst, call, (tol_defined, tol, start, stop_defined, stop));
        fr::ok(inst.enter_initialization_mode_with(tol_defined.then_some(tol), start, stop_defined.then_some(stop)))
    })
}

/// `fmi3UpdateDiscreteStates`: fills the six results.
#[allow(clippy::too_many_arguments)]
pub unsafe fn update_discrete_states<M: Model>(
    c: *mut c_void,
    needs_update: *mut bool,
    terminate: *mut bool,
    nominals_changed: *mut bool,
    values_changed: *mut bool,
    next_defined: *mut bool,
    next_time: *mut f64,
) -> c_int {
    let call = Call::UpdateDiscreteStates;
    with_instance::<Fmi3, M>(c, call, |inst| {
        inst.check(call)?;
        if needs_update.is_null()
            || terminate.is_null()
            || nominals_changed.is_null()
            || values_changed.is_null()
            || next_defined.is_null()
            || next_time.is_null()
        {
            return Err(Failure::error("fmi3UpdateDiscreteStates: one of the result pointers is NULL"));
        }
        let u = inst.update_discrete_states()?;
        *needs_update = u.discrete_states_need_update;
        *terminate = u.terminate_simulation;
        *nominals_changed = u.nominals_of_continuous_states_changed;
        *values_changed = u.values_of_continuous_states_changed;
        *next_defined = u.next_event_time.is_some();
        *next_time = u.next_event_time.unwrap_or(0.0);
        Ok(Status::Ok)
    })
}

/// `fmi3GetNumberOfEventIndicators` and `fmi3GetNumberOfContinuousStates` (`what` names the
/// result): the number `count` gives, written to `n`.
unsafe fn number_of<M: Model>(
    c: *mut c_void,
    call: Call,
    n: *mut usize,
    what: &str,
    count: impl FnOnce(&super::Instance<M>) -> crate::core::CallResult<usize>,
) -> c_int {
    with_instance::<Fmi3, M>(c, call, |inst| {
        let value = count(inst)?;
        if n.is_null() {
            return Err(Failure::error(format!("{}: {what} is NULL", Fmi3::name(call))));
        }
        *n = value;
        Ok(Status::Ok)
    })
}

/// `fmi3GetNumberOfEventIndicators`.
pub unsafe fn get_number_of_event_indicators<M: Model>(c: *mut c_void, n: *mut usize) -> c_int {
    number_of::<M>(c, Call::GetNumberOfEventIndicators, n, "nEventIndicators", |inst| inst.number_of_event_indicators())
}

/// `fmi3GetNumberOfContinuousStates`.
pub unsafe fn get_number_of_continuous_states<M: Model>(c: *mut c_void, n: *mut usize) -> c_int {
    number_of::<M>(c, Call::GetNumberOfContinuousStates, n, "nContinuousStates", |inst| inst.number_of_continuous_states())
}

/// `fmi3DoStep`: fills the four results.
#[allow(clippy::too_many_arguments)]
pub unsafe fn do_step<M: Model>(
    c: *mut c_void,
    current: f64,
    h: f64,
    _no_set_prior: bool,
    event_handling_needed: *mut bool,
    terminate: *mut bool,
    early_return: *mut bool,
    last_successful_time: *mut f64,
) -> c_int {
    let call = Call::DoStep;
    with_instance::<Fmi3, M>(c, call, |inst| {
        if event_handling_needed.is_null() || terminate.is_null() || early_return.is_null() || last_successful_time.is_null() {
            inst.check(call)?;
            return Err(Failure::error("fmi3DoStep: one of the result pointers is NULL"));
        }
        inst.trace(call, || format!("currentCommunicationPoint={current}, communicationStepSize={h}"));
        let r = inst.do_step(current, h)?;
        *event_handling_needed = r.event_handling_needed;
        *terminate = r.terminate_simulation;
        *early_return = r.early_return;
        *last_successful_time = r.last_successful_time;
        Ok(Status::Ok)
    })
}

/// Exports all 75 FMI 3.0 functions for `$model`, plus `fmu3_model_description` (used by
/// `runner build` to write the FMI 3.0 `.fmu`'s XML from the compiled table). Expanded by
/// [`export_fmu!`](crate::export_fmu); not for direct use.
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi3 {
    (@absent_get $($name:ident $call:ident)*) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: *mut c_void, _vr: *const u32, _n: usize, _v: *mut c_void, _nv: usize) -> c_int {
                fr::refuse::<V, M>(c, Call::$call)
            }
        )*
    };
    (@absent_set $($name:ident $call:ident)*) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: *mut c_void, _vr: *const u32, _n: usize, _v: *const c_void, _nv: usize) -> c_int {
                fr::refuse::<V, M>(c, Call::$call)
            }
        )*
    };
    ($model:ty) => {
        /// The FMI 3.0 C ABI of this FMU (generated by `fmu::export_fmu!`).
        #[allow(unsafe_code, non_snake_case, clippy::missing_safety_doc, clippy::too_many_arguments)]
        pub mod fmi3_exports {
            #[allow(unused_imports)]
            use super::*;
            use ::std::ffi::{c_char, c_int, c_void};
            use $crate::fmi3::ffi as f;
            use $crate::frontend::ffi as fr;
            use $crate::frontend::Call;
            type V = $crate::fmi3::Fmi3;
            type M = $model;
            type Log = ::std::option::Option<f::LogMessageCallback>;
            type Vrs = *const u32;

            #[no_mangle]
            pub extern "C" fn fmi3GetVersion() -> *const c_char {
                f::get_version()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetDebugLogging(c: *mut c_void, on: bool, n: usize, cats: *const *const c_char) -> c_int {
                fr::set_debug_logging::<V, M>(c, on, n, cats)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateModelExchange(
                name: *const c_char,
                token: *const c_char,
                res: *const c_char,
                _visible: bool,
                logging: bool,
                env: *mut c_void,
                log: Log,
            ) -> *mut c_void {
                f::instantiate_model_exchange::<M>(name, token, res, logging, env, log)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateCoSimulation(
                name: *const c_char,
                token: *const c_char,
                res: *const c_char,
                _visible: bool,
                logging: bool,
                event_mode_used: bool,
                early_return_allowed: bool,
                _required: Vrs,
                _n_required: usize,
                env: *mut c_void,
                log: Log,
                _intermediate: *const c_void,
            ) -> *mut c_void {
                f::instantiate_co_simulation::<M>(name, token, res, logging, event_mode_used, early_return_allowed, env, log)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3InstantiateScheduledExecution(
                _name: *const c_char,
                _token: *const c_char,
                _res: *const c_char,
                _visible: bool,
                _logging: bool,
                env: *mut c_void,
                log: Log,
                _clock_update: *const c_void,
                _lock: *const c_void,
                _unlock: *const c_void,
            ) -> *mut c_void {
                f::instantiate_scheduled_execution(env, log)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeInstance(c: *mut c_void) {
                fr::free_instance::<V, M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterInitializationMode(
                c: *mut c_void,
                tol_defined: bool,
                tol: f64,
                start: f64,
                stop_defined: bool,
                stop: f64,
            ) -> c_int {
                f::enter_initialization_mode::<M>(c, tol_defined, tol, start, stop_defined, stop)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitInitializationMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterEventMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterEventMode, |i| i.enter_event_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Terminate(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::Terminate, |i| i.terminate())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Reset(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::Reset, |i| i.reset())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFloat64(c: *mut c_void, vr: Vrs, n: usize, v: *mut f64, nv: usize) -> c_int {
                fr::get_real::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt32(c: *mut c_void, vr: Vrs, n: usize, v: *mut i32, nv: usize) -> c_int {
                fr::get_integer::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBoolean(c: *mut c_void, vr: Vrs, n: usize, v: *mut bool, nv: usize) -> c_int {
                fr::get_boolean::<V, M, bool>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFloat64(c: *mut c_void, vr: Vrs, n: usize, v: *const f64, nv: usize) -> c_int {
                fr::set_real::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt32(c: *mut c_void, vr: Vrs, n: usize, v: *const i32, nv: usize) -> c_int {
                fr::set_integer::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBoolean(c: *mut c_void, vr: Vrs, n: usize, v: *const u8, nv: usize) -> c_int {
                fr::set_boolean::<V, M, u8>(c, vr, n, v, nv)
            }
            $crate::export_fmi3!(@absent_get
                fmi3GetFloat32 GetFloat32 fmi3GetInt8 GetInt8 fmi3GetUInt8 GetUInt8 fmi3GetInt16 GetInt16 fmi3GetUInt16 GetUInt16
                fmi3GetUInt32 GetUInt32 fmi3GetInt64 GetInt64 fmi3GetUInt64 GetUInt64);
            $crate::export_fmi3!(@absent_set
                fmi3SetFloat32 SetFloat32 fmi3SetInt8 SetInt8 fmi3SetUInt8 SetUInt8 fmi3SetInt16 SetInt16 fmi3SetUInt16 SetUInt16
                fmi3SetUInt32 SetUInt32 fmi3SetInt64 SetInt64 fmi3SetUInt64 SetUInt64);
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetString(c: *mut c_void, vr: Vrs, n: usize, v: *mut *const c_char, nv: usize) -> c_int {
                fr::get_string::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetString(c: *mut c_void, vr: Vrs, n: usize, v: *const *const c_char, nv: usize) -> c_int {
                fr::set_string::<V, M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBinary(c: *mut c_void, _vr: Vrs, _n: usize, _sizes: *mut usize, _v: *mut *const u8, _nv: usize) -> c_int {
                fr::refuse::<V, M>(c, Call::GetBinary)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBinary(c: *mut c_void, _vr: Vrs, _n: usize, _sizes: *const usize, _v: *const *const u8, _nv: usize) -> c_int {
                fr::refuse::<V, M>(c, Call::SetBinary)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetClock(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut bool) -> c_int {
                fr::refuse::<V, M>(c, Call::GetClock)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetClock(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const bool) -> c_int {
                fr::refuse::<V, M>(c, Call::SetClock)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(c: *mut c_void, _vr: u32, _n: *mut usize) -> c_int {
                fr::refuse::<V, M>(c, Call::GetNumberOfVariableDependencies)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetVariableDependencies(
                c: *mut c_void,
                _dependent: u32,
                _element_of_dependent: *mut usize,
                _independents: *mut u32,
                _element_of_independents: *mut usize,
                _kinds: *mut c_int,
                _n: usize,
            ) -> c_int {
                fr::refuse::<V, M>(c, Call::GetVariableDependencies)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFMUState(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                fr::get_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFMUState(c: *mut c_void, s: *mut c_void) -> c_int {
                fr::set_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeFMUState(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                fr::free_fmu_state::<V, M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializedFMUStateSize(c: *mut c_void, s: *mut c_void, size: *mut usize) -> c_int {
                fr::serialized_fmu_state_size::<V, M>(c, s, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializeFMUState(c: *mut c_void, s: *mut c_void, buf: *mut u8, size: usize) -> c_int {
                fr::serialize_fmu_state::<V, M>(c, s, buf, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DeserializeFMUState(c: *mut c_void, buf: *const u8, size: usize, s: *mut *mut c_void) -> c_int {
                fr::deserialize_fmu_state::<V, M>(c, buf, size, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
                c: *mut c_void,
                unknowns: Vrs,
                n_unknowns: usize,
                knowns: Vrs,
                n_knowns: usize,
                seed: *const f64,
                n_seed: usize,
                sensitivity: *mut f64,
                n_sensitivity: usize,
            ) -> c_int {
                fr::get_directional_derivative::<V, M>(c, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_seed), (sensitivity, n_sensitivity))
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetAdjointDerivative(
                c: *mut c_void,
                unknowns: Vrs,
                n_unknowns: usize,
                knowns: Vrs,
                n_knowns: usize,
                seed: *const f64,
                n_seed: usize,
                sensitivity: *mut f64,
                n_sensitivity: usize,
            ) -> c_int {
                let call = Call::GetAdjointDerivative;
                fr::get_sensitivity::<V, M>(c, call, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_seed), (sensitivity, n_sensitivity))
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterConfigurationMode(c: *mut c_void) -> c_int {
                fr::refuse::<V, M>(c, Call::EnterConfigurationMode)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitConfigurationMode(c: *mut c_void) -> c_int {
                fr::refuse::<V, M>(c, Call::ExitConfigurationMode)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetIntervalDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut f64, _q: *mut c_int) -> c_int {
                fr::refuse::<V, M>(c, Call::GetIntervalDecimal)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetIntervalFraction(
                c: *mut c_void,
                _vr: Vrs,
                _n: usize,
                _counter: *mut u64,
                _resolution: *mut u64,
                _q: *mut c_int,
            ) -> c_int {
                fr::refuse::<V, M>(c, Call::GetIntervalFraction)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut f64) -> c_int {
                fr::refuse::<V, M>(c, Call::GetShiftDecimal)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *mut u64, _resolution: *mut u64) -> c_int {
                fr::refuse::<V, M>(c, Call::GetShiftFraction)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const f64) -> c_int {
                fr::refuse::<V, M>(c, Call::SetIntervalDecimal)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *const u64, _resolution: *const u64) -> c_int {
                fr::refuse::<V, M>(c, Call::SetIntervalFraction)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const f64) -> c_int {
                fr::refuse::<V, M>(c, Call::SetShiftDecimal)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *const u64, _resolution: *const u64) -> c_int {
                fr::refuse::<V, M>(c, Call::SetShiftFraction)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EvaluateDiscreteStates(c: *mut c_void) -> c_int {
                fr::refuse::<V, M>(c, Call::EvaluateDiscreteStates)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3UpdateDiscreteStates(
                c: *mut c_void,
                needs_update: *mut bool,
                terminate: *mut bool,
                nominals_changed: *mut bool,
                values_changed: *mut bool,
                next_defined: *mut bool,
                next_time: *mut f64,
            ) -> c_int {
                f::update_discrete_states::<M>(c, needs_update, terminate, nominals_changed, values_changed, next_defined, next_time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterContinuousTimeMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterContinuousTimeMode, |i| i.enter_continuous_time_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3CompletedIntegratorStep(c: *mut c_void, _no_set_prior: bool, enter: *mut bool, terminate: *mut bool) -> c_int {
                fr::completed_integrator_step::<V, M, bool>(c, enter, terminate)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetTime(c: *mut c_void, time: f64) -> c_int {
                fr::set_time::<V, M>(c, time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetContinuousStates(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
                fr::set_continuous_states::<V, M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
                fr::get_derivatives::<V, M>(c, dx, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetEventIndicators(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
                fr::get_event_indicators::<V, M>(c, z, ni)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                fr::get_continuous_states::<V, M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                fr::get_nominals_of_continuous_states::<V, M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfEventIndicators(c: *mut c_void, n: *mut usize) -> c_int {
                f::get_number_of_event_indicators::<M>(c, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfContinuousStates(c: *mut c_void, n: *mut usize) -> c_int {
                f::get_number_of_continuous_states::<M>(c, n)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterStepMode(c: *mut c_void) -> c_int {
                fr::simple::<V, M>(c, Call::EnterStepMode, |i| i.enter_step_mode())
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetOutputDerivatives(c: *mut c_void, vr: Vrs, n: usize, order: *const i32, v: *mut f64, nv: usize) -> c_int {
                fr::get_output_derivatives::<V, M>(c, vr, n, order, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DoStep(
                c: *mut c_void,
                t: f64,
                h: f64,
                no_set_prior: bool,
                event: *mut bool,
                terminate: *mut bool,
                early: *mut bool,
                last: *mut f64,
            ) -> c_int {
                f::do_step::<M>(c, t, h, no_set_prior, event, terminate, early, last)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ActivateModelPartition(c: *mut c_void, _clock: u32, _t: f64) -> c_int {
                fr::refuse::<V, M>(c, Call::ActivateModelPartition)
            }

            /// Writes this FMU's FMI 3.0 modelDescription.xml into `buf`; returns the size needed.
            #[no_mangle]
            pub unsafe extern "C" fn fmu3_model_description(buf: *mut c_char, size: usize) -> usize {
                match ::std::panic::catch_unwind(|| $crate::fmi3::describe::model_description_xml::<M>()) {
                    Ok(xml) => fr::copy_out(&xml, buf, size),
                    _ => 0,
                }
            }
        }
    };
}
