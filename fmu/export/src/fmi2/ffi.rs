//! The C boundary of FMI 2.0: the generic bodies of the `fmi2*` functions, and
//! [`export_fmu!`](crate::export_fmu) which instantiates them for one model. Every body checks
//! its pointers, catches panics, and reports failures through the logger and the status.

#![allow(clippy::missing_safety_doc)]

use std::ffi::{c_char, c_int, c_uint, c_void, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use fmi_c::fmi2::{CallbackFunctions, CallbackLogger as LoggerFn, EventInfo, CO_SIMULATION as FMI2_COSIMULATION};
use fmi_c::fmi2::{DO_STEP_STATUS, LAST_SUCCESSFUL_TIME, MODEL_EXCHANGE, TERMINATED};

use super::state_machine::{Call, FmiState, Interface};
use super::Instance;
use crate::core::{snapshot, CallResult, Failure, State};
use crate::glue::{self, c_message, opt_str};
pub use crate::glue::{copy_out, model_tag};
use crate::logging::{Logger, Sink, Status};
use crate::model::Model;

const COMPONENT_MAGIC: u64 = 0x464d_4932_434f_4d50; // "FMI2COMP"

/// What `fmi2Component` points at: a tag to recognise our own pointers, then the instance.
pub struct Component<M: Model> {
    magic: u64,
    instance: Instance<M>,
}

/// What `fmi2FMUstate` points at: the core's state and the state-machine state.
pub struct StateBox<M: Model> {
    magic: u64,
    saved: (State<M>, FmiState),
}

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

/// Runs `body` on the instance behind `c`: checks the pointer, catches panics, logs failures.
unsafe fn with_instance<M: Model>(c: *mut c_void, call: Call, body: impl FnOnce(&mut Instance<M>) -> CallResult<Status>) -> c_int {
    let component = c as *mut Component<M>;
    if component.is_null() || (*component).magic != COMPONENT_MAGIC {
        // Nothing to log through: the logger lives in the instance.
        return Status::Error as c_int;
    }
    // The status code is formed inside the unwinding guard: catch_unwind then hands back a
    // plain c_int. Handing back the call's Result made the compiler store its 4-byte status and
    // reload it as 8 bytes, a store-forwarding stall that cost fmi2DoStep 4 % of a sweep.
    let result = catch_unwind(AssertUnwindSafe(|| match body(&mut (*component).instance) {
        Ok(status) => status as c_int,
        Err(failure) => glue::report_failure(&mut (*component).instance, call.name(), failure),
    }));
    match result {
        Ok(code) => code,
        Err(payload) => glue::report_panic(&mut (*component).instance, call.name(), payload),
    }
}

unsafe fn slice<'a, T>(p: *const T, n: usize, call: Call, what: &str) -> CallResult<&'a [T]> {
    glue::slice(p, n, call.name(), what)
}

unsafe fn slice_mut<'a, T>(p: *mut T, n: usize, call: Call, what: &str) -> CallResult<&'a mut [T]> {
    glue::slice_mut(p, n, call.name(), what)
}

fn ok(r: CallResult) -> CallResult<Status> {
    r.map(|()| Status::Ok)
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
    let result = catch_unwind(|| {
        if functions.is_null() {
            return std::ptr::null_mut();
        }
        let functions = &*functions;
        let name = opt_str(instance_name).unwrap_or("");
        let mut logger = Logger::new(sink_for(functions, if name.is_empty() { "?" } else { name }), logging_on != 0);
        let refuse = |logger: &mut Logger, why: String| {
            logger.status(Status::Error, &format!("fmi2Instantiate: {why}"));
            std::ptr::null_mut()
        };
        if name.is_empty() {
            return refuse(&mut logger, "instanceName must be a non-empty string".to_owned());
        }
        let interface = match fmu_type {
            FMI2_COSIMULATION => Interface::CoSimulation,
            MODEL_EXCHANGE => Interface::ModelExchange,
            _ => return refuse(&mut logger, format!("fmuType = {fmu_type} is neither fmi2ModelExchange (0) nor fmi2CoSimulation (1)")),
        };
        let expected = crate::table::guid::<M>();
        match opt_str(guid) {
            Some(g) if g == expected => {}
            other => {
                return refuse(
                    &mut logger,
                    format!(
                        "GUID {:?} does not match this FMU's {expected}: the modelDescription.xml and the binary are from different builds",
                        other.unwrap_or("(NULL)")
                    ),
                )
            }
        }
        let mut instance = Instance::<M>::for_interface(name, logger, interface);
        if let Some(dir) = opt_str(resource_location).and_then(resource_dir) {
            if let Err(e) = instance.load_resources(&dir) {
                return refuse(instance.logger(), format!("the FMU's resources ({}): {e}", dir.display()));
            }
        }
        let component = Box::new(Component { magic: COMPONENT_MAGIC, instance });
        Box::into_raw(component) as *mut c_void
    });
    result.unwrap_or(std::ptr::null_mut())
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

/// `fmi2FreeInstance`.
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

/// `fmi2SetDebugLogging`.
pub unsafe fn set_debug_logging<M: Model>(c: *mut c_void, on: c_int, n: usize, categories: *const *const c_char) -> c_int {
    with_instance::<M>(c, Call::SetDebugLogging, |inst| {
        let ptrs = slice(categories, n, Call::SetDebugLogging, "categories[]")?;
        let mut names = Vec::with_capacity(n);
        for p in ptrs {
            names.push(opt_str(*p).ok_or_else(|| Failure::error("fmi2SetDebugLogging: a category is NULL or not UTF-8"))?);
        }
        ok(inst.set_debug_logging(on != 0, &names))
    })
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
    with_instance::<M>(c, Call::SetupExperiment, |inst| {
        inst.trace(Call::SetupExperiment, || {
            format!("toleranceDefined={tol_defined}, tolerance={tol}, startTime={start}, stopTimeDefined={stop_defined}, stopTime={stop}")
        });
        ok(inst.setup_experiment((tol_defined != 0).then_some(tol), start, (stop_defined != 0).then_some(stop)))
    })
}

/// `fmi2EnterInitializationMode`.
pub unsafe fn enter_initialization_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterInitializationMode, |inst| ok(inst.enter_initialization_mode()))
}

