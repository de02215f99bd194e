//! The state machine, cell by cell: every function in every state the validator can reach, a
//! legal call with valid arguments expected to succeed, an illegal one expected to be refused
//! with fmi2Error and to leave every readable value unchanged. And the arguments no importer
//! should pass but some do: NULL and zero-length arrays, unknown value references.

use std::collections::HashMap;
use std::ffi::{c_int, c_void, CString};

use fmi_c::fmi2 as c;

use super::{capabilities, Ctx, NAME};
use crate::fmi2::model::{Base, Grid, Model, Var};
use crate::fmi2::raw::{Api, Code, Fmu, Instance, Outcome};
use crate::fmi2::run::{expect_ok, got_function, initialize, instantiate, set_function, Failure};
use crate::fmi2::table::{may_get_in_initialization, may_set, Function, Interface, Rule, State};
use crate::report::Severity;

/// A value read or to set.
#[derive(Debug, Clone, PartialEq)]
enum Val {
    Num(f64),
    Text(Option<String>),
}

impl Val {
    fn same(&self, other: &Val) -> bool {
        match (self, other) {
            (Val::Num(a), Val::Num(b)) => a.to_bits() == b.to_bits(),
            (a, b) => a == b,
        }
    }

    fn shown(&self) -> String {
        match self {
            Val::Num(v) => v.to_string(),
            Val::Text(Some(t)) => format!("{t:?}"),
            Val::Text(None) => "NULL".to_owned(),
        }
    }
}

/// A fresh instance in `state`: the calls an importer makes to get there, the event iteration
/// included for Model Exchange; Error by an fmi2SetReal of an unknown value reference, which
/// the standard answers with fmi2Error.
pub(super) fn reach<'f>(fmu: &'f Fmu, state: State) -> Result<Instance<'f>, Failure> {
    let mut inst = instantiate(fmu, NAME, 0)?;
    if state == State::Instantiated {
        return Ok(inst);
    }
    let grid = Grid::new(&fmu.model.md, true);
    if state == State::InitializationMode {
        let setup = inst.setup_experiment(grid.tolerance, grid.start, grid.stop);
        expect_ok(setup, Function::SetupExperiment, State::Instantiated)?;
        let enter = inst.simple(Function::EnterInitializationMode);
        expect_ok(enter, Function::EnterInitializationMode, State::Instantiated)?;
        inst.state = State::InitializationMode;
        return Ok(inst);
    }
    initialize(&mut inst, &grid)?;
    if inst.interface() == Interface::ModelExchange {
        for _ in 0..crate::fmi2::run::MAX_EVENT_ITERATIONS {
            let got = inst.new_discrete_states();
            let info = expect_ok(got, Function::NewDiscreteStates, State::EventMode)?;
            if info.new_discrete_states_needed == 0 {
                break;
            }
        }
        if matches!(state, State::ContinuousTimeMode | State::Terminated) {
            let enter = inst.simple(Function::EnterContinuousTimeMode);
            expect_ok(enter, Function::EnterContinuousTimeMode, State::EventMode)?;
            inst.state = State::ContinuousTimeMode;
        }
    }
    match state {
        State::Terminated => {
            let from = inst.state;
            let terminate = inst.simple(Function::Terminate);
            expect_ok(terminate, Function::Terminate, from)?;
            inst.state = State::Terminated;
        }
        State::Error => {
            let unknown = fmu.model.unknown_vr();
            let from = inst.state;
            let set = inst.set_numbers(Base::Real, &[unknown], &[0.0], "an unknown value reference");
            if set.code != Code::ERROR {
                return Err(Failure::new(format!(
                    "the Error state was not reached: fmi2SetReal of the unknown value reference {unknown} returned {}",
                    set.code.name()
                ))
                .at(Function::SetReal, from));
            }
            inst.state = State::Error;
        }
        _ => {}
    }
    Ok(inst)
}

/// The variables whose reads succeed in `state`, found one by one on a scratch instance, for
/// the before-and-after comparisons.
fn readable(fmu: &Fmu, state: State) -> Vec<usize> {
    let model = &fmu.model;
    let candidates: Vec<usize> = match state {
        State::Instantiated | State::Gone => return Vec::new(),
        State::InitializationMode => {
            (0..model.vars.len()).filter(|&i| may_get_in_initialization(&model.vars[i], model.initial_unknowns.contains(&i))).collect()
        }
        _ => (0..model.vars.len()).collect(),
    };
    let Ok(mut inst) = reach(fmu, state) else { return Vec::new() };
    let mut found = Vec::new();
    for i in candidates {
        if read_one(&mut inst, &model.vars[i]).is_some() {
            found.push(i);
        } else if inst.state != state {
            // A refused read moved it into Error: start again.
            let Ok(fresh) = reach(fmu, state) else { break };
            inst = fresh;
        }
    }
    found
}

fn read_one(inst: &mut Instance, v: &Var) -> Option<Val> {
    if v.base == Base::String {
        let got = inst.get_strings(&[v.vr], &v.name);
        return got.code.ok().then(|| Val::Text(got.value.into_iter().next().flatten()));
    }
    let got = inst.get_numbers(v.base, &[v.vr], &v.name);
    got.code.ok().then(|| Val::Num(got.value[0]))
}

