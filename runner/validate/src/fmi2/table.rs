//! The FMI 2.0 state machines as data: the tables of sections 4.2.4 (Co-Simulation) and 3.2.3
//! (Model Exchange) of FMI 2.0.4, every function in every state, including the conditions on
//! the variable a set or get names. Written from the standard, independently of our exporter's
//! table, so that it checks it.

use crate::fmi::{Interface, Op, State, Type};
use crate::model::{Causality, Initial, Var, Variability};
use crate::table::{Row, Table};

/// The columns of the Co-Simulation table.
const CO_SIMULATION: [State; 6] =
    [State::Instantiated, State::InitializationMode, State::StepComplete, State::StepFailed, State::Terminated, State::Error];
/// The columns of the Model Exchange table.
const MODEL_EXCHANGE: [State; 6] =
    [State::Instantiated, State::InitializationMode, State::EventMode, State::ContinuousTimeMode, State::Terminated, State::Error];

/// A row of both interfaces.
const fn both(op: Op, name: &'static str, rules: &'static str) -> Row {
    Row { op, name, co_simulation: Some(rules), model_exchange: Some(rules) }
}

/// A row of each interface's own rules; `""` for a function the interface does not have.
const fn each(op: Op, name: &'static str, co_simulation: &'static str, model_exchange: &'static str) -> Row {
    Row {
        op,
        name,
        co_simulation: if co_simulation.is_empty() { None } else { Some(co_simulation) },
        model_exchange: if model_exchange.is_empty() { None } else { Some(model_exchange) },
    }
}

// The rules, one per column: x allowed ("7" and "8" too: allowed, values for debugging only),
// . not allowed, s a set allowed for some variables (conditions 1, 3, 4, 5, 6), g a get
// allowed for outputs and InitialUnknowns (condition 2), t fmi2SetTime in Event Mode
// (condition 8), - not probed here. fmi2GetTypesPlatform and fmi2GetVersion are allowed in
// every state but need no instance: they are probed once. fmi2Instantiate makes every
// instance, and fmi2FreeInstance closes every state's cells.
//
//                        Co-Simulation: Instantiated, InitializationMode, StepComplete, StepFailed, Terminated, Error
//                        Model Exchange: Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated, Error
const ROWS: [Row; 44] = [
    both(Op::GetTypesPlatform, "fmi2GetTypesPlatform", "x - - - - -"),
    both(Op::GetVersion, "fmi2GetVersion", "x - - - - -"),
    both(Op::SetDebugLogging, "fmi2SetDebugLogging", "x x x x x x"),
    both(Op::Instantiate, "fmi2Instantiate", "- - - - - -"),
    both(Op::FreeInstance, "fmi2FreeInstance", "x x x x x x"),
    both(Op::SetupExperiment, "fmi2SetupExperiment", "x . . . . ."),
    both(Op::EnterInitializationMode, "fmi2EnterInitializationMode", "x . . . . ."),
    both(Op::ExitInitializationMode, "fmi2ExitInitializationMode", ". x . . . ."),
    both(Op::Terminate, "fmi2Terminate", ". . x x . ."),
    both(Op::Reset, "fmi2Reset", "x x x x x x"),
    both(Op::Get(Type::Real), "fmi2GetReal", ". g x x x x"),
    both(Op::Get(Type::Integer), "fmi2GetInteger", ". g x x x x"),
    both(Op::Get(Type::Boolean), "fmi2GetBoolean", ". g x x x x"),
    both(Op::Get(Type::String), "fmi2GetString", ". g x x x x"),
    each(Op::Set(Type::Real), "fmi2SetReal", "s s s . . .", "s s s s . ."),
    both(Op::Set(Type::Integer), "fmi2SetInteger", "s s s . . ."),
    both(Op::Set(Type::Boolean), "fmi2SetBoolean", "s s s . . ."),
    both(Op::Set(Type::String), "fmi2SetString", "s s s . . ."),
    both(Op::GetFmuState, "fmi2GetFMUstate", "x x x x x x"),
    both(Op::SetFmuState, "fmi2SetFMUstate", "x x x x x x"),
    both(Op::FreeFmuState, "fmi2FreeFMUstate", "x x x x x x"),
    both(Op::SerializedFmuStateSize, "fmi2SerializedFMUstateSize", "x x x x x x"),
    both(Op::SerializeFmuState, "fmi2SerializeFMUstate", "x x x x x x"),
    both(Op::DeserializeFmuState, "fmi2DeSerializeFMUstate", "x x x x x x"),
    both(Op::GetDirectionalDerivative, "fmi2GetDirectionalDerivative", ". x x x x x"),
    each(Op::EnterEventMode, "fmi2EnterEventMode", "", ". . x x . ."),
    each(Op::UpdateDiscreteStates, "fmi2NewDiscreteStates", "", ". . x . . ."),
    each(Op::EnterContinuousTimeMode, "fmi2EnterContinuousTimeMode", "", ". . x . . ."),
    each(Op::CompletedIntegratorStep, "fmi2CompletedIntegratorStep", "", ". . . x . ."),
    each(Op::SetTime, "fmi2SetTime", "", ". . t x . ."),
    each(Op::SetContinuousStates, "fmi2SetContinuousStates", "", ". . . x . ."),
    // Also in Initialization Mode: the FMI 2.0.1 bugfix.
    each(Op::GetDerivatives, "fmi2GetDerivatives", "", ". x x x x x"),
    each(Op::GetEventIndicators, "fmi2GetEventIndicators", "", ". x x x x x"),
    each(Op::GetContinuousStates, "fmi2GetContinuousStates", "", ". x x x x x"),
    each(Op::GetNominalsOfContinuousStates, "fmi2GetNominalsOfContinuousStates", "", "x x x x x x"),
    each(Op::SetInputDerivatives, "fmi2SetRealInputDerivatives", "x x x . . .", ""),
    each(Op::GetOutputDerivatives, "fmi2GetRealOutputDerivatives", ". . x x x x", ""),
    each(Op::DoStep, "fmi2DoStep", ". . x . . .", ""),
    // Only in StepInProgress, which a synchronous run never enters.
    each(Op::CancelStep, "fmi2CancelStep", ". . . . . .", ""),
    each(Op::Status(None), "fmi2GetStatus", ". . x x x .", ""),
    each(Op::Status(Some(Type::Real)), "fmi2GetRealStatus", ". . x x x .", ""),
    each(Op::Status(Some(Type::Integer)), "fmi2GetIntegerStatus", ". . x x x .", ""),
    each(Op::Status(Some(Type::Boolean)), "fmi2GetBooleanStatus", ". . x x x .", ""),
    each(Op::Status(Some(Type::String)), "fmi2GetStringStatus", ". . x x x .", ""),
];

