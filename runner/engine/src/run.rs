//! One simulation run: instantiate, set, initialize, step on a fixed communication grid, read.
//! A Model Exchange FMU is integrated by the runner between the grid points, with the grid's
//! solver; a Co-Simulation FMU integrates itself.

use fmi_importer::state::SavedState;
use fmi_importer::{Description, Fmu, Instance, Interface, Method, Reader, Solver, Step, Value, Variable};

use crate::input::Inputs;

/// Most communication steps a run may have: a billion is minutes per run and a CSV of a
/// hundred gigabytes, so more is a typo in the stop time or the interval, not an experiment.
pub const MAX_STEPS: usize = 1_000_000_000;

/// The time grid and tolerance of a run.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    /// Start time (s).
    pub start: f64,
    /// Stop time (s).
    pub stop: f64,
    /// Communication interval (s).
    pub interval: f64,
    /// Relative tolerance for fmi2SetupExperiment (`None`: the FMU's own default), also the
    /// runner's integrator's for Model Exchange.
    pub tolerance: Option<f64>,
    /// The runner's integrator for Model Exchange (unused for Co-Simulation).
    pub solver: Solver,
    /// Communication points on a logarithmic time scale (fmusim's `--log-time-scale`): point
    /// `i` is `start * interval^i`, `interval` then a factor above 1 and `start` above 0.
    #[serde(default)]
    pub logarithmic: bool,
}

/// How a caller's users write the integrator's options, for the messages of [`solver_of`] and
/// [`refuse_solver_under_co_simulation`]: `--fixed-step ` on the command line, `fixed_step=`
/// in Python.
#[derive(Debug, Clone, Copy)]
pub struct SolverOptionNames {
    /// The fixed step's option up to its value.
    pub fixed_step: &'static str,
    /// The absolute tolerance's option up to its value.
    pub abs_tolerance: &'static str,
    /// All the integrator's options, as a list in a sentence.
    pub all: &'static str,
    /// How to choose Model Exchange instead, for an FMU that offers it.
    pub to_model_exchange: &'static str,
}

/// Refuses the integrator's options (`given`: one of them was) for an FMU that runs as
/// Co-Simulation (`interface`), where they would silently do nothing.
pub fn refuse_solver_under_co_simulation(
    given: bool,
    description: &Description,
    identifier: &str,
    interface: Interface,
    names: SolverOptionNames,
) -> Result<(), String> {
    if given && interface == Interface::CoSimulation {
        return Err(format!(
            "{} set the runner's integrator, which only Model Exchange uses; {identifier} runs as Co-Simulation here, where the FMU integrates itself ({})",
            names.all,
            if description.model_exchange.is_some() { names.to_model_exchange } else { "it offers no Model Exchange interface" }
        ));
    }
    Ok(())
}

/// The runner's integrator for Model Exchange from a caller's options, checked: the method
/// called `method`, `fixed_step` (s) and `abs_tolerance`, each the toolkit's default when not
/// given (DOPRI5, 1 ms, 1e-9). A bad option is refused by its name as the caller spells it.
pub fn solver_of(
    method: Option<&str>,
    fixed_step: Option<f64>,
    abs_tolerance: Option<f64>,
    names: SolverOptionNames,
) -> Result<Solver, String> {
    let mut solver = Solver::default();
    if let Some(name) = method {
        solver.method = Method::from_name(name).ok_or_else(|| {
            let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
            format!("unknown solver '{name}': use {}", names.join(", "))
        })?;
    }
    if let Some(h) = fixed_step {
        if !(h.is_finite() && h > 0.0) {
            return Err(format!("{}{h} must be a positive number (seconds)", names.fixed_step));
        }
        solver.fixed_step = h;
    }
    if let Some(a) = abs_tolerance {
        if !(a.is_finite() && a >= 0.0) {
            return Err(format!("{}{a} must be a number, zero or greater", names.abs_tolerance));
        }
        solver.abs_tol = a;
    }
    Ok(solver)
}

