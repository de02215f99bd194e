//! Runs through the DefaultExperiment, the material of most dynamic checks: Co-Simulation by
//! fmi2DoStep on the communication grid, Model Exchange by the validator's own integration
//! (classical RK4 on the same grid, state events located by bisection, time events and step
//! events handled, the event iteration bounded). Both record the outputs at every
//! communication point into a [`Trajectory`], which the checks compare bit for bit.

use std::path::Path;

use fmi_c::fmi2 as c;

use super::model::{Base, Grid, Model};
use super::raw::{numbers, Code, Fmu, Instance, Outcome};
use super::table::{Function, Interface, State};
use crate::report::{Finding, Severity};

/// The most fmi2NewDiscreteStates calls one event may take before the iteration counts as not
/// converging: event iterations of real models take a handful.
pub(crate) const MAX_EVENT_ITERATIONS: usize = 100;
/// The most events at one time instant before the run counts as stuck in an event loop.
const MAX_EVENTS_AT_ONE_TIME: usize = 20;
/// The most events one run handles.
const MAX_EVENTS: usize = 100_000;

/// A problem a probe ran into, ready to become a finding.
#[derive(Debug, Clone)]
pub(crate) struct Failure {
    /// The check it belongs to, when not the probe's own.
    pub check: Option<&'static str>,
    pub message: String,
    pub call: Option<String>,
    pub state: Option<String>,
    pub variable: Option<String>,
    pub value: Option<String>,
    pub log: Option<String>,
}

impl Failure {
    /// A problem described by `message` alone.
    pub(crate) fn new(message: impl Into<String>) -> Failure {
        Failure { check: None, message: message.into(), call: None, state: None, variable: None, value: None, log: None }
    }

    /// A call to `function` in `state` that returned `code` where success was due.
    pub(crate) fn refused<T>(function: Function, state: State, outcome: &Outcome<T>, what: &str) -> Failure {
        Failure {
            message: format!("{} {what} returned {}", function.name(), outcome.code.name()),
            call: Some(function.name().to_owned()),
            state: Some(state.name().to_owned()),
            log: outcome.log.clone(),
            ..Failure::new("")
        }
    }

    pub(crate) fn check(mut self, check: &'static str) -> Failure {
        self.check = Some(check);
        self
    }

    pub(crate) fn variable(mut self, variable: impl Into<String>) -> Failure {
        self.variable = Some(variable.into());
        self
    }

    pub(crate) fn value(mut self, value: impl Into<String>) -> Failure {
        self.value = Some(value.into());
        self
    }

    /// Names fmi2Instantiate as the call, made before any instance exists.
    pub(crate) fn at_instantiate(mut self) -> Failure {
        self.call = Some(Function::Instantiate.name().to_owned());
        self.state = Some("(no instance)".to_owned());
        self
    }

    pub(crate) fn at(mut self, function: Function, state: State) -> Failure {
        self.call = Some(function.name().to_owned());
        self.state = Some(state.name().to_owned());
        self
    }

    /// The finding, under `default_check` unless the failure names its own.
    pub(crate) fn finding(self, default_check: &str, severity: Severity) -> Finding {
        let mut f = Finding::new(self.check.unwrap_or(default_check), severity, self.message).log(self.log);
        f.call = self.call;
        f.state = self.state;
        f.variable = self.variable;
        f.value = self.value;
        f
    }
}

/// The outputs (see [`Model::recorded`]) at every communication point of one run.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Trajectory {
    pub columns: Vec<String>,
    pub times: Vec<f64>,
    /// Row-major, `columns.len()` values per time.
    pub values: Vec<f64>,
}

impl Trajectory {
    fn new(columns: Vec<String>) -> Trajectory {
        Trajectory { columns, times: Vec::new(), values: Vec::new() }
    }

    pub(crate) fn rows(&self) -> usize {
        self.times.len()
    }

    pub(crate) fn row(&self, i: usize) -> &[f64] {
        let n = self.columns.len();
        &self.values[i * n..(i + 1) * n]
    }

