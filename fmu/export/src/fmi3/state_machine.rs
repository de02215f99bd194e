//! The FMI 3.0 state machines of the two interfaces this toolkit offers: Co-Simulation (FMI
//! 3.0.2, section 4.3) and Model Exchange (section 3.3). As for FMI 2.0, one table over the
//! union of their states decides which call is allowed when; a Co-Simulation instance never
//! enters Continuous-Time Mode and a Model Exchange instance never Step Mode, and a call of the
//! other interface is refused whatever the state. Configuration Mode, Clock Activation Mode and
//! Intermediate Update Mode are never entered (no structural parameters, no clocks, no
//! intermediate-update callback is used), so they are not states here.

use serde::{Deserialize, Serialize};

pub use crate::frontend::{Call, Interface};
use crate::frontend::{MachineState, Row};

/// States of an instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FmiState {
    Instantiated,
    InitializationMode,
    /// Discrete-time equations active, time stands still: Model Exchange after initialization
    /// and at each event; Co-Simulation with `eventModeUsed` likewise.
    EventMode,
    /// Model Exchange: the importer integrates the continuous states.
    ContinuousTimeMode,
    /// Co-Simulation: the FMU steps with `fmi3DoStep`.
    StepMode,
    Terminated,
    Error,
    Fatal,
}