/// `fmi2ExitInitializationMode`.
pub unsafe fn exit_initialization_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::ExitInitializationMode, |inst| ok(inst.exit_initialization_mode()))
}

/// `fmi2Terminate`.
pub unsafe fn terminate<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::Terminate, |inst| ok(inst.terminate()))
}

/// `fmi2Reset`.
pub unsafe fn reset<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::Reset, |inst| ok(inst.reset()))
}

/// `fmi2GetReal`. A read of states and time only, the sweep's at every communication point,
/// is served before the unwinding guard (nothing on that path can panic); any other read, and
/// any problem, takes the checked path.
#[inline(always)]
pub unsafe fn get_real<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *mut f64) -> c_int {
    let component = c as *mut Component<M>;
    if n > 0 && !vr.is_null() && !value.is_null() && !component.is_null() && (*component).magic == COMPONENT_MAGIC {
        // SAFETY: FMI's contract: vr and value point at n values each, value writable.
        let (vrs, values) = (std::slice::from_raw_parts(vr, n), std::slice::from_raw_parts_mut(value, n));
        if (*component).instance.read_states(vrs, values) {
            return Status::Ok as c_int;
        }
    }
    checked_get_real::<M>(c, vr, n, value)
}

#[inline(never)]
unsafe fn checked_get_real<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *mut f64) -> c_int {
    with_instance::<M>(c, Call::GetReal, |inst| {
        let vrs = slice(vr, n, Call::GetReal, "vr[]")?;
        let values = slice_mut(value, n, Call::GetReal, "value[]")?;
        ok(inst.get_real(vrs, values))
    })
}

/// `fmi2GetInteger`.
pub unsafe fn get_integer<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *mut c_int) -> c_int {
    with_instance::<M>(c, Call::GetInteger, |inst| {
        let vrs = slice(vr, n, Call::GetInteger, "vr[]")?;
        let values = slice_mut(value, n, Call::GetInteger, "value[]")?;
        ok(inst.get_integer(vrs, values))
    })
}

/// `fmi2GetBoolean`.
pub unsafe fn get_boolean<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *mut c_int) -> c_int {
    with_instance::<M>(c, Call::GetBoolean, |inst| {
        let vrs = slice(vr, n, Call::GetBoolean, "vr[]")?;
        let values = slice_mut(value, n, Call::GetBoolean, "value[]")?;
        let mut bools = vec![false; n];
        inst.get_boolean(vrs, &mut bools)?;
        for (v, b) in values.iter_mut().zip(bools) {
            *v = b as c_int;
        }
        Ok(Status::Ok)
    })
}