    fn truncate(&mut self, rows: usize) {
        self.times.truncate(rows);
        self.values.truncate(rows * self.columns.len());
    }

    /// Writes the trajectory for another probe process to compare with.
    pub(crate) fn save(&self, path: &Path) -> Result<(), String> {
        let mut bytes = Vec::with_capacity(16 + 8 * (self.times.len() + self.values.len()));
        bytes.extend((self.columns.len() as u64).to_le_bytes());
        bytes.extend((self.times.len() as u64).to_le_bytes());
        for v in self.times.iter().chain(&self.values) {
            bytes.extend(v.to_bits().to_le_bytes());
        }
        std::fs::write(path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))
    }

    /// Reads a trajectory [`Trajectory::save`] wrote, with `columns` as its names.
    pub(crate) fn load(path: &Path, columns: Vec<String>) -> Result<Trajectory, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
        let word = |i: usize| bytes.get(8 * i..8 * i + 8).map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")));
        let (Some(ncols), Some(nrows)) = (word(0), word(1)) else { return Err(format!("{} is truncated", path.display())) };
        let (ncols, nrows) = (ncols as usize, nrows as usize);
        if ncols != columns.len() || bytes.len() != 16 + 8 * nrows * (1 + ncols) {
            return Err(format!("{} does not hold a trajectory of {} columns", path.display(), columns.len()));
        }
        let all: Vec<f64> = (2..2 + nrows * (1 + ncols)).map(|i| f64::from_bits(word(i).expect("length checked"))).collect();
        Ok(Trajectory { columns, times: all[..nrows].to_vec(), values: all[nrows..].to_vec() })
    }

    /// The first place where `other` differs from `self`, bit for bit, described with `mine` and
    /// `theirs` naming the two runs; `None` when they are identical.
    pub(crate) fn difference(&self, other: &Trajectory, mine: &str, theirs: &str) -> Option<Failure> {
        let rows = self.rows().min(other.rows());
        for i in 0..rows {
            if self.times[i].to_bits() != other.times[i].to_bits() {
                return Some(Failure::new(format!(
                    "communication point {i} is at t = {} in {mine} but at t = {} in {theirs}",
                    self.times[i], other.times[i]
                )));
            }
            for (j, (a, b)) in self.row(i).iter().zip(other.row(i)).enumerate() {
                if a.to_bits() != b.to_bits() {
                    return Some(
                        Failure::new(format!(
                            "{} at t = {} is {a:e} in {mine} but {b:e} in {theirs} (they must be equal bit for bit)",
                            self.columns[j], self.times[i]
                        ))
                        .variable(self.columns[j].clone())
                        .value(format!("{a:e} vs {b:e}")),
                    );
                }
            }
        }
        if self.rows() != other.rows() {
            return Some(Failure::new(format!(
                "{mine} has {} communication points but {theirs} has {} (it ended at t = {} against t = {})",
                self.rows(),
                other.rows(),
                self.times.last().copied().unwrap_or(f64::NAN),
                other.times.last().copied().unwrap_or(f64::NAN)
            )));
        }
        None
    }

    /// The first value that is not finite: (time, column, value).
    pub(crate) fn first_non_finite(&self) -> Option<(f64, &str, f64)> {
        let n = self.columns.len();
        let i = self.values.iter().position(|v| !v.is_finite())?;
        Some((self.times[i / n], &self.columns[i % n], self.values[i]))
    }
}

/// Reads the recorded variables in one call per base type.
#[derive(Clone)]
pub(crate) struct Recorder {
    columns: Vec<String>,
    /// Per base type: the value references and the column each fills.
    groups: Vec<(Base, Vec<u32>, Vec<usize>, String)>,
}