/// The readable values now, by variable name; reads that fail are left out.
fn snapshot(inst: &mut Instance, model: &Model, readable: &[usize]) -> HashMap<String, Val> {
    let state = inst.state;
    let mut values = HashMap::new();
    for base in Base::ALL {
        let vars: Vec<&Var> = readable.iter().map(|&i| &model.vars[i]).filter(|v| v.base == base).collect();
        if vars.is_empty() {
            continue;
        }
        let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
        let names = format!("{} readable {} variable(s)", vars.len(), base.name());
        let got: Option<Vec<Val>> = if base == Base::String {
            let got = inst.get_strings(&vrs, &names);
            got.code.ok().then(|| got.value.into_iter().map(Val::Text).collect())
        } else {
            let got = inst.get_numbers(base, &vrs, &names);
            got.code.ok().then(|| got.value.into_iter().map(Val::Num).collect())
        };
        for (v, value) in vars.iter().zip(got.into_iter().flatten()) {
            values.insert(v.name.clone(), value);
        }
    }
    // An observation, not a step of the state machine.
    inst.state = state;
    values
}

/// The first readable value that differs between two snapshots.
fn changed(before: &HashMap<String, Val>, after: &HashMap<String, Val>, model: &Model) -> Option<(String, Val, Val)> {
    model.vars.iter().find_map(|v| match (before.get(&v.name), after.get(&v.name)) {
        (Some(a), Some(b)) if !a.same(b) => Some((v.name.clone(), a.clone(), b.clone())),
        _ => None,
    })
}

/// A value for `v` other than `current` (and within its min and max where that is possible),
/// so that an accepted illegal set shows.
fn different(v: &Var, current: Option<&Val>) -> Val {
    let start = || match &v.start {
        Some(fmi_schema::fmi2::StartValue::Real(x)) => Some(*x),
        Some(fmi_schema::fmi2::StartValue::Integer(i) | fmi_schema::fmi2::StartValue::Enumeration(i)) => Some(f64::from(*i)),
        Some(fmi_schema::fmi2::StartValue::Boolean(b)) => Some(*b as i32 as f64),
        _ => None,
    };
    match v.base {
        Base::String => {
            let now = match current {
                Some(Val::Text(t)) => t.clone(),
                _ => None,
            };
            let text = if now.as_deref() == Some("runner validate") { "runner validate 2" } else { "runner validate" };
            Val::Text(Some(text.to_owned()))
        }
        Base::Boolean => {
            let now = match current {
                Some(Val::Num(x)) => *x != 0.0,
                _ => start().is_some_and(|x| x != 0.0),
            };
            Val::Num(if now { 0.0 } else { 1.0 })
        }
        Base::Real | Base::Integer => {
            let now = match current {
                Some(Val::Num(x)) if x.is_finite() => *x,
                _ => start().filter(|x| x.is_finite()).unwrap_or(0.0),
            };
            let within = |x: f64| v.min.is_none_or(|m| x >= m) && v.max.is_none_or(|m| x <= m);
            let candidates = [now + 1.0, now - 1.0, (v.min.unwrap_or(now) + v.max.unwrap_or(now + 2.0)) / 2.0, now * 2.0 + 1.0];
            let pick = candidates.into_iter().find(|&x| x != now && within(x) && (v.base == Base::Real || x.fract() == 0.0));
            Val::Num(pick.unwrap_or(now + 1.0))
        }
    }
}

/// The value a legal set passes: the current one where it can be read, else the start value.
fn same_value(v: &Var, current: Option<&Val>) -> Val {
    if let Some(value) = current {
        return value.clone();
    }
    match &v.start {
        Some(fmi_schema::fmi2::StartValue::Real(x)) => Val::Num(*x),
        Some(fmi_schema::fmi2::StartValue::Integer(i) | fmi_schema::fmi2::StartValue::Enumeration(i)) => Val::Num(f64::from(*i)),
        Some(fmi_schema::fmi2::StartValue::Boolean(b)) => Val::Num(*b as i32 as f64),
        Some(fmi_schema::fmi2::StartValue::String(s)) => Val::Text(Some(s.clone())),
        None if v.base == Base::String => Val::Text(Some(String::new())),
        None => Val::Num(0.0),
    }
}

