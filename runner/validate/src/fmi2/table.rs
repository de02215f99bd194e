//! The FMI 2.0 state machines as data: every function, every state, and which function the
//! standard allows in which state (the tables of sections 3.2.3 and 4.2.4 of FMI 2.0.4),
//! including the conditions on the variable a set or get names. Written from the standard,
//! independently of our exporter's table, so that it checks it.

use super::model::{Causality, Initial, Var, Variability};

/// The interface an instance is created for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Interface {
    CoSimulation,
    ModelExchange,
}

impl Interface {
    /// As the report names it.
    pub(crate) fn title(self) -> &'static str {
        match self {
            Interface::CoSimulation => "Co-Simulation",
            Interface::ModelExchange => "Model Exchange",
        }
    }

    /// As the probe's command line names it.
    pub(crate) fn arg(self) -> &'static str {
        match self {
            Interface::CoSimulation => "cs",
            Interface::ModelExchange => "me",
        }
    }

    pub(crate) fn from_arg(arg: &str) -> Option<Interface> {
        match arg {
            "cs" => Some(Interface::CoSimulation),
            "me" => Some(Interface::ModelExchange),
            _ => None,
        }
    }

    /// `fmi2Type` for fmi2Instantiate.
    pub(crate) fn fmi_type(self) -> fmi_c::fmi2::Type {
        match self {
            Interface::CoSimulation => fmi_c::fmi2::CO_SIMULATION,
            Interface::ModelExchange => fmi_c::fmi2::MODEL_EXCHANGE,
        }
    }

    pub(crate) fn other(self) -> Interface {
        match self {
            Interface::CoSimulation => Interface::ModelExchange,
            Interface::ModelExchange => Interface::CoSimulation,
        }
    }
}

/// A state of an FMI 2.0 instance (both interfaces' states in one list).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum State {
    Instantiated,
    InitializationMode,
    StepComplete,
    StepFailed,
    EventMode,
    ContinuousTimeMode,
    Terminated,
    /// After a call returned fmi2Error.
    Error,
    /// After fmi2FreeInstance (or fmi2Fatal): no call may follow.
    Gone,
}

impl State {
    /// The standard's name.
    pub(crate) fn name(self) -> &'static str {
        match self {
            State::Instantiated => "Instantiated",
            State::InitializationMode => "InitializationMode",
            State::StepComplete => "StepComplete",
            State::StepFailed => "StepFailed",
            State::EventMode => "EventMode",
            State::ContinuousTimeMode => "ContinuousTimeMode",
            State::Terminated => "Terminated",
            State::Error => "Error",
            State::Gone => "freed",
        }
    }

    /// The states the validator can drive an instance into, in the order it visits them.
    pub(crate) fn reachable(interface: Interface) -> &'static [State] {
        match interface {
            Interface::CoSimulation => {
                &[State::Instantiated, State::InitializationMode, State::StepComplete, State::Terminated, State::Error]
            }
            Interface::ModelExchange => &[
                State::Instantiated,
                State::InitializationMode,
                State::EventMode,
                State::ContinuousTimeMode,
                State::Terminated,
                State::Error,
            ],
        }
    }

    pub(crate) fn from_name(name: &str) -> Option<State> {
        [
            State::Instantiated,
            State::InitializationMode,
            State::StepComplete,
            State::StepFailed,
            State::EventMode,
            State::ContinuousTimeMode,
            State::Terminated,
            State::Error,
        ]
        .into_iter()
        .find(|s| s.name() == name)
    }
}

macro_rules! functions {
    ($($variant:ident = $name:literal,)*) => {
        /// The 44 functions of FMI 2.0.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub(crate) enum Function {
            $($variant,)*
        }

        impl Function {
            /// All of them, in fmi2FunctionTypes.h's order.
            pub(crate) const ALL: &'static [Function] = &[$(Function::$variant,)*];

            /// The C name.
            pub(crate) fn name(self) -> &'static str {
                match self {
                    $(Function::$variant => $name,)*
                }
            }
        }
    };
}

