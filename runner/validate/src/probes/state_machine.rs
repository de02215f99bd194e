//! The state machine, cell by cell, from the version's table: every function the table lists
//! in every state the validator can reach, a legal call with valid arguments expected to
//! succeed, an illegal one expected to be refused with Error and to leave every readable value
//! unchanged; a set of each kind of variable judged by the table's conditions.

use std::collections::{HashMap, HashSet};

use super::capabilities::serialize;
use super::values::{changed, different, read_one, readable, same_value, set_value, snapshot, Val};
use crate::failure::Failure;
use crate::fmi::{Code, Op, Outcome, State, Type, Version};
use crate::instance::Instance;
use crate::model::{Grid, Model, Var};
use crate::probe::Ctx;
use crate::report::Severity;
use crate::run::reach;
use crate::table::Rule;

/// One representative of each kind of variable (type, causality, variability, initial, state
/// or not): the state machine's conditions depend on nothing else.
fn representatives(model: &Model, ty: Type) -> Vec<&Var> {
    let mut seen = HashSet::new();
    model
        .of(ty)
        .filter(|v| seen.insert((v.causality.as_str(), v.variability.as_str(), v.initial.map(|i| i.as_str()), v.is_state)))
        .collect()
}

/// What a cell does.
enum Cell<'m> {
    /// A call the standard allows: it must succeed (or, for some, at least not crash).
    Legal(Op),
    /// A set of one variable the standard allows.
    LegalAccess(Op, &'m Var),
    /// A get of the variables the standard allows reading now.
    LegalGet(Op, Vec<&'m Var>),
    /// A call the standard does not allow.
    Illegal(Op),
    /// A set of one variable the standard does not allow now.
    IllegalSet(Op, &'m Var),
}

/// The cells of `state`, in the table's order; FreeInstance comes last.
fn cells<'m>(ctx: &Ctx, model: &'m Model, state: State) -> Vec<Cell<'m>> {
    let (table, interface) = (ctx.binary.table(), ctx.interface);
    let event_mode = model.capabilities(interface).event_mode;
    let mut cells = Vec::new();
    for op in table.functions(interface) {
        // Made in other cells: the instantiation makes every instance, the FMU-state trio and
        // the serialization trio are one cell each, FreeInstance closes the state.
        if matches!(
            op,
            Op::Instantiate | Op::FreeInstance | Op::SetFmuState | Op::FreeFmuState | Op::SerializedFmuStateSize | Op::DeserializeFmuState
        ) {
            continue;
        }
        match table.rule(op, interface, state) {
            Rule::Allowed => match op.access() {
                Some((ty, true)) => cells.push(Cell::LegalGet(op, model.of(ty).collect())),
                _ => cells.push(Cell::Legal(op)),
            },
            // The Error state is entered differently by each FMU; only its legal calls (reset,
            // free, debugging reads) are probed.
            Rule::Illegal if state == State::Error => {}
            Rule::Illegal => cells.push(Cell::Illegal(op)),
            Rule::SetIf => {
                let ty = op.access().expect("a set").0;
                for v in representatives(model, ty) {
                    match (table.may_set)(op, interface, state, v) {
                        Some(true) => cells.push(Cell::LegalAccess(op, v)),
                        Some(false) => cells.push(Cell::IllegalSet(op, v)),
                        None => {}
                    }
                }
            }
            Rule::GetIf => {
                let ty = op.access().expect("a get").0;
                let vars: Vec<&Var> = model
                    .vars
                    .iter()
                    .enumerate()
                    .filter(|(i, v)| v.ty == ty && (table.may_get_in_initialization)(v, model.initial_unknowns.contains(i)))
                    .map(|(_, v)| v)
                    .collect();
                if !vars.is_empty() {
                    cells.push(Cell::LegalGet(op, vars));
                }
            }
            Rule::SetTimeIf if model.nx() > 0 => cells.push(Cell::Illegal(op)),
            // Legal only after a converged event iteration: reach() did one.
            Rule::SetTimeIf => cells.push(Cell::Legal(op)),
            Rule::EventModeUsed if event_mode => cells.push(Cell::Legal(op)),
            Rule::EventModeUsed => cells.push(Cell::Illegal(op)),
            Rule::Unprobed => {}
        }
    }
    cells
}