fn set_value(inst: &mut Instance, v: &Var, value: &Val) -> Outcome<()> {
    match value {
        Val::Num(x) => inst.set_numbers(v.base, &[v.vr], &[*x], &v.name),
        Val::Text(t) => inst.set_strings(&[v.vr], &[t.clone().unwrap_or_default()], &v.name),
    }
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

/// One representative of each kind of variable (base type, causality, variability, initial,
/// state or not): the state machine's conditions depend on nothing else.
fn representatives(model: &Model, base: Base) -> Vec<&Var> {
    let mut seen = std::collections::HashSet::new();
    model
        .of(base)
        .filter(|v| seen.insert((v.causality.as_str(), v.variability.as_str(), v.initial.map(|i| i.as_str()), v.is_state)))
        .collect()
}

/// What a cell does.
enum Cell<'m> {
    /// A call the standard allows: it must succeed (`strict`) or at least not crash.
    Legal(Function),
    /// A set or get of one variable the standard allows.
    LegalAccess(Function, &'m Var),
    /// A get of the variables condition 2 guarantees in Initialization Mode.
    LegalGetIf(Function, Vec<&'m Var>),
    /// A call the standard does not allow.
    Illegal(Function),
    /// A set of one variable the standard does not allow now.
    IllegalSet(Function, &'m Var),
}

/// The cells of `state`, in fmi2FunctionTypes.h's order; fmi2FreeInstance comes last.
fn cells<'m>(model: &'m Model, interface: Interface, state: State) -> Vec<Cell<'m>> {
    let mut cells = Vec::new();
    for f in Function::of(interface) {
        // Made in other cells: fmi2Instantiate makes every instance, the FMU-state trio and
        // the serialization trio are one cell each, fmi2FreeInstance closes the state.
        if matches!(
            f,
            Function::Instantiate
                | Function::FreeInstance
                | Function::SetFmuState
                | Function::FreeFmuState
                | Function::SerializedFmuStateSize
                | Function::DeSerializeFmuState
        ) {
            continue;
        }
        if matches!(f, Function::GetTypesPlatform | Function::GetVersion) && state != State::Instantiated {
            continue;
        }
        let base = base_of(f);
        match f.rule(interface, state) {
            Rule::Allowed => match base {
                Some(base) if is_get(f) => cells.push(Cell::LegalGetIf(f, model.of(base).collect())),
                _ => cells.push(Cell::Legal(f)),
            },
            // The Error state is entered differently by each FMU; only its legal calls (reset,
            // free, debugging reads) are probed.
            Rule::Illegal if state == State::Error => {}
            Rule::Illegal => cells.push(Cell::Illegal(f)),
            Rule::SetIf => {
                for v in representatives(model, base.expect("a set")) {
                    match may_set(f, interface, state, v) {
                        Some(true) => cells.push(Cell::LegalAccess(f, v)),
                        Some(false) => cells.push(Cell::IllegalSet(f, v)),
                        None => {}
                    }
                }
            }
            Rule::GetIf => {
                let vars: Vec<&Var> = model
                    .vars
                    .iter()
                    .enumerate()
                    .filter(|(i, v)| Some(v.base) == base && may_get_in_initialization(v, model.initial_unknowns.contains(i)))
                    .map(|(_, v)| v)
                    .collect();
                if !vars.is_empty() {
                    cells.push(Cell::LegalGetIf(f, vars));
                }
            }
            Rule::SetTimeIf if model.nx() > 0 => cells.push(Cell::Illegal(f)),
            // Legal only after a converged event iteration: reach() did one.
            Rule::SetTimeIf => cells.push(Cell::Legal(f)),
        }
    }
    cells
}

/// The variable type a get or set function reads or writes.
pub(super) fn base_of(f: Function) -> Option<Base> {
    match f {
        Function::GetReal | Function::SetReal => Some(Base::Real),
        Function::GetInteger | Function::SetInteger => Some(Base::Integer),
        Function::GetBoolean | Function::SetBoolean => Some(Base::Boolean),
        Function::GetString | Function::SetString => Some(Base::String),
        _ => None,
    }
}

fn is_get(f: Function) -> bool {
    matches!(f, Function::GetReal | Function::GetInteger | Function::GetBoolean | Function::GetString)
}

/// Calls that leave the instance as it was when they succeed, so the next cell may reuse it.
fn keeps_instance(f: Function) -> bool {
    matches!(
        f,
        Function::GetTypesPlatform
            | Function::GetVersion
            | Function::SetDebugLogging
            | Function::GetReal
            | Function::GetInteger
            | Function::GetBoolean
            | Function::GetString
            | Function::GetDirectionalDerivative
            | Function::GetEventIndicators
            | Function::GetContinuousStates
            | Function::GetDerivatives
            | Function::GetNominalsOfContinuousStates
            | Function::GetStatus
            | Function::GetRealStatus
            | Function::GetIntegerStatus
            | Function::GetBooleanStatus
            | Function::GetStringStatus
            | Function::SetReal
            | Function::SetInteger
            | Function::SetBoolean
            | Function::SetString
    )
}

/// Every function in `state`.
pub(super) fn state(ctx: &mut Ctx, state: State) {
    let fmu = ctx.fmu;
    let model = &fmu.model;
    let interface = fmu.interface;
    let cells = cells(model, interface, state);
    let readable = readable(fmu, state);
    let mut current: Option<Instance> = None;
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
            Some(inst) if inst.state == state => inst,
            _ => match reach(fmu, state) {
                Ok(inst) => inst,
                Err(f) => {
                    ctx.skip(check, format!("the state {} could not be reached: {}", state.name(), f.message));
                    return;
                }
            },
        };
        match cell {
            Cell::Legal(f) => {
                if let Some(failure) = legal_call(&mut inst, *f, state) {
                    ctx.fail(check, failure);
                }
                if keeps_instance(*f) && inst.state == state {
                    current = Some(inst);
                }
            }
            Cell::LegalAccess(f, v) => {
                let now = readable.iter().any(|&i| model.vars[i].name == v.name).then(|| read_one(&mut inst, v)).flatten();
                inst.state = state;
                let value = same_value(v, now.as_ref());
                let set = set_value(&mut inst, v, &value);
                if !set.code.ok() {
                    ctx.fail(
                        check,
                        Failure::new(format!(
                            "{} of {} ({}) returned {} in {}, where the standard allows it",
                            f.name(),
                            v.name,
                            v.kind(),
                            set.code.name(),
                            state.name()
                        ))
                        .at(*f, state)
                        .variable(v.name.clone())
                        .value(value.shown())
                        .with_log(set.log),
                    );
                } else {
                    current = Some(inst);
                }
            }
            Cell::LegalGetIf(f, vars) => {
                let base = base_of(*f).expect("a get");
                let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
                let names = vars.iter().map(|v| v.name.as_str()).collect::<Vec<_>>().join(", ");
                let code = if base == Base::String {
                    let got = inst.get_strings(&vrs, &names);
                    (got.code, got.log)
                } else {
                    let got = inst.get_numbers(base, &vrs, &names);
                    (got.code, got.log)
                };
                // In the Error state reads are allowed but their values "usable for debugging
                // only": any status will do there.
                if !code.0.ok() && state != State::Error {
                    // Which variable it refuses: read each alone, one instance at a time.
                    drop(inst);
                    let culprit = vars
                        .iter()
                        .find(|v| reach(fmu, state).ok().is_some_and(|mut scratch| read_one(&mut scratch, v).is_none()))
                        .map(|v| v.name.clone());
                    let failure = Failure::new(format!(
                        "{} of {} returned {} in {}, where the standard allows it",
                        f.name(),
                        culprit.as_deref().map_or(format!("{} variable(s)", vars.len()), |c| c.to_owned()),
                        code.0.name(),
                        state.name()
                    ))
                    .at(*f, state)
                    .variable(culprit.unwrap_or(names))
                    .with_log(code.1);
                    ctx.fail(check, failure);
                } else if inst.state == state || state == State::Error {
                    inst.state = state;
                    current = Some(inst);
                }
            }
            Cell::Illegal(f) => {
                let before = snapshot(&mut inst, model, &readable);
                let (outcome, variable, value) = illegal_call(&mut inst, *f, state);
                judge_illegal(ctx, &mut inst, model, &readable, before, outcome, *f, state, variable, value, None);
            }
            Cell::IllegalSet(f, v) => {
                let before = snapshot(&mut inst, model, &readable);
                let value = different(v, before.get(&v.name));
                let outcome = set_value(&mut inst, v, &value);
                judge_illegal(
                    ctx,
                    &mut inst,
                    model,
                    &readable,
                    before,
                    outcome,
                    *f,
                    state,
                    Some(v.name.clone()),
                    Some(value.shown()),
                    Some(v),
                );
            }
        }
    }
    if ctx.cell("state-machine.legal", Severity::Error) {
        // The last cell: fmi2FreeInstance in this state (a crash here is a finding too).
        match current.take().map(Ok).unwrap_or_else(|| reach(fmu, state)) {
            Ok(mut inst) => inst.free(),
            Err(f) => ctx.skip("state-machine.legal", format!("the state {} could not be reached: {}", state.name(), f.message)),
        }
    }
    ctx.pass("state-machine.legal", format!("{}: {legal} legal calls succeeded, fmi2FreeInstance returned", state.name()));
    if illegal > 0 {
        ctx.pass(
            "state-machine.illegal",
            format!("{}: {illegal} illegal calls refused with fmi2Error, no readable value changed", state.name()),
        );
    }
}