/// Grid settings from one source (the command line, an experiment file); `None` leaves the
/// choice to the next source.
#[derive(Debug, Clone, Copy, Default)]
pub struct GridSettings {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub output_interval: Option<f64>,
    pub tolerance: Option<f64>,
}

impl Grid {
    /// The first of `sources` (in priority order) that sets each value, then the FMU's
    /// DefaultExperiment, then fmpy's fallbacks (stop 1 s, 500 intervals), so a comparison
    /// with fmpy uses the same grid.
    pub fn choose(description: &Description, sources: &[GridSettings]) -> Result<Grid, String> {
        let default = description.default_experiment.unwrap_or_default();
        let first = |pick: fn(&GridSettings) -> Option<f64>| sources.iter().find_map(pick);
        let start = first(|s| s.start_time).or(default.start_time).unwrap_or(0.0);
        let stop = first(|s| s.stop_time).or(default.stop_time).unwrap_or(start + 1.0);
        let interval = first(|s| s.output_interval).or(default.step_size).unwrap_or((stop - start) / 500.0);
        let tolerance = first(|s| s.tolerance).or(default.tolerance);
        Grid::checked(start, stop, interval, tolerance)
    }

    /// The grid, after checking that it makes sense and that its steps are not absurdly many.
    pub fn checked(start: f64, stop: f64, interval: f64, tolerance: Option<f64>) -> Result<Grid, String> {
        if stop <= start || !stop.is_finite() {
            return Err(format!("stop time {stop} must be a number after the start time {start}"));
        }
        if interval <= 0.0 || !interval.is_finite() {
            return Err(format!("output interval {interval} must be a positive number"));
        }
        let steps = (stop - start) / interval;
        if steps > MAX_STEPS as f64 {
            return Err(format!(
                "{:?} s of simulated time at an output interval of {interval:?} s is {steps:.3e} communication steps, more than the {MAX_STEPS:.0e} a run may have (raise the output interval)",
                stop - start
            ));
        }
        if let Some(t) = tolerance {
            if t <= 0.0 || !t.is_finite() {
                return Err(format!("tolerance {t} must be a positive number"));
            }
        }
        Ok(Grid { start, stop, interval, tolerance, solver: Solver::default(), logarithmic: false })
    }

    /// The grid of `start`, `stop` and `tolerance` of `description` and `sources` (as
    /// [`Grid::choose`]) with its points on a logarithmic time scale, as fmusim's
    /// `--log-time-scale`: point `i` is `start * factor^i`. The factor is the first source's
    /// output interval (a DefaultExperiment's stepSize is a step, not a factor, so it is not
    /// taken), else the one that gives 500 intervals from start to stop.
    pub fn choose_logarithmic(description: &Description, sources: &[GridSettings]) -> Result<Grid, String> {
        let default = description.default_experiment.unwrap_or_default();
        let first = |pick: fn(&GridSettings) -> Option<f64>| sources.iter().find_map(pick);
        let start = first(|s| s.start_time).or(default.start_time).unwrap_or(0.0);
        let stop = first(|s| s.stop_time).or(default.stop_time).unwrap_or(start + 1.0);
        let tolerance = first(|s| s.tolerance).or(default.tolerance);
        if start <= 0.0 || !start.is_finite() {
            return Err(format!(
                "a logarithmic time scale starts above 0, not at start time {start}: give --start-time (the Reference FMU Roberts starts at 1e-5 s)"
            ));
        }
        if stop <= start || !stop.is_finite() {
            return Err(format!("stop time {stop} must be a number after the start time {start}"));
        }
        let factor = first(|s| s.output_interval).unwrap_or_else(|| (stop / start).powf(1.0 / 500.0));
        if factor <= 1.0 || !factor.is_finite() {
            return Err(format!(
                "on a logarithmic time scale the output interval is the factor from one point to the next, a number above 1, not {factor}"
            ));
        }
        let steps = (stop / start).ln() / factor.ln();
        if steps > MAX_STEPS as f64 {
            return Err(format!(
                "a factor of {factor:?} from {start:?} s to {stop:?} s is {steps:.3e} communication steps, more than the {MAX_STEPS:.0e} a run may have (raise the factor)"
            ));
        }
        let grid = Grid::checked(start, stop, 1.0, tolerance)?;
        Ok(Grid { interval: factor, logarithmic: true, ..grid })
    }

