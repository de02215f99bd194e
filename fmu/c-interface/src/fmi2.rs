//! FMI 2.0 (`fmi2TypesPlatform.h`, `fmi2FunctionTypes.h`): the C types with the "default"
//! types platform, status codes, the signature of every one of the 44 functions and (feature
//! `symbols`) the table of them a loaded binary exports ([`Functions`]).

use std::ffi::{c_char, c_int, c_uint, c_void};

/// `fmi2Component`: an FMU instance.
pub type Component = *mut c_void;
/// `fmi2ComponentEnvironment`: the importer's pointer, handed back to its callbacks.
pub type ComponentEnvironment = *mut c_void;
/// `fmi2FMUstate`: a captured FMU state.
pub type FmuState = *mut c_void;
/// `fmi2ValueReference`.
pub type ValueReference = c_uint;
/// `fmi2Real`.
pub type Real = f64;
/// `fmi2Integer`.
pub type Integer = c_int;
/// `fmi2Boolean` (`fmi2True` = 1, `fmi2False` = 0).
pub type Boolean = c_int;
/// `fmi2String`.
pub type FmiString = *const c_char;
/// `fmi2Byte`.
pub type Byte = c_char;

/// `fmi2True`.
pub const TRUE: Boolean = 1;
/// `fmi2False`.
pub const FALSE: Boolean = 0;

pub use crate::Status;

/// The standard's name of a C status value (`fmi2OK`, ...), also for values it does not define.
pub fn status_name(code: c_int) -> &'static str {
    Status::from_c(code, crate::FmiVersion::Fmi2).map_or("an unknown fmi2Status", |s| s.name(crate::FmiVersion::Fmi2))
}

/// `fmi2Type`: the interface an instance is created for.
pub type Type = c_int;
/// `fmi2ModelExchange`.
pub const MODEL_EXCHANGE: Type = 0;
/// `fmi2CoSimulation`.
pub const CO_SIMULATION: Type = 1;

/// `fmi2StatusKind`.
pub type StatusKind = c_int;
/// `fmi2DoStepStatus`.
pub const DO_STEP_STATUS: StatusKind = 0;
/// `fmi2PendingStatus`.
pub const PENDING_STATUS: StatusKind = 1;
/// `fmi2LastSuccessfulTime`.
pub const LAST_SUCCESSFUL_TIME: StatusKind = 2;
/// `fmi2Terminated`.
pub const TERMINATED: StatusKind = 3;

/// `fmi2CallbackLogger`: variadic, the message is a printf format.
pub type CallbackLogger = unsafe extern "C" fn(ComponentEnvironment, FmiString, c_int, FmiString, FmiString, ...);
/// `fmi2CallbackAllocateMemory`.
pub type CallbackAllocateMemory = unsafe extern "C" fn(usize, usize) -> *mut c_void;
/// `fmi2CallbackFreeMemory`.
pub type CallbackFreeMemory = unsafe extern "C" fn(*mut c_void);
/// `fmi2StepFinished`.
pub type StepFinished = unsafe extern "C" fn(ComponentEnvironment, c_int);

/// `fmi2CallbackFunctions`.
#[repr(C)]
pub struct CallbackFunctions {
    pub logger: Option<CallbackLogger>,
    pub allocate_memory: Option<CallbackAllocateMemory>,
    pub free_memory: Option<CallbackFreeMemory>,
    pub step_finished: Option<StepFinished>,
    pub component_environment: ComponentEnvironment,
}

/// `fmi2EventInfo`, filled by `fmi2NewDiscreteStates` (Model Exchange).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EventInfo {
    pub new_discrete_states_needed: Boolean,
    pub terminate_simulation: Boolean,
    pub nominals_of_continuous_states_changed: Boolean,
    pub values_of_continuous_states_changed: Boolean,
    pub next_event_time_defined: Boolean,
    pub next_event_time: Real,
}

// The function types of fmi2FunctionTypes.h, in its order.

// Common to both interfaces.
pub type GetTypesPlatform = unsafe extern "C" fn() -> *const c_char;
pub type GetVersion = unsafe extern "C" fn() -> *const c_char;
pub type SetDebugLogging = unsafe extern "C" fn(Component, Boolean, usize, *const FmiString) -> c_int;
pub type Instantiate = unsafe extern "C" fn(FmiString, Type, FmiString, FmiString, *const CallbackFunctions, Boolean, Boolean) -> Component;
pub type FreeInstance = unsafe extern "C" fn(Component);
pub type SetupExperiment = unsafe extern "C" fn(Component, Boolean, Real, Real, Boolean, Real) -> c_int;
pub type EnterInitializationMode = unsafe extern "C" fn(Component) -> c_int;
pub type ExitInitializationMode = unsafe extern "C" fn(Component) -> c_int;
pub type Terminate = unsafe extern "C" fn(Component) -> c_int;
pub type Reset = unsafe extern "C" fn(Component) -> c_int;
pub type GetReal = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Real) -> c_int;
pub type GetInteger = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Integer) -> c_int;
pub type GetBoolean = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut Boolean) -> c_int;
pub type GetString = unsafe extern "C" fn(Component, *const ValueReference, usize, *mut FmiString) -> c_int;
pub type SetReal = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Real) -> c_int;
pub type SetInteger = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer) -> c_int;
pub type SetBoolean = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Boolean) -> c_int;
pub type SetString = unsafe extern "C" fn(Component, *const ValueReference, usize, *const FmiString) -> c_int;
pub type GetFmuState = unsafe extern "C" fn(Component, *mut FmuState) -> c_int;
pub type SetFmuState = unsafe extern "C" fn(Component, FmuState) -> c_int;
pub type FreeFmuState = unsafe extern "C" fn(Component, *mut FmuState) -> c_int;
pub type SerializedFmuStateSize = unsafe extern "C" fn(Component, FmuState, *mut usize) -> c_int;
pub type SerializeFmuState = unsafe extern "C" fn(Component, FmuState, *mut Byte, usize) -> c_int;
pub type DeSerializeFmuState = unsafe extern "C" fn(Component, *const Byte, usize, *mut FmuState) -> c_int;
pub type GetDirectionalDerivative =
    unsafe extern "C" fn(Component, *const ValueReference, usize, *const ValueReference, usize, *const Real, *mut Real) -> c_int;

