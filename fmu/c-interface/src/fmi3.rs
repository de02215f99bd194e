//! FMI 3.0 (`fmi3PlatformTypes.h`, `fmi3FunctionTypes.h`): the C types, status codes, the
//! signature of every one of the 75 functions and (feature `symbols`) the table of them a loaded
//! binary exports ([`Functions`]).

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

pub use crate::Status;

/// The standard's name of a C status value (`fmi3OK`, ...), also for values it does not define.
pub fn status_name(code: c_int) -> &'static str {
    Status::from_c(code, crate::FmiVersion::Fmi3).map_or("an unknown fmi3Status", |s| s.name(crate::FmiVersion::Fmi3))
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

crate::functions::functions! {
    /// The functions common to every interface, as fmi3Functions.h lists them.
    COMMON_FUNCTIONS {
        get_version: GetVersion = "fmi3GetVersion",
        set_debug_logging: SetDebugLogging = "fmi3SetDebugLogging",
        instantiate_model_exchange: InstantiateModelExchange = "fmi3InstantiateModelExchange",
        instantiate_co_simulation: InstantiateCoSimulation = "fmi3InstantiateCoSimulation",
        instantiate_scheduled_execution: InstantiateScheduledExecution = "fmi3InstantiateScheduledExecution",
        free_instance: FreeInstance = "fmi3FreeInstance",
        enter_initialization_mode: EnterInitializationMode = "fmi3EnterInitializationMode",
        exit_initialization_mode: ExitInitializationMode = "fmi3ExitInitializationMode",
        enter_event_mode: EnterEventMode = "fmi3EnterEventMode",
        terminate: Terminate = "fmi3Terminate",
        reset: Reset = "fmi3Reset",
        get_float32: GetFloat32 = "fmi3GetFloat32",
        get_float64: GetFloat64 = "fmi3GetFloat64",
        get_int8: GetInt8 = "fmi3GetInt8",
        get_uint8: GetUInt8 = "fmi3GetUInt8",
        get_int16: GetInt16 = "fmi3GetInt16",
        get_uint16: GetUInt16 = "fmi3GetUInt16",
        get_int32: GetInt32 = "fmi3GetInt32",
        get_uint32: GetUInt32 = "fmi3GetUInt32",
        get_int64: GetInt64 = "fmi3GetInt64",
        get_uint64: GetUInt64 = "fmi3GetUInt64",
        get_boolean: GetBoolean = "fmi3GetBoolean",
        get_string: GetString = "fmi3GetString",
        get_binary: GetBinary = "fmi3GetBinary",
        get_clock: GetClock = "fmi3GetClock",
        set_float32: SetFloat32 = "fmi3SetFloat32",
        set_float64: SetFloat64 = "fmi3SetFloat64",
        set_int8: SetInt8 = "fmi3SetInt8",
        set_uint8: SetUInt8 = "fmi3SetUInt8",
        set_int16: SetInt16 = "fmi3SetInt16",
        set_uint16: SetUInt16 = "fmi3SetUInt16",
        set_int32: SetInt32 = "fmi3SetInt32",
        set_uint32: SetUInt32 = "fmi3SetUInt32",
        set_int64: SetInt64 = "fmi3SetInt64",
        set_uint64: SetUInt64 = "fmi3SetUInt64",
        set_boolean: SetBoolean = "fmi3SetBoolean",
        set_string: SetString = "fmi3SetString",
        set_binary: SetBinary = "fmi3SetBinary",
        set_clock: SetClock = "fmi3SetClock",
        get_number_of_variable_dependencies: GetNumberOfVariableDependencies = "fmi3GetNumberOfVariableDependencies",
        get_variable_dependencies: GetVariableDependencies = "fmi3GetVariableDependencies",
        get_fmu_state: GetFmuState = "fmi3GetFMUState",
        set_fmu_state: SetFmuState = "fmi3SetFMUState",
        free_fmu_state: FreeFmuState = "fmi3FreeFMUState",
        serialized_fmu_state_size: SerializedFmuStateSize = "fmi3SerializedFMUStateSize",
        serialize_fmu_state: SerializeFmuState = "fmi3SerializeFMUState",
        deserialize_fmu_state: DeserializeFmuState = "fmi3DeserializeFMUState",
        get_directional_derivative: GetDirectionalDerivative = "fmi3GetDirectionalDerivative",
        get_adjoint_derivative: GetAdjointDerivative = "fmi3GetAdjointDerivative",
        enter_configuration_mode: EnterConfigurationMode = "fmi3EnterConfigurationMode",
        exit_configuration_mode: ExitConfigurationMode = "fmi3ExitConfigurationMode",
        get_interval_decimal: GetIntervalDecimal = "fmi3GetIntervalDecimal",
        get_interval_fraction: GetIntervalFraction = "fmi3GetIntervalFraction",
        get_shift_decimal: GetShiftDecimal = "fmi3GetShiftDecimal",
        get_shift_fraction: GetShiftFraction = "fmi3GetShiftFraction",
        set_interval_decimal: SetIntervalDecimal = "fmi3SetIntervalDecimal",
        set_interval_fraction: SetIntervalFraction = "fmi3SetIntervalFraction",
        set_shift_decimal: SetShiftDecimal = "fmi3SetShiftDecimal",
        set_shift_fraction: SetShiftFraction = "fmi3SetShiftFraction",
        evaluate_discrete_states: EvaluateDiscreteStates = "fmi3EvaluateDiscreteStates",
        update_discrete_states: UpdateDiscreteStates = "fmi3UpdateDiscreteStates",
    }

    /// The Model Exchange functions.
    MODEL_EXCHANGE_FUNCTIONS {
        enter_continuous_time_mode: EnterContinuousTimeMode = "fmi3EnterContinuousTimeMode",
        completed_integrator_step: CompletedIntegratorStep = "fmi3CompletedIntegratorStep",
        set_time: SetTime = "fmi3SetTime",
        set_continuous_states: SetContinuousStates = "fmi3SetContinuousStates",
        get_continuous_state_derivatives: GetContinuousStateDerivatives = "fmi3GetContinuousStateDerivatives",
        get_event_indicators: GetEventIndicators = "fmi3GetEventIndicators",
        get_continuous_states: GetContinuousStates = "fmi3GetContinuousStates",
        get_nominals_of_continuous_states: GetNominalsOfContinuousStates = "fmi3GetNominalsOfContinuousStates",
        get_number_of_event_indicators: GetNumberOfEventIndicators = "fmi3GetNumberOfEventIndicators",
        get_number_of_continuous_states: GetNumberOfContinuousStates = "fmi3GetNumberOfContinuousStates",
    }

    /// The Co-Simulation functions.
    CO_SIMULATION_FUNCTIONS {
        enter_step_mode: EnterStepMode = "fmi3EnterStepMode",
        get_output_derivatives: GetOutputDerivatives = "fmi3GetOutputDerivatives",
        do_step: DoStep = "fmi3DoStep",
    }

    /// The Scheduled Execution functions.
    SCHEDULED_EXECUTION_FUNCTIONS {
        activate_model_partition: ActivateModelPartition = "fmi3ActivateModelPartition",
    }
}