trait WithLog {
    fn with_log(self, log: Option<String>) -> Self;
}

impl WithLog for Failure {
    fn with_log(mut self, log: Option<String>) -> Failure {
        if log.is_some() {
            self.log = log;
        }
        self
    }
}

/// A legal call in `state` with valid arguments; the failure when it did not succeed where it
/// had to.
fn legal_call(inst: &mut Instance, f: Function, state: State) -> Option<Failure> {
    let fmu = inst.fmu;
    let model = &fmu.model;
    let grid = Grid::new(&model.md, true);
    let (get_set, serialize, _) = capabilities(fmu);
    // `strict`: the call must succeed; otherwise it must only return.
    let (outcome, strict): (Outcome<()>, bool) = match f {
        Function::GetTypesPlatform | Function::GetVersion => {
            // Checked for content by the binary probe; here only that they return.
            let _ = inst.status(f, None, None, |api, _| {
                // SAFETY: no arguments.
                let p = if f == Function::GetVersion {
                    api.get_version.map(|g| unsafe { g() })
                } else {
                    api.get_types_platform.map(|g| unsafe { g() })
                };
                p.map(|_| Code::OK.0)
            });
            return None;
        }
        Function::SetDebugLogging => (inst.set_debug_logging(false), true),
        Function::SetupExperiment => (inst.setup_experiment(grid.tolerance, grid.start, grid.stop), true),
        Function::EnterInitializationMode
        | Function::ExitInitializationMode
        | Function::Terminate
        | Function::Reset
        | Function::EnterEventMode
        | Function::EnterContinuousTimeMode => (inst.simple(f), true),
        Function::DoStep => (inst.do_step(grid.start, grid.h), true),
        Function::NewDiscreteStates => {
            let got = inst.new_discrete_states();
            (Outcome { code: got.code, value: (), log: got.log }, true)
        }
        Function::CompletedIntegratorStep => {
            let got = inst.completed_integrator_step();
            (Outcome { code: got.code, value: (), log: got.log }, true)
        }
        Function::SetTime => (inst.set_time(grid.start), true),
        Function::SetContinuousStates => {
            let nx = model.nx();
            let got = inst.get_vector(Function::GetContinuousStates, nx);
            let x = if got.code.ok() { got.value } else { vec![0.0; nx] };
            inst.state = state;
            (inst.set_continuous_states(&x), true)
        }
        Function::GetEventIndicators
        | Function::GetContinuousStates
        | Function::GetDerivatives
        | Function::GetNominalsOfContinuousStates => {
            let n = if f == Function::GetEventIndicators { model.event_indicators } else { model.nx() };
            let got = inst.get_vector(f, n);
            (Outcome { code: got.code, value: (), log: got.log }, state != State::Error)
        }
        Function::GetFmuState => {
            let got = inst.get_fmu_state();
            let mut fmu_state = got.value;
            if !got.code.ok() {
                return (get_set && state != State::Error).then(|| refused(f, state, got.code, got.log, "canGetAndSetFMUstate=\"true\""));
            }
            if get_set && !fmu_state.is_null() {
                let set = inst.set_fmu_state(fmu_state);
                if !set.code.ok() {
                    return Some(refused(Function::SetFmuState, state, set.code, set.log, "canGetAndSetFMUstate=\"true\""));
                }
            }
            let freed = inst.free_fmu_state(&mut fmu_state);
            (freed, get_set)
        }
        Function::SerializeFmuState => {
            if !(get_set && serialize) {
                return None;
            }
            let got = inst.get_fmu_state();
            if !got.code.ok() {
                return (state != State::Error)
                    .then(|| refused(Function::GetFmuState, state, got.code, got.log, "canGetAndSetFMUstate=\"true\""));
            }
            let mut fmu_state = got.value;
            let bytes = inst.serialize(fmu_state);
            if !bytes.code.ok() {
                let _ = inst.free_fmu_state(&mut fmu_state);
                return Some(refused(Function::SerializeFmuState, state, bytes.code, bytes.log, "canSerializeFMUstate=\"true\""));
            }
            let back = inst.deserialize(&bytes.value);
            let _ = inst.free_fmu_state(&mut fmu_state);
            if !back.code.ok() {
                return Some(refused(Function::DeSerializeFmuState, state, back.code, back.log, "canSerializeFMUstate=\"true\""));
            }
            let mut restored = back.value;
            (inst.free_fmu_state(&mut restored), true)
        }
        Function::GetDirectionalDerivative => (
            inst.status(f, None, Some("no unknowns, no knowns".to_owned()), |api, c| {
                // SAFETY: zero-length arrays: the FMU reads no element.
                api.get_directional_derivative.map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) })
            }),
            false,
        ),
        Function::SetRealInputDerivatives | Function::GetRealOutputDerivatives => (
            inst.status(f, None, Some("no variables".to_owned()), |api, c| {
                // SAFETY: zero-length arrays.
                if f == Function::SetRealInputDerivatives {
                    api.set_real_input_derivatives.map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), [].as_ptr()) })
                } else {
                    api.get_real_output_derivatives.map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) })
                }
            }),
            false,
        ),
        Function::GetStatus
        | Function::GetRealStatus
        | Function::GetIntegerStatus
        | Function::GetBooleanStatus
        | Function::GetStringStatus => {
            // The statuses mean something only after fmi2Pending or fmi2Discard; the call must
            // return, whatever it answers (fmi2Discard: "cannot be retrieved").
            (status_query(inst, f), false)
        }
        _ => return None,
    };
    if outcome.code == Code::MISSING {
        return None;
    }
    (strict && !outcome.code.ok()).then(|| refused(f, state, outcome.code, outcome.log, "the standard allows it"))
}