// Model Exchange.
pub type EnterEventMode = unsafe extern "C" fn(Component) -> c_int;
pub type NewDiscreteStates = unsafe extern "C" fn(Component, *mut EventInfo) -> c_int;
pub type EnterContinuousTimeMode = unsafe extern "C" fn(Component) -> c_int;
pub type CompletedIntegratorStep = unsafe extern "C" fn(Component, Boolean, *mut Boolean, *mut Boolean) -> c_int;
pub type SetTime = unsafe extern "C" fn(Component, Real) -> c_int;
pub type SetContinuousStates = unsafe extern "C" fn(Component, *const Real, usize) -> c_int;
pub type GetDerivatives = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetEventIndicators = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetContinuousStates = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;
pub type GetNominalsOfContinuousStates = unsafe extern "C" fn(Component, *mut Real, usize) -> c_int;

// Co-Simulation.
pub type SetRealInputDerivatives = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer, *const Real) -> c_int;
pub type GetRealOutputDerivatives = unsafe extern "C" fn(Component, *const ValueReference, usize, *const Integer, *mut Real) -> c_int;
pub type DoStep = unsafe extern "C" fn(Component, Real, Real, Boolean) -> c_int;
pub type CancelStep = unsafe extern "C" fn(Component) -> c_int;
pub type GetStatus = unsafe extern "C" fn(Component, StatusKind, *mut c_int) -> c_int;
pub type GetRealStatus = unsafe extern "C" fn(Component, StatusKind, *mut Real) -> c_int;
pub type GetIntegerStatus = unsafe extern "C" fn(Component, StatusKind, *mut Integer) -> c_int;
pub type GetBooleanStatus = unsafe extern "C" fn(Component, StatusKind, *mut Boolean) -> c_int;
pub type GetStringStatus = unsafe extern "C" fn(Component, StatusKind, *mut FmiString) -> c_int;

crate::functions::functions! {
    /// The functions every FMI 2.0 FMU exports, whatever its interfaces.
    COMMON_FUNCTIONS {
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
    }

    /// The functions a Model Exchange FMU exports besides the common ones.
    MODEL_EXCHANGE_FUNCTIONS {
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
    }

    /// The functions a Co-Simulation FMU exports besides the common ones.
    CO_SIMULATION_FUNCTIONS {
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
}

/// What the logger shim's `componentEnvironment` points at: the plain callback that receives
/// each formatted message, and the importer's context handed to it.
#[cfg(feature = "logger-shim")]
#[repr(C)]
pub struct LogForwarder {
    /// Receives (context, instance name, status, category, formatted text); must not unwind.
    pub forward: unsafe extern "C" fn(*mut c_void, FmiString, c_int, FmiString, FmiString),
    /// Passed to `forward` as its first argument.
    pub context: *mut c_void,
}

#[cfg(feature = "logger-shim")]
extern "C" {
    /// The variadic `fmi2CallbackLogger` of `logger.c`: formats the message with `vsnprintf`
    /// and hands the text to the [`LogForwarder`] its environment points at.
    pub fn fmi_c_fmi2_logger(env: ComponentEnvironment, instance: FmiString, status: c_int, category: FmiString, message: FmiString, ...);
}

/// The shim as the `fmi2CallbackLogger` to put in [`CallbackFunctions`]; its
/// `component_environment` must point at a [`LogForwarder`].
#[cfg(feature = "logger-shim")]
pub fn logger_shim() -> CallbackLogger {
    fmi_c_fmi2_logger
}

#[cfg(feature = "logger-shim")]
impl CallbackFunctions {
    /// The callbacks an importer hands to `fmi2Instantiate`: the logger shim, whose messages
    /// reach `forwarder` (which must outlive the instance), C's `calloc` and `free`, and no
    /// `stepFinished` (steps are never asynchronous).
    pub fn forwarding_to(forwarder: &LogForwarder) -> CallbackFunctions {
        CallbackFunctions {
            logger: Some(logger_shim()),
            allocate_memory: Some(libc::calloc),
            free_memory: Some(libc::free),
            step_finished: None,
            component_environment: forwarder as *const LogForwarder as *mut c_void,
        }
    }
}