functions! {
    GetTypesPlatform = "fmi2GetTypesPlatform",
    GetVersion = "fmi2GetVersion",
    SetDebugLogging = "fmi2SetDebugLogging",
    Instantiate = "fmi2Instantiate",
    FreeInstance = "fmi2FreeInstance",
    SetupExperiment = "fmi2SetupExperiment",
    EnterInitializationMode = "fmi2EnterInitializationMode",
    ExitInitializationMode = "fmi2ExitInitializationMode",
    Terminate = "fmi2Terminate",
    Reset = "fmi2Reset",
    GetReal = "fmi2GetReal",
    GetInteger = "fmi2GetInteger",
    GetBoolean = "fmi2GetBoolean",
    GetString = "fmi2GetString",
    SetReal = "fmi2SetReal",
    SetInteger = "fmi2SetInteger",
    SetBoolean = "fmi2SetBoolean",
    SetString = "fmi2SetString",
    GetFmuState = "fmi2GetFMUstate",
    SetFmuState = "fmi2SetFMUstate",
    FreeFmuState = "fmi2FreeFMUstate",
    SerializedFmuStateSize = "fmi2SerializedFMUstateSize",
    SerializeFmuState = "fmi2SerializeFMUstate",
    DeSerializeFmuState = "fmi2DeSerializeFMUstate",
    GetDirectionalDerivative = "fmi2GetDirectionalDerivative",
    EnterEventMode = "fmi2EnterEventMode",
    NewDiscreteStates = "fmi2NewDiscreteStates",
    EnterContinuousTimeMode = "fmi2EnterContinuousTimeMode",
    CompletedIntegratorStep = "fmi2CompletedIntegratorStep",
    SetTime = "fmi2SetTime",
    SetContinuousStates = "fmi2SetContinuousStates",
    GetDerivatives = "fmi2GetDerivatives",
    GetEventIndicators = "fmi2GetEventIndicators",
    GetContinuousStates = "fmi2GetContinuousStates",
    GetNominalsOfContinuousStates = "fmi2GetNominalsOfContinuousStates",
    SetRealInputDerivatives = "fmi2SetRealInputDerivatives",
    GetRealOutputDerivatives = "fmi2GetRealOutputDerivatives",
    DoStep = "fmi2DoStep",
    CancelStep = "fmi2CancelStep",
    GetStatus = "fmi2GetStatus",
    GetRealStatus = "fmi2GetRealStatus",
    GetIntegerStatus = "fmi2GetIntegerStatus",
    GetBooleanStatus = "fmi2GetBooleanStatus",
    GetStringStatus = "fmi2GetStringStatus",
}

/// What the standard's table says of one function in one state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Rule {
    /// Allowed ("x"; also "7" and "8": allowed, values usable for debugging only).
    Allowed,
    /// Not allowed (an empty cell).
    Illegal,
    /// A set allowed only for some variables: the table's conditions 1, 3, 4, 5 and 6.
    SetIf,
    /// A get allowed for outputs and InitialUnknowns (condition 2, Initialization Mode).
    GetIf,
    /// fmi2SetTime in Event Mode: only for an FMU without continuous states, after the event
    /// iteration (condition 8).
    SetTimeIf,
}

