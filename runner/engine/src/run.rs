//! One simulation run: instantiate, set, initialize, step on a fixed communication grid, read.
//! A Model Exchange FMU is integrated by the runner between the grid points, with the grid's
//! solver; a Co-Simulation FMU integrates itself.

use fmi_importer::{Description, Fmu, Instance, Reader, Solver, Step, Value, Variable};

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
}

/// Grid settings from one source (the command line, an experiment file); `None` leaves the
/// choice to the next source.
#[derive(Debug, Clone, Copy, Default)]
pub struct GridSettings {
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
        let start = default.start_time.unwrap_or(0.0);
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
        Ok(Grid { start, stop, interval, tolerance, solver: Solver::default() })
    }

    /// Number of communication steps; a last partial interval is kept (shortened to end at stop).
    pub fn steps(&self) -> usize {
        let n = (self.stop - self.start) / self.interval;
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
    /// Model Exchange: the runner's integrator's accepted steps and right-hand-side
    /// evaluations (`None` for Co-Simulation).
    pub counters: Option<(u64, u64)>,
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

/// Runs one instance named `name`: sets `assignments` before initialization, then calls
/// `sample(t, values)` at every communication point with the values of `recorded` in order
/// (scalars only: arrays go through [`run_recording`]).
pub fn run(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    recorded: &[&Variable],
    debug_logging: bool,
    sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
) -> Result<Outcome, String> {
    run_driven(fmu, name, grid, assignments, None, recorded, debug_logging, sample)
}

/// The exact text of each column of a sample (strings, binary, wide integers): the [`Reader`]
/// that read it, or in a supervisor the numbers and the texts its worker sent.
pub trait Texts {
    /// Column `c` of the sample whose numbers are `values`.
    fn text(&self, c: usize, values: &[f64]) -> String;
    /// True when column `c`'s number alone does not give its text.
    fn needs_text(&self, c: usize) -> bool;
}

impl Texts for Reader {
    fn text(&self, c: usize, values: &[f64]) -> String {
        Reader::text(self, c, values)
    }

    fn needs_text(&self, c: usize) -> bool {
        Reader::needs_text(self, c)
    }
}

/// [`run`] for the columns of a [`Recording`], arrays included; `sample` also gets the texts
/// that give each column exactly.
pub fn run_recording(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    recording: &Recording,
    debug_logging: bool,
    sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
) -> Result<Outcome, String> {
    run_with_inputs(fmu, name, grid, assignments, None, recording, debug_logging, sample)
}

/// [`run`] with `inputs` (`None`: none) set before initialization ends and before every step,
/// each step ending on the inputs' next discontinuity where it would cross one.
#[allow(clippy::too_many_arguments)]
pub fn run_driven(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    inputs: Option<&Inputs>,
    recorded: &[&Variable],
    debug_logging: bool,
    mut sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
) -> Result<Outcome, String> {
    let recording = Recording::scalars(recorded)?;
    run_with_inputs(fmu, name, grid, assignments, inputs, &recording, debug_logging, |t, values, _| sample(t, values))
}

/// [`run_recording`] with `inputs` (`None`: none), as [`run_driven`] applies them.
#[allow(clippy::too_many_arguments)]
pub fn run_with_inputs(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    inputs: Option<&Inputs>,
    recording: &Recording,
    debug_logging: bool,
    sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
) -> Result<Outcome, String> {
    run_sampled(fmu, name, grid, assignments, inputs, recording, debug_logging, Closure(sample))
}

/// What a run does with each sample. A closure `sample(t, values, texts)` is one (see
/// [`run_with_inputs`]); a type of its own can have its method always inlined into the run's
/// loop, which a closure called at the loop's several places is not (a call of its own cost
/// a sweep about 20 instructions per sample).
pub trait Sampler {
    /// The values of the recorded columns at time `t`, and their exact texts.
    fn sample(&mut self, t: f64, values: &[f64], texts: &dyn Texts) -> Result<(), String>;
}

struct Closure<F>(F);

impl<F: FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>> Sampler for Closure<F> {
    #[inline]
    fn sample(&mut self, t: f64, values: &[f64], texts: &dyn Texts) -> Result<(), String> {
        (self.0)(t, values, texts)
    }
}

/// [`run_with_inputs`] with a [`Sampler`].
#[allow(clippy::too_many_arguments)]
pub fn run_sampled(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    inputs: Option<&Inputs>,
    recording: &Recording,
    debug_logging: bool,
    sampler: impl Sampler,
) -> Result<Outcome, String> {
    // Two copies of the loop: the one without inputs is the sweep's hot path, unchanged.
    match inputs {
        None => drive(fmu, name, grid, assignments, &Constant, recording, debug_logging, sampler),
        Some(inputs) => drive(fmu, name, grid, assignments, inputs, recording, debug_logging, sampler),
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

#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn drive(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    inputs: &impl Stimulus,
    recording: &Recording,
    debug_logging: bool,
    mut sampler: impl Sampler,
) -> Result<Outcome, String> {
    let mut reader = Reader::with_sizes(fmu.description.fmi_version, &recording.variables, &recording.sizes)?;
    let mut values = vec![0.0; reader.len()];
    let mut instance = fmu.instantiate(name, debug_logging)?;
    instance.set_solver(grid.solver);
    instance.setup_experiment(grid.tolerance, grid.start, grid.stop)?;
    for (variable, value) in assignments {
        instance.set(variable, value)?;
    }
    instance.enter_initialization_mode()?;
    inputs.apply(&mut instance, grid.start)?;
    instance.exit_initialization_mode()?;
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
                        return Ok(Outcome { ended_early: Some(reason), counters: instance.counters() });
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
                    return Ok(Outcome { ended_early: Some(reason), counters: instance.counters() });
                }
            }
        }
        instance.read(&mut reader, &mut values)?;
        sampler.sample(t_next, &values, &reader)?;
        t = t_next;
    }
    Ok(Outcome { ended_early: None, counters: instance.counters() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::{Dimension, FmiVersion, Start};
    use fmi_importer::{Causality, Kind, Variability};

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

    /// A 2 x n matrix output, n a structural parameter with start 3: its columns are named
    /// row-major, 1-based, and follow a value set for n.
    #[test]
    fn arrays_expand_to_row_major_columns_sized_by_structural_parameters() {
        let n = variable("n", 1, Kind::UInt64, Causality::StructuralParameter, Some(Start::Integer(3)), vec![]);
        let y = variable("y", 2, Kind::Real, Causality::Output, None, vec![Dimension::Fixed(2), Dimension::Variable(1)]);
        let s = variable("s", 3, Kind::Real, Causality::Output, None, vec![]);
        let description = Description {
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
            variables: vec![n.clone(), y.clone(), s.clone()],
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        };
        let r = Recording::new(&description, &[&s, &y], &[]).unwrap();
        assert_eq!(r.names, ["s", "y[1,1]", "y[1,2]", "y[1,3]", "y[2,1]", "y[2,2]", "y[2,3]"]);
        assert_eq!(r.sizes, [1, 6]);
        let r = Recording::new(&description, &[&y], &[(&n, Value::Int(1))]).unwrap();
        assert_eq!(r.names, ["y[1,1]", "y[2,1]"]);
        let no_size = Variable { start: None, ..n.clone() };
        let description = Description { variables: vec![no_size, y.clone()], ..description };
        assert!(Recording::new(&description, &[&y], &[]).err().unwrap().contains("the size of y is given by value reference 1"));
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
