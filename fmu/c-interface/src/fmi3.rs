//! FMI 3.0 (`fmi3PlatformTypes.h`, `fmi3FunctionTypes.h`): the C types, status codes and the
//! signature of every one of the 75 functions.

use std::ffi::{c_char, c_int, c_void};

/// `fmi3Instance`.
pub type Instance = *mut c_void;
/// `fmi3InstanceEnvironment`: the importer's pointer, handed back to its callbacks.
pub type InstanceEnvironment = *mut c_void;
/// `fmi3FMUState`.
pub type FmuState = *mut c_void;
/// `fmi3ValueReference`.
pub type ValueReference = u32;
/// `fmi3Float32`.
pub type Float32 = f32;
/// `fmi3Float64`.
pub type Float64 = f64;
/// `fmi3Boolean` (C `bool`, one byte).
pub type Boolean = bool;
/// `fmi3Char`.
pub type Char = c_char;
/// `fmi3String`.
pub type FmiString = *const c_char;
/// `fmi3Byte`.
pub type Byte = u8;
/// `fmi3Binary`.
pub type Binary = *const u8;
/// `fmi3Clock` (C `bool`).
pub type Clock = bool;

/// `fmi3Status` (an enum, passed as a C int).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(i32)]
pub enum Status {
    Ok = 0,
    Warning = 1,
    Discard = 2,
    Error = 3,
    Fatal = 4,
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
            _ => return None,
        })
    }

    /// The standard's name (`fmi3OK`, `fmi3Error`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Status::Ok => "fmi3OK",
            Status::Warning => "fmi3Warning",
            Status::Discard => "fmi3Discard",
            Status::Error => "fmi3Error",
            Status::Fatal => "fmi3Fatal",
        }
    }
}

/// The standard's name of a C status value, also for values it does not define.
pub fn status_name(code: c_int) -> &'static str {
    Status::from_c(code).map_or("an unknown fmi3Status", Status::name)
}

/// `fmi3DependencyKind`.
pub type DependencyKind = c_int;
/// `fmi3IntervalQualifier`.
pub type IntervalQualifier = c_int;

/// `fmi3LogMessageCallback` (not variadic, unlike FMI 2.0's logger).
pub type LogMessageCallback = unsafe extern "C" fn(InstanceEnvironment, c_int, FmiString, FmiString);
/// `fmi3ClockUpdateCallback`.
pub type ClockUpdateCallback = unsafe extern "C" fn(InstanceEnvironment);
/// `fmi3IntermediateUpdateCallback`.
pub type IntermediateUpdateCallback =
    unsafe extern "C" fn(InstanceEnvironment, Float64, Boolean, Boolean, Boolean, Boolean, *mut Boolean, *mut Float64);
/// `fmi3LockPreemptionCallback`.
pub type LockPreemptionCallback = unsafe extern "C" fn();
/// `fmi3UnlockPreemptionCallback`.
pub type UnlockPreemptionCallback = unsafe extern "C" fn();

// The function types of fmi3FunctionTypes.h, in its order.

// Common functions.
pub type GetVersion = unsafe extern "C" fn() -> *const c_char;
pub type SetDebugLogging = unsafe extern "C" fn(Instance, Boolean, usize, *const FmiString) -> c_int;
pub type InstantiateModelExchange =
    unsafe extern "C" fn(FmiString, FmiString, FmiString, Boolean, Boolean, InstanceEnvironment, Option<LogMessageCallback>) -> Instance;
pub type InstantiateCoSimulation = unsafe extern "C" fn(
    FmiString,
    FmiString,
    FmiString,
    Boolean,
    Boolean,
    Boolean,
    Boolean,
    *const ValueReference,
    usize,
    InstanceEnvironment,
    Option<LogMessageCallback>,
    Option<IntermediateUpdateCallback>,
) -> Instance;
pub type InstantiateScheduledExecution = unsafe extern "C" fn(
    FmiString,
    FmiString,
    FmiString,
    Boolean,
    Boolean,
    InstanceEnvironment,
    Option<LogMessageCallback>,
    Option<ClockUpdateCallback>,
    Option<LockPreemptionCallback>,
    Option<UnlockPreemptionCallback>,
) -> Instance;
pub type FreeInstance = unsafe extern "C" fn(Instance);
pub type EnterInitializationMode = unsafe extern "C" fn(Instance, Boolean, Float64, Float64, Boolean, Float64) -> c_int;
pub type ExitInitializationMode = unsafe extern "C" fn(Instance) -> c_int;
pub type EnterEventMode = unsafe extern "C" fn(Instance) -> c_int;
pub type Terminate = unsafe extern "C" fn(Instance) -> c_int;
pub type Reset = unsafe extern "C" fn(Instance) -> c_int;