/// `fmi2GetString`.
pub unsafe fn get_string<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *mut *const c_char) -> c_int {
    with_instance::<M>(c, Call::GetString, |inst| {
        let vrs = slice(vr, n, Call::GetString, "vr[]")?;
        let values = slice_mut(value, n, Call::GetString, "value[]")?;
        for (out, text) in values.iter_mut().zip(inst.get_string(vrs)?) {
            *out = text.as_ptr();
        }
        Ok(Status::Ok)
    })
}

/// `fmi2SetReal`.
pub unsafe fn set_real<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *const f64) -> c_int {
    with_instance::<M>(c, Call::SetReal, |inst| {
        let vrs = slice(vr, n, Call::SetReal, "vr[]")?;
        let values = slice(value, n, Call::SetReal, "value[]")?;
        inst.trace(Call::SetReal, || format!("vr={vrs:?}, value={values:?}"));
        ok(inst.set_real(vrs, values))
    })
}

/// `fmi2SetInteger`.
pub unsafe fn set_integer<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *const c_int) -> c_int {
    with_instance::<M>(c, Call::SetInteger, |inst| {
        let vrs = slice(vr, n, Call::SetInteger, "vr[]")?;
        let values = slice(value, n, Call::SetInteger, "value[]")?;
        inst.trace(Call::SetInteger, || format!("vr={vrs:?}, value={values:?}"));
        ok(inst.set_integer(vrs, values))
    })
}

/// `fmi2SetBoolean`.
pub unsafe fn set_boolean<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *const c_int) -> c_int {
    with_instance::<M>(c, Call::SetBoolean, |inst| {
        let vrs = slice(vr, n, Call::SetBoolean, "vr[]")?;
        let values: Vec<bool> = slice(value, n, Call::SetBoolean, "value[]")?.iter().map(|v| *v != 0).collect();
        inst.trace(Call::SetBoolean, || format!("vr={vrs:?}, value={values:?}"));
        ok(inst.set_boolean(vrs, &values))
    })
}

/// `fmi2SetString`.
pub unsafe fn set_string<M: Model>(c: *mut c_void, vr: *const c_uint, n: usize, value: *const *const c_char) -> c_int {
    with_instance::<M>(c, Call::SetString, |inst| {
        let vrs = slice(vr, n, Call::SetString, "vr[]")?;
        let pointers = slice(value, n, Call::SetString, "value[]")?;
        let texts = glue::texts(pointers, vrs, inst.table(), Call::SetString.name(), "value")?;
        inst.trace(Call::SetString, || format!("vr={vrs:?}, value={texts:?}"));
        ok(inst.set_string(vrs, &texts))
    })
}

unsafe fn state_box<'a, M: Model>(state: *mut c_void, call: Call) -> CallResult<&'a mut StateBox<M>> {
    let b = state as *mut StateBox<M>;
    if b.is_null() {
        return Err(Failure::error(format!("{}: the FMU state is NULL", call.name())));
    }
    if (*b).magic != model_tag::<M>() {
        return Err(Failure::error(format!(
            "{}: the FMU state was not made by this model's fmi2GetFMUstate, or was already freed",
            call.name()
        )));
    }
    Ok(&mut *b)
}

/// `fmi2GetFMUstate`: a new state, or the one `*state` points at overwritten.
pub unsafe fn get_fmu_state<M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    with_instance::<M>(c, Call::GetFMUstate, |inst| {
        if state.is_null() {
            return Err(Failure::error("fmi2GetFMUstate: the FMUstate pointer is NULL"));
        }
        let saved = inst.get_fmu_state()?;
        if (*state).is_null() {
            *state = Box::into_raw(Box::new(StateBox { magic: model_tag::<M>(), saved })) as *mut c_void;
        } else {
            state_box::<M>(*state, Call::GetFMUstate)?.saved = saved;
        }
        Ok(Status::Ok)
    })
}

/// `fmi2SetFMUstate`.
pub unsafe fn set_fmu_state<M: Model>(c: *mut c_void, state: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::SetFMUstate, |inst| {
        let b = state_box::<M>(state, Call::SetFMUstate)?;
        ok(inst.set_fmu_state(&b.saved))
    })
}