impl Recorder {
    pub(crate) fn new(model: &Model) -> Recorder {
        let recorded = model.recorded();
        let columns: Vec<String> = recorded.iter().map(|&i| model.vars[i].name.clone()).collect();
        let mut groups = Vec::new();
        for base in [Base::Real, Base::Integer, Base::Boolean] {
            let slots: Vec<usize> = (0..recorded.len()).filter(|&j| model.vars[recorded[j]].base == base).collect();
            if slots.is_empty() {
                continue;
            }
            let vrs = slots.iter().map(|&j| model.vars[recorded[j]].vr).collect();
            let names = slots.iter().map(|&j| model.vars[recorded[j]].name.as_str()).collect::<Vec<_>>().join(", ");
            groups.push((base, vrs, slots, names));
        }
        Recorder { columns, groups }
    }

    pub(crate) fn columns(&self) -> Vec<String> {
        self.columns.clone()
    }

    /// The recorded variables now.
    pub(crate) fn read(&self, inst: &mut Instance) -> Result<Vec<f64>, Failure> {
        let mut row = vec![0.0; self.columns.len()];
        for (base, vrs, slots, names) in &self.groups {
            let state = inst.state;
            let got = inst.get_numbers(*base, vrs, names);
            if !got.code.ok() {
                let function = got_function(*base);
                return Err(Failure::refused(function, state, &got, "of the outputs").variable(names.clone()));
            }
            for (&slot, &v) in slots.iter().zip(&got.value) {
                row[slot] = v;
            }
        }
        Ok(row)
    }
}

/// The fmi2Get function of a base type.
pub(crate) fn got_function(base: Base) -> Function {
    match base {
        Base::Real => Function::GetReal,
        Base::Integer => Function::GetInteger,
        Base::Boolean => Function::GetBoolean,
        Base::String => Function::GetString,
    }
}

/// The fmi2Set function of a base type.
pub(crate) fn set_function(base: Base) -> Function {
    match base {
        Base::Real => Function::SetReal,
        Base::Integer => Function::SetInteger,
        Base::Boolean => Function::SetBoolean,
        Base::String => Function::SetString,
    }
}

/// Checks that `outcome` succeeded, else the failure of `function` in `state`.
pub(crate) fn expect_ok<T>(outcome: Outcome<T>, function: Function, state: State) -> Result<T, Failure> {
    if outcome.code.ok() {
        Ok(outcome.value)
    } else {
        Err(Failure::refused(function, state, &outcome, ""))
    }
}

/// Instantiate, set up the experiment, initialize: the common start of every run.
pub(crate) fn initialize(inst: &mut Instance, grid: &Grid) -> Result<(), Failure> {
    let state = inst.state;
    let setup = inst.setup_experiment(grid.tolerance, grid.start, grid.stop);
    expect_ok(setup, Function::SetupExperiment, state)?;
    let enter = inst.simple(Function::EnterInitializationMode);
    expect_ok(enter, Function::EnterInitializationMode, State::Instantiated)?;
    inst.state = State::InitializationMode;
    let exit = inst.simple(Function::ExitInitializationMode);
    expect_ok(exit, Function::ExitInitializationMode, State::InitializationMode)?;
    inst.state = match inst.interface() {
        Interface::CoSimulation => State::StepComplete,
        Interface::ModelExchange => State::EventMode,
    };
    Ok(())
}

/// A new instance named `name`, or the failure of fmi2Instantiate.
pub(crate) fn instantiate<'f>(fmu: &'f Fmu, name: &str, slot: usize) -> Result<Instance<'f>, Failure> {
    fmu.instantiate(name, slot).map_err(|(code, log)| {
        let what = if code == Code::MISSING { "is not exported".to_owned() } else { "returned NULL with the FMU's own GUID".to_owned() };
        Failure { log, ..Failure::new(format!("fmi2Instantiate {what}")) }.at_instantiate().value(format!(
            "fmuType {}, GUID {}",
            fmu.interface.title(),
            fmu.model.md.guid
        ))
    })
}

/// How a state saved for a rollback looks to the run: the FMU's state and the run's own.
pub(crate) struct Saved {
    pub fmu_state: c::FmuState,
    rows: usize,
    t: f64,
    k: usize,
    next_time_event: Option<f64>,
    events: usize,
}