fn refused(f: Function, state: State, code: Code, log: Option<String>, why: &str) -> Failure {
    Failure::new(format!("{} returned {} in {}, where it must succeed ({why})", f.name(), code.name(), state.name()))
        .at(f, state)
        .with_log(log)
}

/// One fmi2Get*Status call, with the status kind that fits its type.
pub(super) fn status_query(inst: &mut Instance, f: Function) -> Outcome<()> {
    let (kind, name) = match f {
        Function::GetRealStatus => (c::LAST_SUCCESSFUL_TIME, "fmi2LastSuccessfulTime"),
        Function::GetBooleanStatus => (c::TERMINATED, "fmi2Terminated"),
        Function::GetStringStatus => (c::PENDING_STATUS, "fmi2PendingStatus"),
        _ => (c::DO_STEP_STATUS, "fmi2DoStepStatus"),
    };
    inst.status(f, None, Some(name.to_owned()), |api, comp| {
        let mut buffer = [0u64; 1];
        let out = buffer.as_mut_ptr() as *mut c_void;
        // SAFETY: an 8-byte, 8-aligned buffer holds any of the five value types.
        unsafe {
            match f {
                Function::GetStatus => api.get_status.map(|g| g(comp, kind, out as *mut c_int)),
                Function::GetRealStatus => api.get_real_status.map(|g| g(comp, kind, out as *mut f64)),
                Function::GetIntegerStatus => api.get_integer_status.map(|g| g(comp, kind, out as *mut c::Integer)),
                Function::GetBooleanStatus => api.get_boolean_status.map(|g| g(comp, kind, out as *mut c::Boolean)),
                _ => api.get_string_status.map(|g| g(comp, kind, out as *mut c::FmiString)),
            }
        }
    })
}

