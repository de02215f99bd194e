//! One simulation run: instantiate, set, initialize, step on a fixed communication grid, read.

use fmi_importer::{Description, Fmu, Reader, Step, Value, Variable};

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
    /// Relative tolerance for fmi2SetupExperiment (`None`: the FMU's own default).
    pub tolerance: Option<f64>,
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
        Ok(Grid { start, stop, interval, tolerance })
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
    fn time_of(&self, i: usize, steps: usize) -> f64 {
        if i >= steps {
            self.stop
        } else {
            self.start + i as f64 * self.interval
        }
    }
}

/// How a run ended.
pub struct Outcome {
    /// `Some(reason)` when the model stopped before the stop time (fmi2Discard + terminated).
    pub ended_early: Option<String>,
}

/// Runs one instance named `name`: sets `assignments` before initialization, then calls
/// `sample(t, values)` at every communication point with the values of `recorded` in order.
pub fn run(
    fmu: &Fmu,
    name: &str,
    grid: &Grid,
    assignments: &[(&Variable, Value)],
    recorded: &[&Variable],
    debug_logging: bool,
    mut sample: impl FnMut(f64, &[f64]) -> Result<(), String>,
) -> Result<Outcome, String> {
    let mut reader = Reader::new(recorded)?;
    let mut values = vec![0.0; recorded.len()];
    let mut instance = fmu.instantiate(name, debug_logging)?;
    instance.setup_experiment(grid.tolerance, grid.start, grid.stop)?;
    for (variable, value) in assignments {
        instance.set(variable, value)?;
    }
    instance.enter_initialization_mode()?;
    instance.exit_initialization_mode()?;
    instance.read(&mut reader, &mut values)?;
    sample(grid.start, &values)?;
    let n = grid.steps();
    let mut t = grid.time_of(0, n);
    for i in 0..n {
        let t_next = grid.time_of(i + 1, n);
        match instance.do_step(t, t_next - t)? {
            Step::Done => {
                instance.read(&mut reader, &mut values)?;
                sample(t_next, &values)?;
            }
            Step::Ended { reason, last_time } => {
                // Like fmpy: keep the state the model reached as a last row, when it is new.
                if let Some(last) = last_time.filter(|&last| last > t) {
                    instance.read(&mut reader, &mut values)?;
                    sample(last, &values)?;
                }
                return Ok(Outcome { ended_early: Some(reason) });
            }
        }
        t = t_next;
    }
    Ok(Outcome { ended_early: None })
}

#[cfg(test)]
mod tests {
    use super::*;

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
