//! The FMI 3.0 state machines as data, from the "Allowed Function Calls" of each state in FMI
//! 3.0.2 (sections 2.3, 3.2 and 4.2: functions of another interface are not allowed at all),
//! for the functions the validator probes: the lifecycle, the mode changes and steps of both
//! interfaces, the values of the four types it exchanges, FMU state. Cells marked `-` are not
//! probed yet (the clocks, configuration mode, derivatives and the other value types are not
//! probed at all).

use crate::fmi::{Interface, Op, State, Type};
use crate::model::{Causality, Var, Variability};
use crate::table::{Row, Table};

/// The columns of Co-Simulation (Event Mode only in instances made with eventModeUsed).
const CO_SIMULATION: [State; 5] = [State::Instantiated, State::InitializationMode, State::EventMode, State::StepMode, State::Terminated];
/// The columns of Model Exchange.
const MODEL_EXCHANGE: [State; 5] =
    [State::Instantiated, State::InitializationMode, State::EventMode, State::ContinuousTimeMode, State::Terminated];

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

// The rules, one per column: x allowed, . not allowed, s a set allowed for some variables
// (see may_set), e fmi3EnterEventMode in Step Mode, allowed only with eventModeUsed, - not
// probed here. fmi3GetVersion needs no instance: it is probed once. The gets in Instantiated
// (the standard allows them: "Returns the current start values") are not probed yet: the
// FMUs this project exports refuse them. The instantiation
// functions make every instance, and fmi3FreeInstance closes every state's cells. The Model
// Exchange evaluations are not probed in Instantiated (where the standard leaves them out,
// and the sizes may still change), nor in Co-Simulation instances but for the three the
// Reference FMUs' deviations show.
//
//                     Co-Simulation: Instantiated, InitializationMode, EventMode, StepMode, Terminated
//                     Model Exchange: Instantiated, InitializationMode, EventMode, ContinuousTimeMode, Terminated
const ROWS: [Row; 37] = [
    both(Op::GetVersion, "fmi3GetVersion", "x - - - -"),
    both(Op::SetDebugLogging, "fmi3SetDebugLogging", "x x x x x"),
    each(Op::Instantiate, "fmi3InstantiateModelExchange", "", "- - - - -"),
    each(Op::Instantiate, "fmi3InstantiateCoSimulation", "- - - - -", ""),
    both(Op::FreeInstance, "fmi3FreeInstance", "x x x x x"),
    both(Op::EnterInitializationMode, "fmi3EnterInitializationMode", "x . . . ."),
    both(Op::ExitInitializationMode, "fmi3ExitInitializationMode", ". x . . ."),
    each(Op::EnterEventMode, "fmi3EnterEventMode", ". . . e .", ". . . x ."),
    both(Op::Terminate, "fmi3Terminate", ". . x x ."),
    both(Op::Reset, "fmi3Reset", "x x x x x"),
    both(Op::Get(Type::Real), "fmi3GetFloat64", "- x x x x"),
    both(Op::Get(Type::Integer), "fmi3GetInt32", "- x x x x"),
    both(Op::Get(Type::Boolean), "fmi3GetBoolean", "- x x x x"),
    both(Op::Get(Type::String), "fmi3GetString", "- x x x x"),
    both(Op::Set(Type::Real), "fmi3SetFloat64", "s s s s s"),
    both(Op::Set(Type::Integer), "fmi3SetInt32", "s s s s s"),
    both(Op::Set(Type::Boolean), "fmi3SetBoolean", "s s s s s"),
    both(Op::Set(Type::String), "fmi3SetString", "s s s s s"),
    both(Op::GetFmuState, "fmi3GetFMUState", "x x x x x"),
    both(Op::SetFmuState, "fmi3SetFMUState", "x x x x x"),
    both(Op::FreeFmuState, "fmi3FreeFMUState", "x x x x x"),
    both(Op::SerializedFmuStateSize, "fmi3SerializedFMUStateSize", "x x x x x"),
    both(Op::SerializeFmuState, "fmi3SerializeFMUState", "x x x x x"),
    both(Op::DeserializeFmuState, "fmi3DeserializeFMUState", "x x x x x"),
    both(Op::UpdateDiscreteStates, "fmi3UpdateDiscreteStates", ". . x . ."),
    each(Op::EnterContinuousTimeMode, "fmi3EnterContinuousTimeMode", ". . . . .", ". . x . ."),
    each(Op::CompletedIntegratorStep, "fmi3CompletedIntegratorStep", "- - - - -", ". . . x ."),
    each(Op::SetTime, "fmi3SetTime", ". . . . .", ". . . x ."),
    each(Op::SetContinuousStates, "fmi3SetContinuousStates", "- - - - -", ". . . x ."),
    each(Op::GetDerivatives, "fmi3GetContinuousStateDerivatives", ". . . . .", "- x x x x"),
    each(Op::GetEventIndicators, "fmi3GetEventIndicators", "- - - - -", "- x x x x"),
    each(Op::GetContinuousStates, "fmi3GetContinuousStates", "- - - - -", "- x x x x"),
    each(Op::GetNominalsOfContinuousStates, "fmi3GetNominalsOfContinuousStates", "- - - - -", "- x x x x"),
    each(Op::GetNumberOfEventIndicators, "fmi3GetNumberOfEventIndicators", "- - - - -", "- - - - -"),
    each(Op::GetNumberOfContinuousStates, "fmi3GetNumberOfContinuousStates", "- - - - -", "- - - - -"),
    each(Op::EnterStepMode, "fmi3EnterStepMode", ". . x . .", ". . . . ."),
    each(Op::DoStep, "fmi3DoStep", ". . . x .", ". . . . ."),
];