impl Function {
    /// The functions an FMU offering `interface` must export.
    pub(crate) fn of(interface: Interface) -> impl Iterator<Item = Function> {
        let names: &'static [&'static str] = match interface {
            Interface::CoSimulation => &fmi_c::fmi2::CO_SIMULATION_FUNCTIONS,
            Interface::ModelExchange => &fmi_c::fmi2::MODEL_EXCHANGE_FUNCTIONS,
        };
        Function::ALL.iter().copied().filter(move |f| fmi_c::fmi2::COMMON_FUNCTIONS.contains(&f.name()) || names.contains(&f.name()))
    }

    /// Whether the standard allows this function in `state` of an `interface` instance.
    pub(crate) fn rule(self, interface: Interface, state: State) -> Rule {
        use Function as F;
        use Rule::*;
        use State as S;
        if matches!(self, F::GetTypesPlatform | F::GetVersion) {
            return Allowed;
        }
        if state == S::Gone {
            return Illegal;
        }
        let get = |s: State| match s {
            S::InitializationMode => GetIf,
            S::StepComplete | S::StepFailed | S::EventMode | S::ContinuousTimeMode | S::Terminated | S::Error => Allowed,
            _ => Illegal,
        };
        let any_instance = |s: State| if s == S::Gone { Illegal } else { Allowed };
        match interface {
            Interface::CoSimulation => match self {
                F::SetDebugLogging | F::FreeInstance | F::Reset => any_instance(state),
                F::SetupExperiment | F::EnterInitializationMode => only(state, &[S::Instantiated]),
                F::ExitInitializationMode => only(state, &[S::InitializationMode]),
                F::Terminate => only(state, &[S::StepComplete, S::StepFailed]),
                F::GetReal | F::GetInteger | F::GetBoolean | F::GetString => get(state),
                F::SetReal | F::SetInteger | F::SetBoolean | F::SetString => {
                    if matches!(state, S::Instantiated | S::InitializationMode | S::StepComplete) {
                        SetIf
                    } else {
                        Illegal
                    }
                }
                F::GetFmuState
                | F::SetFmuState
                | F::FreeFmuState
                | F::SerializedFmuStateSize
                | F::SerializeFmuState
                | F::DeSerializeFmuState => any_instance(state),
                F::GetDirectionalDerivative => {
                    only(state, &[S::InitializationMode, S::StepComplete, S::StepFailed, S::Terminated, S::Error])
                }
                F::SetRealInputDerivatives => only(state, &[S::Instantiated, S::InitializationMode, S::StepComplete]),
                F::GetRealOutputDerivatives => only(state, &[S::StepComplete, S::StepFailed, S::Terminated, S::Error]),
                F::DoStep => only(state, &[S::StepComplete]),
                // Only in StepInProgress, which a synchronous run never enters.
                F::CancelStep => Illegal,
                F::GetStatus | F::GetRealStatus | F::GetIntegerStatus | F::GetBooleanStatus | F::GetStringStatus => {
                    only(state, &[S::StepComplete, S::StepFailed, S::Terminated])
                }
                _ => Illegal,
            },
            Interface::ModelExchange => match self {
                F::SetDebugLogging | F::FreeInstance | F::Reset => any_instance(state),
                F::SetupExperiment | F::EnterInitializationMode => only(state, &[S::Instantiated]),
                F::ExitInitializationMode => only(state, &[S::InitializationMode]),
                F::Terminate => only(state, &[S::EventMode, S::ContinuousTimeMode]),
                F::GetReal | F::GetInteger | F::GetBoolean | F::GetString => get(state),
                F::SetReal => {
                    if matches!(state, S::Instantiated | S::InitializationMode | S::EventMode | S::ContinuousTimeMode) {
                        SetIf
                    } else {
                        Illegal
                    }
                }
                F::SetInteger | F::SetBoolean | F::SetString => {
                    if matches!(state, S::Instantiated | S::InitializationMode | S::EventMode) {
                        SetIf
                    } else {
                        Illegal
                    }
                }
                F::GetFmuState
                | F::SetFmuState
                | F::FreeFmuState
                | F::SerializedFmuStateSize
                | F::SerializeFmuState
                | F::DeSerializeFmuState => any_instance(state),
                F::GetDirectionalDerivative | F::GetEventIndicators | F::GetContinuousStates | F::GetDerivatives => {
                    only(state, &[S::InitializationMode, S::EventMode, S::ContinuousTimeMode, S::Terminated, S::Error])
                }
                F::GetNominalsOfContinuousStates => {
                    only(state, &[S::Instantiated, S::InitializationMode, S::EventMode, S::ContinuousTimeMode, S::Terminated, S::Error])
                }
                F::EnterEventMode => only(state, &[S::EventMode, S::ContinuousTimeMode]),
                F::NewDiscreteStates | F::EnterContinuousTimeMode => only(state, &[S::EventMode]),
                F::CompletedIntegratorStep | F::SetContinuousStates => only(state, &[S::ContinuousTimeMode]),
                F::SetTime => match state {
                    S::ContinuousTimeMode => Allowed,
                    S::EventMode => SetTimeIf,
                    _ => Illegal,
                },
                _ => Illegal,
            },
        }
    }
}