/// A run of either interface on the grid.
pub(crate) struct Run<'f> {
    pub inst: Instance<'f>,
    pub grid: Grid,
    /// Communication points reached.
    pub k: usize,
    pub t: f64,
    pub trajectory: Trajectory,
    recorder: Recorder,
    /// The model ended the run early (fmi2Terminated, terminateSimulation): why.
    pub ended: Option<String>,
    me: Option<MeState>,
}

/// What the validator's own integrator keeps between steps.
#[derive(Debug, Clone, Default)]
struct MeState {
    x: Vec<f64>,
    z: Vec<f64>,
    next_time_event: Option<f64>,
    /// Events handled: (time, which indicator for a state event).
    events: Vec<(f64, Option<usize>)>,
    /// The most fmi2NewDiscreteStates calls any event took.
    most_iterations: usize,
    /// Derivatives at the start (after the initial event iteration).
    start_derivatives: Vec<f64>,
}

impl<'f> Run<'f> {
    /// Instantiates an instance named `name` on `slot` and initializes it; the outputs at the
    /// start are the first row.
    pub(crate) fn start(fmu: &'f Fmu, name: &str, slot: usize) -> Result<Run<'f>, Failure> {
        let variable = fmu.model.md.co_simulation.as_ref().is_some_and(|cs| cs.can_handle_variable_communication_step_size)
            || fmu.interface == Interface::ModelExchange;
        let grid = Grid::new(&fmu.model.md, variable);
        let inst = instantiate(fmu, name, slot)?;
        let recorder = Recorder::new(&fmu.model);
        let trajectory = Trajectory::new(recorder.columns());
        let me = (fmu.interface == Interface::ModelExchange).then(MeState::default);
        let mut run = Run { inst, grid, k: 0, t: grid.start, trajectory, recorder, ended: None, me };
        run.begin()?;
        Ok(run)
    }

    /// Sets up, initializes and records the first row (also after fmi2Reset).
    fn begin(&mut self) -> Result<(), Failure> {
        initialize(&mut self.inst, &self.grid)?;
        (self.k, self.t, self.ended) = (0, self.grid.start, None);
        self.trajectory.truncate(0);
        if let Some(me) = &mut self.me {
            *me = MeState::default();
            let grid = self.grid;
            me_begin(&mut self.inst, me, &grid, &mut self.ended)?;
        }
        self.record()
    }

    fn record(&mut self) -> Result<(), Failure> {
        let row = self.recorder.read(&mut self.inst)?;
        self.trajectory.times.push(self.t);
        self.trajectory.values.extend(row);
        Ok(())
    }

    /// True when the run reached its end or the model ended it.
    pub(crate) fn done(&self) -> bool {
        self.k >= self.grid.steps || self.ended.is_some()
    }

    /// Advances to the next communication point.
    pub(crate) fn step(&mut self) -> Result<(), Failure> {
        let target = self.grid.point(self.k + 1);
        self.step_to(target)
    }

    /// Advances to time `target` (the next communication point of this run) and records it.
    pub(crate) fn step_to(&mut self, target: f64) -> Result<(), Failure> {
        match &mut self.me {
            None => {
                let h = target - self.t;
                let step = self.inst.do_step(self.t, h);
                if step.code == Code::DISCARD {
                    let terminated = self.inst.terminated_status();
                    if terminated.code.ok() && terminated.value {
                        self.ended = Some(step.log.unwrap_or_else(|| format!("the model ended the run in the step from t = {}", self.t)));
                        self.inst.state = State::StepFailed;
                        return Ok(());
                    }
                    return Err(Failure::refused(Function::DoStep, State::StepComplete, &step, "")
                        .value(format!("t = {}, h = {h}", self.t))
                        .check("lifecycle.run"));
                }
                if !step.code.ok() {
                    return Err(
                        Failure::refused(Function::DoStep, State::StepComplete, &step, "").value(format!("t = {}, h = {h}", self.t))
                    );
                }
            }
            Some(me) => {
                me_advance(&mut self.inst, me, self.t, target, &mut self.ended)?;
            }
        }
        self.t = target;
        self.k += 1;
        self.record()
    }

    /// Steps to the end of the grid (or until the model ends the run).
    pub(crate) fn run_to_end(&mut self) -> Result<(), Failure> {
        while !self.done() {
            self.step()?;
        }
        Ok(())
    }

    /// fmi2Terminate (unless the model ended the run, which leaves it terminated already).
    pub(crate) fn terminate(&mut self) -> Result<(), Failure> {
        // After fmi2Discard with fmi2Terminated (StepFailed) the standard allows it too.
        let state = self.inst.state;
        let terminate = self.inst.simple(Function::Terminate);
        expect_ok(terminate, Function::Terminate, state)?;
        self.inst.state = State::Terminated;
        Ok(())
    }

    /// fmi2Reset, then a fresh start of the same experiment.
    pub(crate) fn reset(&mut self) -> Result<(), Failure> {
        let state = self.inst.state;
        let reset = self.inst.simple(Function::Reset);
        expect_ok(reset, Function::Reset, state)?;
        self.inst.state = State::Instantiated;
        self.begin()
    }

    /// Saves the FMU state (fmi2GetFMUstate) and the run's own.
    pub(crate) fn save(&mut self) -> Result<Saved, Failure> {
        let state = self.inst.state;
        let got = self.inst.get_fmu_state();
        let fmu_state = expect_ok(got, Function::GetFmuState, state)?;
        let me = self.me.as_ref();
        Ok(Saved {
            fmu_state,
            rows: self.trajectory.rows(),
            t: self.t,
            k: self.k,
            next_time_event: me.and_then(|m| m.next_time_event),
            events: me.map_or(0, |m| m.events.len()),
        })
    }

    /// Restores a save: fmi2SetFMUstate, then the run's own bookkeeping; the recorded rows after
    /// it are dropped, and the restored outputs are compared with the row recorded then.
    pub(crate) fn restore(&mut self, saved: &Saved) -> Result<(), Failure> {
        let state = self.inst.state;
        let set = self.inst.set_fmu_state(saved.fmu_state);
        expect_ok(set, Function::SetFmuState, state)?;
        self.inst.state = match self.inst.interface() {
            Interface::CoSimulation => State::StepComplete,
            Interface::ModelExchange => State::ContinuousTimeMode,
        };
        let row = self.recorder.read(&mut self.inst)?;
        let columns = self.trajectory.columns.clone();
        let recorded = Trajectory { columns: columns.clone(), times: vec![saved.t], values: self.trajectory.row(saved.rows - 1).to_vec() };
        let now = Trajectory { columns, times: vec![saved.t], values: row };
        if let Some(difference) = recorded.difference(&now, "the saved state", "the state after fmi2SetFMUstate") {
            return Err(Failure {
                message: format!("fmi2SetFMUstate did not restore the state saved at t = {}: {}", saved.t, difference.message),
                ..difference
            }
            .at(Function::SetFmuState, state));
        }
        self.trajectory.truncate(saved.rows);
        (self.t, self.k, self.ended) = (saved.t, saved.k, None);
        if let Some(me) = &mut self.me {
            me.next_time_event = saved.next_time_event;
            me.events.truncate(saved.events);
            let nx = self.inst.fmu.model.nx();
            let nz = self.inst.fmu.model.event_indicators;
            me.x = read_vector(&mut self.inst, Function::GetContinuousStates, nx)?;
            me.z = read_vector(&mut self.inst, Function::GetEventIndicators, nz)?;
        }
        Ok(())
    }

    /// Events the Model Exchange run handled: (time, indicator of a state event).
    pub(crate) fn events(&self) -> &[(f64, Option<usize>)] {
        self.me.as_ref().map_or(&[], |m| &m.events)
    }

    /// The most fmi2NewDiscreteStates calls an event took (Model Exchange).
    pub(crate) fn most_iterations(&self) -> usize {
        self.me.as_ref().map_or(0, |m| m.most_iterations)
    }

    /// The derivatives at the start (Model Exchange).
    pub(crate) fn start_derivatives(&self) -> &[f64] {
        self.me.as_ref().map_or(&[], |m| &m.start_derivatives)
    }
}

/// Reads `n` values of a Model Exchange vector (nothing to call for none).
fn read_vector(inst: &mut Instance, function: Function, n: usize) -> Result<Vec<f64>, Failure> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let state = inst.state;
    let got = inst.get_vector(function, n);
    let values = expect_ok(got, function, state)?;
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        let what = match function {
            Function::GetDerivatives => "derivative",
            Function::GetEventIndicators => "event indicator",
            Function::GetContinuousStates => "state",
            _ => "value",
        };
        return Err(Failure::new(format!(
            "{} returned {what} {} = {} at this point, which is not finite",
            function.name(),
            i + 1,
            values[i]
        ))
        .at(function, state)
        .value(numbers(&values))
        .check("health.finite"));
    }
    Ok(values)
}

