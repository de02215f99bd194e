//! The C boundary of FMI 3.0: the generic bodies of the 75 `fmi3*` functions, and
//! `export_fmi3!`, which [`export_fmu!`](crate::export_fmu) expands for every model beside the
//! FMI 2.0 functions (the two name sets do not collide, so one binary serves both versions).
//! Every body checks its pointers, catches panics, and reports failures through the logger and
//! the status. The functions that do not apply to these FMUs (Scheduled Execution, clocks,
//! Configuration Mode, types no variable has, derivatives they do not provide) check the
//! state machine, log why, and return `fmi3Error`.

#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, c_int, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use fmi_c::fmi3::LogMessageCallback;

use super::state_machine::{Call, Interface};
use super::{Instance, Machine, Setup};
use crate::core::{snapshot, CallResult, Failure, State};
use crate::glue::{self, c_message, model_tag, opt_str, slice, slice_mut};
use crate::logging::{Logger, Sink, Status};
use crate::model::Model;

pub use crate::glue::copy_out;

const COMPONENT_MAGIC: u64 = 0x464d_4933_494e_5354; // "FMI3INST"

/// What `fmi3Instance` points at: a tag to recognise our own pointers, then the instance.
pub struct Component<M: Model> {
    magic: u64,
    instance: Instance<M>,
}

/// What `fmi3FMUState` points at: the core's state and the state machine's.
pub struct StateBox<M: Model> {
    magic: u64,
    saved: (State<M>, Machine),
}

/// The tag of this model's FMI 3.0 FMU states, in memory and serialized: not FMI 2.0's, so
/// a state of one version is refused by the other instead of misread.
pub fn state_tag<M: Model>() -> u64 {
    model_tag::<M>().rotate_left(17) ^ 0x0000_0000_0000_0030
}

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

/// Runs `body` on the instance behind `c`: checks the pointer, catches panics, logs failures.
unsafe fn with_instance<M: Model>(c: *mut c_void, call: Call, body: impl FnOnce(&mut Instance<M>) -> CallResult<Status>) -> c_int {
    let component = c as *mut Component<M>;
    if component.is_null() || (*component).magic != COMPONENT_MAGIC {
        return Status::Error as c_int;
    }
    // The status is formed inside the unwinding guard (see fmi2::ffi::with_instance).
    let result = catch_unwind(AssertUnwindSafe(|| match body(&mut (*component).instance) {
        Ok(status) => status as c_int,
        Err(failure) => glue::report_failure(&mut (*component).instance, call.name(), failure),
    }));
    match result {
        Ok(code) => code,
        Err(payload) => glue::report_panic(&mut (*component).instance, call.name(), payload),
    }
}

fn ok(r: CallResult) -> CallResult<Status> {
    r.map(|()| Status::Ok)
}

/// Refuses a value array whose length is not the number of value references (every variable
/// of these FMUs is a scalar).
#[inline(always)]
fn check_values(call: Call, n_vr: usize, n_values: usize) -> CallResult {
    if n_vr == n_values {
        Ok(())
    } else {
        Err(wrong_length(call, n_vr, n_values))
    }
}

#[cold]
#[inline(never)]
fn wrong_length(call: Call, n_vr: usize, n_values: usize) -> Failure {
    Failure::error(format!("{}: nValues = {n_values} but the {n_vr} value references are scalars with {n_vr} values", call.name()))
}

/// `fmi3GetVersion`.
pub fn get_version() -> *const c_char {
    c"3.0".as_ptr()
}