/// `fmi2FreeFMUstate`: frees and sets `*state` to NULL (a NULL state is a no-op).
pub unsafe fn free_fmu_state<M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    with_instance::<M>(c, Call::FreeFMUstate, |inst| {
        inst.check(Call::FreeFMUstate)?;
        if state.is_null() || (*state).is_null() {
            return Ok(Status::Ok);
        }
        let b = state_box::<M>(*state, Call::FreeFMUstate)?;
        b.magic = 0;
        drop(Box::from_raw(b as *mut StateBox<M>));
        *state = std::ptr::null_mut();
        Ok(Status::Ok)
    })
}

/// `fmi2SerializedFMUstateSize`.
pub unsafe fn serialized_fmu_state_size<M: Model>(c: *mut c_void, state: *mut c_void, size: *mut usize) -> c_int {
    with_instance::<M>(c, Call::SerializedFMUstateSize, |inst| {
        inst.check(Call::SerializedFMUstateSize)?;
        if size.is_null() {
            return Err(Failure::error("fmi2SerializedFMUstateSize: size is NULL"));
        }
        let b = state_box::<M>(state, Call::SerializedFMUstateSize)?;
        *size = snapshot::encode(&b.saved.0, &b.saved.1, model_tag::<M>()).map_err(Failure::error)?.len();
        Ok(Status::Ok)
    })
}

/// `fmi2SerializeFMUstate`: `size` must be what `fmi2SerializedFMUstateSize` returned.
pub unsafe fn serialize_fmu_state<M: Model>(c: *mut c_void, state: *mut c_void, buffer: *mut c_char, size: usize) -> c_int {
    with_instance::<M>(c, Call::SerializeFMUstate, |inst| {
        inst.check(Call::SerializeFMUstate)?;
        let b = state_box::<M>(state, Call::SerializeFMUstate)?;
        let bytes = snapshot::encode(&b.saved.0, &b.saved.1, model_tag::<M>()).map_err(Failure::error)?;
        if size != bytes.len() {
            return Err(Failure::error(format!(
                "fmi2SerializeFMUstate: the buffer has {size} bytes but the state needs {} (ask fmi2SerializedFMUstateSize)",
                bytes.len()
            )));
        }
        let out = slice_mut(buffer as *mut u8, size, Call::SerializeFMUstate, "serializedState[]")?;
        out.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// `fmi2DeSerializeFMUstate`: refuses buffers of the wrong size, model or checksum.
pub unsafe fn deserialize_fmu_state<M: Model>(c: *mut c_void, buffer: *const c_char, size: usize, state: *mut *mut c_void) -> c_int {
    with_instance::<M>(c, Call::DeSerializeFMUstate, |inst| {
        inst.check(Call::DeSerializeFMUstate)?;
        if state.is_null() {
            return Err(Failure::error("fmi2DeSerializeFMUstate: the FMUstate pointer is NULL"));
        }
        let bytes = slice(buffer as *const u8, size, Call::DeSerializeFMUstate, "serializedState[]")?;
        let saved = snapshot::decode::<M, FmiState>(bytes, model_tag::<M>())
            .map_err(|e| Failure::error(format!("fmi2DeSerializeFMUstate: {e}")))?;
        if (*state).is_null() {
            *state = Box::into_raw(Box::new(StateBox { magic: model_tag::<M>(), saved })) as *mut c_void;
        } else {
            state_box::<M>(*state, Call::DeSerializeFMUstate)?.saved = saved;
        }
        Ok(Status::Ok)
    })
}

/// `fmi2GetDirectionalDerivative`: not provided (`providesDirectionalDerivative="false"`).
pub unsafe fn get_directional_derivative<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::GetDirectionalDerivative, |inst| {
        inst.check(Call::GetDirectionalDerivative)?;
        Err(Failure::error(
            "fmi2GetDirectionalDerivative: this FMU does not provide directional derivatives (providesDirectionalDerivative=\"false\")",
        ))
    })
}

/// `fmi2SetRealInputDerivatives`: inputs are held constant (`canInterpolateInputs="false"`).
pub unsafe fn set_real_input_derivatives<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::SetRealInputDerivatives, |inst| {
        inst.check(Call::SetRealInputDerivatives)?;
        Err(Failure::error("fmi2SetRealInputDerivatives: this FMU holds inputs constant over a step and cannot interpolate them (canInterpolateInputs=\"false\")"))
    })
}

