//! FMI 1.0 (`fmiModelTypes.h`/`fmiPlatformTypes.h`, `fmiModelFunctions.h` for Model Exchange,
//! `fmiFunctions.h` for Co-Simulation): the C types, the event info, the callbacks (passed by
//! value, unlike FMI 2.0's), the signature of every function and (feature `symbols`) the table
//! of them a loaded binary exports ([`Functions`]). FMI 1.0 prefixes every exported name with
//! the modelIdentifier (`<id>_fmiDoStep`), so the table is resolved for one identifier.

use std::ffi::{c_char, c_int, c_uint, c_void};

/// `fmiComponent`: an FMU instance.
pub type Component = *mut c_void;
/// `fmiValueReference`.
pub type ValueReference = c_uint;
/// `fmiReal`.
pub type Real = f64;
/// `fmiInteger`.
pub type Integer = c_int;
/// `fmiBoolean`: a C `char` in FMI 1.0 (`fmiTrue` = 1, `fmiFalse` = 0).
pub type Boolean = c_char;
/// `fmiString`.
pub type FmiString = *const c_char;

/// `fmiTrue`.
pub const TRUE: Boolean = 1;
/// `fmiFalse`.
pub const FALSE: Boolean = 0;

/// The standard's name of a C status value (`fmiOK`, ...), also for values it does not define.
pub fn status_name(code: c_int) -> &'static str {
    crate::Status::from_c(code, crate::FmiVersion::Fmi1).map_or("an unknown fmiStatus", |s| s.name(crate::FmiVersion::Fmi1))
}

/// `fmiStatusKind` (Co-Simulation).
pub type StatusKind = c_int;
/// `fmiDoStepStatus`.
pub const DO_STEP_STATUS: StatusKind = 0;
/// `fmiPendingStatus`.
pub const PENDING_STATUS: StatusKind = 1;
/// `fmiLastSuccessfulTime`.
pub const LAST_SUCCESSFUL_TIME: StatusKind = 2;

/// `fmiCallbackLogger`: variadic, the message is a printf format; its first argument is the
/// FMU's own component (FMI 1.0 has no environment pointer for the importer).
pub type CallbackLogger = unsafe extern "C" fn(Component, FmiString, c_int, FmiString, FmiString, ...);
/// `fmiCallbackAllocateMemory`.
pub type CallbackAllocateMemory = unsafe extern "C" fn(usize, usize) -> *mut c_void;
/// `fmiCallbackFreeMemory`.
pub type CallbackFreeMemory = unsafe extern "C" fn(*mut c_void);
/// `fmiStepFinished` (Co-Simulation).
pub type StepFinished = unsafe extern "C" fn(Component, c_int);

/// `fmiCallbackFunctions` of Model Exchange (`fmiModelFunctions.h`).
#[repr(C)]
#[derive(Clone, Copy)]
pub struct ModelCallbacks {
    pub logger: Option<CallbackLogger>,
    pub allocate_memory: Option<CallbackAllocateMemory>,
    pub free_memory: Option<CallbackFreeMemory>,
}

/// `fmiCallbackFunctions` of Co-Simulation (`fmiFunctions.h`): the Model Exchange ones and
/// `stepFinished`.
#[repr(C)]
#[derive(Clone, Copy)]
pub struct SlaveCallbacks {
    pub logger: Option<CallbackLogger>,
    pub allocate_memory: Option<CallbackAllocateMemory>,
    pub free_memory: Option<CallbackFreeMemory>,
    pub step_finished: Option<StepFinished>,
}

/// `fmiEventInfo`, filled by `fmiInitialize` and `fmiEventUpdate` (Model Exchange).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EventInfo {
    pub iteration_converged: Boolean,
    pub state_value_references_changed: Boolean,
    pub state_values_changed: Boolean,
    pub terminate_simulation: Boolean,
    pub upcoming_time_event: Boolean,
    pub next_event_time: Real,
}

// Both interfaces.
pub type GetVersion = unsafe extern "C" fn() -> *const c_char;
pub type SetDebugLogging = unsafe extern "C" fn(Component, Boolean) -> c_int;
pub type GetReal = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Real) -> c_int;
pub type GetInteger = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Integer) -> c_int;
pub type GetBoolean = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Boolean) -> c_int;
pub type GetString = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut FmiString) -> c_int;
pub type SetReal = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Real) -> c_int;
pub type SetInteger = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer) -> c_int;
pub type SetBoolean = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Boolean) -> c_int;
pub type SetString = unsafe extern "C" fn(Component, *const ValueReference, usize, *const FmiString) -> c_int;