/// Calls that leave the instance as it was when they succeed, so the next cell may reuse it.
fn keeps_instance(op: Op) -> bool {
    matches!(
        op,
        Op::GetTypesPlatform
            | Op::GetVersion
            | Op::SetDebugLogging
            | Op::Get(_)
            | Op::Set(_)
            | Op::GetDirectionalDerivative
            | Op::GetEventIndicators
            | Op::GetContinuousStates
            | Op::GetDerivatives
            | Op::GetNominalsOfContinuousStates
            | Op::Status(_)
    )
}

/// Every function in `state`.
pub(super) fn state(ctx: &mut Ctx, state: State) {
    let model = ctx.model();
    let cells = cells(ctx, model, state);
    let readable = readable(ctx, state);
    let mut current: Option<Box<dyn Instance>> = None;
    // Counted from the plan, not from the cells this process ran: after a crash another
    // process runs the rest.
    let illegal = cells.iter().filter(|c| matches!(c, Cell::Illegal(_) | Cell::IllegalSet(..))).count();
    let legal = cells.len() - illegal;
    for cell in &cells {
        let check = match cell {
            Cell::Illegal(_) | Cell::IllegalSet(..) => "state-machine.illegal",
            _ => "state-machine.legal",
        };
        if !ctx.cell(check, Severity::Error) {
            continue;
        }
        let mut inst = match current.take() {
            Some(inst) if inst.core().state == state => inst,
            _ => match reach(ctx, state) {
                Ok(inst) => inst,
                Err(f) => {
                    ctx.skip(check, format!("the state {} could not be reached: {}", state.name(), f.message));
                    return;
                }
            },
        };
        match cell {
            Cell::Legal(op) => {
                if let Some(failure) = legal_call(inst.as_mut(), *op, state) {
                    ctx.fail(check, failure);
                }
                if keeps_instance(*op) && inst.core().state == state {
                    current = Some(inst);
                }
            }
            Cell::LegalAccess(op, v) => {
                let now = readable.iter().any(|&i| model.vars[i].name == v.name).then(|| read_one(inst.as_mut(), v)).flatten();
                inst.core_mut().state = state;
                let value = same_value(v, now.as_ref());
                let set = set_value(inst.as_mut(), v, &value);
                if !set.code.ok() {
                    let name = inst.core().name(*op);
                    let message = format!(
                        "{name} of {} ({}) returned {} in {}, where the standard allows it",
                        v.name,
                        v.kind(),
                        set.code.name(),
                        state.name()
                    );
                    ctx.fail(check, Failure::new(message).at(name, state).variable(v.name.clone()).value(value.shown()).with_log(set.log));
                } else {
                    current = Some(inst);
                }
            }
            Cell::LegalGet(op, vars) => {
                let ty = op.access().expect("a get").0;
                let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
                let names = vars.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", ");
                let (code, log) = if ty == Type::String {
                    let got = inst.get_strings(&vrs, &names);
                    (got.code, got.log)
                } else {
                    let got = inst.get_numbers(ty, &vrs, &names);
                    (got.code, got.log)
                };
                // In the Error state reads are allowed but their values "usable for debugging
                // only": any status will do there.
                if !code.ok() && state != State::Error {
                    let name = inst.core().name(*op);
                    // Which variable it refuses: read each alone, one instance at a time.
                    drop(inst);
                    let culprit = vars
                        .iter()
                        .find(|v| reach(ctx, state).ok().is_some_and(|mut scratch| read_one(scratch.as_mut(), v).is_none()))
                        .map(|v| v.name.clone());
                    let what = culprit.as_deref().map_or(format!("{} variable(s)", vars.len()), |c| c.to_owned());
                    let message = format!("{name} of {what} returned {} in {}, where the standard allows it", code.name(), state.name());
                    ctx.fail(check, Failure::new(message).at(name, state).variable(culprit.unwrap_or(names)).with_log(log));
                } else if inst.core().state == state || state == State::Error {
                    inst.core_mut().state = state;
                    current = Some(inst);
                }
            }
            Cell::Illegal(op) => {
                let before = snapshot(inst.as_mut(), model, &readable);
                let (outcome, variable, value) = illegal_call(inst.as_mut(), *op);
                let call = Illegal { op: *op, state, variable, value, set: None };
                judge_illegal(ctx, inst.as_mut(), &readable, before, outcome, call);
            }
            Cell::IllegalSet(op, v) => {
                let before = snapshot(inst.as_mut(), model, &readable);
                let value = different(v, before.get(&v.name));
                let outcome = set_value(inst.as_mut(), v, &value);
                let call = Illegal { op: *op, state, variable: Some(v.name.clone()), value: Some(value.shown()), set: Some(v) };
                judge_illegal(ctx, inst.as_mut(), &readable, before, outcome, call);
            }
        }
    }
    let free = ctx.binary.table().name(Op::FreeInstance, ctx.interface);
    if ctx.cell("state-machine.legal", Severity::Error) {
        // The last cell: FreeInstance in this state (a crash here is a finding too).
        match current.take().map(Ok).unwrap_or_else(|| reach(ctx, state)) {
            Ok(mut inst) => inst.free(),
            Err(f) => ctx.skip("state-machine.legal", format!("the state {} could not be reached: {}", state.name(), f.message)),
        }
    }
    ctx.pass("state-machine.legal", format!("{}: {legal} legal calls succeeded, {free} returned", state.name()));
    if illegal > 0 {
        let error = Code::error_of(ctx.fmi()).name();
        ctx.pass(
            "state-machine.illegal",
            format!("{}: {illegal} illegal calls refused with {error}, no readable value changed", state.name()),
        );
    }
}

