//! The shape of a version's state table, as data: one row per function, one character per
//! state of each interface saying what the standard allows there, and the conditions on the
//! variable a set or get names. Each version's `table.rs` fills one in; the state-machine
//! probe reads it.

use crate::fmi::{Interface, Op, State};
use crate::model::Var;

/// What the table says of one function in one state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Rule {
    /// Allowed: a call with valid arguments must succeed (`x`).
    Allowed,
    /// Not allowed: the call must be refused with Error (`.`).
    Illegal,
    /// A set allowed only for some variables (`s`): see [`Table::may_set`].
    SetIf,
    /// A get allowed for outputs and InitialUnknowns (`g`): see
    /// [`Table::may_get_in_initialization`].
    GetIf,
    /// FMI 2.0 fmi2SetTime in Event Mode (`t`): only for an FMU without continuous states,
    /// after the event iteration (condition 8 of its table).
    SetTimeIf,
    /// FMI 3.0 fmi3EnterEventMode in Step Mode (`e`): only for an instance made with
    /// eventModeUsed.
    EventModeUsed,
    /// Not probed here (`-`), for the reason the table gives.
    Unprobed,
}

impl Rule {
    fn of(c: char) -> Rule {
        match c {
            'x' => Rule::Allowed,
            '.' => Rule::Illegal,
            's' => Rule::SetIf,
            'g' => Rule::GetIf,
            't' => Rule::SetTimeIf,
            'e' => Rule::EventModeUsed,
            '-' => Rule::Unprobed,
            other => panic!("{other:?} is not a state table rule"),
        }
    }
}

/// One function: its operation, C name, and its rules in the states of each interface (one
/// character per state column, blanks ignored); `None` where the interface does not have the
/// function.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Row {
    pub op: Op,
    pub name: &'static str,
    pub co_simulation: Option<&'static str>,
    pub model_exchange: Option<&'static str>,
}

impl Row {
    fn rules(&self, interface: Interface) -> Option<&'static str> {
        match interface {
            Interface::CoSimulation => self.co_simulation,
            Interface::ModelExchange => self.model_exchange,
        }
    }
}

/// A version's state machines as data.
pub(crate) struct Table {
    /// The state columns of each interface's rows.
    pub co_simulation: &'static [State],
    pub model_exchange: &'static [State],
    /// The Co-Simulation state between steps (FMI 2.0 StepComplete, FMI 3.0 StepMode).
    pub between_steps: State,
    /// The states of Co-Simulation the validator cannot reach (it steps synchronously), and
    /// the report's words for them.
    pub unreached: Option<(State, &'static str)>,
    /// Every function, in the order of the version's header.
    pub rows: &'static [Row],
    /// Whether the standard lets `op` (a set) set `var` in `state` of an `interface`
    /// instance: `Some(true)` yes, `Some(false)` no, `None` where the validator does not hold
    /// an FMU to the letter (or does not probe the kind of variable yet).
    pub may_set: fn(Op, Interface, State, &Var) -> Option<bool>,
    /// Whether a get of a variable is guaranteed in Initialization Mode (the variable, and
    /// whether it is an InitialUnknown).
    pub may_get_in_initialization: fn(&Var, bool) -> bool,
    /// Why the standard forbids setting a variable in a state, for the message.
    pub why_not_settable: fn(State) -> &'static str,
}

impl Table {
    fn row(&self, op: Op, interface: Interface) -> Option<&'static Row> {
        self.rows.iter().find(|r| r.op == op && r.rules(interface).is_some()).or_else(|| self.rows.iter().find(|r| r.op == op))
    }

    /// The C name of `op` for an `interface` instance (FMI 3.0 instantiates each interface
    /// with a function of its own).
    pub(crate) fn name(&self, op: Op, interface: Interface) -> &'static str {
        self.row(op, interface).map_or("(a function this FMI version does not have)", |r| r.name)
    }

    /// Whether the version has `op` at all.
    pub(crate) fn has(&self, op: Op) -> bool {
        self.rows.iter().any(|r| r.op == op)
    }

    /// The functions of `interface`, in the table's order.
    pub(crate) fn functions(&self, interface: Interface) -> impl Iterator<Item = Op> + '_ {
        self.rows.iter().filter(move |r| r.rules(interface).is_some()).map(|r| r.op)
    }

    /// The functions of `interface` the probes call in some state.
    pub(crate) fn probed(&self, interface: Interface) -> impl Iterator<Item = Op> + '_ {
        self.rows.iter().filter(move |r| r.rules(interface).is_some_and(|s| s.chars().any(|c| c != '-' && c != ' '))).map(|r| r.op)
    }

    /// The states of `interface` (in its column order) the validator drives an instance into;
    /// `event_mode`: a Co-Simulation instance made with eventModeUsed (only it has Event
    /// Mode).
    pub(crate) fn states(&self, interface: Interface, event_mode: bool) -> Vec<State> {
        let columns = match interface {
            Interface::CoSimulation => self.co_simulation,
            Interface::ModelExchange => self.model_exchange,
        };
        columns
            .iter()
            .copied()
            .filter(|s| self.unreached.is_none_or(|(u, _)| u != *s))
            .filter(|s| !(interface == Interface::CoSimulation && *s == State::EventMode && !event_mode))
            .collect()
    }

    /// What the table says of `op` in `state` of an `interface` instance.
    pub(crate) fn rule(&self, op: Op, interface: Interface, state: State) -> Rule {
        let columns = match interface {
            Interface::CoSimulation => self.co_simulation,
            Interface::ModelExchange => self.model_exchange,
        };
        let (Some(rules), Some(column)) =
            (self.row(op, interface).and_then(|r| r.rules(interface)), columns.iter().position(|s| *s == state))
        else {
            return Rule::Illegal;
        };
        rules.chars().filter(|c| *c != ' ').nth(column).map_or(Rule::Illegal, Rule::of)
    }

    /// Checks the table's own consistency: each row has one rule per state column.
    #[cfg(test)]
    pub(crate) fn malformed(&self) -> Vec<String> {
        let mut problems = Vec::new();
        for row in self.rows {
            for (interface, columns) in [(Interface::CoSimulation, self.co_simulation), (Interface::ModelExchange, self.model_exchange)] {
                if let Some(rules) = row.rules(interface) {
                    let rules: Vec<char> = rules.chars().filter(|c| *c != ' ').collect();
                    if rules.len() != columns.len() || rules.iter().any(|c| !"x.sgte-".contains(*c)) {
                        problems.push(format!("{} ({}): {rules:?} for {} states", row.name, interface.title(), columns.len()));
                    }
                }
            }
        }
        problems
    }
}
