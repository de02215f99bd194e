//! FMI 2.0 (`fmi2TypesPlatform.h`, `fmi2FunctionTypes.h`): the C types with the "default"
//! types platform, status codes and the signature of every one of the 44 functions.

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

/// `fmi2Status`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(i32)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
    Pending = 5,
}

impl Status {
    /// The status for a C return value, `None` for a value the standard does not define.
    pub fn from_c(code: c_int) -> Option<Status> {
        Some(match code {
            0 => Status::Ok,
            1 => Status::Warning,
            2 => Status::Discard,
            3 => Status::Error,
            4 => Status::Fatal,
            5 => Status::Pending,
            _ => return None,
        })
    }

    /// The standard's name (`fmi2OK`, `fmi2Error`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "fmi2OK",
            Status::Warning => "fmi2Warning",
            Status::Discard => "fmi2Discard",
            Status::Error => "fmi2Error",
            Status::Fatal => "fmi2Fatal",
            Status::Pending => "fmi2Pending",
        }
    }
}

/// The standard's name of a C status value, also for values it does not define.
pub fn status_name(code: c_int) -> &'static str {
    Status::from_c(code).map_or("an unknown fmi2Status", Status::name)
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

/// The functions every FMI 2.0 FMU exports, whatever its interfaces.
pub const COMMON_FUNCTIONS: [&str; 25] = [
    "fmi2GetTypesPlatform",
    "fmi2GetVersion",
    "fmi2SetDebugLogging",
    "fmi2Instantiate",
    "fmi2FreeInstance",
    "fmi2SetupExperiment",
    "fmi2EnterInitializationMode",
    "fmi2ExitInitializationMode",
    "fmi2Terminate",
    "fmi2Reset",
    "fmi2GetReal",
    "fmi2GetInteger",
    "fmi2GetBoolean",
    "fmi2GetString",
    "fmi2SetReal",
    "fmi2SetInteger",
    "fmi2SetBoolean",
    "fmi2SetString",
    "fmi2GetFMUstate",
    "fmi2SetFMUstate",
    "fmi2FreeFMUstate",
    "fmi2SerializedFMUstateSize",
    "fmi2SerializeFMUstate",
    "fmi2DeSerializeFMUstate",
    "fmi2GetDirectionalDerivative",
];

/// The functions a Model Exchange FMU exports besides the common ones.
pub const MODEL_EXCHANGE_FUNCTIONS: [&str; 10] = [
    "fmi2EnterEventMode",
    "fmi2NewDiscreteStates",
    "fmi2EnterContinuousTimeMode",
    "fmi2CompletedIntegratorStep",
    "fmi2SetTime",
    "fmi2SetContinuousStates",
    "fmi2GetDerivatives",
    "fmi2GetEventIndicators",
    "fmi2GetContinuousStates",
    "fmi2GetNominalsOfContinuousStates",
];

/// The functions a Co-Simulation FMU exports besides the common ones.
pub const CO_SIMULATION_FUNCTIONS: [&str; 9] = [
    "fmi2SetRealInputDerivatives",
    "fmi2GetRealOutputDerivatives",
    "fmi2DoStep",
    "fmi2CancelStep",
    "fmi2GetStatus",
    "fmi2GetRealStatus",
    "fmi2GetIntegerStatus",
    "fmi2GetBooleanStatus",
    "fmi2GetStringStatus",
];

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