/// A legal call in `state` with valid arguments; the failure when it did not succeed where it
/// had to.
fn legal_call(inst: &mut dyn Instance, op: Op, state: State) -> Option<Failure> {
    let model = inst.core().model();
    let grid = Grid::new(&model.experiment, true);
    let capabilities = model.capabilities(inst.core().interface);
    let get_set = capabilities.can_get_and_set_fmu_state;
    let name = |inst: &dyn Instance, op| inst.core().name(op);
    let get_set_flag = format!("{}=\"true\"", inst.core().fmi().fmu_state_flag(false));
    let serialize_flag = format!("{}=\"true\"", inst.core().fmi().fmu_state_flag(true));
    // `strict`: the call must succeed; otherwise it must only return.
    let (outcome, strict): (Outcome<()>, bool) = match op {
        Op::GetTypesPlatform | Op::GetVersion => {
            // Checked for content by the binary probe; here only that they return.
            let binary = inst.core().binary;
            let ok = Code::ok_of(inst.core().fmi()).status;
            let _ = inst.core_mut().call(op, None, None, |_| binary.query(op).map(|_| (ok, ())), ());
            return None;
        }
        Op::SetDebugLogging => (inst.set_debug_logging(false), true),
        Op::SetupExperiment => (inst.setup_experiment(&grid)?, true),
        Op::EnterInitializationMode => (inst.enter_initialization_mode(&grid), true),
        Op::ExitInitializationMode | Op::Terminate | Op::Reset | Op::EnterEventMode | Op::EnterContinuousTimeMode | Op::EnterStepMode => {
            (inst.simple(op), true)
        }
        Op::DoStep => (inst.do_step(grid.start, grid.h).unit(), true),
        Op::UpdateDiscreteStates => (inst.update_discrete_states().unit(), true),
        Op::CompletedIntegratorStep => (inst.completed_integrator_step().unit(), true),
        Op::SetTime => (inst.set_time(grid.start), true),
        Op::SetContinuousStates => {
            let nx = model.nx();
            let got = inst.get_vector(Op::GetContinuousStates, nx);
            let x = if got.code.ok() { got.value } else { vec![0.0; nx] };
            inst.core_mut().state = state;
            (inst.set_continuous_states(&x), true)
        }
        Op::GetEventIndicators | Op::GetContinuousStates | Op::GetDerivatives | Op::GetNominalsOfContinuousStates => {
            let n = if op == Op::GetEventIndicators { model.nz() } else { model.nx() };
            (inst.get_vector(op, n).unit(), state != State::Error)
        }
        Op::GetFmuState => {
            let got = inst.get_fmu_state();
            let mut fmu_state = got.value;
            if !got.code.ok() {
                return (get_set && state != State::Error).then(|| refused(name(inst, op), state, got.code, got.log, &get_set_flag));
            }
            if get_set && !fmu_state.is_null() {
                let set = inst.set_fmu_state(fmu_state);
                if !set.code.ok() {
                    return Some(refused(name(inst, Op::SetFmuState), state, set.code, set.log, &get_set_flag));
                }
            }
            (inst.free_fmu_state(&mut fmu_state), get_set)
        }
        Op::SerializeFmuState => {
            if !(get_set && capabilities.can_serialize_fmu_state) {
                return None;
            }
            let got = inst.get_fmu_state();
            if !got.code.ok() {
                return (state != State::Error).then(|| refused(name(inst, Op::GetFmuState), state, got.code, got.log, &get_set_flag));
            }
            let mut fmu_state = got.value;
            let bytes = match serialize(inst, fmu_state) {
                Ok(bytes) => bytes,
                Err(f) => {
                    let _ = inst.free_fmu_state(&mut fmu_state);
                    return Some(Failure {
                        message: format!("{} in {}, where it must succeed ({serialize_flag})", f.message, state.name()),
                        ..f
                    });
                }
            };
            let back = inst.deserialize_fmu_state(&bytes);
            let _ = inst.free_fmu_state(&mut fmu_state);
            if !back.code.ok() {
                return Some(refused(name(inst, Op::DeserializeFmuState), state, back.code, back.log, &serialize_flag));
            }
            let mut restored = back.value;
            (inst.free_fmu_state(&mut restored), true)
        }
        // The statuses mean something only after a pending or discarded step; the call must
        // return, whatever it answers (Discard: "cannot be retrieved"). The derivative
        // functions are called with no variables.
        Op::GetDirectionalDerivative | Op::SetInputDerivatives | Op::GetOutputDerivatives | Op::Status(_) => (inst.other(op), false),
        _ => return None,
    };
    if outcome.code.is_missing() {
        return None;
    }
    (strict && !outcome.code.ok()).then(|| refused(name(inst, op), state, outcome.code, outcome.log, "the standard allows it"))
}