/// `fmi2GetRealOutputDerivatives`: not provided (`maxOutputDerivativeOrder="0"`).
pub unsafe fn get_real_output_derivatives<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::GetRealOutputDerivatives, |inst| {
        inst.check(Call::GetRealOutputDerivatives)?;
        Err(Failure::error("fmi2GetRealOutputDerivatives: this FMU does not provide output derivatives (maxOutputDerivativeOrder=\"0\")"))
    })
}

/// `fmi2DoStep`.
pub unsafe fn do_step<M: Model>(c: *mut c_void, current: f64, h: f64, _no_set_prior: c_int) -> c_int {
    with_instance::<M>(c, Call::DoStep, |inst| {
        inst.trace(Call::DoStep, || format!("currentCommunicationPoint={current}, communicationStepSize={h}"));
        inst.do_step(current, h)
    })
}

/// `fmi2CancelStep`: never allowed, steps are synchronous.
pub unsafe fn cancel_step<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::CancelStep, |inst| inst.check(Call::CancelStep).map(|()| Status::Ok))
}

fn unsupported_kind(call: Call, kind: c_int) -> Failure {
    Failure {
        status: Status::Discard,
        message: format!("{}: status kind {kind} is not available from this FMU", call.name()),
        broken: false,
    }
}

/// `fmi2GetStatus`: `fmi2DoStepStatus` gives the last step's status.
pub unsafe fn get_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut c_int) -> c_int {
    with_instance::<M>(c, Call::GetStatus, |inst| {
        if value.is_null() {
            return Err(Failure::error("fmi2GetStatus: value is NULL"));
        }
        match kind {
            DO_STEP_STATUS => {
                *value = inst.do_step_status()? as c_int;
                Ok(Status::Ok)
            }
            _ => {
                inst.check(Call::GetStatus)?;
                Err(unsupported_kind(Call::GetStatus, kind))
            }
        }
    })
}

/// `fmi2GetRealStatus`: `fmi2LastSuccessfulTime`.
pub unsafe fn get_real_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut f64) -> c_int {
    with_instance::<M>(c, Call::GetRealStatus, |inst| {
        if value.is_null() {
            return Err(Failure::error("fmi2GetRealStatus: value is NULL"));
        }
        match kind {
            LAST_SUCCESSFUL_TIME => {
                *value = inst.last_successful_time()?;
                Ok(Status::Ok)
            }
            _ => {
                inst.check(Call::GetRealStatus)?;
                Err(unsupported_kind(Call::GetRealStatus, kind))
            }
        }
    })
}

/// `fmi2GetIntegerStatus`: no integer status kinds exist in FMI 2.0.
pub unsafe fn get_integer_status<M: Model>(c: *mut c_void, kind: c_int, _value: *mut c_int) -> c_int {
    with_instance::<M>(c, Call::GetIntegerStatus, |inst| {
        inst.check(Call::GetIntegerStatus)?;
        Err(unsupported_kind(Call::GetIntegerStatus, kind))
    })
}

/// `fmi2GetBooleanStatus`: `fmi2Terminated`, true once the model ended the experiment.
pub unsafe fn get_boolean_status<M: Model>(c: *mut c_void, kind: c_int, value: *mut c_int) -> c_int {
    with_instance::<M>(c, Call::GetBooleanStatus, |inst| {
        if value.is_null() {
            return Err(Failure::error("fmi2GetBooleanStatus: value is NULL"));
        }
        match kind {
            TERMINATED => {
                *value = inst.terminated()? as c_int;
                Ok(Status::Ok)
            }
            _ => {
                inst.check(Call::GetBooleanStatus)?;
                Err(unsupported_kind(Call::GetBooleanStatus, kind))
            }
        }
    })
}

/// `fmi2GetStringStatus`: `fmi2PendingStatus` is meaningless for synchronous steps.
pub unsafe fn get_string_status<M: Model>(c: *mut c_void, kind: c_int, _value: *mut *const c_char) -> c_int {
    with_instance::<M>(c, Call::GetStringStatus, |inst| {
        inst.check(Call::GetStringStatus)?;
        Err(unsupported_kind(Call::GetStringStatus, kind))
    })
}