/// After initialization: the event iteration, Continuous-Time Mode, states, indicators and
/// derivatives at the start.
fn me_begin(inst: &mut Instance, me: &mut MeState, grid: &Grid, ended: &mut Option<String>) -> Result<(), Failure> {
    let (info, calls) = event_iteration(inst, grid.start)?;
    me.most_iterations = calls;
    if info.terminate_simulation != 0 {
        *ended = Some("the model asked to terminate during initialization".to_owned());
    }
    let enter = inst.simple(Function::EnterContinuousTimeMode);
    expect_ok(enter, Function::EnterContinuousTimeMode, State::EventMode)?;
    inst.state = State::ContinuousTimeMode;
    me.next_time_event = (info.next_event_time_defined != 0).then_some(info.next_event_time);
    let (nx, nz) = (inst.fmu.model.nx(), inst.fmu.model.event_indicators);
    me.x = read_vector(inst, Function::GetContinuousStates, nx)?;
    me.z = read_vector(inst, Function::GetEventIndicators, nz)?;
    me.start_derivatives = read_vector(inst, Function::GetDerivatives, nx).map_err(|f| f.check("model-exchange.derivatives"))?;
    Ok(())
}

/// fmi2NewDiscreteStates until no new discrete states are needed; returns the last event info
/// and how many calls it took.
fn event_iteration(inst: &mut Instance, t: f64) -> Result<(c::EventInfo, usize), Failure> {
    for calls in 1..=MAX_EVENT_ITERATIONS {
        let got = inst.new_discrete_states();
        let info = expect_ok(got, Function::NewDiscreteStates, State::EventMode)?;
        if info.new_discrete_states_needed == 0 || info.terminate_simulation != 0 {
            return Ok((info, calls));
        }
    }
    Err(event_iteration_failure(t))
}

