//! Runs through the DefaultExperiment, the material of most dynamic checks, for either version
//! and interface: Co-Simulation by DoStep on the communication grid (with Event Mode and early
//! return where an FMI 3.0 FMU offers them), Model Exchange by the validator's own integration
//! ([`Exchange`]). Both record the outputs at every communication point into a [`Trajectory`],
//! which the checks compare bit for bit. And [`reach`], the calls an importer makes to bring a
//! fresh instance into a state.

use std::path::Path;

use crate::exchange::{enter, event_iteration, Exchange, SavedExchange, MAX_EVENT_ITERATIONS};
use crate::failure::Failure;
use crate::fmi::{Interface, Op, State, Type};
use crate::instance::{Binary, FmuState, Instance};
use crate::model::{Grid, Model};
use crate::probe::Ctx;

/// The most events (or early returns) within one communication step.
const MAX_EVENTS_PER_STEP: usize = 10_000;

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

    /// The reference run of `ctx`'s interface, which the lifecycle probe saved.
    pub(crate) fn reference(ctx: &Ctx) -> Result<Trajectory, String> {
        Trajectory::load(&ctx.reference_path(), Recorder::new(ctx.model()).columns.clone())
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

/// Reads the recorded variables in one call per type.
#[derive(Clone)]
pub(crate) struct Recorder {
    columns: Vec<String>,
    /// Per type: the value references, the column each fills, and their names.
    groups: Vec<(Type, Vec<u32>, Vec<usize>, String)>,
}

impl Recorder {
    pub(crate) fn new(model: &Model) -> Recorder {
        let recorded = model.recorded();
        let columns: Vec<String> = recorded.iter().map(|&i| model.vars[i].name.clone()).collect();
        let mut groups = Vec::new();
        for ty in [Type::Real, Type::Integer, Type::Boolean] {
            let slots: Vec<usize> = (0..recorded.len()).filter(|&j| model.vars[recorded[j]].ty == ty).collect();
            if slots.is_empty() {
                continue;
            }
            let vrs = slots.iter().map(|&j| model.vars[recorded[j]].vr).collect();
            let names = slots.iter().map(|&j| model.vars[recorded[j]].name.as_str()).collect::<Vec<_>>().join(", ");
            groups.push((ty, vrs, slots, names));
        }
        Recorder { columns, groups }
    }

    /// The recorded variables now.
    pub(crate) fn read(&self, inst: &mut dyn Instance) -> Result<Vec<f64>, Failure> {
        let mut row = vec![0.0; self.columns.len()];
        for (ty, vrs, slots, names) in &self.groups {
            let state = inst.core().state;
            let got = inst.get_numbers(*ty, vrs, names);
            if !got.code.ok() {
                return Err(Failure::refused(inst.core().name(Op::Get(*ty)), state, &got, "of the outputs").variable(names.clone()));
            }
            for (&slot, &v) in slots.iter().zip(&got.value) {
                row[slot] = v;
            }
        }
        Ok(row)
    }
}

/// The state of an instance right after initialization: Event Mode for Model Exchange and
/// for Co-Simulation with Event Mode, else between steps.
pub(crate) fn after_initialization(binary: &dyn Binary, interface: Interface) -> State {
    match interface {
        Interface::CoSimulation if !binary.model().capabilities(interface).event_mode => binary.table().between_steps,
        _ => State::EventMode,
    }
}

/// Sets up the experiment and initializes: the common start of every run.
pub(crate) fn initialize(inst: &mut dyn Instance, grid: &Grid) -> Result<(), Failure> {
    let state = inst.core().state;
    if let Some(setup) = inst.setup_experiment(grid) {
        inst.core().expect(setup, Op::SetupExperiment, state)?;
    }
    let entered = inst.enter_initialization_mode(grid);
    inst.core().expect(entered, Op::EnterInitializationMode, State::Instantiated)?;
    inst.core_mut().state = State::InitializationMode;
    let exit = inst.simple(Op::ExitInitializationMode);
    inst.core().expect(exit, Op::ExitInitializationMode, State::InitializationMode)?;
    inst.core_mut().state = after_initialization(inst.core().binary, inst.core().interface);
    Ok(())
}

/// A fresh instance in `state`: the calls an importer makes to get there, the event iteration
/// included where the instance starts in Event Mode; Error by a set of an unknown value
/// reference, which the standard answers with Error.
pub(crate) fn reach(ctx: &Ctx, state: State) -> Result<Box<dyn Instance>, Failure> {
    let mut inst = ctx.instantiate(crate::probe::NAME, 0)?;
    if state == State::Instantiated {
        return Ok(inst);
    }
    let grid = Grid::new(&ctx.model().experiment, true);
    if state == State::InitializationMode {
        if let Some(setup) = inst.setup_experiment(&grid) {
            inst.core().expect(setup, Op::SetupExperiment, State::Instantiated)?;
        }
        let entered = inst.enter_initialization_mode(&grid);
        inst.core().expect(entered, Op::EnterInitializationMode, State::Instantiated)?;
        inst.core_mut().state = State::InitializationMode;
        return Ok(inst);
    }
    initialize(inst.as_mut(), &grid)?;
    if inst.core().state == State::EventMode {
        for _ in 0..MAX_EVENT_ITERATIONS {
            let got = inst.update_discrete_states();
            let update = inst.core().expect(got, Op::UpdateDiscreteStates, State::EventMode)?;
            if !update.again {
                break;
            }
        }
        let leave = match ctx.interface {
            Interface::ModelExchange => (Op::EnterContinuousTimeMode, State::ContinuousTimeMode),
            Interface::CoSimulation => (Op::EnterStepMode, State::StepMode),
        };
        if matches!(state, State::ContinuousTimeMode | State::StepMode | State::Terminated) {
            enter(inst.as_mut(), leave.0, State::EventMode, leave.1)?;
        }
    }
    match state {
        State::Terminated => {
            let from = inst.core().state;
            enter(inst.as_mut(), Op::Terminate, from, State::Terminated)?;
        }
        State::Error => {
            let unknown = ctx.model().unknown_vr();
            let from = inst.core().state;
            let set = inst.set_numbers(Type::Real, &[unknown], &[0.0], "an unknown value reference");
            let name = inst.core().name(Op::Set(Type::Real));
            if !set.code.is_error() {
                return Err(Failure::new(format!(
                    "the Error state was not reached: {name} of the unknown value reference {unknown} returned {}",
                    set.code.name()
                ))
                .at(name, from));
            }
            inst.core_mut().state = State::Error;
        }
        _ => {}
    }
    Ok(inst)
}

/// A state saved for a rollback: the FMU's and the run's own.
pub(crate) struct Saved {
    pub fmu_state: FmuState,
    rows: usize,
    t: f64,
    k: usize,
    exchange: Option<SavedExchange>,
}

/// A run of either interface on the grid.
pub(crate) struct Run {
    pub inst: Box<dyn Instance>,
    pub grid: Grid,
    /// Communication points reached.
    pub k: usize,
    pub t: f64,
    pub trajectory: Trajectory,
    recorder: Recorder,
    /// The model ended the run early (terminated, terminateSimulation): why.
    pub ended: Option<String>,
    /// The Model Exchange integration.
    me: Option<Exchange>,
}

impl Run {
    /// Instantiates an instance named `name` on `slot` and initializes it; the outputs at the
    /// start are the first row.
    pub(crate) fn start(ctx: &Ctx, name: &str, slot: usize) -> Result<Run, Failure> {
        let model = ctx.model();
        let grid = Grid::of(model, ctx.interface);
        let inst = ctx.instantiate(name, slot)?;
        let recorder = Recorder::new(model);
        let trajectory = Trajectory::new(recorder.columns.clone());
        let mut run = Run { inst, grid, k: 0, t: grid.start, trajectory, recorder, ended: None, me: None };
        run.begin()?;
        Ok(run)
    }

    /// Sets up, initializes and records the first row (also after a reset).
    fn begin(&mut self) -> Result<(), Failure> {
        initialize(self.inst.as_mut(), &self.grid)?;
        (self.k, self.t, self.ended) = (0, self.grid.start, None);
        self.trajectory.truncate(0);
        self.me = None;
        let inst = self.inst.as_mut();
        match inst.core().interface {
            Interface::ModelExchange => self.me = Some(Exchange::begin(inst, &self.grid, &mut self.ended)?),
            // With Event Mode: the initial event iteration, then Step Mode.
            Interface::CoSimulation if inst.core().state == State::EventMode => {
                if event_iteration(inst, self.grid.start)?.0.terminate {
                    self.ended = Some("the model asked to terminate during initialization".to_owned());
                } else {
                    enter(inst, Op::EnterStepMode, State::EventMode, State::StepMode)?;
                }
            }
            Interface::CoSimulation => {}
        }
        self.record()
    }

    fn record(&mut self) -> Result<(), Failure> {
        let row = self.recorder.read(self.inst.as_mut())?;
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
        let inst = self.inst.as_mut();
        match &mut self.me {
            Some(me) => me.advance(inst, self.t, target, &mut self.ended)?,
            None => {
                if let Some(stop) = co_simulation_step(inst, self.t, target)? {
                    if let Some(t) = stop.reached {
                        self.t = t;
                    }
                    self.ended = Some(stop.why);
                    return Ok(());
                }
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

    /// Terminate (after the model ended the run too: the standard allows it after a
    /// discarded step, and in Event Mode).
    pub(crate) fn terminate(&mut self) -> Result<(), Failure> {
        let state = self.inst.core().state;
        enter(self.inst.as_mut(), Op::Terminate, state, State::Terminated)
    }

    /// Reset, then a fresh start of the same experiment.
    pub(crate) fn reset(&mut self) -> Result<(), Failure> {
        let state = self.inst.core().state;
        enter(self.inst.as_mut(), Op::Reset, state, State::Instantiated)?;
        self.begin()
    }

    /// Saves the FMU state (GetFMUState) and the run's own.
    pub(crate) fn save(&mut self) -> Result<Saved, Failure> {
        let state = self.inst.core().state;
        let got = self.inst.get_fmu_state();
        let name = self.inst.core().name(Op::GetFmuState);
        let fmu_state = self.inst.core().expect(got, Op::GetFmuState, state)?;
        if fmu_state.is_null() {
            return Err(Failure::new(format!("{name} returned OK but no FMU state (NULL)")).at(name, state));
        }
        Ok(Saved { fmu_state, rows: self.trajectory.rows(), t: self.t, k: self.k, exchange: self.me.as_ref().map(Exchange::saved) })
    }

    /// Restores a save: SetFMUState, then the run's own bookkeeping; the recorded rows after it
    /// are dropped, and the restored outputs are compared with the row recorded then.
    pub(crate) fn restore(&mut self, saved: &Saved) -> Result<(), Failure> {
        let state = self.inst.core().state;
        let set = self.inst.set_fmu_state(saved.fmu_state);
        let name = self.inst.core().name(Op::SetFmuState);
        self.inst.core().expect(set, Op::SetFmuState, state)?;
        self.inst.core_mut().state = match self.inst.core().interface {
            Interface::CoSimulation => self.inst.core().binary.table().between_steps,
            Interface::ModelExchange => State::ContinuousTimeMode,
        };
        let row = self.recorder.read(self.inst.as_mut())?;
        let columns = self.trajectory.columns.clone();
        let recorded = Trajectory { columns: columns.clone(), times: vec![saved.t], values: self.trajectory.row(saved.rows - 1).to_vec() };
        let now = Trajectory { columns, times: vec![saved.t], values: row };
        if let Some(difference) = recorded.difference(&now, "the saved state", &format!("the state after {name}")) {
            return Err(Failure {
                message: format!("{name} did not restore the state saved at t = {}: {}", saved.t, difference.message),
                ..difference
            }
            .at(name, state));
        }
        self.trajectory.truncate(saved.rows);
        (self.t, self.k, self.ended) = (saved.t, saved.k, None);
        if let (Some(me), Some(exchange)) = (&mut self.me, saved.exchange) {
            me.restore(self.inst.as_mut(), exchange)?;
        }
        Ok(())
    }

    /// The Model Exchange integration of this run.
    pub(crate) fn exchange(&self) -> Option<&Exchange> {
        self.me.as_ref()
    }
}

/// Why a Co-Simulation run stops before its next communication point.
struct Stop {
    /// Where the model got to, if it says.
    reached: Option<f64>,
    why: String,
}

/// A time within rounding of another (an FMU's own sum of steps against the validator's).
fn within_rounding(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

/// DoStep from `t` to `target`, through the events and early returns an FMI 3.0 FMU asks for;
/// `Some` when the model ends the run.
fn co_simulation_step(inst: &mut dyn Instance, mut t: f64, target: f64) -> Result<Option<Stop>, Failure> {
    let capabilities = inst.core().model().capabilities(Interface::CoSimulation);
    let name = inst.core().name(Op::DoStep);
    let mut events = 0;
    while t < target {
        let state = inst.core().state;
        let h = target - t;
        let step = inst.do_step(t, h);
        if step.code.is_discard() {
            let terminated = step.value.terminate || {
                let status = inst.terminated();
                status.code.ok() && status.value
            };
            if terminated {
                let why = step.log.unwrap_or_else(|| format!("the model ended the run in the step from t = {t}"));
                if inst.core().binary.table().co_simulation.contains(&State::StepFailed) {
                    inst.core_mut().state = State::StepFailed;
                }
                return Ok(Some(Stop { reached: None, why }));
            }
            return Err(Failure::refused(name, state, &step, "").value(format!("t = {t}, h = {h}")).check("lifecycle.run"));
        }
        if !step.code.ok() {
            return Err(Failure::refused(name, state, &step, "").value(format!("t = {t}, h = {h}")));
        }
        let result = step.value;
        let reached = if result.early {
            let wrong = if !capabilities.early_return {
                Some(format!("{name} from t = {t} returned earlyReturn = true, but the instance was made with earlyReturnAllowed = false"))
            } else if !(result.last > t && (result.last <= target || within_rounding(result.last, target))) {
                Some(format!(
                    "{name} from t = {t} to {target} returned early with lastSuccessfulTime = {}, which is not within the step",
                    result.last
                ))
            } else {
                None
            };
            if let Some(message) = wrong {
                return Err(Failure::new(message).at(name, state).with_log(step.log));
            }
            // An FMU that counts time its own way may land a rounding past the target.
            if within_rounding(result.last, target) {
                target
            } else {
                result.last
            }
        } else {
            target
        };
        if result.terminate {
            return Ok(Some(Stop { reached: Some(reached), why: format!("terminateSimulation from {name} at t = {reached}") }));
        }
        t = reached;
        if result.event || reached < target {
            events += 1;
            if events > MAX_EVENTS_PER_STEP {
                return Err(Failure::new(format!(
                    "more than {MAX_EVENTS_PER_STEP} events or early returns within the step to t = {target}"
                ))
                .at(name, state));
            }
        }
        if result.event && capabilities.event_mode {
            enter(inst, Op::EnterEventMode, State::StepMode, State::EventMode)?;
            if event_iteration(inst, t)?.0.terminate {
                return Ok(Some(Stop { reached: Some(t), why: format!("the model asked to terminate at the event at t = {t}") }));
            }
            enter(inst, Op::EnterStepMode, State::EventMode, State::StepMode)?;
        }
    }
    Ok(None)
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
        let short = Trajectory { times: vec![0.0], values: vec![1.0, 2.0], ..a.clone() };
        assert!(a.difference(&short, "a", "b").unwrap().message.contains("a has 2 communication points but b has 1"));
    }
}