/// `fmi2EnterEventMode`.
pub unsafe fn enter_event_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterEventMode, |inst| ok(inst.enter_event_mode()))
}

/// `fmi2NewDiscreteStates`: fills `*info`.
pub unsafe fn new_discrete_states<M: Model>(c: *mut c_void, info: *mut EventInfo) -> c_int {
    with_instance::<M>(c, Call::NewDiscreteStates, |inst| {
        if info.is_null() {
            inst.check(Call::NewDiscreteStates)?;
            return Err(Failure::error("fmi2NewDiscreteStates: eventInfo is NULL"));
        }
        let event = inst.new_discrete_states()?;
        *info = EventInfo {
            new_discrete_states_needed: event.new_discrete_states_needed as c_int,
            terminate_simulation: event.terminate_simulation as c_int,
            nominals_of_continuous_states_changed: event.nominals_of_continuous_states_changed as c_int,
            values_of_continuous_states_changed: event.values_of_continuous_states_changed as c_int,
            next_event_time_defined: event.next_event_time.is_some() as c_int,
            next_event_time: event.next_event_time.unwrap_or(0.0),
        };
        Ok(Status::Ok)
    })
}

/// `fmi2EnterContinuousTimeMode`.
pub unsafe fn enter_continuous_time_mode<M: Model>(c: *mut c_void) -> c_int {
    with_instance::<M>(c, Call::EnterContinuousTimeMode, |inst| ok(inst.enter_continuous_time_mode()))
}

/// `fmi2CompletedIntegratorStep`: fills `*enter_event_mode` and `*terminate_simulation`.
pub unsafe fn completed_integrator_step<M: Model>(
    c: *mut c_void,
    _no_set_prior: c_int,
    enter_event_mode: *mut c_int,
    terminate_simulation: *mut c_int,
) -> c_int {
    with_instance::<M>(c, Call::CompletedIntegratorStep, |inst| {
        if enter_event_mode.is_null() || terminate_simulation.is_null() {
            inst.check(Call::CompletedIntegratorStep)?;
            return Err(Failure::error("fmi2CompletedIntegratorStep: enterEventMode or terminateSimulation is NULL"));
        }
        let step = inst.completed_integrator_step()?;
        *enter_event_mode = step.enter_event_mode as c_int;
        *terminate_simulation = step.terminate_simulation as c_int;
        Ok(Status::Ok)
    })
}

/// The instance behind `c` when it is one of ours, for the hot paths below.
#[inline(always)]
unsafe fn instance_mut<'a, M: Model>(c: *mut c_void) -> Option<&'a mut Instance<M>> {
    let component = c as *mut Component<M>;
    if component.is_null() || (*component).magic != COMPONENT_MAGIC {
        None
    } else {
        Some(&mut (*component).instance)
    }
}

// fmi2SetTime, fmi2SetContinuousStates and fmi2GetDerivatives come once per evaluation of the
// derivatives, several times per solver step of the importer: their usual call is done in
// place and answers fmi2OK directly; anything else takes the general path (out of line, so the
// usual call does not set up its frame), which checks the call again and explains the refusal.
// fmi2SetTime and fmi2SetContinuousStates run no model code, so their usual call cannot unwind.

/// `fmi2SetTime`.
#[inline(always)]
pub unsafe fn set_time<M: Model>(c: *mut c_void, time: f64) -> c_int {
    if let Some(inst) = instance_mut::<M>(c) {
        if inst.try_set_time(time) {
            return Status::Ok as c_int;
        }
    }
    set_time_in_full::<M>(c, time)
}

#[cold]
#[inline(never)]
unsafe fn set_time_in_full<M: Model>(c: *mut c_void, time: f64) -> c_int {
    with_instance::<M>(c, Call::SetTime, |inst| ok(inst.set_time(time)))
}

/// `fmi2SetContinuousStates`.
#[inline(always)]
pub unsafe fn set_continuous_states<M: Model>(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
    if let Some(inst) = instance_mut::<M>(c) {
        if !x.is_null() && inst.try_set_continuous_states(std::slice::from_raw_parts(x, nx)) {
            return Status::Ok as c_int;
        }
    }
    set_continuous_states_in_full::<M>(c, x, nx)
}