/// The checks both instantiations make; NULL with a logged reason on refusal.
// The arguments of fmi3Instantiate*, passed on as the standard lists them.
#[allow(clippy::too_many_arguments)]
unsafe fn instantiate<M: Model>(
    call: &str,
    instance_name: *const c_char,
    token: *const c_char,
    resource_path: *const c_char,
    logging_on: bool,
    env: *mut c_void,
    log: Option<LogMessageCallback>,
    setup: Setup,
) -> *mut c_void {
    let result = catch_unwind(|| {
        let mut logger = Logger::new(sink_for(log, env), logging_on);
        let refuse = |logger: &mut Logger, why: String| {
            logger.status(Status::Error, &format!("{call}: {why}"));
            std::ptr::null_mut()
        };
        let name = match opt_str(instance_name) {
            Some(name) if !name.is_empty() => name,
            _ => return refuse(&mut logger, "instanceName must be a non-empty string".to_owned()),
        };
        let expected = crate::table::guid::<M>();
        match opt_str(token) {
            Some(t) if t == expected => {}
            other => {
                return refuse(
                    &mut logger,
                    format!(
                        "instantiationToken {:?} does not match this FMU's {expected}: the modelDescription.xml and the binary are from different builds",
                        other.unwrap_or("(NULL)")
                    ),
                )
            }
        }
        let mut instance = Instance::<M>::new(name, logger, setup);
        // FMI 3.0 passes the resources folder as a plain path (FMI 2.0: a file URI); NULL or
        // empty when the importer has none, and then the model keeps its defaults.
        if let Some(dir) = opt_str(resource_path).filter(|p| !p.is_empty()) {
            if let Err(e) = instance.load_resources(std::path::Path::new(dir)) {
                return refuse(instance.logger(), format!("the FMU's resources ({dir}): {e}"));
            }
        }
        let component = Box::new(Component { magic: COMPONENT_MAGIC, instance });
        Box::into_raw(component) as *mut c_void
    });
    result.unwrap_or(std::ptr::null_mut())
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
    let setup = Setup { interface: Interface::ModelExchange, event_mode_used: false, early_return_allowed: false };
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

/// `fmi3FreeInstance`.
pub unsafe fn free_instance<M: Model>(c: *mut c_void) {
    let component = c as *mut Component<M>;
    if component.is_null() || (*component).magic != COMPONENT_MAGIC {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (*component).magic = 0;
        drop(Box::from_raw(component));
    }));
}

/// `fmi3SetDebugLogging`.
pub unsafe fn set_debug_logging<M: Model>(c: *mut c_void, on: bool, n: usize, categories: *const *const c_char) -> c_int {
    let call = Call::SetDebugLogging;
    with_instance::<M>(c, call, |inst| {
        let ptrs = slice(categories, n, call.name(), "categories[]")?;
        let mut names = Vec::with_capacity(n);
        for p in ptrs {
            names.push(opt_str(*p).ok_or_else(|| Failure::error("fmi3SetDebugLogging: a category is NULL or not UTF-8"))?);
        }
        ok(inst.set_debug_logging(on, &names))
    })
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
    with_instance::<M>(c, Call::EnterInitializationMode, |inst| {
        inst.trace(Call::EnterInitializationMode, || {
            format!("toleranceDefined={tol_defined}, tolerance={tol}, startTime={start}, stopTimeDefined={stop_defined}, stopTime={stop}")
        });
        ok(inst.enter_initialization_mode(tol_defined.then_some(tol), start, stop_defined.then_some(stop)))
    })
}

/// `fmi3ExitInitializationMode`.
pub unsafe fn exit_initialization_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::ExitInitializationMode, |inst| ok(inst.exit_initialization_mode()))
}

/// `fmi3EnterEventMode`.
pub unsafe fn enter_event_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterEventMode, |inst| ok(inst.enter_event_mode()))
}

/// `fmi3Terminate`.
pub unsafe fn terminate<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::Terminate, |inst| ok(inst.terminate()))
}

/// `fmi3Reset`.
pub unsafe fn reset<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::Reset, |inst| ok(inst.reset()))
}

