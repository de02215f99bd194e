//! The FMI 3.0 state machines of the two interfaces this toolkit offers: Co-Simulation (FMI
//! 3.0.2, section 4.3) and Model Exchange (section 3.3). As for FMI 2.0, one table over the
//! union of their states decides which call is allowed when; a Co-Simulation instance never
//! enters Continuous-Time Mode and a Model Exchange instance never Step Mode, and a call of the
//! other interface is refused whatever the state. Configuration Mode, Clock Activation Mode and
//! Intermediate Update Mode are never entered (no structural parameters, no clocks, no
//! intermediate-update callback is used), so they are not states here.

use serde::{Deserialize, Serialize};

/// The interface an instance was created for (which `fmi3Instantiate...` made it).
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

impl FmiState {
    /// The standard's name of the state, for log messages.
    pub fn name(self) -> &'static str {
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

    /// The interface whose state machine has this state; `None` for the states both share.
    pub fn interface(self) -> Option<Interface> {
        match self {
            FmiState::StepMode => Some(Interface::CoSimulation),
            FmiState::ContinuousTimeMode => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    const fn bit(self) -> u16 {
        1 << (self as u16)
    }
}

/// Every instance-level FMI 3.0 call (all 75 functions but `fmi3GetVersion` and the three
/// instantiations, which have no instance), for the allowed-state check and messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Call {
    SetDebugLogging,
    FreeInstance,
    EnterInitializationMode,
    ExitInitializationMode,
    EnterEventMode,
    Terminate,
    Reset,
    /// `fmi3GetFloat64` (the other getters and setters of types these FMUs have: below).
    GetFloat64,
    GetInt32,
    GetBoolean,
    GetString,
    SetFloat64,
    SetInt32,
    SetBoolean,
    SetString,
    /// A getter of a type no variable of these FMUs has (`fmi3GetFloat32`, ...): its name.
    GetOther(&'static str),
    /// A setter of a type no variable of these FMUs has.
    SetOther(&'static str),
    GetNumberOfVariableDependencies,
    GetVariableDependencies,
    GetFMUState,
    SetFMUState,
    FreeFMUState,
    SerializedFMUStateSize,
    SerializeFMUState,
    DeserializeFMUState,
    GetDirectionalDerivative,
    GetAdjointDerivative,
    EnterConfigurationMode,
    ExitConfigurationMode,
    /// The clock functions (`fmi3GetClock`, `fmi3SetIntervalDecimal`, ...): its name.
    Clock(&'static str),
    EvaluateDiscreteStates,
    UpdateDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetContinuousStateDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
    GetNumberOfEventIndicators,
    GetNumberOfContinuousStates,
    EnterStepMode,
    GetOutputDerivatives,
    DoStep,
    ActivateModelPartition,
}

const I: u16 = FmiState::Instantiated.bit();
const INIT: u16 = FmiState::InitializationMode.bit();
const EVENT: u16 = FmiState::EventMode.bit();
const CT: u16 = FmiState::ContinuousTimeMode.bit();
const STEP: u16 = FmiState::StepMode.bit();
const TERM: u16 = FmiState::Terminated.bit();
const ERR: u16 = FmiState::Error.bit();
/// Every state but Fatal: after a fatal error nothing but freeing is meaningful.
const ALIVE: u16 = I | INIT | EVENT | CT | STEP | TERM | ERR;
/// Where values may be read (and the Model Exchange evaluations made).
const READABLE: u16 = INIT | EVENT | CT | STEP | TERM | ERR;

impl Call {
    /// The C name of the call, for log messages.
    pub fn name(self) -> &'static str {
        match self {
            Call::SetDebugLogging => "fmi3SetDebugLogging",
            Call::FreeInstance => "fmi3FreeInstance",
            Call::EnterInitializationMode => "fmi3EnterInitializationMode",
            Call::ExitInitializationMode => "fmi3ExitInitializationMode",
            Call::EnterEventMode => "fmi3EnterEventMode",
            Call::Terminate => "fmi3Terminate",
            Call::Reset => "fmi3Reset",
            Call::GetFloat64 => "fmi3GetFloat64",
            Call::GetInt32 => "fmi3GetInt32",
            Call::GetBoolean => "fmi3GetBoolean",
            Call::GetString => "fmi3GetString",
            Call::SetFloat64 => "fmi3SetFloat64",
            Call::SetInt32 => "fmi3SetInt32",
            Call::SetBoolean => "fmi3SetBoolean",
            Call::SetString => "fmi3SetString",
            Call::GetOther(name) | Call::SetOther(name) | Call::Clock(name) => name,
            Call::GetNumberOfVariableDependencies => "fmi3GetNumberOfVariableDependencies",
            Call::GetVariableDependencies => "fmi3GetVariableDependencies",
            Call::GetFMUState => "fmi3GetFMUState",
            Call::SetFMUState => "fmi3SetFMUState",
            Call::FreeFMUState => "fmi3FreeFMUState",
            Call::SerializedFMUStateSize => "fmi3SerializedFMUStateSize",
            Call::SerializeFMUState => "fmi3SerializeFMUState",
            Call::DeserializeFMUState => "fmi3DeserializeFMUState",
            Call::GetDirectionalDerivative => "fmi3GetDirectionalDerivative",
            Call::GetAdjointDerivative => "fmi3GetAdjointDerivative",
            Call::EnterConfigurationMode => "fmi3EnterConfigurationMode",
            Call::ExitConfigurationMode => "fmi3ExitConfigurationMode",
            Call::EvaluateDiscreteStates => "fmi3EvaluateDiscreteStates",
            Call::UpdateDiscreteStates => "fmi3UpdateDiscreteStates",
            Call::EnterContinuousTimeMode => "fmi3EnterContinuousTimeMode",
            Call::CompletedIntegratorStep => "fmi3CompletedIntegratorStep",
            Call::SetTime => "fmi3SetTime",
            Call::SetContinuousStates => "fmi3SetContinuousStates",
            Call::GetContinuousStateDerivatives => "fmi3GetContinuousStateDerivatives",
            Call::GetEventIndicators => "fmi3GetEventIndicators",
            Call::GetContinuousStates => "fmi3GetContinuousStates",
            Call::GetNominalsOfContinuousStates => "fmi3GetNominalsOfContinuousStates",
            Call::GetNumberOfEventIndicators => "fmi3GetNumberOfEventIndicators",
            Call::GetNumberOfContinuousStates => "fmi3GetNumberOfContinuousStates",
            Call::EnterStepMode => "fmi3EnterStepMode",
            Call::GetOutputDerivatives => "fmi3GetOutputDerivatives",
            Call::DoStep => "fmi3DoStep",
            Call::ActivateModelPartition => "fmi3ActivateModelPartition",
        }
    }

    /// The interface this call belongs to; `None` for the functions both share.
    pub fn interface(self) -> Option<Interface> {
        match self {
            Call::EnterStepMode | Call::GetOutputDerivatives | Call::DoStep => Some(Interface::CoSimulation),
            Call::EnterContinuousTimeMode
            | Call::CompletedIntegratorStep
            | Call::SetTime
            | Call::SetContinuousStates
            | Call::GetContinuousStateDerivatives
            | Call::GetEventIndicators
            | Call::GetContinuousStates
            | Call::GetNominalsOfContinuousStates
            | Call::GetNumberOfEventIndicators
            | Call::GetNumberOfContinuousStates => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    /// The states in which the standard allows this call (both interfaces' tables in one). A
    /// call allowed here may still be refused for what it asks (a type these FMUs do not
    /// have, a fixed parameter after initialization): the front end decides that.
    fn allowed(self) -> u16 {
        match self {
            Call::SetDebugLogging | Call::FreeInstance | Call::Reset => ALIVE,
            Call::EnterInitializationMode => I,
            Call::ExitInitializationMode => INIT,
            // Model Exchange from Continuous-Time Mode; Co-Simulation from Step Mode (with
            // eventModeUsed, which the front end checks).
            Call::EnterEventMode => CT | STEP,
            Call::Terminate => EVENT | CT | STEP,
            Call::GetFloat64 | Call::GetInt32 | Call::GetBoolean | Call::GetString | Call::GetOther(_) => READABLE,
            // In Continuous-Time Mode only continuous-time inputs may be set, which are Float64.
            Call::SetFloat64 | Call::SetOther(_) => I | INIT | EVENT | CT | STEP,
            Call::SetInt32 | Call::SetBoolean | Call::SetString => I | INIT | EVENT | STEP,
            Call::GetNumberOfVariableDependencies | Call::GetVariableDependencies => READABLE,
            Call::GetFMUState
            | Call::SetFMUState
            | Call::FreeFMUState
            | Call::SerializedFMUStateSize
            | Call::SerializeFMUState
            | Call::DeserializeFMUState => ALIVE,
            Call::GetDirectionalDerivative | Call::GetAdjointDerivative => INIT | EVENT | CT | STEP | TERM | ERR,
            Call::EnterConfigurationMode => I | STEP,
            // Only allowed in Configuration Mode, which an FMU without structural parameters
            // never enters.
            Call::ExitConfigurationMode => 0,
            Call::Clock(_) => EVENT,
            Call::EvaluateDiscreteStates => EVENT | CT | STEP,
            Call::UpdateDiscreteStates => EVENT,
            Call::EnterContinuousTimeMode => EVENT,
            Call::CompletedIntegratorStep | Call::SetContinuousStates => CT,
            // In Event Mode only for an FMU without continuous states (the front end checks).
            Call::SetTime => EVENT | CT,
            Call::GetContinuousStateDerivatives | Call::GetEventIndicators | Call::GetContinuousStates => INIT | EVENT | CT | TERM | ERR,
            Call::GetNominalsOfContinuousStates => INIT | EVENT | CT | TERM | ERR,
            Call::GetNumberOfEventIndicators | Call::GetNumberOfContinuousStates => ALIVE,
            Call::EnterStepMode => EVENT,
            Call::GetOutputDerivatives => STEP | TERM | ERR,
            Call::DoStep => STEP,
            // A Scheduled Execution function: no instance of this FMU is ever one.
            Call::ActivateModelPartition => 0,
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

    /// Spot checks against the standard's tables (FMI 3.0.2, sections 3.3 and 4.3).
    #[test]
    fn table_matches_the_standard() {
        use FmiState::*;
        assert!(Call::DoStep.is_allowed_in(StepMode));
        for s in [Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error, Fatal] {
            assert!(!Call::DoStep.is_allowed_in(s), "DoStep in {s:?}");
        }
        assert!(Call::EnterStepMode.is_allowed_in(EventMode) && !Call::EnterStepMode.is_allowed_in(StepMode));
        assert!(Call::UpdateDiscreteStates.is_allowed_in(EventMode) && !Call::UpdateDiscreteStates.is_allowed_in(StepMode));
        assert!(Call::EnterEventMode.is_allowed_in(StepMode) && Call::EnterEventMode.is_allowed_in(ContinuousTimeMode));
        assert!(!Call::EnterEventMode.is_allowed_in(EventMode));
        assert!(Call::EnterInitializationMode.is_allowed_in(Instantiated) && !Call::EnterInitializationMode.is_allowed_in(Terminated));
        assert!(!Call::GetFloat64.is_allowed_in(Instantiated) && Call::GetFloat64.is_allowed_in(Error));
        assert!(Call::SetFloat64.is_allowed_in(ContinuousTimeMode) && !Call::SetInt32.is_allowed_in(ContinuousTimeMode));
        assert!(!Call::SetFloat64.is_allowed_in(Terminated));
        assert!(Call::Reset.is_allowed_in(Error) && !Call::Reset.is_allowed_in(Fatal));
        assert!(Call::SetContinuousStates.is_allowed_in(ContinuousTimeMode) && !Call::SetContinuousStates.is_allowed_in(EventMode));
        assert!(Call::GetContinuousStateDerivatives.is_allowed_in(InitializationMode));
        assert!(!Call::ExitConfigurationMode.is_allowed_in(Instantiated) && !Call::ActivateModelPartition.is_allowed_in(StepMode));
        assert_eq!(Call::DoStep.interface(), Some(Interface::CoSimulation));
        assert_eq!(Call::SetTime.interface(), Some(Interface::ModelExchange));
        assert_eq!(Call::UpdateDiscreteStates.interface(), None);
        assert_eq!(
            (StepMode.interface(), ContinuousTimeMode.interface(), EventMode.interface()),
            (Some(Interface::CoSimulation), Some(Interface::ModelExchange), None)
        );
    }
}