#[cold]
#[inline(never)]
unsafe fn set_continuous_states_in_full<M: Model>(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
    with_instance::<M>(c, Call::SetContinuousStates, |inst| {
        let x = slice(x, nx, Call::SetContinuousStates, "x[]")?;
        ok(inst.set_continuous_states(x))
    })
}

/// `fmi2GetDerivatives`.
#[inline(always)]
pub unsafe fn get_derivatives<M: Model>(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
    if let Some(inst) = instance_mut::<M>(c) {
        if !dx.is_null() {
            let out = std::slice::from_raw_parts_mut(dx, nx);
            // The model's code runs: inside the unwinding guard.
            if let Ok(Some(true)) = catch_unwind(AssertUnwindSafe(|| inst.try_get_derivatives(out))) {
                return Status::Ok as c_int;
            }
        }
    }
    get_derivatives_in_full::<M>(c, dx, nx)
}

/// The general path of `fmi2GetDerivatives` (evaluates the derivatives again: a refusal
/// counts twice in `n_rhs`, the usual call once).
#[cold]
#[inline(never)]
unsafe fn get_derivatives_in_full<M: Model>(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
    with_instance::<M>(c, Call::GetDerivatives, |inst| {
        let dx = slice_mut(dx, nx, Call::GetDerivatives, "derivatives[]")?;
        inst.get_derivatives(dx)
    })
}

/// `fmi2GetEventIndicators`.
pub unsafe fn get_event_indicators<M: Model>(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
    with_instance::<M>(c, Call::GetEventIndicators, |inst| {
        let z = slice_mut(z, ni, Call::GetEventIndicators, "eventIndicators[]")?;
        ok(inst.get_event_indicators(z))
    })
}

/// `fmi2GetContinuousStates`.
pub unsafe fn get_continuous_states<M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    with_instance::<M>(c, Call::GetContinuousStates, |inst| {
        let x = slice_mut(x, nx, Call::GetContinuousStates, "x[]")?;
        ok(inst.get_continuous_states(x))
    })
}

/// `fmi2GetNominalsOfContinuousStates`.
pub unsafe fn get_nominals_of_continuous_states<M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    with_instance::<M>(c, Call::GetNominalsOfContinuousStates, |inst| {
        let x = slice_mut(x, nx, Call::GetNominalsOfContinuousStates, "x_nominal[]")?;
        ok(inst.get_nominals_of_continuous_states(x))
    })
}