/// An illegal call with otherwise valid arguments: (outcome, variable, value).
fn illegal_call(inst: &mut Instance, f: Function, state: State) -> (Outcome<()>, Option<String>, Option<String>) {
    let fmu = inst.fmu;
    let model = &fmu.model;
    let grid = Grid::new(&model.md, true);
    let first = |base: Base| model.of(base).next();
    let no = |outcome| (outcome, None, None);
    match f {
        Function::SetupExperiment => no(inst.setup_experiment(grid.tolerance, grid.start, grid.stop)),
        Function::EnterInitializationMode
        | Function::ExitInitializationMode
        | Function::Terminate
        | Function::EnterEventMode
        | Function::EnterContinuousTimeMode
        | Function::CancelStep => no(inst.simple(f)),
        Function::DoStep => (inst.do_step(grid.start, grid.h), None, Some(format!("t = {}, h = {}", grid.start, grid.h))),
        Function::GetReal | Function::GetInteger | Function::GetBoolean | Function::GetString => {
            let base = base_of(f).expect("a get");
            match first(base) {
                Some(v) if base == Base::String => {
                    let got = inst.get_strings(&[v.vr], &v.name);
                    (Outcome { code: got.code, value: (), log: got.log }, Some(v.name.clone()), None)
                }
                Some(v) => {
                    let got = inst.get_numbers(base, &[v.vr], &v.name);
                    (Outcome { code: got.code, value: (), log: got.log }, Some(v.name.clone()), None)
                }
                // No variable of the type: an empty read, which must be refused all the same.
                None if base == Base::String => {
                    let got = inst.get_strings(&[], "no variables");
                    (Outcome { code: got.code, value: (), log: got.log }, None, None)
                }
                None => {
                    let got = inst.get_numbers(base, &[], "no variables");
                    (Outcome { code: got.code, value: (), log: got.log }, None, None)
                }
            }
        }
        Function::NewDiscreteStates => {
            let got = inst.new_discrete_states();
            no(Outcome { code: got.code, value: (), log: got.log })
        }
        Function::CompletedIntegratorStep => {
            let got = inst.completed_integrator_step();
            no(Outcome { code: got.code, value: (), log: got.log })
        }
        Function::SetTime => (inst.set_time(grid.start + grid.h), None, Some(format!("time {}", grid.start + grid.h))),
        Function::SetContinuousStates => {
            let x: Vec<f64> = (0..model.nx()).map(|i| i as f64 + 1.5).collect();
            no(inst.set_continuous_states(&x))
        }
        Function::GetEventIndicators
        | Function::GetContinuousStates
        | Function::GetDerivatives
        | Function::GetNominalsOfContinuousStates => {
            let n = if f == Function::GetEventIndicators { model.event_indicators } else { model.nx() };
            let got = inst.get_vector(f, n);
            no(Outcome { code: got.code, value: (), log: got.log })
        }
        Function::GetDirectionalDerivative | Function::SetRealInputDerivatives | Function::GetRealOutputDerivatives => {
            let _ = state;
            no(inst.status(f, None, Some("no variables".to_owned()), |api, c| {
                // SAFETY: zero-length arrays.
                match f {
                    Function::GetDirectionalDerivative => api
                        .get_directional_derivative
                        .map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) }),
                    Function::SetRealInputDerivatives => {
                        api.set_real_input_derivatives.map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), [].as_ptr()) })
                    }
                    _ => api.get_real_output_derivatives.map(|g| unsafe { g(c, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()) }),
                }
            }))
        }
        Function::GetStatus
        | Function::GetRealStatus
        | Function::GetIntegerStatus
        | Function::GetBooleanStatus
        | Function::GetStringStatus => no(status_query(inst, f)),
        _ => no(Outcome { code: Code::MISSING, value: (), log: None }),
    }
}