/// The derivatives at (t, x): fmi2SetTime, fmi2SetContinuousStates, fmi2GetDerivatives.
fn derivatives(inst: &mut Instance, t: f64, x: &[f64]) -> Result<Vec<f64>, Failure> {
    set_point(inst, t, x)?;
    read_vector(inst, Function::GetDerivatives, x.len())
}

fn set_point(inst: &mut Instance, t: f64, x: &[f64]) -> Result<(), Failure> {
    let time = inst.set_time(t);
    expect_ok(time, Function::SetTime, State::ContinuousTimeMode)?;
    if !x.is_empty() {
        let states = inst.set_continuous_states(x);
        expect_ok(states, Function::SetContinuousStates, State::ContinuousTimeMode)?;
    }
    Ok(())
}

/// One classical Runge-Kutta step from (t, x) over h.
fn rk4(inst: &mut Instance, t: f64, x: &[f64], h: f64) -> Result<Vec<f64>, Failure> {
    if x.is_empty() {
        return Ok(Vec::new());
    }
    let along = |x: &[f64], k: &[f64], f: f64| x.iter().zip(k).map(|(a, b)| a + f * b).collect::<Vec<f64>>();
    let k1 = derivatives(inst, t, x)?;
    let k2 = derivatives(inst, t + h / 2.0, &along(x, &k1, h / 2.0))?;
    let k3 = derivatives(inst, t + h / 2.0, &along(x, &k2, h / 2.0))?;
    let k4 = derivatives(inst, t + h, &along(x, &k3, h))?;
    Ok((0..x.len()).map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])).collect())
}