fn refused(call: &str, state: State, code: Code, log: Option<String>, why: &str) -> Failure {
    Failure::new(format!("{call} returned {} in {}, where it must succeed ({why})", code.name(), state.name()))
        .at(call, state)
        .with_log(log)
}

/// An illegal call with otherwise valid arguments: (outcome, variable, value).
fn illegal_call(inst: &mut dyn Instance, op: Op) -> (Outcome<()>, Option<String>, Option<String>) {
    let model = inst.core().model();
    let grid = Grid::new(&model.experiment, true);
    let no = |outcome| (outcome, None, None);
    match op {
        Op::SetupExperiment => match inst.setup_experiment(&grid) {
            Some(outcome) => no(outcome),
            None => no(missing(inst)),
        },
        Op::EnterInitializationMode => no(inst.enter_initialization_mode(&grid)),
        Op::ExitInitializationMode
        | Op::Terminate
        | Op::EnterEventMode
        | Op::EnterContinuousTimeMode
        | Op::EnterStepMode
        | Op::CancelStep => no(inst.simple(op)),
        Op::DoStep => (inst.do_step(grid.start, grid.h).unit(), None, Some(format!("t = {}, h = {}", grid.start, grid.h))),
        Op::Get(ty) => match model.of(ty).next() {
            Some(v) if ty == Type::String => (inst.get_strings(&[v.vr], &v.name).unit(), Some(v.name.clone()), None),
            Some(v) => (inst.get_numbers(ty, &[v.vr], &v.name).unit(), Some(v.name.clone()), None),
            // No variable of the type: an empty read, which must be refused all the same.
            None if ty == Type::String => no(inst.get_strings(&[], "no variables").unit()),
            None => no(inst.get_numbers(ty, &[], "no variables").unit()),
        },
        Op::UpdateDiscreteStates => no(inst.update_discrete_states().unit()),
        Op::CompletedIntegratorStep => no(inst.completed_integrator_step().unit()),
        Op::SetTime => (inst.set_time(grid.start + grid.h), None, Some(format!("time {}", grid.start + grid.h))),
        Op::SetContinuousStates => {
            let x: Vec<f64> = (0..model.nx()).map(|i| i as f64 + 1.5).collect();
            no(inst.set_continuous_states(&x))
        }
        Op::GetEventIndicators | Op::GetContinuousStates | Op::GetDerivatives | Op::GetNominalsOfContinuousStates => {
            let n = if op == Op::GetEventIndicators { model.nz() } else { model.nx() };
            no(inst.get_vector(op, n).unit())
        }
        Op::GetDirectionalDerivative | Op::SetInputDerivatives | Op::GetOutputDerivatives | Op::Status(_) => no(inst.other(op)),
        _ => no(missing(inst)),
    }
}