// Getters: (instance, valueReferences, nValueReferences, values, nValues).
pub type GetFloat32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut f32, usize) -> c_int;
pub type GetFloat64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut f64, usize) -> c_int;
pub type GetInt8 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut i8, usize) -> c_int;
pub type GetUInt8 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u8, usize) -> c_int;
pub type GetInt16 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut i16, usize) -> c_int;
pub type GetUInt16 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u16, usize) -> c_int;
pub type GetInt32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut i32, usize) -> c_int;
pub type GetUInt32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u32, usize) -> c_int;
pub type GetInt64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut i64, usize) -> c_int;
pub type GetUInt64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u64, usize) -> c_int;
pub type GetBoolean = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut Boolean, usize) -> c_int;
pub type GetString = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut FmiString, usize) -> c_int;
pub type GetBinary = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut usize, *mut Binary, usize) -> c_int;
pub type GetClock = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut Clock) -> c_int;
// Setters.
pub type SetFloat32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const f32, usize) -> c_int;
pub type SetFloat64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const f64, usize) -> c_int;
pub type SetInt8 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const i8, usize) -> c_int;
pub type SetUInt8 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u8, usize) -> c_int;
pub type SetInt16 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const i16, usize) -> c_int;
pub type SetUInt16 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u16, usize) -> c_int;
pub type SetInt32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const i32, usize) -> c_int;
pub type SetUInt32 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u32, usize) -> c_int;
pub type SetInt64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const i64, usize) -> c_int;
pub type SetUInt64 = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u64, usize) -> c_int;
pub type SetBoolean = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const Boolean, usize) -> c_int;
pub type SetString = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const FmiString, usize) -> c_int;
pub type SetBinary = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const usize, *const Binary, usize) -> c_int;
pub type SetClock = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const Clock) -> c_int;
// Dependencies, FMU state, derivatives.
pub type GetNumberOfVariableDependencies = unsafe extern "C" fn(Instance, ValueReference, *mut usize) -> c_int;
pub type GetVariableDependencies =
    unsafe extern "C" fn(Instance, ValueReference, *mut usize, *mut ValueReference, *mut usize, *mut DependencyKind, usize) -> c_int;
pub type GetFmuState = unsafe extern "C" fn(Instance, *mut FmuState) -> c_int;
pub type SetFmuState = unsafe extern "C" fn(Instance, FmuState) -> c_int;
pub type FreeFmuState = unsafe extern "C" fn(Instance, *mut FmuState) -> c_int;
pub type SerializedFmuStateSize = unsafe extern "C" fn(Instance, FmuState, *mut usize) -> c_int;
pub type SerializeFmuState = unsafe extern "C" fn(Instance, FmuState, *mut Byte, usize) -> c_int;
pub type DeserializeFmuState = unsafe extern "C" fn(Instance, *const Byte, usize, *mut FmuState) -> c_int;
pub type GetDirectionalDerivative = unsafe extern "C" fn(
    Instance,
    *const ValueReference,
    usize,
    *const ValueReference,
    usize,
    *const Float64,
    usize,
    *mut Float64,
    usize,
) -> c_int;
pub type GetAdjointDerivative = unsafe extern "C" fn(
    Instance,
    *const ValueReference,
    usize,
    *const ValueReference,
    usize,
    *const Float64,
    usize,
    *mut Float64,
    usize,
) -> c_int;
// Configuration mode and clocks.
pub type EnterConfigurationMode = unsafe extern "C" fn(Instance) -> c_int;
pub type ExitConfigurationMode = unsafe extern "C" fn(Instance) -> c_int;
pub type GetIntervalDecimal = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut Float64, *mut IntervalQualifier) -> c_int;
pub type GetIntervalFraction =
    unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u64, *mut u64, *mut IntervalQualifier) -> c_int;
pub type GetShiftDecimal = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut Float64) -> c_int;
pub type GetShiftFraction = unsafe extern "C" fn(Instance, *const ValueReference, usize, *mut u64, *mut u64) -> c_int;
pub type SetIntervalDecimal = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const Float64) -> c_int;
pub type SetIntervalFraction = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u64, *const u64) -> c_int;
pub type SetShiftDecimal = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const Float64) -> c_int;
pub type SetShiftFraction = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const u64, *const u64) -> c_int;
pub type EvaluateDiscreteStates = unsafe extern "C" fn(Instance) -> c_int;
pub type UpdateDiscreteStates =
    unsafe extern "C" fn(Instance, *mut Boolean, *mut Boolean, *mut Boolean, *mut Boolean, *mut Boolean, *mut Float64) -> c_int;