/// The FMI 2.0 table.
pub(crate) static TABLE: Table = Table {
    co_simulation: &CO_SIMULATION,
    model_exchange: &MODEL_EXCHANGE,
    between_steps: State::StepComplete,
    unreached: Some((
        State::StepFailed,
        "StepFailed, StepCanceled and StepInProgress are not probed call by call: the validator steps synchronously and cannot make a model fail a step",
    )),
    rows: &ROWS,
    may_set,
    may_get_in_initialization,
    why_not_settable,
};

/// Whether the standard lets `op` (an fmi2Set*) set `v` in `state`: `Some(true)` yes,
/// `Some(false)` no, `None` where the validator does not hold an FMU to the letter (an input
/// set in Instantiated: the table's condition 1 omits inputs, but setting an input's start
/// value before initialization is harmless and common; a continuous-time state set with
/// fmi2SetReal in Continuous-Time Mode, which FMI 2.0.4's text of fmi2SetReal (section 2.1.7)
/// leaves out and FMI 3.0 added later, while fmi2SetContinuousStates is the call the standard
/// makes for it).
fn may_set(op: Op, interface: Interface, state: State, v: &Var) -> Option<bool> {
    let settable_initial =
        |initials: &[Initial]| v.variability != Variability::Constant && v.initial.is_some_and(|i| initials.contains(&i));
    let input_or_tunable =
        v.causality == Causality::Input || (v.causality == Causality::Parameter && v.variability == Variability::Tunable);
    let set_real = op == Op::Set(Type::Real);
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
            if set_real && v.is_state && v.causality != Causality::Input {
                return None;
            }
            set_real && v.causality == Causality::Input && v.variability == Variability::Continuous
        }
        _ => false,
    })
}

/// Whether a get of `v` is guaranteed in Initialization Mode (condition 2): outputs and
/// InitialUnknowns. Other variables are not probed there.
fn may_get_in_initialization(v: &Var, is_initial_unknown: bool) -> bool {
    v.causality == Causality::Output || is_initial_unknown
}