/// The FMI 3.0 table.
pub(crate) static TABLE: Table = Table {
    co_simulation: &CO_SIMULATION,
    model_exchange: &MODEL_EXCHANGE,
    between_steps: State::StepMode,
    unreached: None,
    rows: &ROWS,
    may_set,
    may_get_in_initialization,
    why_not_settable,
};

/// Whether the standard lets `v` be set in `state` (FMI 3.0.2 section 2.3: before
/// initialization variables that are not constants and have initial exact or approx, in
/// Initialization Mode those with initial exact, then inputs and tunable parameters; in
/// Terminated none): `Some(false)` for constants, and for fixed parameters after
/// initialization; `Some(true)` for parameters and inputs where the standard allows them. The
/// other kinds of variable, and Continuous-Time Mode and Terminated but for those two, are not
/// probed yet (`None`).
fn may_set(_op: Op, _interface: Interface, state: State, v: &Var) -> Option<bool> {
    if v.variability == Variability::Constant {
        return Some(false);
    }
    let before = matches!(state, State::Instantiated | State::InitializationMode);
    let between = matches!(state, State::EventMode | State::StepMode);
    match (v.causality, v.variability) {
        (Causality::Parameter, Variability::Fixed) => Some(before),
        (Causality::Parameter, Variability::Tunable) | (Causality::Input, _) if before || between => Some(true),
        _ => None,
    }
}

/// Initialization Mode lets every variable be read ("Getting variables might trigger
/// computations"; the start values of the others).
fn may_get_in_initialization(_v: &Var, _is_initial_unknown: bool) -> bool {
    true
}