// Model Exchange.
pub type EnterContinuousTimeMode = unsafe extern "C" fn(Instance) -> c_int;
pub type CompletedIntegratorStep = unsafe extern "C" fn(Instance, Boolean, *mut Boolean, *mut Boolean) -> c_int;
pub type SetTime = unsafe extern "C" fn(Instance, Float64) -> c_int;
pub type SetContinuousStates = unsafe extern "C" fn(Instance, *const Float64, usize) -> c_int;
pub type GetContinuousStateDerivatives = unsafe extern "C" fn(Instance, *mut Float64, usize) -> c_int;
pub type GetEventIndicators = unsafe extern "C" fn(Instance, *mut Float64, usize) -> c_int;
pub type GetContinuousStates = unsafe extern "C" fn(Instance, *mut Float64, usize) -> c_int;
pub type GetNominalsOfContinuousStates = unsafe extern "C" fn(Instance, *mut Float64, usize) -> c_int;
pub type GetNumberOfEventIndicators = unsafe extern "C" fn(Instance, *mut usize) -> c_int;
pub type GetNumberOfContinuousStates = unsafe extern "C" fn(Instance, *mut usize) -> c_int;

// Co-Simulation.
pub type EnterStepMode = unsafe extern "C" fn(Instance) -> c_int;
pub type GetOutputDerivatives = unsafe extern "C" fn(Instance, *const ValueReference, usize, *const i32, *mut Float64, usize) -> c_int;
pub type DoStep =
    unsafe extern "C" fn(Instance, Float64, Float64, Boolean, *mut Boolean, *mut Boolean, *mut Boolean, *mut Float64) -> c_int;

// Scheduled Execution.
pub type ActivateModelPartition = unsafe extern "C" fn(Instance, ValueReference, Float64) -> c_int;

/// The functions common to every interface, as fmi3Functions.h lists them.
pub const COMMON_FUNCTIONS: [&str; 61] = [
    "fmi3GetVersion",
    "fmi3SetDebugLogging",
    "fmi3InstantiateModelExchange",
    "fmi3InstantiateCoSimulation",
    "fmi3InstantiateScheduledExecution",
    "fmi3FreeInstance",
    "fmi3EnterInitializationMode",
    "fmi3ExitInitializationMode",
    "fmi3EnterEventMode",
    "fmi3Terminate",
    "fmi3Reset",
    "fmi3GetFloat32",
    "fmi3GetFloat64",
    "fmi3GetInt8",
    "fmi3GetUInt8",
    "fmi3GetInt16",
    "fmi3GetUInt16",
    "fmi3GetInt32",
    "fmi3GetUInt32",
    "fmi3GetInt64",
    "fmi3GetUInt64",
    "fmi3GetBoolean",
    "fmi3GetString",
    "fmi3GetBinary",
    "fmi3GetClock",
    "fmi3SetFloat32",
    "fmi3SetFloat64",
    "fmi3SetInt8",
    "fmi3SetUInt8",
    "fmi3SetInt16",
    "fmi3SetUInt16",
    "fmi3SetInt32",
    "fmi3SetUInt32",
    "fmi3SetInt64",
    "fmi3SetUInt64",
    "fmi3SetBoolean",
    "fmi3SetString",
    "fmi3SetBinary",
    "fmi3SetClock",
    "fmi3GetNumberOfVariableDependencies",
    "fmi3GetVariableDependencies",
    "fmi3GetFMUState",
    "fmi3SetFMUState",
    "fmi3FreeFMUState",
    "fmi3SerializedFMUStateSize",
    "fmi3SerializeFMUState",
    "fmi3DeserializeFMUState",
    "fmi3GetDirectionalDerivative",
    "fmi3GetAdjointDerivative",
    "fmi3EnterConfigurationMode",
    "fmi3ExitConfigurationMode",
    "fmi3GetIntervalDecimal",
    "fmi3GetIntervalFraction",
    "fmi3GetShiftDecimal",
    "fmi3GetShiftFraction",
    "fmi3SetIntervalDecimal",
    "fmi3SetIntervalFraction",
    "fmi3SetShiftDecimal",
    "fmi3SetShiftFraction",
    "fmi3EvaluateDiscreteStates",
    "fmi3UpdateDiscreteStates",
];

/// The Model Exchange functions.
pub const MODEL_EXCHANGE_FUNCTIONS: [&str; 10] = [
    "fmi3EnterContinuousTimeMode",
    "fmi3CompletedIntegratorStep",
    "fmi3SetTime",
    "fmi3SetContinuousStates",
    "fmi3GetContinuousStateDerivatives",
    "fmi3GetEventIndicators",
    "fmi3GetContinuousStates",
    "fmi3GetNominalsOfContinuousStates",
    "fmi3GetNumberOfEventIndicators",
    "fmi3GetNumberOfContinuousStates",
];

/// The Co-Simulation functions.
pub const CO_SIMULATION_FUNCTIONS: [&str; 3] = ["fmi3EnterStepMode", "fmi3GetOutputDerivatives", "fmi3DoStep"];

/// The Scheduled Execution functions.
pub const SCHEDULED_EXECUTION_FUNCTIONS: [&str; 1] = ["fmi3ActivateModelPartition"];