/// `fmi3GetFloat64`. A read of states and time only, the sweep's at every communication
/// point, is served before the unwinding guard (nothing on that path can panic); any other
/// read, and any problem, takes the checked path.
#[inline(always)]
pub unsafe fn get_float64<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut f64, n_values: usize) -> c_int {
    let component = c as *mut Component<M>;
    if n > 0 && n_values == n && !vr.is_null() && !values.is_null() && !component.is_null() && (*component).magic == COMPONENT_MAGIC {
        // SAFETY: FMI's contract: vr points at n value references, values at n_values (= n)
        // writable values (states and time are scalars).
        let (vrs, out) = (std::slice::from_raw_parts(vr, n), std::slice::from_raw_parts_mut(values, n));
        if (*component).instance.read_states(vrs, out) {
            return Status::Ok as c_int;
        }
    }
    checked_get_float64::<M>(c, vr, n, values, n_values)
}

#[inline(never)]
unsafe fn checked_get_float64<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut f64, n_values: usize) -> c_int {
    let call = Call::GetFloat64;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice_mut(values, n, call.name(), "values[]")?;
        ok(inst.get_float64(vrs, values))
    })
}

/// `fmi3GetInt32`.
pub unsafe fn get_int32<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut i32, n_values: usize) -> c_int {
    let call = Call::GetInt32;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice_mut(values, n, call.name(), "values[]")?;
        ok(inst.get_int32(vrs, values))
    })
}

/// `fmi3GetBoolean` (`fmi3Boolean` is C's one-byte `bool`).
pub unsafe fn get_boolean<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut bool, n_values: usize) -> c_int {
    let call = Call::GetBoolean;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice_mut(values, n, call.name(), "values[]")?;
        ok(inst.get_boolean(vrs, values))
    })
}

/// `fmi3SetFloat64`.
pub unsafe fn set_float64<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const f64, n_values: usize) -> c_int {
    let call = Call::SetFloat64;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice(values, n, call.name(), "values[]")?;
        inst.trace(call, || format!("valueReferences={vrs:?}, values={values:?}"));
        ok(inst.set_float64(vrs, values))
    })
}

/// `fmi3SetInt32`.
pub unsafe fn set_int32<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const i32, n_values: usize) -> c_int {
    let call = Call::SetInt32;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice(values, n, call.name(), "values[]")?;
        inst.trace(call, || format!("valueReferences={vrs:?}, values={values:?}"));
        ok(inst.set_int32(vrs, values))
    })
}

/// `fmi3SetBoolean`: each byte read as C reads a `bool` (nonzero is true).
pub unsafe fn set_boolean<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const u8, n_values: usize) -> c_int {
    let call = Call::SetBoolean;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values: Vec<bool> = slice(values, n, call.name(), "values[]")?.iter().map(|b| *b != 0).collect();
        inst.trace(call, || format!("valueReferences={vrs:?}, values={values:?}"));
        ok(inst.set_boolean(vrs, &values))
    })
}

/// `fmi3GetString`: `values[i]` points at the instance's copy of the value, valid until the
/// next `fmi3GetString` on the instance (or until it is freed).
pub unsafe fn get_string<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut *const c_char, n_values: usize) -> c_int {
    let call = Call::GetString;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let values = slice_mut(values, n, call.name(), "values[]")?;
        for (out, text) in values.iter_mut().zip(inst.get_string(vrs)?) {
            *out = text.as_ptr();
        }
        Ok(Status::Ok)
    })
}

/// `fmi3SetString`: a NULL element or text that is not UTF-8 is refused, naming the variable.
pub unsafe fn set_string<M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const *const c_char, n_values: usize) -> c_int {
    let call = Call::SetString;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        check_values(call, n, n_values)?;
        let vrs = slice(vr, n, call.name(), "valueReferences[]")?;
        let pointers = slice(values, n, call.name(), "values[]")?;
        let texts = glue::texts(pointers, vrs, inst.table(), call.name(), "values")?;
        inst.trace(call, || format!("valueReferences={vrs:?}, values={texts:?}"));
        ok(inst.set_string(vrs, &texts))
    })
}