/// The index of the first indicator that changed domain (z > 0 against z <= 0, as FMI 2.0
/// defines a state event).
fn crossing(before: &[f64], after: &[f64]) -> Option<usize> {
    before.iter().zip(after).position(|(a, b)| (*a > 0.0) != (*b > 0.0))
}

/// Integrates from `t` to `target`, handling every event on the way.
fn me_advance(inst: &mut Instance, me: &mut MeState, mut t: f64, target: f64, ended: &mut Option<String>) -> Result<(), Failure> {
    let nz = inst.fmu.model.event_indicators;
    while t < target && ended.is_none() {
        let time_event = me.next_time_event.filter(|&te| te <= target);
        if let Some(te) = time_event.filter(|&te| te <= t) {
            handle_event(inst, me, te, None, ended)?;
            continue;
        }
        let t_end = time_event.unwrap_or(target);
        let h = t_end - t;
        let x_end = rk4(inst, t, &me.x, h)?;
        set_point(inst, t_end, &x_end)?;
        let z_end = read_vector(inst, Function::GetEventIndicators, nz)?;
        if crossing(&me.z, &z_end).is_some() {
            // Bisect on the step's fraction until the bracket is a few ulps of t wide.
            let (mut lo, mut hi) = (0.0f64, 1.0f64);
            let (mut x_hi, mut z_hi) = (x_end, z_end);
            for _ in 0..64 {
                if (hi - lo) * h <= 4.0 * f64::EPSILON * t.abs().max(1.0) {
                    break;
                }
                let mid = 0.5 * (lo + hi);
                let x_mid = rk4(inst, t, &me.x, mid * h)?;
                set_point(inst, t + mid * h, &x_mid)?;
                let z_mid = read_vector(inst, Function::GetEventIndicators, nz)?;
                if crossing(&me.z, &z_mid).is_some() {
                    (hi, x_hi, z_hi) = (mid, x_mid, z_mid);
                } else {
                    lo = mid;
                }
            }
            let t_event = if hi == 1.0 { t_end } else { t + hi * h };
            set_point(inst, t_event, &x_hi)?;
            let which = crossing(&me.z, &z_hi);
            let completed = inst.completed_integrator_step();
            let (_, terminate) = expect_ok(completed, Function::CompletedIntegratorStep, State::ContinuousTimeMode)?;
            (t, me.x, me.z) = (t_event, x_hi, z_hi);
            if terminate {
                *ended = Some(format!("fmi2CompletedIntegratorStep asked to terminate at t = {t}"));
                break;
            }
            handle_event(inst, me, t, which, ended)?;
            continue;
        }
        let completed = inst.completed_integrator_step();
        let (enter, terminate) = expect_ok(completed, Function::CompletedIntegratorStep, State::ContinuousTimeMode)?;
        (t, me.x, me.z) = (t_end, x_end, z_end);
        if terminate {
            *ended = Some(format!("fmi2CompletedIntegratorStep asked to terminate at t = {t}"));
            break;
        }
        if enter || time_event == Some(t_end) {
            handle_event(inst, me, t, None, ended)?;
        }
    }
    Ok(())
}