// Model Exchange.
pub type GetModelTypesPlatform = unsafe extern "C" fn() -> *const c_char;
pub type InstantiateModel = unsafe extern "C" fn(FmiString, FmiString, ModelCallbacks, Boolean) -> Component;
pub type FreeModelInstance = unsafe extern "C" fn(Component);
pub type SetTime = unsafe extern "C" fn(Component, Real) -> c_int;
pub type SetContinuousStates = unsafe extern "C" fn(Component, *const Real, usize) -> c_int;
pub type CompletedIntegratorStep = unsafe extern "C" fn(Component, *mut Boolean) -> c_int;
pub type Initialize = unsafe extern "C" fn(Component, Boolean, Real, *mut EventInfo) -> c_int;
pub type GetDerivatives = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetEventIndicators = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type EventUpdate = unsafe extern "C" fn(Component, Boolean, *mut EventInfo) -> c_int;
pub type GetContinuousStates = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetNominalContinuousStates = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetStateValueReferences = unsafe extern "C" fn(Component, *mut ValueReference, usize) -> c_int;
pub type Terminate = unsafe extern "C" fn(Component) -> c_int;

// Co-Simulation.
pub type GetTypesPlatform = unsafe extern "C" fn() -> *const c_char;
#[allow(clippy::type_complexity)]
pub type InstantiateSlave =
    unsafe extern "C" fn(FmiString, FmiString, FmiString, FmiString, Real, Boolean, Boolean, SlaveCallbacks, Boolean) -> Component;
pub type InitializeSlave = unsafe extern "C" fn(Component, Real, Boolean, Real) -> c_int;
pub type TerminateSlave = unsafe extern "C" fn(Component) -> c_int;
pub type ResetSlave = unsafe extern "C" fn(Component) -> c_int;
pub type FreeSlaveInstance = unsafe extern "C" fn(Component);
pub type SetRealInputDerivatives = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer, *const Real) -> c_int;
pub type GetRealOutputDerivatives = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer, *mut Real) -> c_int;
pub type CancelStep = unsafe extern "C" fn(Component) -> c_int;
pub type DoStep = unsafe extern "C" fn(Component, Real, Real, Boolean) -> c_int;
pub type GetStatus = unsafe extern "C" fn(Component, StatusKind, *mut c_int) -> c_int;
pub type GetRealStatus = unsafe extern "C" fn(Component, StatusKind, *mut Real) -> c_int;
pub type GetIntegerStatus = unsafe extern "C" fn(Component, StatusKind, *mut Integer) -> c_int;
pub type GetBooleanStatus = unsafe extern "C" fn(Component, StatusKind, *mut Boolean) -> c_int;
pub type GetStringStatus = unsafe extern "C" fn(Component, StatusKind, *mut FmiString) -> c_int;