impl MachineState for FmiState {
    fn name(self) -> &'static str {
        match self {
            FmiState::Instantiated => "Instantiated",
            FmiState::InitializationMode => "Initialization Mode",
            FmiState::EventMode => "Event Mode",
            FmiState::ContinuousTimeMode => "Continuous-Time Mode",
            FmiState::StepMode => "Step Mode",
            FmiState::Terminated => "Terminated",
            FmiState::Error => "Error",
            FmiState::Fatal => "Fatal",
        }
    }

    fn interface(self) -> Option<Interface> {
        match self {
            FmiState::StepMode => Some(Interface::CoSimulation),
            FmiState::ContinuousTimeMode => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    #[inline(always)]
    fn bit(self) -> u16 {
        bit(self)
    }
}

/// The bit of `state` in the table's rows.
const fn bit(state: FmiState) -> u16 {
    1 << (state as u16)
}

const I: u16 = bit(FmiState::Instantiated);
const INIT: u16 = bit(FmiState::InitializationMode);
const EVENT: u16 = bit(FmiState::EventMode);
const CT: u16 = bit(FmiState::ContinuousTimeMode);
const STEP: u16 = bit(FmiState::StepMode);
const TERM: u16 = bit(FmiState::Terminated);
const ERR: u16 = bit(FmiState::Error);
/// Every state but Fatal: after a fatal error nothing but freeing is meaningful.
const ALIVE: u16 = I | INIT | EVENT | CT | STEP | TERM | ERR;
/// Where values may be read (and the Model Exchange evaluations made).
const READABLE: u16 = INIT | EVENT | CT | STEP | TERM | ERR;

const ANY: Option<Interface> = None;
const CS: Option<Interface> = Some(Interface::CoSimulation);
const ME: Option<Interface> = Some(Interface::ModelExchange);

/// Why `fmi3GetNumberOfVariableDependencies` and `fmi3GetVariableDependencies` refuse.
const NO_DEPENDENCY_FUNCTIONS: &str =
    "this FMU does not provide per-element dependencies (providesPerElementDependencies=\"false\"): its ModelStructure in modelDescription.xml lists the dependencies of its scalar variables";
/// Why the getters and setters of the types no variable has refuse.
const NO_SUCH_TYPE: &str = "this FMU has no variables of this type (its variables are Float64, Int32, Boolean or String)";
/// Why Configuration Mode is refused.
const NO_CONFIGURATION: &str = "this FMU has no structural parameters, so there is no Configuration Mode to enter or leave";
/// Why the clock functions refuse.
const NO_CLOCKS: &str = "this FMU has no clocks";

/// FMI 3.0's table: each call's C name, interface, the states that allow it (both interfaces'
/// tables in one), and why these FMUs refuse the ones they do not serve. A call allowed here
/// may still be refused for what it asks (a fixed parameter after initialization): the front
/// end decides that.
#[inline(always)]
pub fn row(call: Call) -> Row {
    use Call::*;
    match call {
        SetDebugLogging => Row::serves("fmi3SetDebugLogging", ANY, ALIVE),
        FreeInstance => Row::serves("fmi3FreeInstance", ANY, ALIVE),
        EnterInitializationMode => Row::serves("fmi3EnterInitializationMode", ANY, I),
        ExitInitializationMode => Row::serves("fmi3ExitInitializationMode", ANY, INIT),
        // Model Exchange from Continuous-Time Mode; Co-Simulation from Step Mode (with
        // eventModeUsed, which the front end checks).
        EnterEventMode => Row::serves("fmi3EnterEventMode", ANY, CT | STEP),
        Terminate => Row::serves("fmi3Terminate", ANY, EVENT | CT | STEP),
        Reset => Row::serves("fmi3Reset", ANY, ALIVE),
        GetReal => Row::serves("fmi3GetFloat64", ANY, READABLE),
        GetInteger => Row::serves("fmi3GetInt32", ANY, READABLE),
        GetBoolean => Row::serves("fmi3GetBoolean", ANY, READABLE),
        GetString => Row::serves("fmi3GetString", ANY, READABLE),
        GetFloat32 => Row::refuses("fmi3GetFloat32", ANY, READABLE, NO_SUCH_TYPE),
        GetInt8 => Row::refuses("fmi3GetInt8", ANY, READABLE, NO_SUCH_TYPE),
        GetUInt8 => Row::refuses("fmi3GetUInt8", ANY, READABLE, NO_SUCH_TYPE),
        GetInt16 => Row::refuses("fmi3GetInt16", ANY, READABLE, NO_SUCH_TYPE),
        GetUInt16 => Row::refuses("fmi3GetUInt16", ANY, READABLE, NO_SUCH_TYPE),
        GetUInt32 => Row::refuses("fmi3GetUInt32", ANY, READABLE, NO_SUCH_TYPE),
        GetInt64 => Row::refuses("fmi3GetInt64", ANY, READABLE, NO_SUCH_TYPE),
        GetUInt64 => Row::refuses("fmi3GetUInt64", ANY, READABLE, NO_SUCH_TYPE),
        GetBinary => Row::refuses("fmi3GetBinary", ANY, READABLE, NO_SUCH_TYPE),
        // In Continuous-Time Mode only continuous-time inputs may be set, which are Float64.
        SetReal => Row::serves("fmi3SetFloat64", ANY, I | INIT | EVENT | CT | STEP),
        SetFloat32 => Row::refuses("fmi3SetFloat32", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetInt8 => Row::refuses("fmi3SetInt8", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetUInt8 => Row::refuses("fmi3SetUInt8", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetInt16 => Row::refuses("fmi3SetInt16", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetUInt16 => Row::refuses("fmi3SetUInt16", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetUInt32 => Row::refuses("fmi3SetUInt32", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetInt64 => Row::refuses("fmi3SetInt64", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetUInt64 => Row::refuses("fmi3SetUInt64", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetBinary => Row::refuses("fmi3SetBinary", ANY, I | INIT | EVENT | CT | STEP, NO_SUCH_TYPE),
        SetInteger => Row::serves("fmi3SetInt32", ANY, I | INIT | EVENT | STEP),
        SetBoolean => Row::serves("fmi3SetBoolean", ANY, I | INIT | EVENT | STEP),
        SetString => Row::serves("fmi3SetString", ANY, I | INIT | EVENT | STEP),
        GetNumberOfVariableDependencies => Row::refuses("fmi3GetNumberOfVariableDependencies", ANY, READABLE, NO_DEPENDENCY_FUNCTIONS),
        GetVariableDependencies => Row::refuses("fmi3GetVariableDependencies", ANY, READABLE, NO_DEPENDENCY_FUNCTIONS),
        GetFMUState => Row::serves("fmi3GetFMUState", ANY, ALIVE),
        SetFMUState => Row::serves("fmi3SetFMUState", ANY, ALIVE),
        FreeFMUState => Row::serves("fmi3FreeFMUState", ANY, ALIVE),
        SerializedFMUStateSize => Row::serves("fmi3SerializedFMUStateSize", ANY, ALIVE),
        SerializeFMUState => Row::serves("fmi3SerializeFMUState", ANY, ALIVE),
        DeserializeFMUState => Row::serves("fmi3DeserializeFMUState", ANY, ALIVE),
        GetDirectionalDerivative => Row::serves("fmi3GetDirectionalDerivative", ANY, INIT | EVENT | CT | STEP | TERM | ERR),
        GetAdjointDerivative => Row::serves("fmi3GetAdjointDerivative", ANY, INIT | EVENT | CT | STEP | TERM | ERR),
        EnterConfigurationMode => Row::refuses("fmi3EnterConfigurationMode", ANY, I | STEP, NO_CONFIGURATION),
        // Only allowed in Configuration Mode, which an FMU without structural parameters
        // never enters.
        ExitConfigurationMode => Row::refuses("fmi3ExitConfigurationMode", ANY, 0, NO_CONFIGURATION),
        GetClock => Row::refuses("fmi3GetClock", ANY, EVENT, NO_CLOCKS),
        SetClock => Row::refuses("fmi3SetClock", ANY, EVENT, NO_CLOCKS),
        GetIntervalDecimal => Row::refuses("fmi3GetIntervalDecimal", ANY, EVENT, NO_CLOCKS),
        GetIntervalFraction => Row::refuses("fmi3GetIntervalFraction", ANY, EVENT, NO_CLOCKS),
        GetShiftDecimal => Row::refuses("fmi3GetShiftDecimal", ANY, EVENT, NO_CLOCKS),
        GetShiftFraction => Row::refuses("fmi3GetShiftFraction", ANY, EVENT, NO_CLOCKS),
        SetIntervalDecimal => Row::refuses("fmi3SetIntervalDecimal", ANY, EVENT, NO_CLOCKS),
        SetIntervalFraction => Row::refuses("fmi3SetIntervalFraction", ANY, EVENT, NO_CLOCKS),
        SetShiftDecimal => Row::refuses("fmi3SetShiftDecimal", ANY, EVENT, NO_CLOCKS),
        SetShiftFraction => Row::refuses("fmi3SetShiftFraction", ANY, EVENT, NO_CLOCKS),
        EvaluateDiscreteStates => Row::refuses(
            "fmi3EvaluateDiscreteStates",
            ANY,
            EVENT | CT | STEP,
            "this FMU does not provide it (providesEvaluateDiscreteStates=\"false\")",
        ),
        UpdateDiscreteStates => Row::serves("fmi3UpdateDiscreteStates", ANY, EVENT),
        EnterContinuousTimeMode => Row::serves("fmi3EnterContinuousTimeMode", ME, EVENT),
        CompletedIntegratorStep => Row::serves("fmi3CompletedIntegratorStep", ME, CT),
        // In Event Mode only for an FMU without continuous states (the front end checks).
        SetTime => Row::serves("fmi3SetTime", ME, EVENT | CT),
        SetContinuousStates => Row::serves("fmi3SetContinuousStates", ME, CT),
        GetDerivatives => Row::serves("fmi3GetContinuousStateDerivatives", ME, INIT | EVENT | CT | TERM | ERR),
        GetEventIndicators => Row::serves("fmi3GetEventIndicators", ME, INIT | EVENT | CT | TERM | ERR),
        GetContinuousStates => Row::serves("fmi3GetContinuousStates", ME, INIT | EVENT | CT | TERM | ERR),
        GetNominalsOfContinuousStates => Row::serves("fmi3GetNominalsOfContinuousStates", ME, INIT | EVENT | CT | TERM | ERR),
        GetNumberOfEventIndicators => Row::serves("fmi3GetNumberOfEventIndicators", ME, ALIVE),
        GetNumberOfContinuousStates => Row::serves("fmi3GetNumberOfContinuousStates", ME, ALIVE),
        EnterStepMode => Row::serves("fmi3EnterStepMode", CS, EVENT),
        GetOutputDerivatives => Row::serves("fmi3GetOutputDerivatives", CS, STEP | TERM | ERR),
        DoStep => Row::serves("fmi3DoStep", CS, STEP),
        // A Scheduled Execution function: no instance of this FMU is ever one.
        ActivateModelPartition => Row::refuses(
            "fmi3ActivateModelPartition",
            ANY,
            0,
            "this FMU does not offer Scheduled Execution, so no instance has model partitions",
        ),
        // FMI 2.0's alone.
        SetupExperiment | SetInputDerivatives | CancelStep | GetStatus | GetRealStatus | GetIntegerStatus | GetBooleanStatus
        | GetStringStatus => Row::ABSENT,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allowed(call: Call, state: FmiState) -> bool {
        crate::frontend::is_allowed_in::<super::super::Fmi3>(call, state)
    }

    /// Spot checks against the standard's tables (FMI 3.0.2, sections 3.3 and 4.3).
    #[test]
    fn table_matches_the_standard() {
        use FmiState::*;
        assert!(allowed(Call::DoStep, StepMode));
        for s in [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error, Fatal] {
            assert!(!allowed(Call::DoStep, s), "DoStep in {s:?}");
        }
        assert!(allowed(Call::EnterStepMode, EventMode) && !allowed(Call::EnterStepMode, StepMode));
        assert!(allowed(Call::UpdateDiscreteStates, EventMode) && !allowed(Call::UpdateDiscreteStates, StepMode));
        assert!(allowed(Call::EnterEventMode, StepMode) && allowed(Call::EnterEventMode, ContinuousTimeMode));
        assert!(!allowed(Call::EnterEventMode, EventMode));
        assert!(allowed(Call::EnterInitializationMode, Instantiated) && !allowed(Call::EnterInitializationMode, Terminated));
        assert!(!allowed(Call::GetReal, Instantiated) && allowed(Call::GetReal, Error));
        assert!(allowed(Call::SetReal, ContinuousTimeMode) && !allowed(Call::SetInteger, ContinuousTimeMode));
        assert!(!allowed(Call::SetReal, Terminated));
        assert!(allowed(Call::Reset, Error) && !allowed(Call::Reset, Fatal));
        assert!(allowed(Call::SetContinuousStates, ContinuousTimeMode) && !allowed(Call::SetContinuousStates, EventMode));
        assert!(allowed(Call::GetDerivatives, InitializationMode));
        assert!(!allowed(Call::ExitConfigurationMode, Instantiated) && !allowed(Call::ActivateModelPartition, StepMode));
        assert_eq!(row(Call::DoStep).interface, Some(Interface::CoSimulation));
        assert_eq!(row(Call::SetTime).interface, Some(Interface::ModelExchange));
        assert_eq!(row(Call::UpdateDiscreteStates).interface, None);
        assert_eq!(
            (StepMode.interface(), ContinuousTimeMode.interface(), EventMode.interface()),
            (Some(Interface::CoSimulation), Some(Interface::ModelExchange), None)
        );
    }
}
