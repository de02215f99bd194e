//! The FMI 2.0 state machines of both interfaces: Co-Simulation (FMI 2.0.4, section 4.2.4) and
//! Model Exchange (section 3.2.3), which share their first and last states. One table over the
//! union of their states decides which call is allowed when: a Co-Simulation instance never
//! enters EventMode or ContinuousTimeMode and a Model Exchange instance never StepComplete or
//! StepFailed, and a call of the other interface is refused whatever the state (the states
//! Terminated and Error are shared). This table is the only place that decides it.

use serde::{Deserialize, Serialize};

/// The interface an instance was created for (`fmuType` of `fmi2Instantiate`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Interface {
    ModelExchange,
    CoSimulation,
}

impl Interface {
    /// The standard's name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Interface::ModelExchange => "Model Exchange",
            Interface::CoSimulation => "Co-Simulation",
        }
    }
}

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

impl FmiState {
    /// The standard's name of the state, for log messages.
    pub fn name(self) -> &'static str {
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

    /// The interface whose state machine has this state; `None` for the states both share.
    pub fn interface(self) -> Option<Interface> {
        match self {
            FmiState::StepComplete | FmiState::StepFailed => Some(Interface::CoSimulation),
            FmiState::EventMode | FmiState::ContinuousTimeMode => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    const fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

/// Every instance-level FMI 2.0 call of either interface, for the allowed-state check and
/// messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    SetDebugLogging,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    GetFMUstate,
    SetFMUstate,
    FreeFMUstate,
    SerializedFMUstateSize,
    SerializeFMUstate,
    DeSerializeFMUstate,
    GetDirectionalDerivative,
    SetRealInputDerivatives,
    GetRealOutputDerivatives,
    DoStep,
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
}

const I: u16 = FmiState::Instantiated.bit();
const INIT: u16 = FmiState::InitializationMode.bit();
const DONE: u16 = FmiState::StepComplete.bit();
const FAILED: u16 = FmiState::StepFailed.bit();
const TERM: u16 = FmiState::Terminated.bit();
const ERR: u16 = FmiState::Error.bit();
const EVENT: u16 = FmiState::EventMode.bit();
const CT: u16 = FmiState::ContinuousTimeMode.bit();
/// Every state but Fatal: after a fatal error nothing but freeing is meaningful.
const ALIVE: u16 = I | INIT | DONE | FAILED | TERM | ERR | EVENT | CT;

impl Call {
    /// The C name of the call, for log messages.
    pub fn name(self) -> &'static str {
        match self {
            Call::SetDebugLogging => "fmi2SetDebugLogging",
            Call::FreeInstance => "fmi2FreeInstance",
            Call::SetupExperiment => "fmi2SetupExperiment",
            Call::EnterInitializationMode => "fmi2EnterInitializationMode",
            Call::ExitInitializationMode => "fmi2ExitInitializationMode",
            Call::Terminate => "fmi2Terminate",
            Call::Reset => "fmi2Reset",
            Call::GetReal => "fmi2GetReal",
            Call::GetInteger => "fmi2GetInteger",
            Call::GetBoolean => "fmi2GetBoolean",
            Call::GetString => "fmi2GetString",
            Call::SetReal => "fmi2SetReal",
            Call::SetInteger => "fmi2SetInteger",
            Call::SetBoolean => "fmi2SetBoolean",
            Call::SetString => "fmi2SetString",
            Call::GetFMUstate => "fmi2GetFMUstate",
            Call::SetFMUstate => "fmi2SetFMUstate",
            Call::FreeFMUstate => "fmi2FreeFMUstate",
            Call::SerializedFMUstateSize => "fmi2SerializedFMUstateSize",
            Call::SerializeFMUstate => "fmi2SerializeFMUstate",
            Call::DeSerializeFMUstate => "fmi2DeSerializeFMUstate",
            Call::GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            Call::SetRealInputDerivatives => "fmi2SetRealInputDerivatives",
            Call::GetRealOutputDerivatives => "fmi2GetRealOutputDerivatives",
            Call::DoStep => "fmi2DoStep",
            Call::CancelStep => "fmi2CancelStep",
            Call::GetStatus => "fmi2GetStatus",
            Call::GetRealStatus => "fmi2GetRealStatus",
            Call::GetIntegerStatus => "fmi2GetIntegerStatus",
            Call::GetBooleanStatus => "fmi2GetBooleanStatus",
            Call::GetStringStatus => "fmi2GetStringStatus",
            Call::EnterEventMode => "fmi2EnterEventMode",
            Call::NewDiscreteStates => "fmi2NewDiscreteStates",
            Call::EnterContinuousTimeMode => "fmi2EnterContinuousTimeMode",
            Call::CompletedIntegratorStep => "fmi2CompletedIntegratorStep",
            Call::SetTime => "fmi2SetTime",
            Call::SetContinuousStates => "fmi2SetContinuousStates",
            Call::GetDerivatives => "fmi2GetDerivatives",
            Call::GetEventIndicators => "fmi2GetEventIndicators",
            Call::GetContinuousStates => "fmi2GetContinuousStates",
            Call::GetNominalsOfContinuousStates => "fmi2GetNominalsOfContinuousStates",
        }
    }

    /// The interface this call belongs to; `None` for the functions both share.
    pub fn interface(self) -> Option<Interface> {
        match self {
            Call::SetRealInputDerivatives
            | Call::GetRealOutputDerivatives
            | Call::DoStep
            | Call::CancelStep
            | Call::GetStatus
            | Call::GetRealStatus
            | Call::GetIntegerStatus
            | Call::GetBooleanStatus
            | Call::GetStringStatus => Some(Interface::CoSimulation),
            Call::EnterEventMode
            | Call::NewDiscreteStates
            | Call::EnterContinuousTimeMode
            | Call::CompletedIntegratorStep
            | Call::SetTime
            | Call::SetContinuousStates
            | Call::GetDerivatives
            | Call::GetEventIndicators
            | Call::GetContinuousStates
            | Call::GetNominalsOfContinuousStates => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    /// The states in which the standard allows this call (both interfaces' tables in one: each
    /// interface's states are disjoint except the shared ones).
    fn allowed(self) -> u16 {
        match self {
            Call::SetDebugLogging => ALIVE,
            Call::FreeInstance | Call::Reset => ALIVE,
            Call::SetupExperiment | Call::EnterInitializationMode => I,
            Call::ExitInitializationMode => INIT,
            Call::Terminate => DONE | FAILED | EVENT | CT,
            Call::GetReal | Call::GetInteger | Call::GetBoolean | Call::GetString => INIT | DONE | FAILED | TERM | ERR | EVENT | CT,
            // In ContinuousTimeMode only continuous Real inputs may be set (the core's rules
            // refuse the rest), so only fmi2SetReal is allowed there.
            Call::SetReal => I | INIT | DONE | EVENT | CT,
            Call::SetInteger | Call::SetBoolean | Call::SetString => I | INIT | DONE | EVENT,
            Call::GetFMUstate
            | Call::SetFMUstate
            | Call::FreeFMUstate
            | Call::SerializedFMUstateSize
            | Call::SerializeFMUstate
            | Call::DeSerializeFMUstate => ALIVE,
            Call::GetDirectionalDerivative => INIT | DONE | FAILED | TERM | ERR | EVENT | CT,
            Call::SetRealInputDerivatives => I | INIT | DONE,
            Call::GetRealOutputDerivatives => DONE | FAILED | TERM | ERR,
            Call::DoStep => DONE,
            // Only allowed in StepInProgress, which a synchronous slave never enters.
            Call::CancelStep => 0,
            Call::GetStatus | Call::GetRealStatus | Call::GetIntegerStatus | Call::GetBooleanStatus | Call::GetStringStatus => {
                DONE | FAILED | TERM
            }
            // Model Exchange (section 3.2.3).
            Call::EnterEventMode => EVENT | CT,
            Call::NewDiscreteStates | Call::EnterContinuousTimeMode => EVENT,
            Call::CompletedIntegratorStep | Call::SetContinuousStates => CT,
            // In Event Mode only for an FMU without continuous states (footnote 8; the model
            // exchange front end applies that half).
            Call::SetTime => EVENT | CT,
            // Initialization Mode too, since FMI 2.0.1 (tickets 288 and 1277 of the standard).
            Call::GetEventIndicators | Call::GetContinuousStates | Call::GetDerivatives => INIT | EVENT | CT | TERM | ERR,
            Call::GetNominalsOfContinuousStates => I | INIT | EVENT | CT | TERM | ERR,
        }
    }

    /// True when the standard allows this call in `state` (of an instance of the call's
    /// interface: see [`Call::interface`]).
    #[inline]
    pub fn is_allowed_in(self, state: FmiState) -> bool {
        self.allowed() & state.bit() != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spot checks against the standard's table: a wrong bit here would let an importer drive
    /// the slave through an illegal sequence.
    #[test]
    fn table_matches_the_standard() {
        use FmiState::*;
        assert!(Call::DoStep.is_allowed_in(StepComplete));
        for s in [Instantiated, InitializationMode, StepFailed, Terminated, Error, Fatal] {
            assert!(!Call::DoStep.is_allowed_in(s), "DoStep in {s:?}");
        }
        assert!(Call::SetupExperiment.is_allowed_in(Instantiated));
        assert!(!Call::SetupExperiment.is_allowed_in(InitializationMode));
        assert!(!Call::GetReal.is_allowed_in(Instantiated));
        assert!(Call::GetReal.is_allowed_in(Error));
        assert!(!Call::SetReal.is_allowed_in(Terminated));
        assert!(Call::Terminate.is_allowed_in(StepFailed));
        assert!(!Call::Terminate.is_allowed_in(Instantiated));
        assert!(Call::Reset.is_allowed_in(Error));
        assert!(!Call::Reset.is_allowed_in(Fatal));
        assert!(!Call::CancelStep.is_allowed_in(StepComplete));
        assert!(Call::GetBooleanStatus.is_allowed_in(StepFailed));
        assert!(!Call::GetBooleanStatus.is_allowed_in(Error));
    }

    /// Spot checks against the Model Exchange table (section 3.2.3), and the rule that keeps
    /// the two interfaces apart.
    #[test]
    fn model_exchange_table_matches_the_standard() {
        use FmiState::*;
        assert!(Call::SetContinuousStates.is_allowed_in(ContinuousTimeMode));
        assert!(!Call::SetContinuousStates.is_allowed_in(EventMode));
        assert!(Call::NewDiscreteStates.is_allowed_in(EventMode));
        assert!(!Call::NewDiscreteStates.is_allowed_in(ContinuousTimeMode));
        assert!(Call::EnterEventMode.is_allowed_in(ContinuousTimeMode) && Call::EnterEventMode.is_allowed_in(EventMode));
        assert!(!Call::CompletedIntegratorStep.is_allowed_in(EventMode));
        assert!(Call::GetContinuousStates.is_allowed_in(InitializationMode));
        assert!(Call::GetDerivatives.is_allowed_in(InitializationMode) && Call::GetDerivatives.is_allowed_in(Error));
        assert!(!Call::GetDerivatives.is_allowed_in(Instantiated));
        assert!(Call::GetNominalsOfContinuousStates.is_allowed_in(Instantiated));
        assert!(Call::GetNominalsOfContinuousStates.is_allowed_in(InitializationMode));
        assert!(Call::Terminate.is_allowed_in(EventMode) && Call::Terminate.is_allowed_in(ContinuousTimeMode));
        assert!(Call::SetReal.is_allowed_in(ContinuousTimeMode) && !Call::SetInteger.is_allowed_in(ContinuousTimeMode));
        assert!(Call::SetBoolean.is_allowed_in(EventMode));
        for s in [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error, Fatal] {
            assert!(!Call::DoStep.is_allowed_in(s), "DoStep in {s:?}");
        }
        assert_eq!(Call::GetBooleanStatus.interface(), Some(Interface::CoSimulation));
        assert_eq!(Call::GetDerivatives.interface(), Some(Interface::ModelExchange));
        assert_eq!(Call::GetReal.interface(), None);
        assert_eq!(
            (EventMode.interface(), StepFailed.interface(), Terminated.interface()),
            (Some(Interface::ModelExchange), Some(Interface::CoSimulation), None)
        );
    }
}