fn only(state: State, allowed: &[State]) -> Rule {
    if allowed.contains(&state) {
        Rule::Allowed
    } else {
        Rule::Illegal
    }
}

/// Whether the standard lets `function` (an fmi2Set*) set `v` in `state`: `Some(true)` yes,
/// `Some(false)` no, `None` where the validator does not hold an FMU to the letter (an input
/// set in Instantiated: the table's condition 1 omits inputs, but setting an input's start
/// value before initialization is harmless and common; a continuous-time state set with
/// fmi2SetReal in Continuous-Time Mode, which FMI 2.0.4's text of fmi2SetReal (section 2.1.7)
/// leaves out and FMI 3.0 added later, while fmi2SetContinuousStates is the call the standard
/// makes for it).
pub(crate) fn may_set(function: Function, interface: Interface, state: State, v: &Var) -> Option<bool> {
    let settable_initial =
        |initials: &[Initial]| v.variability != Variability::Constant && v.initial.is_some_and(|i| initials.contains(&i));
    let input_or_tunable =
        v.causality == Causality::Input || (v.causality == Causality::Parameter && v.variability == Variability::Tunable);
    Some(match (interface, state) {
        // Condition 1.
        (_, State::Instantiated) => {
            if v.causality == Causality::Input {
                return None;
            }
            settable_initial(&[Initial::Exact, Initial::Approx])
        }
        // Condition 3.
        (_, State::InitializationMode) => settable_initial(&[Initial::Exact]) || v.causality == Causality::Input,
        // Condition 6 (Co-Simulation) and 4 (Model Exchange, Event Mode).
        (Interface::CoSimulation, State::StepComplete) | (Interface::ModelExchange, State::EventMode) => input_or_tunable,
        // Condition 5: fmi2SetReal only, continuous inputs; continuous-time states either way.
        (Interface::ModelExchange, State::ContinuousTimeMode) => {
            if function == Function::SetReal && v.is_state && v.causality != Causality::Input {
                return None;
            }
            function == Function::SetReal && v.causality == Causality::Input && v.variability == Variability::Continuous
        }
        _ => false,
    })
}