    /// Number of communication steps; a last partial interval is kept (shortened to end at stop).
    pub fn steps(&self) -> usize {
        let n = match self.logarithmic {
            true => (self.stop / self.start).ln() / self.interval.ln(),
            false => (self.stop - self.start) / self.interval,
        };
        // Round away float noise such as 10 / 1e-3 = 9999.999999999998.
        if (n - n.round()).abs() < 1e-9 * n.max(1.0) {
            n.round() as usize
        } else {
            n.ceil() as usize
        }
    }

    /// Communication point `i`, computed from `i` rather than accumulated so it does not drift.
    pub fn time(&self, i: usize) -> f64 {
        self.time_of(i, self.steps())
    }

    /// [`Grid::time`] for a grid of `steps` steps, so a loop computes `steps()` only once.
    pub fn time_of(&self, i: usize, steps: usize) -> f64 {
        if i >= steps {
            self.stop
        } else if self.logarithmic {
            // As fmusim computes its points: from i, not accumulated (i < steps <= MAX_STEPS
            // fits an i32).
            self.start * self.interval.powi(i as i32)
        } else {
            // i < steps <= MAX_STEPS: as i64 it converts in one instruction (an unsigned one
            // takes five), to the same exact value.
            self.start + (i as i64) as f64 * self.interval
        }
    }
}

/// How a run ended.
pub struct Outcome {
    /// `Some(reason)` when the model stopped before the stop time (fmi2Discard + terminated,
    /// or terminateSimulation under Model Exchange).
    pub ended_early: Option<String>,
    /// Model Exchange: the work of the runner's integrator (`None` for Co-Simulation).
    pub counters: Option<fmi_importer::exchange::Counters>,
    /// The state at the stop time, as bytes naming the FMU, when the run asked for it
    /// ([`Run::final_state`]; not when the model ended the run early).
    pub final_state: Option<Vec<u8>>,
}

/// The columns a run records: its variables, with each array expanded into its elements
/// (`name[i]`, `name[i,j]`, 1-based as FMI's structured names), sized by the structural
/// parameters the run's assignments set (else their start values).
pub struct Recording<'a> {
    pub variables: Vec<&'a Variable>,
    /// Elements per variable (1 for a scalar).
    pub sizes: Vec<usize>,
    /// One name per column.
    pub names: Vec<String>,
    /// Also sample at each event an FMU stops a step at (before handling it), besides the
    /// communication points.
    pub events: bool,
}