/// Judges an illegal call: refused with fmi2Error, and no readable value changed.
#[allow(clippy::too_many_arguments)]
fn judge_illegal(
    ctx: &mut Ctx,
    inst: &mut Instance,
    model: &Model,
    readable: &[usize],
    before: HashMap<String, Val>,
    outcome: Outcome<()>,
    f: Function,
    state: State,
    variable: Option<String>,
    value: Option<String>,
    set_var: Option<&Var>,
) {
    const CHECK: &str = "state-machine.illegal";
    if outcome.code == Code::MISSING {
        return;
    }
    let what = match set_var {
        Some(v) => format!("{} of {} ({})", f.name(), v.name, v.kind()),
        None => f.name().to_owned(),
    };
    let reason = match set_var {
        Some(_) => why_not_settable(state).to_owned(),
        None => format!("the standard does not allow {} in {}", f.name(), state.name()),
    };
    let base = |message: String| {
        let mut failure = Failure::new(message).at(f, state).with_log(outcome.log.clone());
        failure.variable = variable.clone();
        failure.value = value.clone();
        failure
    };
    let after = (!before.is_empty() && inst.state != State::Gone).then(|| snapshot(inst, model, readable));
    let change = after.and_then(|after| changed(&before, &after, model));
    let change_text = |(name, old, new): &(String, Val, Val)| format!("it changed {name} from {} to {}", old.shown(), new.shown());
    if outcome.code.ok() {
        let effect = change.as_ref().map_or_else(|| "no readable value changed".to_owned(), change_text);
        ctx.fail(
            CHECK,
            base(format!(
                "{what} returned {} in {}: {reason}, so it must be refused with fmi2Error ({effect})",
                outcome.code.name(),
                state.name()
            )),
        );
        return;
    }
    if outcome.code != Code::ERROR {
        ctx.warn(
            CHECK,
            base(format!("{what} in {} was refused with {} instead of fmi2Error ({reason})", state.name(), outcome.code.name())),
        );
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

/// One call of the arguments probe: (check, base type, function, NULL value references?, NULL
/// values?, number of values, the value reference passed).
type ArgumentProbe = (&'static str, Base, Function, bool, bool, usize, Option<u32>);

/// The arguments a careless importer passes: NULL and zero-length arrays, and value
/// references the FMU does not have (which the standard says must give fmi2Error).
pub(super) fn arguments(ctx: &mut Ctx) {
    let fmu = ctx.fmu;
    let model = &fmu.model;
    let interface = fmu.interface;
    // Where values may be read and inputs set: after initialization.
    let state = match interface {
        Interface::CoSimulation => State::StepComplete,
        Interface::ModelExchange => State::EventMode,
    };
    let readable = readable(fmu, state);
    let unknown = model.unknown_vr();
    let mut probes: Vec<ArgumentProbe> = Vec::new();
    for base in Base::ALL {
        let get = got_function(base);
        let set = set_function(base);
        let readable_var = readable.iter().map(|&i| &model.vars[i]).find(|v| v.base == base);
        let settable_var = model.of(base).find(|v| may_set(set, interface, state, v) == Some(true));
        probes.extend([
            ("arguments.zero-length", base, get, true, true, 0, None),
            ("arguments.zero-length", base, set, true, true, 0, None),
            ("arguments.null-arrays", base, get, true, false, 1, None),
            ("arguments.null-arrays", base, set, true, false, 1, None),
            ("arguments.unknown-vr", base, get, false, false, 1, Some(unknown)),
            ("arguments.unknown-vr", base, set, false, false, 1, Some(unknown)),
        ]);
        if let Some(v) = readable_var {
            probes.push(("arguments.null-arrays", base, get, false, true, 1, Some(v.vr)));
        }
        if let Some(v) = settable_var {
            probes.push(("arguments.null-arrays", base, set, false, true, 1, Some(v.vr)));
        }
    }
    let nx = model.nx();
    let vectors: Vec<(Function, usize)> = match interface {
        Interface::ModelExchange => vec![
            (Function::GetContinuousStates, nx),
            (Function::GetDerivatives, nx),
            (Function::GetNominalsOfContinuousStates, nx),
            (Function::GetEventIndicators, model.event_indicators),
            (Function::SetContinuousStates, nx),
        ],
        Interface::CoSimulation => Vec::new(),
    };
    // Counted from the plan: after a crash another process runs the rest.
    let count = |check: &str| probes.iter().filter(|p| p.0 == check).count();
    let zero = count("arguments.zero-length") + vectors.iter().filter(|(_, n)| *n == 0).count();
    let null = count("arguments.null-arrays") + vectors.iter().filter(|(_, n)| *n > 0).count();
    let unknown_refused = count("arguments.unknown-vr");
    {
        for (check, base, f, null_vrs, null_values, n, vr) in probes {
            let crash = if check == "arguments.null-arrays" { Severity::Warning } else { Severity::Error };
            if !ctx.cell(check, crash) {
                continue;
            }
            let mut inst = match reach(fmu, state) {
                Ok(inst) => inst,
                Err(f) => return ctx.skip(check, format!("the state {} could not be reached: {}", state.name(), f.message)),
            };
            let before = snapshot(&mut inst, model, &readable);
            let variable = vr.map(|vr| match model.vars.iter().find(|v| v.vr == vr && v.base == base) {
                Some(v) => v.name.clone(),
                None => format!("value reference {vr} (no {} variable has it)", base.name()),
            });
            let value = Some(format!(
                "vr {}, nvr {n}, value {}",
                if null_vrs { "NULL" } else { "a valid array" },
                if null_values { "NULL" } else { "a valid array" }
            ));
            let outcome = raw_access(&mut inst, f, base, null_vrs, null_values, n, vr.unwrap_or(0), variable.as_deref(), value.clone());
            if outcome.code == Code::MISSING {
                continue;
            }
            let mut failure = Failure::new("").at(f, state).with_log(outcome.log.clone());
            failure.variable = variable.clone();
            failure.value = value.clone();
            match check {
                "arguments.zero-length" => {
                    if !outcome.code.ok() {
                        ctx.warn(
                            check,
                            Failure {
                                message: format!(
                                    "{} with zero values (NULL arrays) returned {}: nothing to do should succeed",
                                    f.name(),
                                    outcome.code.name()
                                ),
                                ..failure.clone()
                            },
                        );
                    }
                }
                "arguments.null-arrays" => {
                    if outcome.code != Code::ERROR {
                        ctx.warn(
                            check,
                            Failure {
                                message: format!(
                                    "{} with a NULL array and {n} value returned {}; a robust FMU refuses it with fmi2Error (the standard requires arrays of nvr elements, so this is the importer's error)",
                                    f.name(),
                                    outcome.code.name()
                                ),
                                ..failure.clone()
                            },
                        );
                        continue;
                    }
                }
                _ => {
                    if outcome.code != Code::ERROR {
                        ctx.fail(
                            check,
                            Failure {
                                message: format!(
                                    "{} of value reference {unknown}, which no variable has, returned {}: the standard requires fmi2Error for a wrong value reference (section 2.1.7)",
                                    f.name(),
                                    outcome.code.name()
                                ),
                                ..failure.clone()
                            },
                        );
                        continue;
                    }
                }
            }
            if check != "arguments.zero-length" && !before.is_empty() {
                let after = snapshot(&mut inst, model, &readable);
                if let Some((name, old, new)) = changed(&before, &after, model) {
                    ctx.fail(
                        check,
                        Failure {
                            message: format!(
                                "the refused {} changed {name} from {} to {}: a refused call must leave the instance as it was",
                                f.name(),
                                old.shown(),
                                new.shown()
                            ),
                            ..failure.clone()
                        }
                        .variable(name),
                    );
                }
            }
        }
    }
    {
        for (f, n) in vectors {
            let check = if n == 0 { "arguments.zero-length" } else { "arguments.null-arrays" };
            if !ctx.cell(check, if n == 0 { Severity::Error } else { Severity::Warning }) {
                continue;
            }
            let mut inst = match reach(fmu, State::ContinuousTimeMode) {
                Ok(inst) => inst,
                Err(failure) => return ctx.skip(check, format!("the state ContinuousTimeMode could not be reached: {}", failure.message)),
            };
            let outcome = inst.status(f, None, Some(format!("a NULL array of {n} values")), |api, c| {
                // SAFETY: deliberately a NULL array: the FMU must not touch it.
                unsafe {
                    match f {
                        Function::GetContinuousStates => api.get_continuous_states.map(|g| g(c, std::ptr::null_mut(), n)),
                        Function::GetDerivatives => api.get_derivatives.map(|g| g(c, std::ptr::null_mut(), n)),
                        Function::GetNominalsOfContinuousStates => {
                            api.get_nominals_of_continuous_states.map(|g| g(c, std::ptr::null_mut(), n))
                        }
                        Function::GetEventIndicators => api.get_event_indicators.map(|g| g(c, std::ptr::null_mut(), n)),
                        _ => api.set_continuous_states.map(|g| g(c, std::ptr::null(), n)),
                    }
                }
            });
            if outcome.code == Code::MISSING {
                continue;
            }
            let failure = Failure::new("").at(f, State::ContinuousTimeMode).value(format!("NULL, {n}")).with_log(outcome.log.clone());
            if n == 0 {
                if !outcome.code.ok() {
                    ctx.warn(
                        check,
                        Failure { message: format!("{} with zero values returned {}", f.name(), outcome.code.name()), ..failure.clone() },
                    );
                }
            } else {
                if outcome.code != Code::ERROR {
                    ctx.warn(
                        check,
                        Failure {
                            message: format!(
                                "{} with a NULL array of {n} values returned {}; a robust FMU refuses it with fmi2Error",
                                f.name(),
                                outcome.code.name()
                            ),
                            ..failure.clone()
                        },
                    );
                }
            }
        }
    }
    let null_instance = super::null_arguments::null_instance(ctx, state);
    let null = null + super::null_arguments::null_pointers(ctx, state);
    ctx.pass("arguments.zero-length", format!("{zero} calls with zero values and NULL arrays succeeded"));
    ctx.pass(
        "arguments.null-instance",
        format!("{null_instance} calls with a NULL fmi2Component refused with fmi2Error (fmi2FreeInstance ignored it)"),
    );
    if null > 0 {
        ctx.pass(
            "arguments.null-arrays",
            format!("{null} calls with a NULL array and a nonzero length, or another NULL pointer, refused with fmi2Error"),
        );
    }
    ctx.pass(
        "arguments.unknown-vr",
        format!("{unknown_refused} gets and sets of the unknown value reference {unknown} refused with fmi2Error"),
    );
}

/// fmi2Get* or fmi2Set* of `base` with raw arrays: NULL where asked, else one value
/// reference `vr` and a valid value buffer.
#[allow(clippy::too_many_arguments)]
fn raw_access(
    inst: &mut Instance,
    f: Function,
    base: Base,
    null_vrs: bool,
    null_values: bool,
    n: usize,
    vr: u32,
    variable: Option<&str>,
    value: Option<String>,
) -> Outcome<()> {
    let vrs = [vr];
    let vr_ptr = if null_vrs { std::ptr::null() } else { vrs.as_ptr() };
    // An 8-byte buffer holds one value of any type; the String one points at a valid text.
    let text = CString::new("runner validate").expect("no NUL");
    let mut buffer: [u64; 1] = match base {
        Base::Real => [1.5f64.to_bits()],
        Base::String => [text.as_ptr() as u64],
        _ => [1],
    };
    let values: *mut c_void = if null_values { std::ptr::null_mut() } else { buffer.as_mut_ptr() as *mut c_void };
    let is_get = is_get(f);
    inst.status(f, variable, value, |api: &Api, c| {
        // SAFETY: the arrays are either NULL (what is being probed) or valid for n <= 1.
        unsafe {
            match (base, is_get) {
                (Base::Real, true) => api.get_real.map(|g| g(c, vr_ptr, n, values as *mut f64)),
                (Base::Integer, true) => api.get_integer.map(|g| g(c, vr_ptr, n, values as *mut c::Integer)),
                (Base::Boolean, true) => api.get_boolean.map(|g| g(c, vr_ptr, n, values as *mut c::Boolean)),
                (Base::String, true) => api.get_string.map(|g| g(c, vr_ptr, n, values as *mut c::FmiString)),
                (Base::Real, false) => api.set_real.map(|g| g(c, vr_ptr, n, values as *const f64)),
                (Base::Integer, false) => api.set_integer.map(|g| g(c, vr_ptr, n, values as *const c::Integer)),
                (Base::Boolean, false) => api.set_boolean.map(|g| g(c, vr_ptr, n, values as *const c::Boolean)),
                (Base::String, false) => api.set_string.map(|g| g(c, vr_ptr, n, values as *const c::FmiString)),
            }
        }
    })
}
