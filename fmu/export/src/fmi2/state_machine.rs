//! The FMI 2.0 state machines of both interfaces: Co-Simulation (FMI 2.0.4, section 4.2.4) and
//! Model Exchange (section 3.2.3), which share their first and last states. One table over the
//! union of their states decides which call is allowed when: a Co-Simulation instance never
//! enters EventMode or ContinuousTimeMode and a Model Exchange instance never StepComplete or
//! StepFailed, and a call of the other interface is refused whatever the state (the states
//! Terminated and Error are shared). This table is the only place that decides it.

use serde::{Deserialize, Serialize};

pub use crate::frontend::{Call, Interface};
use crate::frontend::{MachineState, Row};

/// States of an instance. A Co-Simulation slave steps synchronously, so the asynchronous
/// states (StepInProgress, StepCanceled) are never entered. The Model Exchange states come
/// last so that the numbering of the Co-Simulation ones, which FMU states record, is unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FmiState {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
    Fatal,
    /// Model Exchange: discrete-time equations active, time stands still (after initialization
    /// and at each event).
    EventMode,
    /// Model Exchange: the importer integrates the continuous states.
    ContinuousTimeMode,
}

impl MachineState for FmiState {
    fn name(self) -> &'static str {
        match self {
            FmiState::Instantiated => "Instantiated",
            FmiState::InitializationMode => "InitializationMode",
            FmiState::StepComplete => "StepComplete",
            FmiState::StepFailed => "StepFailed",
            FmiState::Terminated => "Terminated",
            FmiState::Error => "Error",
            FmiState::Fatal => "Fatal",
            FmiState::EventMode => "EventMode",
            FmiState::ContinuousTimeMode => "ContinuousTimeMode",
        }
    }

    fn interface(self) -> Option<Interface> {
        match self {
            FmiState::StepComplete | FmiState::StepFailed => Some(Interface::CoSimulation),
            FmiState::EventMode | FmiState::ContinuousTimeMode => Some(Interface::ModelExchange),
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
const DONE: u16 = bit(FmiState::StepComplete);
const FAILED: u16 = bit(FmiState::StepFailed);
const TERM: u16 = bit(FmiState::Terminated);
const ERR: u16 = bit(FmiState::Error);
const EVENT: u16 = bit(FmiState::EventMode);
const CT: u16 = bit(FmiState::ContinuousTimeMode);
/// Every state but Fatal: after a fatal error nothing but freeing is meaningful.
const ALIVE: u16 = I | INIT | DONE | FAILED | TERM | ERR | EVENT | CT;
/// Where values may be read (and the directional derivatives asked for).
const READABLE: u16 = INIT | DONE | FAILED | TERM | ERR | EVENT | CT;

const ANY: Option<Interface> = None;
const CS: Option<Interface> = Some(Interface::CoSimulation);
const ME: Option<Interface> = Some(Interface::ModelExchange);

/// FMI 2.0's table: each call's C name, interface, the states that allow it (both interfaces'
/// tables in one: each interface's states are disjoint except the shared ones), and why these
/// FMUs refuse the ones they do not serve.
#[inline(always)]
pub fn row(call: Call) -> Row {
    use Call::*;
    match call {
        SetDebugLogging => Row::serves("fmi2SetDebugLogging", ANY, ALIVE),
        FreeInstance => Row::serves("fmi2FreeInstance", ANY, ALIVE),
        SetupExperiment => Row::serves("fmi2SetupExperiment", ANY, I),
        EnterInitializationMode => Row::serves("fmi2EnterInitializationMode", ANY, I),
        ExitInitializationMode => Row::serves("fmi2ExitInitializationMode", ANY, INIT),
        Terminate => Row::serves("fmi2Terminate", ANY, DONE | FAILED | EVENT | CT),
        Reset => Row::serves("fmi2Reset", ANY, ALIVE),
        GetReal => Row::serves("fmi2GetReal", ANY, READABLE),
        GetInteger => Row::serves("fmi2GetInteger", ANY, READABLE),
        GetBoolean => Row::serves("fmi2GetBoolean", ANY, READABLE),
        GetString => Row::serves("fmi2GetString", ANY, READABLE),
        // In ContinuousTimeMode only continuous Real inputs may be set (the core's rules
        // refuse the rest), so only fmi2SetReal is allowed there.
        SetReal => Row::serves("fmi2SetReal", ANY, I | INIT | DONE | EVENT | CT),
        SetInteger => Row::serves("fmi2SetInteger", ANY, I | INIT | DONE | EVENT),
        SetBoolean => Row::serves("fmi2SetBoolean", ANY, I | INIT | DONE | EVENT),
        SetString => Row::serves("fmi2SetString", ANY, I | INIT | DONE | EVENT),
        GetFMUState => Row::serves("fmi2GetFMUstate", ANY, ALIVE),
        SetFMUState => Row::serves("fmi2SetFMUstate", ANY, ALIVE),
        FreeFMUState => Row::serves("fmi2FreeFMUstate", ANY, ALIVE),
        SerializedFMUStateSize => Row::serves("fmi2SerializedFMUstateSize", ANY, ALIVE),
        SerializeFMUState => Row::serves("fmi2SerializeFMUstate", ANY, ALIVE),
        DeserializeFMUState => Row::serves("fmi2DeSerializeFMUstate", ANY, ALIVE),
        GetDirectionalDerivative => Row::serves("fmi2GetDirectionalDerivative", ANY, READABLE),
        SetInputDerivatives => Row::serves("fmi2SetRealInputDerivatives", CS, I | INIT | DONE),
        GetOutputDerivatives => Row::serves("fmi2GetRealOutputDerivatives", CS, DONE | FAILED | TERM | ERR),
        DoStep => Row::serves("fmi2DoStep", CS, DONE),
        // Only allowed in StepInProgress, which a synchronous slave never enters.
        CancelStep => Row::serves("fmi2CancelStep", CS, 0),
        GetStatus => Row::serves("fmi2GetStatus", CS, DONE | FAILED | TERM),
        GetRealStatus => Row::serves("fmi2GetRealStatus", CS, DONE | FAILED | TERM),
        GetIntegerStatus => Row::serves("fmi2GetIntegerStatus", CS, DONE | FAILED | TERM),
        GetBooleanStatus => Row::serves("fmi2GetBooleanStatus", CS, DONE | FAILED | TERM),
        GetStringStatus => Row::serves("fmi2GetStringStatus", CS, DONE | FAILED | TERM),
        // Model Exchange (section 3.2.3).
        EnterEventMode => Row::serves("fmi2EnterEventMode", ME, EVENT | CT),
        UpdateDiscreteStates => Row::serves("fmi2NewDiscreteStates", ME, EVENT),
        EnterContinuousTimeMode => Row::serves("fmi2EnterContinuousTimeMode", ME, EVENT),
        CompletedIntegratorStep => Row::serves("fmi2CompletedIntegratorStep", ME, CT),
        // In Event Mode only for an FMU without continuous states (footnote 8; the model
        // exchange front end applies that half).
        SetTime => Row::serves("fmi2SetTime", ME, EVENT | CT),
        SetContinuousStates => Row::serves("fmi2SetContinuousStates", ME, CT),
        // Initialization Mode too, since FMI 2.0.1 (tickets 288 and 1277 of the standard).
        GetDerivatives => Row::serves("fmi2GetDerivatives", ME, INIT | EVENT | CT | TERM | ERR),
        GetEventIndicators => Row::serves("fmi2GetEventIndicators", ME, INIT | EVENT | CT | TERM | ERR),
        GetContinuousStates => Row::serves("fmi2GetContinuousStates", ME, INIT | EVENT | CT | TERM | ERR),
        GetNominalsOfContinuousStates => Row::serves("fmi2GetNominalsOfContinuousStates", ME, I | INIT | EVENT | CT | TERM | ERR),
        // FMI 3.0's alone.
        GetFloat32 | GetInt8 | GetUInt8 | GetInt16 | GetUInt16 | GetUInt32 | GetInt64 | GetUInt64 | GetBinary => Row::ABSENT,
        SetFloat32 | SetInt8 | SetUInt8 | SetInt16 | SetUInt16 | SetUInt32 | SetInt64 | SetUInt64 | SetBinary => Row::ABSENT,
        GetClock | SetClock | GetIntervalDecimal | GetIntervalFraction | GetShiftDecimal | GetShiftFraction => Row::ABSENT,
        SetIntervalDecimal | SetIntervalFraction | SetShiftDecimal | SetShiftFraction => Row::ABSENT,
        GetAdjointDerivative
        | GetNumberOfEventIndicators
        | GetNumberOfContinuousStates
        | EnterStepMode
        | GetNumberOfVariableDependencies
        | GetVariableDependencies
        | EnterConfigurationMode
        | ExitConfigurationMode
        | EvaluateDiscreteStates
        | ActivateModelPartition => Row::ABSENT,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn allowed(call: Call, state: FmiState) -> bool {
        crate::frontend::is_allowed_in::<super::super::Fmi2>(call, state)
    }

    /// Spot checks against the standard's table: a wrong bit here would let an importer drive
    /// the slave through an illegal sequence.
    #[test]
    fn table_matches_the_standard() {
        use FmiState::*;
        assert!(allowed(Call::DoStep, StepComplete));
        for s in [Instantiated, InitializationMode, StepFailed, Terminated, Error, Fatal] {
            assert!(!allowed(Call::DoStep, s), "DoStep in {s:?}");
        }
        assert!(allowed(Call::SetupExperiment, Instantiated));
        assert!(!allowed(Call::SetupExperiment, InitializationMode));
        assert!(!allowed(Call::GetReal, Instantiated));
        assert!(allowed(Call::GetReal, Error));
        assert!(!allowed(Call::SetReal, Terminated));
        assert!(allowed(Call::Terminate, StepFailed));
        assert!(!allowed(Call::Terminate, Instantiated));
        assert!(allowed(Call::Reset, Error));
        assert!(!allowed(Call::Reset, Fatal));
        assert!(!allowed(Call::CancelStep, StepComplete));
        assert!(allowed(Call::GetBooleanStatus, StepFailed));
        assert!(!allowed(Call::GetBooleanStatus, Error));
    }

    /// Spot checks against the Model Exchange table (section 3.2.3), and the rule that keeps
    /// the two interfaces apart.
    #[test]
    fn model_exchange_table_matches_the_standard() {
        use FmiState::*;
        assert!(allowed(Call::SetContinuousStates, ContinuousTimeMode));
        assert!(!allowed(Call::SetContinuousStates, EventMode));
        assert!(allowed(Call::UpdateDiscreteStates, EventMode));
        assert!(!allowed(Call::UpdateDiscreteStates, ContinuousTimeMode));
        assert!(allowed(Call::EnterEventMode, ContinuousTimeMode) && allowed(Call::EnterEventMode, EventMode));
        assert!(!allowed(Call::CompletedIntegratorStep, EventMode));
        assert!(allowed(Call::GetContinuousStates, InitializationMode));
        assert!(allowed(Call::GetDerivatives, InitializationMode) && allowed(Call::GetDerivatives, Error));
        assert!(!allowed(Call::GetDerivatives, Instantiated));
        assert!(allowed(Call::GetNominalsOfContinuousStates, Instantiated));
        assert!(allowed(Call::GetNominalsOfContinuousStates, InitializationMode));
        assert!(allowed(Call::Terminate, EventMode) && allowed(Call::Terminate, ContinuousTimeMode));
        assert!(allowed(Call::SetReal, ContinuousTimeMode) && !allowed(Call::SetInteger, ContinuousTimeMode));
        assert!(allowed(Call::SetBoolean, EventMode));
        for s in [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error, Fatal] {
            assert!(!allowed(Call::DoStep, s), "DoStep in {s:?}");
        }
        assert_eq!(row(Call::GetBooleanStatus).interface, Some(Interface::CoSimulation));
        assert_eq!(row(Call::GetDerivatives).interface, Some(Interface::ModelExchange));
        assert_eq!(row(Call::GetReal).interface, None);
        assert_eq!(
            (EventMode.interface(), StepFailed.interface(), Terminated.interface()),
            (Some(Interface::ModelExchange), Some(Interface::CoSimulation), None)
        );
    }
}