crate::functions::functions! {
    /// The functions of both interfaces (each name after the `<modelIdentifier>_` prefix).
    COMMON_FUNCTIONS {
        get_version: GetVersion = "fmiGetVersion",
        set_debug_logging: SetDebugLogging = "fmiSetDebugLogging",
        get_real: GetReal = "fmiGetReal",
        get_integer: GetInteger = "fmiGetInteger",
        get_boolean: GetBoolean = "fmiGetBoolean",
        get_string: GetString = "fmiGetString",
        set_real: SetReal = "fmiSetReal",
        set_integer: SetInteger = "fmiSetInteger",
        set_boolean: SetBoolean = "fmiSetBoolean",
        set_string: SetString = "fmiSetString",
    }

    /// The functions a Model Exchange FMU exports besides the common ones.
    MODEL_EXCHANGE_FUNCTIONS {
        get_model_types_platform: GetModelTypesPlatform = "fmiGetModelTypesPlatform",
        instantiate_model: InstantiateModel = "fmiInstantiateModel",
        free_model_instance: FreeModelInstance = "fmiFreeModelInstance",
        set_time: SetTime = "fmiSetTime",
        set_continuous_states: SetContinuousStates = "fmiSetContinuousStates",
        completed_integrator_step: CompletedIntegratorStep = "fmiCompletedIntegratorStep",
        initialize: Initialize = "fmiInitialize",
        get_derivatives: GetDerivatives = "fmiGetDerivatives",
        get_event_indicators: GetEventIndicators = "fmiGetEventIndicators",
        event_update: EventUpdate = "fmiEventUpdate",
        get_continuous_states: GetContinuousStates = "fmiGetContinuousStates",
        get_nominal_continuous_states: GetNominalContinuousStates = "fmiGetNominalContinuousStates",
        get_state_value_references: GetStateValueReferences = "fmiGetStateValueReferences",
        terminate: Terminate = "fmiTerminate",
    }

    /// The functions a Co-Simulation FMU exports besides the common ones.
    CO_SIMULATION_FUNCTIONS {
        get_types_platform: GetTypesPlatform = "fmiGetTypesPlatform",
        instantiate_slave: InstantiateSlave = "fmiInstantiateSlave",
        initialize_slave: InitializeSlave = "fmiInitializeSlave",
        terminate_slave: TerminateSlave = "fmiTerminateSlave",
        reset_slave: ResetSlave = "fmiResetSlave",
        free_slave_instance: FreeSlaveInstance = "fmiFreeSlaveInstance",
        set_real_input_derivatives: SetRealInputDerivatives = "fmiSetRealInputDerivatives",
        get_real_output_derivatives: GetRealOutputDerivatives = "fmiGetRealOutputDerivatives",
        cancel_step: CancelStep = "fmiCancelStep",
        do_step: DoStep = "fmiDoStep",
        get_status: GetStatus = "fmiGetStatus",
        get_real_status: GetRealStatus = "fmiGetRealStatus",
        get_integer_status: GetIntegerStatus = "fmiGetIntegerStatus",
        get_boolean_status: GetBooleanStatus = "fmiGetBooleanStatus",
        get_string_status: GetStringStatus = "fmiGetStringStatus",
    }
}

#[cfg(feature = "logger-shim")]
extern "C" {
    /// The variadic `fmiCallbackLogger` of `logger.c`: formats the message with `vsnprintf`
    /// and hands the text, with the component, to the sink set by [`set_log_sink`].
    pub fn fmi_c_fmi1_logger(c: Component, instance: FmiString, status: c_int, category: FmiString, message: FmiString, ...);
    fn fmi_c_fmi1_set_sink(sink: LogSink);
}

/// Receives every formatted FMI 1.0 message: (component, instance name, status, category,
/// text). Must not unwind.
#[cfg(feature = "logger-shim")]
pub type LogSink = unsafe extern "C" fn(Component, FmiString, c_int, FmiString, FmiString);

/// Where the FMI 1.0 logger shim sends every message from now on (for the whole process: FMI
/// 1.0 gives the logger no pointer of the importer's, only the FMU's component and name).
#[cfg(feature = "logger-shim")]
pub fn set_log_sink(sink: LogSink) {
    // SAFETY: stores a function pointer.
    unsafe { fmi_c_fmi1_set_sink(sink) }
}

/// The shim as the `fmiCallbackLogger` to put in the callbacks.
#[cfg(feature = "logger-shim")]
pub fn logger_shim() -> CallbackLogger {
    fmi_c_fmi1_logger
}

#[cfg(feature = "logger-shim")]
impl ModelCallbacks {
    /// The callbacks an importer hands to `fmiInstantiateModel`: the logger shim and C's
    /// `calloc` and `free`.
    pub fn standard() -> ModelCallbacks {
        ModelCallbacks { logger: Some(logger_shim()), allocate_memory: Some(libc::calloc), free_memory: Some(libc::free) }
    }
}

#[cfg(feature = "logger-shim")]
impl SlaveCallbacks {
    /// The callbacks an importer hands to `fmiInstantiateSlave`: the logger shim, C's `calloc`
    /// and `free`, and no `stepFinished` (steps are never asynchronous).
    pub fn standard() -> SlaveCallbacks {
        SlaveCallbacks {
            logger: Some(logger_shim()),
            allocate_memory: Some(libc::calloc),
            free_memory: Some(libc::free),
            step_finished: None,
        }
    }
}