/// A getter or setter of a type no variable of these FMUs has (`name` is the C function).
pub unsafe fn no_such_type<M: Model>(c: *mut c_void, name: &'static str, set: bool) -> c_int {
    let call = if set { Call::SetOther(name) } else { Call::GetOther(name) };
    // "fmi3GetFloat32" -> "Float32"
    let ty = &name[7..];
    with_instance::<M>(c, call, |inst| {
        ok(inst.not_applicable(call, &format!("this FMU has no {ty} variables (its variables are Float64, Int32, Boolean or String)")))
    })
}

/// A function that does not apply to these FMUs: checks the state machine, logs `why` and
/// returns `fmi3Error`.
pub unsafe fn not_applicable<M: Model>(c: *mut c_void, call: Call, why: &'static str) -> c_int {
    with_instance::<M>(c, call, |inst| ok(inst.not_applicable(call, why)))
}

/// The FMU state box `state` points at, when it is one of this model's.
unsafe fn state_box<'a, M: Model>(state: *mut c_void, call: Call) -> CallResult<&'a mut StateBox<M>> {
    let b = state as *mut StateBox<M>;
    if b.is_null() {
        return Err(Failure::error(format!("{}: the FMU state is NULL", call.name())));
    }
    if (*b).magic != state_tag::<M>() {
        return Err(Failure::error(format!(
            "{}: the FMU state was not made by this model's fmi3GetFMUState, or was already freed",
            call.name()
        )));
    }
    Ok(&mut *b)
}

/// `fmi3GetFMUState`: a new state, or the one `*state` points at overwritten.
pub unsafe fn get_fmu_state<M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    let call = Call::GetFMUState;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        if state.is_null() {
            return Err(Failure::error("fmi3GetFMUState: the FMUState pointer is NULL"));
        }
        let saved = inst.get_fmu_state()?;
        if (*state).is_null() {
            *state = Box::into_raw(Box::new(StateBox { magic: state_tag::<M>(), saved })) as *mut c_void;
        } else {
            state_box::<M>(*state, call)?.saved = saved;
        }
        Ok(Status::Ok)
    })
}

/// `fmi3SetFMUState`.
pub unsafe fn set_fmu_state<M: Model>(c: *mut c_void, state: *mut c_void) -> c_int {
    let call = Call::SetFMUState;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let b = state_box::<M>(state, call)?;
        ok(inst.set_fmu_state(&b.saved))
    })
}

/// `fmi3FreeFMUState`: frees and sets `*state` to NULL (a NULL state is a no-op).
pub unsafe fn free_fmu_state<M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    let call = Call::FreeFMUState;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        if state.is_null() || (*state).is_null() {
            return Ok(Status::Ok);
        }
        let b = state_box::<M>(*state, call)?;
        b.magic = 0;
        drop(Box::from_raw(b as *mut StateBox<M>));
        *state = std::ptr::null_mut();
        Ok(Status::Ok)
    })
}

/// `fmi3SerializedFMUStateSize`.
pub unsafe fn serialized_fmu_state_size<M: Model>(c: *mut c_void, state: *mut c_void, size: *mut usize) -> c_int {
    let call = Call::SerializedFMUStateSize;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        if size.is_null() {
            return Err(Failure::error("fmi3SerializedFMUStateSize: size is NULL"));
        }
        let b = state_box::<M>(state, call)?;
        *size = snapshot::encode(&b.saved.0, &b.saved.1, state_tag::<M>()).map_err(Failure::error)?.len();
        Ok(Status::Ok)
    })
}