impl<'a> Recording<'a> {
    /// The columns of scalar variables, one each (an array is refused: name its elements).
    pub fn scalars(variables: &[&'a Variable]) -> Result<Recording<'a>, String> {
        if let Some(array) = variables.iter().find(|v| v.is_array()) {
            return Err(format!("{} is an array; name one of its elements", array.name));
        }
        Ok(Recording { variables: variables.to_vec(), sizes: vec![1; variables.len()], names: Vec::new(), events: false })
    }

    /// The columns of `variables`, arrays sized with `assignments` applied.
    pub fn new(description: &Description, variables: &[&'a Variable], assignments: &[(&Variable, Value)]) -> Result<Recording<'a>, String> {
        let size_of = |vr: u32| {
            assignments.iter().rev().find(|(v, _)| v.value_reference == vr).and_then(|(_, value)| match value {
                Value::Integer(n) => u64::try_from(*n).ok(),
                Value::Int(n) => u64::try_from(*n).ok(),
                _ => None,
            })
        };
        let mut recording = Recording { variables: variables.to_vec(), sizes: Vec::new(), names: Vec::new(), events: false };
        for v in variables {
            if !v.is_array() {
                recording.sizes.push(1);
                recording.names.push(v.name.clone());
                continue;
            }
            let shape = description.shape(v, &size_of)?;
            let count: u64 = shape.iter().product();
            if count > MAX_ARRAY_ELEMENTS {
                return Err(format!("{} has {count} elements, more than the {MAX_ARRAY_ELEMENTS} a recorded array may have", v.name));
            }
            recording.sizes.push(count as usize);
            for flat in 0..count {
                // Row-major: the last index varies fastest.
                let mut rest = flat;
                let mut index = vec![0u64; shape.len()];
                for (slot, n) in index.iter_mut().zip(&shape).rev() {
                    *slot = rest % n + 1;
                    rest /= n;
                }
                let index: Vec<String> = index.iter().map(u64::to_string).collect();
                recording.names.push(format!("{}[{}]", v.name, index.join(",")));
            }
        }
        Ok(recording)
    }
}

/// Most elements a recorded array may have: one CSV column each.
pub const MAX_ARRAY_ELEMENTS: u64 = 100_000;

/// One run of a loaded FMU, its names bound to the FMU's variables: the one argument of the
/// run loop ([`Run::execute`]). It borrows what it names, so a sweep point, a
/// [`crate::request::RunRequest`] bound to an FMU and a trace all make one without copying.
pub struct Run<'r, 'a> {
    /// The instance name.
    pub name: &'r str,
    /// The time grid, tolerance and (Model Exchange) solver.
    pub grid: &'r Grid,
    /// Set before initialization, in order (a later one wins).
    pub assignments: &'r [(&'a Variable, Value)],
    /// Set before initialization ends and before every step, each step ending on the inputs'
    /// next discontinuity where it would cross one.
    pub inputs: Option<&'r Inputs<'a>>,
    /// The columns sampled.
    pub recording: &'r Recording<'a>,
    /// Turns the FMU's debug logging on.
    pub debug_logging: bool,
    /// Restored after initialization: the run goes on from this state (taken at the grid's
    /// start time).
    pub initial_state: Option<&'r SavedState>,
    /// Save the state reached at the stop time ([`Outcome::final_state`]).
    pub final_state: bool,
}

impl Run<'_, '_> {
    /// Runs one instance of `fmu` (the FMU the run's variables are of): instantiate, set,
    /// initialize, step on the grid, calling `sampler` at every communication point (and at
    /// every event a step stops at, when the recording asks).
    pub fn execute(&self, fmu: &Fmu, sampler: impl Sampler) -> Result<Outcome, String> {
        // Two copies of the loop: the one without inputs is the sweep's hot path, unchanged.
        match self.inputs {
            None => drive(fmu, self, &Constant, sampler),
            Some(inputs) => drive(fmu, self, inputs, sampler),
        }
    }
}

/// The exact text of each column of a sample (strings, binary, wide integers): the [`Reader`]
/// that read it, or in a supervisor the numbers and the texts its worker sent.
pub trait Texts {
    /// Column `c` of the sample whose numbers are `values`.
    fn text(&self, c: usize, values: &[f64]) -> String;
    /// True when column `c`'s number alone does not give its text.
    fn needs_text(&self, c: usize) -> bool;
    /// Appends the text of column `c`'s number `x` to `out`, for a column that does not
    /// [`Texts::needs_text`]: what [`Texts::text`] gives, without a String per number.
    fn push_number_text(&self, c: usize, x: f64, out: &mut Vec<u8>);
}

impl Texts for Reader {
    fn text(&self, c: usize, values: &[f64]) -> String {
        Reader::text(self, c, values)
    }

    fn needs_text(&self, c: usize) -> bool {
        Reader::needs_text(self, c)
    }

    fn push_number_text(&self, c: usize, x: f64, out: &mut Vec<u8>) {
        self.push_text_of_number(c, x, out)
    }
}

/// What a run does with each sample: any closure `sample(t, values, texts)` is one; a type of
/// its own (a sweep's summaries) can have its method always inlined into the run's loop.
pub trait Sampler {
    /// The values of the recorded columns at time `t`, and their exact texts.
    fn sample(&mut self, t: f64, values: &[f64], texts: &dyn Texts) -> Result<(), String>;
}

impl<F: FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>> Sampler for F {
    #[inline]
    fn sample(&mut self, t: f64, values: &[f64], texts: &dyn Texts) -> Result<(), String> {
        self(t, values, texts)
    }
}

/// What a run sets before each step.
trait Stimulus {
    /// Sets the inputs at `time`.
    fn apply(&self, instance: &mut Instance, time: f64) -> Result<(), String>;
    /// Where a step from `now` towards `end` must stop.
    fn step_end(&self, now: f64, end: f64) -> f64;
}

/// No inputs: every input keeps the value it was given before initialization.
struct Constant;

impl Stimulus for Constant {
    #[inline(always)]
    fn apply(&self, _: &mut Instance, _: f64) -> Result<(), String> {
        Ok(())
    }

    #[inline(always)]
    fn step_end(&self, _: f64, end: f64) -> f64 {
        end
    }
}

impl Stimulus for Inputs<'_> {
    #[inline]
    fn apply(&self, instance: &mut Instance, time: f64) -> Result<(), String> {
        Inputs::apply(self, instance, time)
    }

    #[inline]
    fn step_end(&self, now: f64, end: f64) -> f64 {
        Inputs::step_end(self, now, end)
    }
}

#[inline(always)]
fn drive(fmu: &Fmu, run: &Run, inputs: &impl Stimulus, mut sampler: impl Sampler) -> Result<Outcome, String> {
    let (grid, recording) = (run.grid, run.recording);
    let mut reader = Reader::with_sizes(fmu.description.fmi_version, &recording.variables, &recording.sizes)?;
    let mut values = vec![0.0; reader.len()];
    let mut instance = fmu.instantiate(run.name, run.debug_logging)?;
    instance.set_solver(grid.solver);
    // A state saved to be continued must not hold the stop time: the FMU is told none.
    let stop = if run.final_state { f64::INFINITY } else { grid.stop };
    instance.setup_experiment(grid.tolerance, grid.start, stop)?;
    for (variable, value) in run.assignments {
        instance.set(variable, value)?;
    }
    instance.enter_initialization_mode()?;
    inputs.apply(&mut instance, grid.start)?;
    instance.exit_initialization_mode()?;
    if let Some(state) = run.initial_state {
        instance.restore_state(state)?;
    }
    instance.read(&mut reader, &mut values)?;
    sampler.sample(grid.start, &values, &reader)?;
    let n = grid.steps();
    let mut t = grid.time_of(0, n);
    for i in 0..n {
        let t_next = grid.time_of(i + 1, n);
        // A step may stop at events before its end, or end early on an input's discontinuity:
        // go on from each until t_next.
        let mut now = t;
        loop {
            inputs.apply(&mut instance, now)?;
            let end = inputs.step_end(now, t_next);
            match instance.do_step(now, end - now)? {
                Step::Done => {
                    if end == t_next {
                        break;
                    }
                    now = end;
                }
                Step::Event { time } => {
                    if recording.events {
                        instance.read(&mut reader, &mut values)?;
                        sampler.sample(time, &values, &reader)?;
                    }
                    if let Some(reason) = instance.handle_event(time)? {
                        instance.read(&mut reader, &mut values)?;
                        sampler.sample(time, &values, &reader)?;
                        return Ok(Outcome { ended_early: Some(reason), counters: instance.counters(), final_state: None });
                    }
                    if time >= t_next {
                        break;
                    }
                    now = time;
                }
                Step::Ended { reason, last_time } => {
                    // Like fmpy: keep the state the model reached as a last row, when it is new.
                    if let Some(last) = last_time.filter(|&last| last > t) {
                        instance.read(&mut reader, &mut values)?;
                        sampler.sample(last, &values, &reader)?;
                    }
                    return Ok(Outcome { ended_early: Some(reason), counters: instance.counters(), final_state: None });
                }
            }
        }
        instance.read(&mut reader, &mut values)?;
        sampler.sample(t_next, &values, &reader)?;
        t = t_next;
    }
    let final_state = match run.final_state {
        true => Some(instance.save_state(grid.stop)?.to_bytes(fmu.state_identity())),
        false => None,
    };
    Ok(Outcome { ended_early: None, counters: instance.counters(), final_state })
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::{Dimension, FmiVersion, Start};
    use fmi_importer::{Causality, Kind, Variability};

    #[test]
    fn solver_options_are_checked_by_the_callers_names() {
        let names = SolverOptionNames { fixed_step: "fixed_step=", abs_tolerance: "abs_tolerance=", all: "", to_model_exchange: "" };
        assert_eq!(solver_of(None, None, None, names).unwrap(), Solver::default());
        let bdf = solver_of(Some("BDF"), Some(1e-4), Some(0.0), names).unwrap();
        assert_eq!((bdf.method, bdf.fixed_step, bdf.abs_tol), (Method::Bdf, 1e-4, 0.0));
        assert!(solver_of(Some("cvode"), None, None, names).unwrap_err().starts_with("unknown solver 'cvode': use euler, rk4"));
        assert_eq!(solver_of(None, Some(-1.0), None, names).unwrap_err(), "fixed_step=-1 must be a positive number (seconds)");
        assert_eq!(solver_of(None, Some(f64::NAN), None, names).unwrap_err(), "fixed_step=NaN must be a positive number (seconds)");
        assert_eq!(solver_of(None, None, Some(-1e-9), names).unwrap_err(), "abs_tolerance=-0.000000001 must be a number, zero or greater");
    }

    /// The integrator's options are refused under Co-Simulation only, and only when given; the
    /// message names the caller's options and says how to reach Model Exchange when the FMU
    /// offers it.
    #[test]
    fn solver_options_are_refused_under_co_simulation() {
        let names = SolverOptionNames { fixed_step: "", abs_tolerance: "", all: "the options", to_model_exchange: "switch" };
        let cs_only = description(vec![]);
        let both = Description { model_exchange: Some(Default::default()), ..description(vec![]) };
        let refuse = |given, d: &Description, interface| refuse_solver_under_co_simulation(given, d, "m", interface, names);
        assert_eq!(refuse(false, &both, Interface::CoSimulation), Ok(()));
        assert_eq!(refuse(true, &both, Interface::ModelExchange), Ok(()));
        assert_eq!(
            refuse(true, &both, Interface::CoSimulation).unwrap_err(),
            "the options set the runner's integrator, which only Model Exchange uses; m runs as Co-Simulation here, where the FMU integrates itself (switch)"
        );
        assert!(refuse(true, &cs_only, Interface::CoSimulation).unwrap_err().ends_with("(it offers no Model Exchange interface)"));
    }

    fn variable(name: &str, vr: u32, kind: Kind, causality: Causality, start: Option<Start>, dimensions: Vec<Dimension>) -> Variable {
        Variable {
            name: name.into(),
            value_reference: vr,
            description: None,
            kind,
            causality,
            variability: Variability::Tunable,
            unit: None,
            display_unit: None,
            start,
            dimensions,
        }
    }

    /// An FMI 3.0 description of `variables`.
    fn description(variables: Vec<Variable>) -> Description {
        Description {
            fmi_version: FmiVersion::Fmi3,
            fmi_version_text: "3.0".into(),
            model_name: "m".into(),
            description: None,
            instantiation_token: "t".into(),
            generation_tool: None,
            co_simulation: None,
            model_exchange: None,
            default_experiment: None,
            units: vec![],
            variables,
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        }
    }

    /// A 2 x n matrix output, n a structural parameter with start 3: its columns are named
    /// row-major, 1-based, and follow a value set for n.
    #[test]
    fn arrays_expand_to_row_major_columns_sized_by_structural_parameters() {
        let n = variable("n", 1, Kind::UInt64, Causality::StructuralParameter, Some(Start::Integer(3)), vec![]);
        let y = variable("y", 2, Kind::Real, Causality::Output, None, vec![Dimension::Fixed(2), Dimension::Variable(1)]);
        let s = variable("s", 3, Kind::Real, Causality::Output, None, vec![]);
        let description = description(vec![n.clone(), y.clone(), s.clone()]);
        let r = Recording::new(&description, &[&s, &y], &[]).unwrap();
        assert_eq!(r.names, ["s", "y[1,1]", "y[1,2]", "y[1,3]", "y[2,1]", "y[2,2]", "y[2,3]"]);
        assert_eq!(r.sizes, [1, 6]);
        let r = Recording::new(&description, &[&y], &[(&n, Value::Int(1))]).unwrap();
        assert_eq!(r.names, ["y[1,1]", "y[2,1]"]);
        let no_size = Variable { start: None, ..n.clone() };
        let description = Description { variables: vec![no_size, y.clone()], ..description };
        assert!(Recording::new(&description, &[&y], &[]).err().unwrap().contains("the size of y is given by value reference 1"));
    }

    /// fmusim's logarithmic grid: point i is start·F^i, ending on the stop time (a last partial
    /// step kept); float noise in ln(stop/start)/ln(F) does not add a step.
    #[test]
    fn logarithmic_grids_multiply_by_the_factor() {
        let description = description(vec![]);
        let settings = GridSettings { start_time: Some(1e-5), stop_time: Some(1e8), output_interval: Some(10.0), tolerance: None };
        let grid = Grid::choose_logarithmic(&description, &[settings]).unwrap();
        assert_eq!(grid.steps(), 13);
        assert_eq!(grid.time(0), 1e-5);
        assert_eq!(grid.time(3), 1e-5 * 1000.0);
        assert_eq!(grid.time(13), 1e8);
        let partial = GridSettings { stop_time: Some(5e-4), ..settings };
        let grid = Grid::choose_logarithmic(&description, &[partial]).unwrap();
        assert_eq!((grid.steps(), grid.time(1), grid.time(2)), (2, 1e-5 * 10.0, 5e-4), "the last step ends at stop");
        let default = Grid::choose_logarithmic(&description, &[GridSettings { output_interval: None, ..settings }]).unwrap();
        assert_eq!(default.steps(), 500, "500 intervals when no factor is given");
        let at_zero = GridSettings { start_time: None, ..settings };
        assert!(Grid::choose_logarithmic(&description, &[at_zero]).unwrap_err().contains("starts above 0"));
    }

    /// A typo such as an output interval of 1e-300 must be refused at once, not start a run
    /// of 1e301 steps; a billion steps is still allowed, and so is any sane grid.
    #[test]
    fn grids_of_more_than_a_billion_steps_are_refused() {
        let err = Grid::checked(0.0, 10.0, 1e-300, None).unwrap_err();
        assert!(err.contains("1.000e301 communication steps, more than the 1e9"), "{err}");
        assert!(Grid::checked(0.0, 1e308, 1e-300, None).unwrap_err().contains("inf communication steps"));
        assert!(Grid::checked(0.0, 10.0, 1e-8, None).is_ok(), "exactly a billion steps");
        assert!(Grid::checked(0.0, 10.0, 0.99e-8, None).is_err());
        assert_eq!(Grid::checked(0.0, 10.0, 1e-3, Some(1e-9)).unwrap().steps(), 10_000);
        assert!(Grid::checked(0.0, 10.0, 1e-3, Some(-1.0)).unwrap_err().contains("tolerance -1 must be a positive number"));
    }
}