/// The outcome of a call not made.
fn missing(inst: &dyn Instance) -> Outcome<()> {
    Outcome { code: Code::missing(inst.core().fmi()), value: (), log: None }
}

/// An illegal call made: which, where, with what.
struct Illegal<'m> {
    op: Op,
    state: State,
    variable: Option<String>,
    value: Option<String>,
    /// The variable of an illegal set.
    set: Option<&'m Var>,
}

/// Judges an illegal call: refused with Error, and no readable value changed.
fn judge_illegal(
    ctx: &mut Ctx,
    inst: &mut dyn Instance,
    readable: &[usize],
    before: HashMap<String, Val>,
    outcome: Outcome<()>,
    call: Illegal,
) {
    const CHECK: &str = "state-machine.illegal";
    if outcome.code.is_missing() {
        return;
    }
    let (name, state) = (inst.core().name(call.op), call.state);
    let error = Code::error_of(inst.core().fmi()).name();
    let what = match call.set {
        Some(v) => format!("{name} of {} ({})", v.name, v.kind()),
        None => name.to_owned(),
    };
    let reason = match call.set {
        Some(_) => (ctx.binary.table().why_not_settable)(state).to_owned(),
        None => format!("the standard does not allow {name} in {}", state.name()),
    };
    let base = |message: String| {
        let mut failure = Failure::new(message).at(name, state).with_log(outcome.log.clone());
        failure.variable = call.variable.clone();
        failure.value = call.value.clone();
        failure
    };
    let model = ctx.model();
    let after = (!before.is_empty() && inst.core().state != State::Gone).then(|| snapshot(inst, model, readable));
    let change = after.and_then(|after| changed(&before, &after, model));
    let change_text = |(name, old, new): &(String, Val, Val)| format!("it changed {name} from {} to {}", old.shown(), new.shown());
    if outcome.code.ok() {
        let effect = change.as_ref().map_or_else(|| "no readable value changed".to_owned(), change_text);
        let message =
            format!("{what} returned {} in {}: {reason}, so it must be refused with {error} ({effect})", outcome.code.name(), state.name());
        ctx.fail(CHECK, base(message));
        return;
    }
    if !outcome.code.is_error() {
        ctx.warn(CHECK, base(format!("{what} in {} was refused with {} instead of {error} ({reason})", state.name(), outcome.code.name())));
    }
    if let Some(change) = &change {
        let mut failure = base(format!(
            "the refused {what} in {}: {}; an illegal call must leave the instance as it was",
            state.name(),
            change_text(change)
        ));
        failure.variable = Some(change.0.clone());
        ctx.fail(CHECK, failure);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::{Fmi, Interface};
    use crate::instance::Binary;
    use crate::report::Severity;
    use crate::testing::{Fake, Fault, Probed};

    /// An FMU that keeps its version's table passes every state of both interfaces: the
    /// engine asks nothing the table does not.
    #[test]
    fn an_fmu_that_keeps_the_table_passes_every_state() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            let fake = Fake::new(fmi, &[]);
            for interface in [Interface::CoSimulation, Interface::ModelExchange] {
                for s in fake.table().states(interface, false) {
                    let probed = Probed::new();
                    state(&mut probed.ctx(fake, interface), s);
                    assert_eq!(probed.troubles(), Vec::<(String, String, String)>::new(), "{fmi:?} {interface:?} {s:?}");
                    let passed = probed.findings().into_iter().filter(|f| f.severity == Severity::Passed).count();
                    assert!(passed >= 1, "{fmi:?} {interface:?} {s:?}: the state's legal calls passed");
                }
            }
        }
    }

    /// An illegal call accepted is an error naming the call and the state, and only there.
    #[test]
    fn an_illegal_call_accepted_is_named_with_its_state() {
        let fake = Fake::new(Fmi::Fmi2, &[Fault::Accepts(Op::DoStep)]);
        for (s, expected) in [(State::Instantiated, 1), (State::StepComplete, 0), (State::Terminated, 1)] {
            let probed = Probed::new();
            state(&mut probed.ctx(fake, Interface::CoSimulation), s);
            let troubles = probed.troubles();
            assert_eq!(troubles.len(), expected, "{s:?}: {troubles:?}");
            if expected == 1 {
                assert_eq!(troubles[0], ("state-machine.illegal".to_owned(), "fmi2DoStep".to_owned(), s.name().to_owned()));
            }
        }
        let fake = Fake::new(Fmi::Fmi3, &[Fault::Accepts(Op::SetTime)]);
        let probed = Probed::new();
        state(&mut probed.ctx(fake, Interface::ModelExchange), State::EventMode);
        assert_eq!(probed.troubles(), [("state-machine.illegal".to_owned(), "fmi3SetTime".to_owned(), "EventMode".to_owned())]);
        let message = &probed.findings().into_iter().find(|f| f.severity == Severity::Error).unwrap().message;
        assert!(message.contains("so it must be refused with fmi3Error"), "{message}");
    }

    /// A fixed parameter set after initialization is refused; accepted, the set is an error
    /// that says the value changed.
    #[test]
    fn a_fixed_parameter_may_not_be_set_after_initialization() {
        let fake = Fake::new(Fmi::Fmi3, &[Fault::Accepts(Op::Set(Type::Real))]);
        let probed = Probed::new();
        state(&mut probed.ctx(fake, Interface::CoSimulation), State::StepMode);
        let errors: Vec<_> = probed.findings().into_iter().filter(|f| f.severity == Severity::Error).collect();
        assert_eq!(errors.len(), 1, "{errors:#?}");
        assert_eq!((errors[0].variable.as_deref(), errors[0].call.as_deref()), (Some("k"), Some("fmi3SetFloat64")));
        assert!(errors[0].message.contains("it changed k from 1 to 2"), "{}", errors[0].message);
    }
}