/// `fmi3SerializeFMUState`: `size` must be what `fmi3SerializedFMUStateSize` returned.
pub unsafe fn serialize_fmu_state<M: Model>(c: *mut c_void, state: *mut c_void, buffer: *mut u8, size: usize) -> c_int {
    let call = Call::SerializeFMUState;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let b = state_box::<M>(state, call)?;
        let bytes = snapshot::encode(&b.saved.0, &b.saved.1, state_tag::<M>()).map_err(Failure::error)?;
        if size != bytes.len() {
            return Err(Failure::error(format!(
                "fmi3SerializeFMUState: the buffer has {size} bytes but the state needs {} (ask fmi3SerializedFMUStateSize)",
                bytes.len()
            )));
        }
        let out = slice_mut(buffer, size, call.name(), "serializedState[]")?;
        out.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// `fmi3DeserializeFMUState`: refuses buffers of the wrong size, model, version or checksum.
pub unsafe fn deserialize_fmu_state<M: Model>(c: *mut c_void, buffer: *const u8, size: usize, state: *mut *mut c_void) -> c_int {
    let call = Call::DeserializeFMUState;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        if state.is_null() {
            return Err(Failure::error("fmi3DeserializeFMUState: the FMUState pointer is NULL"));
        }
        let bytes = slice(buffer, size, call.name(), "serializedState[]")?;
        let saved =
            snapshot::decode::<M, Machine>(bytes, state_tag::<M>()).map_err(|e| Failure::error(format!("fmi3DeserializeFMUState: {e}")))?;
        if (*state).is_null() {
            *state = Box::into_raw(Box::new(StateBox { magic: state_tag::<M>(), saved })) as *mut c_void;
        } else {
            state_box::<M>(*state, call)?.saved = saved;
        }
        Ok(Status::Ok)
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
    with_instance::<M>(c, call, |inst| {
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

/// `fmi3EnterContinuousTimeMode`.
pub unsafe fn enter_continuous_time_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterContinuousTimeMode, |inst| ok(inst.enter_continuous_time_mode()))
}

/// `fmi3CompletedIntegratorStep`.
pub unsafe fn completed_integrator_step<M: Model>(
    c: *mut c_void,
    _no_set_prior: bool,
    enter_event_mode: *mut bool,
    terminate: *mut bool,
) -> c_int {
    let call = Call::CompletedIntegratorStep;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        if enter_event_mode.is_null() || terminate.is_null() {
            return Err(Failure::error("fmi3CompletedIntegratorStep: enterEventMode or terminateSimulation is NULL"));
        }
        let step = inst.completed_integrator_step()?;
        *enter_event_mode = step.enter_event_mode;
        *terminate = step.terminate_simulation;
        Ok(Status::Ok)
    })
}

/// `fmi3SetTime`.
pub unsafe fn set_time<M: Model>(c: *mut c_void, time: f64) -> c_int {
    with_instance::<M>(c, Call::SetTime, |inst| ok(inst.set_time(time)))
}

/// `fmi3SetContinuousStates`.
pub unsafe fn set_continuous_states<M: Model>(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
    let call = Call::SetContinuousStates;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let x = slice(x, nx, call.name(), "continuousStates[]")?;
        ok(inst.set_continuous_states(x))
    })
}

/// `fmi3GetContinuousStateDerivatives`.
pub unsafe fn get_continuous_state_derivatives<M: Model>(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
    let call = Call::GetContinuousStateDerivatives;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let dx = slice_mut(dx, nx, call.name(), "derivatives[]")?;
        ok(inst.get_continuous_state_derivatives(dx))
    })
}

/// `fmi3GetEventIndicators`.
pub unsafe fn get_event_indicators<M: Model>(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
    let call = Call::GetEventIndicators;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let z = slice_mut(z, ni, call.name(), "eventIndicators[]")?;
        ok(inst.get_event_indicators(z))
    })
}

/// `fmi3GetContinuousStates`.
pub unsafe fn get_continuous_states<M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    let call = Call::GetContinuousStates;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let x = slice_mut(x, nx, call.name(), "continuousStates[]")?;
        ok(inst.get_continuous_states(x))
    })
}

/// `fmi3GetNominalsOfContinuousStates`.
pub unsafe fn get_nominals_of_continuous_states<M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    let call = Call::GetNominalsOfContinuousStates;
    with_instance::<M>(c, call, |inst| {
        inst.check(call)?;
        let x = slice_mut(x, nx, call.name(), "nominals[]")?;
        ok(inst.get_nominals_of_continuous_states(x))
    })
}