/// Event Mode at `t`: enter, iterate, leave, and read back what the event changed.
fn handle_event(
    inst: &mut Instance,
    me: &mut MeState,
    t: f64,
    indicator: Option<usize>,
    ended: &mut Option<String>,
) -> Result<(), Failure> {
    let same_time = me.events.iter().rev().take_while(|(te, _)| (te - t).abs() <= 4.0 * f64::EPSILON * t.abs().max(1.0)).count();
    if same_time >= MAX_EVENTS_AT_ONE_TIME || me.events.len() >= MAX_EVENTS {
        let what = match indicator {
            Some(i) => format!("event indicator {} changes domain again", i + 1),
            None => "a time or step event is due again".to_owned(),
        };
        return Err(Failure::new(format!(
            "the events are not handled: {what} at t = {t} right after {same_time} events at the same time, so the integration cannot advance"
        ))
        .at(Function::EnterEventMode, State::ContinuousTimeMode)
        .value(format!("t = {t}"))
        .check("model-exchange.state-events"));
    }
    let enter = inst.simple(Function::EnterEventMode);
    expect_ok(enter, Function::EnterEventMode, State::ContinuousTimeMode)
        .map_err(|f| Failure { message: format!("{} at t = {t}", f.message), ..f }.check("model-exchange.state-events"))?;
    inst.state = State::EventMode;
    let before = inst.fmu.model.event_indicators;
    let (info, calls) = event_iteration(inst, t)?;
    me.most_iterations = me.most_iterations.max(calls);
    me.events.push((t, indicator));
    if info.terminate_simulation != 0 {
        *ended = Some(format!("the model asked to terminate at the event at t = {t}"));
        return Ok(());
    }
    let leave = inst.simple(Function::EnterContinuousTimeMode);
    expect_ok(leave, Function::EnterContinuousTimeMode, State::EventMode)?;
    inst.state = State::ContinuousTimeMode;
    if info.values_of_continuous_states_changed != 0 {
        me.x = read_vector(inst, Function::GetContinuousStates, inst.fmu.model.nx())?;
    }
    me.z = read_vector(inst, Function::GetEventIndicators, before)?;
    me.next_time_event = (info.next_event_time_defined != 0).then_some(info.next_event_time);
    Ok(())
}

fn event_iteration_failure(t: f64) -> Failure {
    Failure::new(format!(
        "the event iteration at t = {t} did not converge: fmi2NewDiscreteStates still set newDiscreteStatesNeeded after {MAX_EVENT_ITERATIONS} calls"
    ))
    .at(Function::NewDiscreteStates, State::EventMode)
    .value(format!("t = {t}"))
    .check("model-exchange.event-iteration")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trajectory(values: &[f64]) -> Trajectory {
        Trajectory { columns: vec!["x".into(), "y".into()], times: vec![0.0, 1.0], values: values.to_vec() }
    }

    #[test]
    fn trajectories_compare_bit_for_bit_and_survive_a_file() {
        let a = trajectory(&[1.0, 2.0, 3.0, f64::NAN]);
        assert!(a.difference(&a.clone(), "a", "b").is_none(), "NaN equals NaN bit for bit");
        let b = trajectory(&[1.0, 2.0, 3.0 + 4e-16, f64::NAN]);
        let d = a.difference(&b, "the first run", "the second").unwrap();
        assert!(d.message.contains("x at t = 1") && d.message.contains("the first run"), "{}", d.message);
        assert_eq!(d.variable.as_deref(), Some("x"));
        let c = trajectory(&[1.0, 2.0, -0.0, 0.0]);
        let zero = trajectory(&[1.0, 2.0, 0.0, 0.0]);
        assert!(c.difference(&zero, "a", "b").is_some(), "-0 and 0 differ in their bits");
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.bin");
        a.save(&path).unwrap();
        let back = Trajectory::load(&path, a.columns.clone()).unwrap();
        assert!(a.difference(&back, "a", "b").is_none());
        assert!(Trajectory::load(&path, vec!["x".into()]).is_err());
        assert_eq!(a.first_non_finite().map(|(t, c, _)| (t, c.to_owned())), Some((1.0, "y".to_owned())));
    }

    #[test]
    fn a_state_event_is_a_change_of_domain() {
        assert_eq!(crossing(&[1.0, 1.0], &[0.5, 0.0]), Some(1), "z > 0 to z <= 0");
        assert_eq!(crossing(&[0.0], &[-1.0]), None, "z <= 0 throughout");
        assert_eq!(crossing(&[-1.0], &[1e-300]), Some(0));
    }
}