/// Why the standard forbids setting a variable in `state`, for the message.
fn why_not_settable(state: State) -> &'static str {
    match state {
        State::Instantiated => {
            "before initialization only variables with initial=\"exact\" or \"approx\" that are not constants may be set"
        }
        State::InitializationMode => "in Initialization Mode only variables with initial=\"exact\" that are not constants may be set",
        State::EventMode | State::StepMode => "after initialization only inputs and tunable parameters may be set",
        State::ContinuousTimeMode => "in Continuous-Time Mode only continuous inputs and continuous states may be set",
        _ => "no variable may be set in this state",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::var;
    use crate::table::Rule;

    #[test]
    fn the_table_is_well_formed() {
        assert_eq!(TABLE.malformed(), Vec::<String>::new());
        for row in &ROWS {
            let all = fmi_c::fmi3::COMMON_FUNCTIONS
                .iter()
                .chain(&fmi_c::fmi3::MODEL_EXCHANGE_FUNCTIONS)
                .chain(&fmi_c::fmi3::CO_SIMULATION_FUNCTIONS);
            assert!(all.clone().any(|f| *f == row.name), "{} is an FMI 3.0 function", row.name);
        }
        assert_eq!(TABLE.name(Op::Instantiate, Interface::CoSimulation), "fmi3InstantiateCoSimulation");
        assert_eq!(TABLE.name(Op::Instantiate, Interface::ModelExchange), "fmi3InstantiateModelExchange");
    }

    /// The calls that move an instance on are allowed exactly in the state they leave (the
    /// table would otherwise flag every correct FMU), and refused everywhere else.
    #[test]
    fn the_table_allows_each_transition_exactly_where_the_standard_does() {
        let cs = Interface::CoSimulation;
        let me = Interface::ModelExchange;
        let allowed_in = |interface, op: Op, event_mode| -> Vec<State> {
            TABLE
                .states(interface, event_mode)
                .into_iter()
                .filter(|s| match TABLE.rule(op, interface, *s) {
                    Rule::Allowed => true,
                    Rule::EventModeUsed => event_mode,
                    _ => false,
                })
                .collect()
        };
        use State as S;
        assert_eq!(allowed_in(cs, Op::DoStep, false), [S::StepMode]);
        assert_eq!(allowed_in(cs, Op::EnterStepMode, true), [S::EventMode]);
        assert_eq!(allowed_in(cs, Op::EnterEventMode, true), [S::StepMode]);
        assert_eq!(allowed_in(cs, Op::EnterEventMode, false), []);
        assert_eq!(allowed_in(me, Op::EnterEventMode, false), [S::ContinuousTimeMode]);
        assert_eq!(allowed_in(me, Op::EnterContinuousTimeMode, false), [S::EventMode]);
        assert_eq!(allowed_in(me, Op::SetTime, false), [S::ContinuousTimeMode]);
        assert_eq!(allowed_in(me, Op::CompletedIntegratorStep, false), [S::ContinuousTimeMode]);
        assert_eq!(allowed_in(me, Op::UpdateDiscreteStates, false), [S::EventMode]);
        assert_eq!(allowed_in(cs, Op::UpdateDiscreteStates, true), [S::EventMode]);
        assert_eq!(allowed_in(me, Op::ExitInitializationMode, false), [S::InitializationMode]);
        assert_eq!(allowed_in(cs, Op::EnterInitializationMode, false), [S::Instantiated]);
        assert_eq!(allowed_in(me, Op::Terminate, false), [S::EventMode, S::ContinuousTimeMode]);
        // The other interface's functions nowhere.
        assert!(allowed_in(me, Op::DoStep, false).is_empty() && allowed_in(me, Op::EnterStepMode, false).is_empty());
        assert!(allowed_in(cs, Op::GetDerivatives, true).is_empty());
        assert_eq!(TABLE.rule(Op::Terminate, cs, S::Terminated), Rule::Illegal);
        assert_eq!(TABLE.states(cs, false), [S::Instantiated, S::InitializationMode, S::StepMode, S::Terminated]);
        assert_eq!(TABLE.states(cs, true).len(), 5);
    }

    #[test]
    fn constants_and_fixed_parameters_after_initialization_may_not_be_set() {
        use Causality as C;
        use Variability as V;
        let constant = var("c", 0, Type::Real, C::Local, V::Constant, None);
        let fixed = var("k", 1, Type::Real, C::Parameter, V::Fixed, None);
        let tunable = var("p", 2, Type::Real, C::Parameter, V::Tunable, None);
        let output = var("y", 3, Type::Real, C::Output, V::Continuous, None);
        let input = var("u", 4, Type::String, C::Input, V::Discrete, None);
        let set = |v: &Var, s| may_set(Op::Set(Type::Real), Interface::CoSimulation, s, v);
        for s in CO_SIMULATION {
            assert_eq!(set(&constant, s), Some(false), "{s:?}");
            assert_eq!(set(&output, s), None, "not probed yet ({s:?})");
        }
        assert_eq!((set(&fixed, State::InitializationMode), set(&fixed, State::StepMode)), (Some(true), Some(false)));
        assert_eq!((set(&tunable, State::StepMode), set(&tunable, State::Terminated)), (Some(true), None));
        assert_eq!((set(&input, State::EventMode), set(&input, State::ContinuousTimeMode)), (Some(true), None));
    }
}