/// `fmi3GetNumberOfEventIndicators`.
pub unsafe fn get_number_of_event_indicators<M: Model>(c: *mut c_void, n: *mut usize) -> c_int {
    let call = Call::GetNumberOfEventIndicators;
    with_instance::<M>(c, call, |inst| {
        let value = inst.number_of_event_indicators()?;
        if n.is_null() {
            return Err(Failure::error("fmi3GetNumberOfEventIndicators: nEventIndicators is NULL"));
        }
        *n = value;
        Ok(Status::Ok)
    })
}

/// `fmi3GetNumberOfContinuousStates`.
pub unsafe fn get_number_of_continuous_states<M: Model>(c: *mut c_void, n: *mut usize) -> c_int {
    let call = Call::GetNumberOfContinuousStates;
    with_instance::<M>(c, call, |inst| {
        let value = inst.number_of_continuous_states()?;
        if n.is_null() {
            return Err(Failure::error("fmi3GetNumberOfContinuousStates: nContinuousStates is NULL"));
        }
        *n = value;
        Ok(Status::Ok)
    })
}

/// `fmi3EnterStepMode`.
pub unsafe fn enter_step_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterStepMode, |inst| ok(inst.enter_step_mode()))
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
    with_instance::<M>(c, call, |inst| {
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

/// Why `fmi3GetNumberOfVariableDependencies` and `fmi3GetVariableDependencies` refuse.
pub const NO_DEPENDENCY_FUNCTIONS: &str =
    "this FMU does not provide per-element dependencies (providesPerElementDependencies=\"false\"): its ModelStructure in modelDescription.xml lists the dependencies of its scalar variables";
/// Why `fmi3GetDirectionalDerivative` refuses.
pub const NO_DIRECTIONAL: &str = "this FMU does not provide directional derivatives (providesDirectionalDerivatives=\"false\")";
/// Why `fmi3GetAdjointDerivative` refuses.
pub const NO_ADJOINT: &str = "this FMU does not provide adjoint derivatives (providesAdjointDerivatives=\"false\")";
/// Why Configuration Mode is refused.
pub const NO_CONFIGURATION: &str = "this FMU has no structural parameters, so there is no Configuration Mode to enter or leave";
/// Why the clock functions refuse.
pub const NO_CLOCKS: &str = "this FMU has no clocks";
/// Why `fmi3EvaluateDiscreteStates` refuses.
pub const NO_EVALUATE: &str = "this FMU does not provide it (providesEvaluateDiscreteStates=\"false\")";
/// Why `fmi3GetOutputDerivatives` refuses.
pub const NO_OUTPUT_DERIVATIVES: &str = "this FMU does not provide output derivatives (maxOutputDerivativeOrder=\"0\")";
/// Why `fmi3ActivateModelPartition` refuses.
pub const NO_SCHEDULED_EXECUTION: &str = "this FMU does not offer Scheduled Execution, so no instance has model partitions";

/// Exports all 75 FMI 3.0 functions for `$model`, plus `fmu3_model_description` (used by
/// `runner build` to write the FMI 3.0 `.fmu`'s XML from the compiled table). Expanded by
/// [`export_fmu!`](crate::export_fmu); not for direct use.
#[doc(hidden)]
#[macro_export]
macro_rules! export_fmi3 {
    (@absent_get $($name:ident)*) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: *mut c_void, _vr: *const u32, _n: usize, _v: *mut c_void, _nv: usize) -> c_int {
                f::no_such_type::<M>(c, stringify!($name), false)
            }
        )*
    };
    (@absent_set $($name:ident)*) => {
        $(
            #[no_mangle]
            pub unsafe extern "C" fn $name(c: *mut c_void, _vr: *const u32, _n: usize, _v: *const c_void, _nv: usize) -> c_int {
                f::no_such_type::<M>(c, stringify!($name), true)
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
            use $crate::fmi3::state_machine::Call;
            type M = $model;
            type Log = ::std::option::Option<f::LogMessageCallback>;
            type Vrs = *const u32;

            #[no_mangle]
            pub extern "C" fn fmi3GetVersion() -> *const c_char {
                f::get_version()
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetDebugLogging(c: *mut c_void, on: bool, n: usize, cats: *const *const c_char) -> c_int {
                f::set_debug_logging::<M>(c, on, n, cats)
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
                f::free_instance::<M>(c)
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
                f::exit_initialization_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterEventMode(c: *mut c_void) -> c_int {
                f::enter_event_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Terminate(c: *mut c_void) -> c_int {
                f::terminate::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3Reset(c: *mut c_void) -> c_int {
                f::reset::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFloat64(c: *mut c_void, vr: Vrs, n: usize, v: *mut f64, nv: usize) -> c_int {
                f::get_float64::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetInt32(c: *mut c_void, vr: Vrs, n: usize, v: *mut i32, nv: usize) -> c_int {
                f::get_int32::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBoolean(c: *mut c_void, vr: Vrs, n: usize, v: *mut bool, nv: usize) -> c_int {
                f::get_boolean::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFloat64(c: *mut c_void, vr: Vrs, n: usize, v: *const f64, nv: usize) -> c_int {
                f::set_float64::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetInt32(c: *mut c_void, vr: Vrs, n: usize, v: *const i32, nv: usize) -> c_int {
                f::set_int32::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBoolean(c: *mut c_void, vr: Vrs, n: usize, v: *const u8, nv: usize) -> c_int {
                f::set_boolean::<M>(c, vr, n, v, nv)
            }
            $crate::export_fmi3!(@absent_get fmi3GetFloat32 fmi3GetInt8 fmi3GetUInt8 fmi3GetInt16 fmi3GetUInt16 fmi3GetUInt32
                fmi3GetInt64 fmi3GetUInt64);
            $crate::export_fmi3!(@absent_set fmi3SetFloat32 fmi3SetInt8 fmi3SetUInt8 fmi3SetInt16 fmi3SetUInt16 fmi3SetUInt32
                fmi3SetInt64 fmi3SetUInt64);
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetString(c: *mut c_void, vr: Vrs, n: usize, v: *mut *const c_char, nv: usize) -> c_int {
                f::get_string::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetString(c: *mut c_void, vr: Vrs, n: usize, v: *const *const c_char, nv: usize) -> c_int {
                f::set_string::<M>(c, vr, n, v, nv)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetBinary(c: *mut c_void, _vr: Vrs, _n: usize, _sizes: *mut usize, _v: *mut *const u8, _nv: usize) -> c_int {
                f::no_such_type::<M>(c, "fmi3GetBinary", false)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetBinary(c: *mut c_void, _vr: Vrs, _n: usize, _sizes: *const usize, _v: *const *const u8, _nv: usize) -> c_int {
                f::no_such_type::<M>(c, "fmi3SetBinary", true)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetClock(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut bool) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3GetClock"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetClock(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const bool) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3SetClock"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNumberOfVariableDependencies(c: *mut c_void, _vr: u32, _n: *mut usize) -> c_int {
                f::not_applicable::<M>(c, Call::GetNumberOfVariableDependencies, f::NO_DEPENDENCY_FUNCTIONS)
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
                f::not_applicable::<M>(c, Call::GetVariableDependencies, f::NO_DEPENDENCY_FUNCTIONS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetFMUState(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                f::get_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetFMUState(c: *mut c_void, s: *mut c_void) -> c_int {
                f::set_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3FreeFMUState(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                f::free_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializedFMUStateSize(c: *mut c_void, s: *mut c_void, size: *mut usize) -> c_int {
                f::serialized_fmu_state_size::<M>(c, s, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SerializeFMUState(c: *mut c_void, s: *mut c_void, buf: *mut u8, size: usize) -> c_int {
                f::serialize_fmu_state::<M>(c, s, buf, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3DeserializeFMUState(c: *mut c_void, buf: *const u8, size: usize, s: *mut *mut c_void) -> c_int {
                f::deserialize_fmu_state::<M>(c, buf, size, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetDirectionalDerivative(
                c: *mut c_void,
                _unknowns: Vrs,
                _n_unknowns: usize,
                _knowns: Vrs,
                _n_knowns: usize,
                _seed: *const f64,
                _n_seed: usize,
                _sensitivity: *mut f64,
                _n_sensitivity: usize,
            ) -> c_int {
                f::not_applicable::<M>(c, Call::GetDirectionalDerivative, f::NO_DIRECTIONAL)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetAdjointDerivative(
                c: *mut c_void,
                _unknowns: Vrs,
                _n_unknowns: usize,
                _knowns: Vrs,
                _n_knowns: usize,
                _seed: *const f64,
                _n_seed: usize,
                _sensitivity: *mut f64,
                _n_sensitivity: usize,
            ) -> c_int {
                f::not_applicable::<M>(c, Call::GetAdjointDerivative, f::NO_ADJOINT)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EnterConfigurationMode(c: *mut c_void) -> c_int {
                f::not_applicable::<M>(c, Call::EnterConfigurationMode, f::NO_CONFIGURATION)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3ExitConfigurationMode(c: *mut c_void) -> c_int {
                f::not_applicable::<M>(c, Call::ExitConfigurationMode, f::NO_CONFIGURATION)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetIntervalDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut f64, _q: *mut c_int) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3GetIntervalDecimal"), f::NO_CLOCKS)
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
                f::not_applicable::<M>(c, Call::Clock("fmi3GetIntervalFraction"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *mut f64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3GetShiftDecimal"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetShiftFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *mut u64, _resolution: *mut u64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3GetShiftFraction"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const f64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3SetIntervalDecimal"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetIntervalFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *const u64, _resolution: *const u64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3SetIntervalFraction"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftDecimal(c: *mut c_void, _vr: Vrs, _n: usize, _v: *const f64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3SetShiftDecimal"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetShiftFraction(c: *mut c_void, _vr: Vrs, _n: usize, _counter: *const u64, _resolution: *const u64) -> c_int {
                f::not_applicable::<M>(c, Call::Clock("fmi3SetShiftFraction"), f::NO_CLOCKS)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3EvaluateDiscreteStates(c: *mut c_void) -> c_int {
                f::not_applicable::<M>(c, Call::EvaluateDiscreteStates, f::NO_EVALUATE)
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
                f::enter_continuous_time_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3CompletedIntegratorStep(c: *mut c_void, no_set_prior: bool, enter: *mut bool, terminate: *mut bool) -> c_int {
                f::completed_integrator_step::<M>(c, no_set_prior, enter, terminate)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetTime(c: *mut c_void, time: f64) -> c_int {
                f::set_time::<M>(c, time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3SetContinuousStates(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
                f::set_continuous_states::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStateDerivatives(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
                f::get_continuous_state_derivatives::<M>(c, dx, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetEventIndicators(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
                f::get_event_indicators::<M>(c, z, ni)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                f::get_continuous_states::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetNominalsOfContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                f::get_nominals_of_continuous_states::<M>(c, x, nx)
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
                f::enter_step_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi3GetOutputDerivatives(c: *mut c_void, _vr: Vrs, _n: usize, _order: *const i32, _v: *mut f64, _nv: usize) -> c_int {
                f::not_applicable::<M>(c, Call::GetOutputDerivatives, f::NO_OUTPUT_DERIVATIVES)
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
                f::not_applicable::<M>(c, Call::ActivateModelPartition, f::NO_SCHEDULED_EXECUTION)
            }

            /// Writes this FMU's FMI 3.0 modelDescription.xml into `buf`; returns the size needed.
            #[no_mangle]
            pub unsafe extern "C" fn fmu3_model_description(buf: *mut c_char, size: usize) -> usize {
                match ::std::panic::catch_unwind(|| $crate::fmi3::describe::model_description_xml::<M>()) {
                    Ok(xml) => f::copy_out(&xml, buf, size),
                    _ => 0,
                }
            }
        }
    };
}