/// Why the standard forbids setting a variable in `state`, for the message.
fn why_not_settable(state: State) -> &'static str {
    match state {
        State::Instantiated => {
            "before initialization only variables with initial=\"exact\" or \"approx\" that are not constants may be set"
        }
        State::InitializationMode => {
            "in Initialization Mode only inputs and variables with initial=\"exact\" that are not constants may be set"
        }
        State::StepComplete | State::EventMode => "after initialization only inputs and tunable parameters may be set",
        State::ContinuousTimeMode => {
            "in Continuous-Time Mode only continuous inputs and continuous states may be set, and only with fmi2SetReal"
        }
        _ => "no variable may be set in this state",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::var;
    use crate::table::Rule;

    #[test]
    fn the_table_is_well_formed_and_lists_every_function() {
        assert_eq!(TABLE.malformed(), Vec::<String>::new());
        let names = |interface| TABLE.functions(interface).map(|op| TABLE.name(op, interface)).collect::<Vec<_>>();
        let mut cs: Vec<&str> = fmi_c::fmi2::COMMON_FUNCTIONS.iter().chain(&fmi_c::fmi2::CO_SIMULATION_FUNCTIONS).copied().collect();
        let mut me: Vec<&str> = fmi_c::fmi2::COMMON_FUNCTIONS.iter().chain(&fmi_c::fmi2::MODEL_EXCHANGE_FUNCTIONS).copied().collect();
        let (mut got_cs, mut got_me) = (names(Interface::CoSimulation), names(Interface::ModelExchange));
        for list in [&mut cs, &mut me, &mut got_cs, &mut got_me] {
            list.sort();
        }
        assert_eq!((got_cs, got_me), (cs, me), "the functions each interface must export");
    }

    /// Spot checks against the standard's two tables (a wrong cell would make the validator
    /// accuse a correct FMU or pass a wrong one).
    #[test]
    fn the_tables_match_the_standard() {
        use Interface::*;
        use State as S;
        let rule = |op, interface, state| TABLE.rule(op, interface, state);
        assert_eq!(rule(Op::DoStep, CoSimulation, S::StepComplete), Rule::Allowed);
        for s in [S::Instantiated, S::InitializationMode, S::Terminated, S::Error] {
            assert_eq!(rule(Op::DoStep, CoSimulation, s), Rule::Illegal, "DoStep in {s:?}");
        }
        assert_eq!(rule(Op::Get(Type::Real), CoSimulation, S::Instantiated), Rule::Illegal);
        assert_eq!(rule(Op::Get(Type::Real), CoSimulation, S::InitializationMode), Rule::GetIf);
        assert_eq!(rule(Op::Get(Type::Real), ModelExchange, S::Error), Rule::Allowed);
        assert_eq!(rule(Op::Terminate, ModelExchange, S::EventMode), Rule::Allowed);
        assert_eq!(rule(Op::Terminate, CoSimulation, S::InitializationMode), Rule::Illegal);
        assert_eq!(rule(Op::Reset, CoSimulation, S::Error), Rule::Allowed);
        assert_eq!(rule(Op::CancelStep, CoSimulation, S::StepComplete), Rule::Illegal);
        assert_eq!(rule(Op::Status(None), CoSimulation, S::Error), Rule::Illegal);
        assert_eq!(rule(Op::GetDerivatives, ModelExchange, S::InitializationMode), Rule::Allowed, "the FMI 2.0.1 bugfix");
        assert_eq!(rule(Op::GetDerivatives, ModelExchange, S::Instantiated), Rule::Illegal);
        assert_eq!(rule(Op::GetNominalsOfContinuousStates, ModelExchange, S::Instantiated), Rule::Allowed);
        assert_eq!(rule(Op::SetTime, ModelExchange, S::EventMode), Rule::SetTimeIf);
        assert_eq!(rule(Op::SetContinuousStates, ModelExchange, S::EventMode), Rule::Illegal);
        assert_eq!(rule(Op::Set(Type::Integer), ModelExchange, S::ContinuousTimeMode), Rule::Illegal);
        assert_eq!(rule(Op::Set(Type::Real), ModelExchange, S::ContinuousTimeMode), Rule::SetIf);
        assert_eq!(rule(Op::UpdateDiscreteStates, ModelExchange, S::ContinuousTimeMode), Rule::Illegal);
        assert_eq!(rule(Op::SetupExperiment, CoSimulation, S::Gone), Rule::Illegal);
        assert_eq!(rule(Op::DoStep, ModelExchange, S::EventMode), Rule::Illegal, "not a function of the interface");
        assert_eq!(rule(Op::GetVersion, CoSimulation, S::Terminated), Rule::Unprobed, "probed once, in Instantiated");
        assert_eq!(TABLE.name(Op::UpdateDiscreteStates, ModelExchange), "fmi2NewDiscreteStates");
        assert_eq!(TABLE.states(CoSimulation, false), [S::Instantiated, S::InitializationMode, S::StepComplete, S::Terminated, S::Error]);
        assert_eq!(TABLE.states(ModelExchange, false).len(), 6);
    }

    #[test]
    fn the_set_conditions_match_the_standard() {
        use Causality as C;
        use Interface::*;
        use State as S;
        use Variability as V;
        let v = |causality, variability, initial, is_state| Var { is_state, ..var("v", 0, Type::Real, causality, variability, initial) };
        let fixed = v(C::Parameter, V::Fixed, Some(Initial::Exact), false);
        let tunable = v(C::Parameter, V::Tunable, Some(Initial::Exact), false);
        let output = v(C::Output, V::Continuous, Some(Initial::Calculated), false);
        let state_output = v(C::Output, V::Continuous, Some(Initial::Exact), true);
        let input = v(C::Input, V::Continuous, None, false);
        let discrete_input = v(C::Input, V::Discrete, None, false);
        let calculated = v(C::CalculatedParameter, V::Fixed, Some(Initial::Calculated), false);
        let constant = v(C::Local, V::Constant, Some(Initial::Exact), false);
        let set = |v: &Var, i, s| may_set(Op::Set(Type::Real), i, s, v);
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
        assert_eq!(may_set(Op::Set(Type::Integer), ModelExchange, S::ContinuousTimeMode, &input), Some(false));
        assert_eq!(set(&fixed, CoSimulation, S::Terminated), Some(false));
    }
}
