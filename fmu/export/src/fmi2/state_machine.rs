//! The FMI 2.0 Co-Simulation state machine (FMI 2.0.4, section 4.2.4): which call is allowed
//! in which state. This table is the only place that decides it.

use serde::{Deserialize, Serialize};

/// States of a Co-Simulation slave (asynchronous states are never entered: we step synchronously).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FmiState {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    Terminated,
    Error,
    Fatal,
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
        }
    }

    fn bit(self) -> u8 {
        1 << (self as u8)
    }
}

/// Every instance-level FMI 2.0 Co-Simulation call, for the allowed-state check and messages.
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
}

const I: u8 = 1 << FmiState::Instantiated as u8;
const INIT: u8 = 1 << FmiState::InitializationMode as u8;
const DONE: u8 = 1 << FmiState::StepComplete as u8;
const FAILED: u8 = 1 << FmiState::StepFailed as u8;
const TERM: u8 = 1 << FmiState::Terminated as u8;
const ERR: u8 = 1 << FmiState::Error as u8;
/// Every state but Fatal: after a fatal error nothing but freeing is meaningful.
const ALIVE: u8 = I | INIT | DONE | FAILED | TERM | ERR;

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
        }
    }

    /// The states in which the standard allows this call.
    fn allowed(self) -> u8 {
        match self {
            Call::SetDebugLogging => ALIVE,
            Call::FreeInstance | Call::Reset => ALIVE,
            Call::SetupExperiment | Call::EnterInitializationMode => I,
            Call::ExitInitializationMode => INIT,
            Call::Terminate => DONE | FAILED,
            Call::GetReal | Call::GetInteger | Call::GetBoolean | Call::GetString => INIT | DONE | FAILED | TERM | ERR,
            Call::SetReal | Call::SetInteger | Call::SetBoolean | Call::SetString => I | INIT | DONE,
            Call::GetFMUstate
            | Call::SetFMUstate
            | Call::FreeFMUstate
            | Call::SerializedFMUstateSize
            | Call::SerializeFMUstate
            | Call::DeSerializeFMUstate => ALIVE,
            Call::GetDirectionalDerivative => INIT | DONE | FAILED | TERM | ERR,
            Call::SetRealInputDerivatives => I | INIT | DONE,
            Call::GetRealOutputDerivatives => DONE | FAILED | TERM | ERR,
            Call::DoStep => DONE,
            // Only allowed in StepInProgress, which a synchronous slave never enters.
            Call::CancelStep => 0,
            Call::GetStatus | Call::GetRealStatus | Call::GetIntegerStatus | Call::GetBooleanStatus | Call::GetStringStatus => {
                DONE | FAILED | TERM
            }
        }
    }

    /// True when the standard allows this call in `state`.
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
}