/// Whether a get of `v` is guaranteed in Initialization Mode (condition 2): outputs and
/// InitialUnknowns. Other variables are not probed there.
pub(crate) fn may_get_in_initialization(v: &Var, is_initial_unknown: bool) -> bool {
    v.causality == Causality::Output || is_initial_unknown
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi2::model::Base;

    /// Spot checks against the standard's two tables (a wrong cell would make the validator
    /// accuse a correct FMU or pass a wrong one).
    #[test]
    fn the_tables_match_the_standard() {
        use Function as F;
        use Interface::*;
        use State as S;
        assert_eq!(Function::ALL.len(), 44);
        assert_eq!(Function::of(CoSimulation).count(), 34);
        assert_eq!(Function::of(ModelExchange).count(), 35);
        assert_eq!(F::DoStep.rule(CoSimulation, S::StepComplete), Rule::Allowed);
        for s in [S::Instantiated, S::InitializationMode, S::Terminated, S::Error] {
            assert_eq!(F::DoStep.rule(CoSimulation, s), Rule::Illegal, "DoStep in {s:?}");
        }
        assert_eq!(F::GetReal.rule(CoSimulation, S::Instantiated), Rule::Illegal);
        assert_eq!(F::GetReal.rule(CoSimulation, S::InitializationMode), Rule::GetIf);
        assert_eq!(F::GetReal.rule(ModelExchange, S::Error), Rule::Allowed);
        assert_eq!(F::Terminate.rule(ModelExchange, S::EventMode), Rule::Allowed);
        assert_eq!(F::Terminate.rule(CoSimulation, S::InitializationMode), Rule::Illegal);
        assert_eq!(F::Reset.rule(CoSimulation, S::Error), Rule::Allowed);
        assert_eq!(F::CancelStep.rule(CoSimulation, S::StepComplete), Rule::Illegal);
        assert_eq!(F::GetStatus.rule(CoSimulation, S::Error), Rule::Illegal);
        assert_eq!(F::GetDerivatives.rule(ModelExchange, S::InitializationMode), Rule::Allowed, "the FMI 2.0.1 bugfix");
        assert_eq!(F::GetDerivatives.rule(ModelExchange, S::Instantiated), Rule::Illegal);
        assert_eq!(F::GetNominalsOfContinuousStates.rule(ModelExchange, S::Instantiated), Rule::Allowed);
        assert_eq!(F::SetTime.rule(ModelExchange, S::EventMode), Rule::SetTimeIf);
        assert_eq!(F::SetContinuousStates.rule(ModelExchange, S::EventMode), Rule::Illegal);
        assert_eq!(F::SetInteger.rule(ModelExchange, S::ContinuousTimeMode), Rule::Illegal);
        assert_eq!(F::SetReal.rule(ModelExchange, S::ContinuousTimeMode), Rule::SetIf);
        assert_eq!(F::NewDiscreteStates.rule(ModelExchange, S::ContinuousTimeMode), Rule::Illegal);
        assert_eq!(F::SetupExperiment.rule(CoSimulation, S::Gone), Rule::Illegal);
    }

    fn var(causality: Causality, variability: Variability, initial: Option<Initial>, is_state: bool) -> Var {
        Var { name: "v".into(), vr: 0, base: Base::Real, causality, variability, initial, is_state, start: None, min: None, max: None }
    }

    #[test]
    fn the_set_conditions_match_the_standard() {
        use Causality as C;
        use Interface::*;
        use State as S;
        use Variability as V;
        let fixed = var(C::Parameter, V::Fixed, Some(Initial::Exact), false);
        let tunable = var(C::Parameter, V::Tunable, Some(Initial::Exact), false);
        let output = var(C::Output, V::Continuous, Some(Initial::Calculated), false);
        let state_output = var(C::Output, V::Continuous, Some(Initial::Exact), true);
        let input = var(C::Input, V::Continuous, None, false);
        let discrete_input = var(C::Input, V::Discrete, None, false);
        let calculated = var(C::CalculatedParameter, V::Fixed, Some(Initial::Calculated), false);
        let constant = var(C::Local, V::Constant, Some(Initial::Exact), false);
        let set = |v: &Var, i, s| may_set(Function::SetReal, i, s, v);
        assert_eq!(set(&fixed, CoSimulation, S::Instantiated), Some(true));
        assert_eq!(set(&fixed, CoSimulation, S::InitializationMode), Some(true));
        assert_eq!(set(&fixed, CoSimulation, S::StepComplete), Some(false), "a fixed parameter after initialization");
        assert_eq!(set(&tunable, CoSimulation, S::StepComplete), Some(true));
        assert_eq!(set(&tunable, ModelExchange, S::ContinuousTimeMode), Some(false));
        assert_eq!(set(&tunable, ModelExchange, S::EventMode), Some(true));
        for s in [S::Instantiated, S::InitializationMode, S::StepComplete] {
            assert_eq!(set(&output, CoSimulation, s), Some(false), "an output is never set ({s:?})");
            assert_eq!(set(&calculated, CoSimulation, s), Some(false), "a calculated parameter is never set ({s:?})");
            assert_eq!(set(&constant, CoSimulation, s), Some(false), "a constant is never set ({s:?})");
        }
        assert_eq!(set(&state_output, ModelExchange, S::ContinuousTimeMode), None, "a state: FMI 2.0.4 and 3.0 differ");
        assert_eq!(set(&state_output, ModelExchange, S::EventMode), Some(false));
        assert_eq!(set(&input, CoSimulation, S::Instantiated), None, "tolerated");
        assert_eq!(set(&input, CoSimulation, S::StepComplete), Some(true));
        assert_eq!(set(&discrete_input, ModelExchange, S::ContinuousTimeMode), Some(false));
        assert_eq!(may_set(Function::SetInteger, ModelExchange, S::ContinuousTimeMode, &input), Some(false));
        assert_eq!(set(&fixed, CoSimulation, S::Terminated), Some(false));
    }
}