/// Exports all 44 FMI 2.0 functions for `$model` (the 25 common ones, the 9 of Co-Simulation
/// and the 10 of Model Exchange: one binary serves both interfaces), plus
/// `fmu_model_description` and `fmu_documentation` (used by `runner build` to write the
/// `.fmu`'s XML and HTML from the compiled table), and all 75 FMI 3.0 functions with
/// `fmu3_model_description` (`export_fmi3!`: the names do not collide, so the same binary is
/// the FMI 3.0 FMU's). Invoke once per model crate.
#[macro_export]
macro_rules! export_fmu {
    ($model:ty) => {
        $crate::export_fmi3!($model);

        /// The C ABI of this FMU (generated by `fmu::export_fmu!`).
        #[allow(unsafe_code, non_snake_case, clippy::missing_safety_doc)]
        pub mod fmi2_exports {
            #[allow(unused_imports)]
            use super::*;
            use ::std::ffi::{c_char, c_int, c_uint, c_void};
            use $crate::fmi2::ffi as f;
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
                f::set_debug_logging::<M>(c, on, n, cats)
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
                f::free_instance::<M>(c)
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
                f::enter_initialization_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2ExitInitializationMode(c: *mut c_void) -> c_int {
                f::exit_initialization_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Terminate(c: *mut c_void) -> c_int {
                f::terminate::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2Reset(c: *mut c_void) -> c_int {
                f::reset::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetReal(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut f64) -> c_int {
                f::get_real::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetInteger(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut c_int) -> c_int {
                f::get_integer::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetBoolean(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut c_int) -> c_int {
                f::get_boolean::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetString(c: *mut c_void, vr: *const c_uint, n: usize, v: *mut *const c_char) -> c_int {
                f::get_string::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetReal(c: *mut c_void, vr: *const c_uint, n: usize, v: *const f64) -> c_int {
                f::set_real::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetInteger(c: *mut c_void, vr: *const c_uint, n: usize, v: *const c_int) -> c_int {
                f::set_integer::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetBoolean(c: *mut c_void, vr: *const c_uint, n: usize, v: *const c_int) -> c_int {
                f::set_boolean::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetString(c: *mut c_void, vr: *const c_uint, n: usize, v: *const *const c_char) -> c_int {
                f::set_string::<M>(c, vr, n, v)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetFMUstate(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                f::get_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetFMUstate(c: *mut c_void, s: *mut c_void) -> c_int {
                f::set_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2FreeFMUstate(c: *mut c_void, s: *mut *mut c_void) -> c_int {
                f::free_fmu_state::<M>(c, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializedFMUstateSize(c: *mut c_void, s: *mut c_void, size: *mut usize) -> c_int {
                f::serialized_fmu_state_size::<M>(c, s, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SerializeFMUstate(c: *mut c_void, s: *mut c_void, buf: *mut c_char, size: usize) -> c_int {
                f::serialize_fmu_state::<M>(c, s, buf, size)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DeSerializeFMUstate(
                c: *mut c_void,
                buf: *const c_char,
                size: usize,
                s: *mut *mut c_void,
            ) -> c_int {
                f::deserialize_fmu_state::<M>(c, buf, size, s)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDirectionalDerivative(
                c: *mut c_void,
                _u: *const c_uint,
                _nu: usize,
                _k: *const c_uint,
                _nk: usize,
                _dk: *const f64,
                _du: *mut f64,
            ) -> c_int {
                f::get_directional_derivative::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetRealInputDerivatives(
                c: *mut c_void,
                _vr: *const c_uint,
                _n: usize,
                _order: *const c_int,
                _v: *const f64,
            ) -> c_int {
                f::set_real_input_derivatives::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetRealOutputDerivatives(
                c: *mut c_void,
                _vr: *const c_uint,
                _n: usize,
                _order: *const c_int,
                _v: *mut f64,
            ) -> c_int {
                f::get_real_output_derivatives::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2DoStep(c: *mut c_void, t: f64, h: f64, no_set_prior: c_int) -> c_int {
                f::do_step::<M>(c, t, h, no_set_prior)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CancelStep(c: *mut c_void) -> c_int {
                f::cancel_step::<M>(c)
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
                f::enter_event_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2NewDiscreteStates(c: *mut c_void, info: *mut f::EventInfo) -> c_int {
                f::new_discrete_states::<M>(c, info)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2EnterContinuousTimeMode(c: *mut c_void) -> c_int {
                f::enter_continuous_time_mode::<M>(c)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2CompletedIntegratorStep(
                c: *mut c_void,
                no_set_prior: c_int,
                enter_event_mode: *mut c_int,
                terminate: *mut c_int,
            ) -> c_int {
                f::completed_integrator_step::<M>(c, no_set_prior, enter_event_mode, terminate)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetTime(c: *mut c_void, time: f64) -> c_int {
                f::set_time::<M>(c, time)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2SetContinuousStates(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
                f::set_continuous_states::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetDerivatives(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
                f::get_derivatives::<M>(c, dx, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetEventIndicators(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
                f::get_event_indicators::<M>(c, z, ni)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                f::get_continuous_states::<M>(c, x, nx)
            }
            #[no_mangle]
            pub unsafe extern "C" fn fmi2GetNominalsOfContinuousStates(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
                f::get_nominals_of_continuous_states::<M>(c, x, nx)
            }

            /// Writes this FMU's modelDescription.xml into `buf`; returns the size needed.
            #[no_mangle]
            pub unsafe extern "C" fn fmu_model_description(buf: *mut c_char, size: usize) -> usize {
                match ::std::panic::catch_unwind(|| $crate::fmi2::describe::model_description_xml::<M>()) {
                    Ok(Ok(xml)) => f::copy_out(&xml, buf, size),
                    _ => 0,
                }
            }
            /// Writes this FMU's documentation/index.html into `buf`; returns the size needed.
            #[no_mangle]
            pub unsafe extern "C" fn fmu_documentation(buf: *mut c_char, size: usize) -> usize {
                match ::std::panic::catch_unwind(|| $crate::documentation::index_html::<M>()) {
                    Ok(html) => f::copy_out(&html, buf, size),
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
