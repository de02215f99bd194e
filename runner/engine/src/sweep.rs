//! Sweeps: the cartesian product of parameter ranges, one FMU instance per point, run in
//! parallel on a rayon pool (one loaded FMU for the whole sweep), with metrics per point and
//! the results handed back in point order as they finish. A [`Plan`] is a
//! [`crate::request::SweepRequest`] bound to an FMU; [`crate::isolated`] runs the same points in
//! worker processes instead.

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;

use fmi_importer::{Description, Fmu, Value, Variable};
use serde::{Deserialize, Serialize};

use fmi_importer::exchange::JacobianSource;

use crate::input::Inputs;
use crate::linear;
use crate::metrics::{Accumulator, Metrics};
use crate::run::{self, Grid};
use crate::variables;

/// A run's samples into a point's accumulators.
struct Summaries<'a> {
    acc: &'a mut [Accumulator],
    stop: &'a dyn Fn() -> bool,
    /// Samples until `stop` is asked again: at the first sample, then every
    /// STOP_CHECK_SAMPLES (a call through a `dyn Fn` per sample was a tenth of the runner's
    /// own work per sample).
    until_check: u32,
    /// No summary has a `from` time: the time test per accumulator and sample is left out.
    counts_all: bool,
}

impl run::Sampler for Summaries<'_> {
    #[inline(always)]
    fn sample(&mut self, t: f64, values: &[f64], _: &dyn run::Texts) -> Result<(), String> {
        if self.until_check == 0 {
            if (self.stop)() {
                return Err(interrupted());
            }
            self.until_check = STOP_CHECK_SAMPLES;
        }
        self.until_check -= 1;
        if self.counts_all {
            for (a, &x) in self.acc.iter_mut().zip(values) {
                a.add_counted(x);
            }
        } else {
            for (a, &x) in self.acc.iter_mut().zip(values) {
                a.add(t, x);
            }
        }
        Ok(())
    }
}

/// The error of a run stopped from outside. Out of line and cold, so the sampler's code at
/// every call in the run's loop does not hold the allocation.
#[cold]
#[inline(never)]
fn interrupted() -> String {
    "interrupted".to_owned()
}

/// Each mode's natural frequency and damping ratio.
type ModeList = Vec<(f64, f64)>;

/// Samples between two checks of a run's `stop` (about 0.2 ms of the Ex. 4 sweep's run).
const STOP_CHECK_SAMPLES: u32 = 128;

/// Values of one `--param`: `START:STOP:STEP` (inclusive, STEP > 0) or a comma list.
pub fn parse_range(text: &str) -> Result<(String, Vec<f64>), String> {
    let (name, spec) = variables::split_assignment(text, "--param")?;
    let number = |s: &str, what: &str| -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| {
                format!(
                    "--param {text}: {what} '{}' is not a number (a sweep varies numbers; give a String parameter one value with --set NAME=TEXT)",
                    s.trim()
                )
            })
    };
    let values = if spec.contains(':') {
        let parts: Vec<&str> = spec.split(':').collect();
        if parts.len() != 3 {
            return Err(format!("--param {text}: a range is START:STOP:STEP (three numbers)"));
        }
        let (start, stop, step) = (number(parts[0], "START")?, number(parts[1], "STOP")?, number(parts[2], "STEP")?);
        if step <= 0.0 {
            return Err(format!("--param {text}: STEP must be positive, it is {step}"));
        }
        if stop < start {
            return Err(format!("--param {text}: STOP ({stop}) is below START ({start}); ranges run upwards from START to STOP"));
        }
        // Points are START + i STEP (not accumulated, so 1:50:0.5 gives exactly 99 points),
        // with a relative allowance so STOP itself is included despite rounding.
        let count = ((stop - start) / step * (1.0 + 1e-12) + 1e-9).floor() as usize + 1;
        if count > 1_000_000 {
            return Err(format!("--param {text}: {count} points is too many"));
        }
        (0..count).map(|i| start + i as f64 * step).collect()
    } else {
        spec.split(',').map(|s| number(s, "value")).collect::<Result<Vec<f64>, String>>()?
    };
    Ok((name.to_owned(), values))
}

/// Largest number of points a sweep may have (the product of its ranges).
pub const MAX_POINTS: usize = 100_000_000;

/// The swept points, the cartesian product of the ranges with the last parameter varying
/// fastest. Point `i` is decoded from `i`, so no list of points is ever held.
pub struct Space {
    /// Each swept parameter's name and values, in `--param` order.
    pub ranges: Vec<(String, Vec<f64>)>,
    /// Number of points.
    pub len: usize,
}

impl Space {
    /// The product of `ranges`, refused when it has more than [`MAX_POINTS`] points.
    pub fn new(ranges: Vec<(String, Vec<f64>)>) -> Result<Space, String> {
        let len = ranges.iter().try_fold(1usize, |n, (_, v)| n.checked_mul(v.len())).filter(|&n| n <= MAX_POINTS);
        let len = len.ok_or_else(|| {
            let sizes: Vec<String> = ranges.iter().map(|(n, v)| format!("{} values of {n}", v.len())).collect();
            format!("the sweep has more than {MAX_POINTS} points ({}); narrow the ranges", sizes.join(" x "))
        })?;
        Ok(Space { ranges, len })
    }

    /// Point `i` of a worker's request as an index into this space, refused when the space has
    /// no such point.
    pub fn index(&self, i: u64) -> Result<usize, String> {
        match usize::try_from(i) {
            Ok(i) if i < self.len => Ok(i),
            _ => Err(format!("point {i} is not in the sweep of {} points", self.len)),
        }
    }

    /// The parameter values of point `i`, in `--param` order.
    pub fn point(&self, mut i: usize, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.ranges.len(), 0.0);
        for (slot, (_, values)) in out.iter_mut().zip(&self.ranges).rev() {
            *slot = values[i % values.len()];
            i /= values.len();
        }
    }
}

/// Result of one point: its metric values (when it ran) and `ok` or the error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PointResult {
    pub metrics: Option<Vec<f64>>,
    pub status: String,
}

/// Everything a sweep runs, checked before the first point.
pub struct Plan<'a> {
    /// The FMU's description (the plan's variables point into it).
    pub description: &'a Description,
    /// The modelIdentifier, which names every point's instance.
    pub identifier: &'a str,
    pub grid: Grid,
    /// Assignments common to every point.
    pub fixed: Vec<(&'a Variable, Value)>,
    /// The swept variables, in the order of the space's ranges.
    pub swept: Vec<&'a Variable>,
    pub space: Space,
    pub metrics: Metrics,
    /// The variables the metrics read, in the order of `metrics.sources`.
    pub sources: Vec<&'a Variable>,
    /// Inputs set before every step of every point.
    pub inputs: Option<Inputs<'a>>,
    /// Per source, the variables its `amplitude` frequency names (in the formula's order).
    frequency_names: Vec<Vec<&'a Variable>>,
}

impl<'a> Plan<'a> {
    /// Checks every name and value before the first run, so a typo costs nothing.
    pub fn new(
        description: &'a Description,
        identifier: &'a str,
        grid: Grid,
        fixed: Vec<(&'a Variable, Value)>,
        ranges: Vec<(String, Vec<f64>)>,
        metrics: Metrics,
    ) -> Result<Plan<'a>, String> {
        let d = description;
        let mut swept: Vec<&Variable> = Vec::new();
        for (name, values) in &ranges {
            let v = variables::find(d, name)?;
            if swept.iter().any(|w| std::ptr::eq(*w, v)) {
                return Err(format!("--param {name} is given twice; give all its values in one --param (V1,V2,... or START:STOP:STEP)"));
            }
            variables::check_settable(v)?;
            for &x in values {
                variables::number_value(v, x)?;
            }
            swept.push(v);
        }
        let sources = metrics
            .sources
            .iter()
            .map(|s| {
                let v = variables::find(d, &s.variable)?;
                if !v.kind.is_numeric() {
                    return Err(format!("'{}' is a String variable; metrics need numbers", v.name));
                }
                Ok(v)
            })
            .collect::<Result<Vec<_>, String>>()?;
        let frequency_names = metrics
            .sources
            .iter()
            .map(|s| {
                let Some(f) = &s.frequency else { return Ok(Vec::new()) };
                f.names
                    .iter()
                    .map(|name| {
                        let v = variables::find(d, name).map_err(|e| format!("amplitude's frequency {}: {e}", f.text))?;
                        let given = swept.iter().any(|w| std::ptr::eq(*w, v)) || fixed.iter().any(|(w, _)| std::ptr::eq(*w, v));
                        if !given && v.start.as_ref().and_then(|s| s.as_number()).is_none() {
                            return Err(format!(
                                "amplitude's frequency {} reads '{name}', which has no number before the run: give it with --set or --param, or use a parameter with a start value",
                                f.text
                            ));
                        }
                        Ok(v)
                    })
                    .collect::<Result<Vec<_>, String>>()
            })
            .collect::<Result<Vec<_>, String>>()?;
        let space = Space::new(ranges)?;
        Ok(Plan { description, identifier, grid, fixed, swept, space, metrics, sources, inputs: None, frequency_names })
    }

    /// The accumulators of a run with `assignments`: `amplitude`'s frequency evaluated with the
    /// values its names have in the run (the last assignment, else the start value).
    fn accumulators(&self, assignments: &[(&Variable, Value)]) -> Result<Vec<Accumulator>, String> {
        let mut acc = self.metrics.accumulators();
        for ((a, source), variables) in acc.iter_mut().zip(&self.metrics.sources).zip(&self.frequency_names) {
            let Some(formula) = &source.frequency else { continue };
            let values: Vec<f64> = variables
                .iter()
                .map(|v| {
                    let assigned = assignments.iter().rev().find(|(w, _)| std::ptr::eq(*w, *v)).map(|(_, x)| x.as_number());
                    assigned.unwrap_or_else(|| v.start.as_ref().and_then(|s| s.as_number())).unwrap_or(f64::NAN)
                })
                .collect();
            let omega = formula.evaluate(&values);
            if !omega.is_finite() || omega <= 0.0 {
                return Err(format!("amplitude's frequency {} is {omega} rad/s here; it must be a positive number", formula.text));
            }
            a.set_frequency(omega);
        }
        Ok(acc)
    }

    /// The instance name of point `i`, e.g. `quarter_car[speed=4.0]`.
    fn instance_name(&self, point: &[f64]) -> String {
        // The shortest form that reads back as x, as in the CSV: Display would spell 1e308
        // with 309 digits.
        let label: Vec<String> = self.swept.iter().zip(point).map(|(v, x)| format!("{}={x:?}", v.name)).collect();
        format!("{}[{}]", self.identifier, label.join(","))
    }

    /// Runs point `i` in its own instance of `fmu` (the FMU the plan's description is of).
    pub fn run_point(&self, fmu: &Fmu, i: usize, point: &mut Vec<f64>, stop: &dyn Fn() -> bool) -> PointResult {
        self.space.point(i, point);
        let mut assignments = self.fixed.clone();
        for (v, &x) in self.swept.iter().zip(point.iter()) {
            // Checked in `Plan::new`, before any run.
            assignments.push((*v, variables::number_value(v, x).expect("value checked before the sweep")));
        }
        let name = self.instance_name(point);
        // Metrics of modes: the point linearized at its initial state, in an instance of its own.
        let modes = match self.metrics.highest_mode() {
            None => Vec::new(),
            Some(highest) => match self.modes(fmu, &name, &assignments, highest) {
                Ok(modes) => modes,
                Err(e) => return PointResult { metrics: None, status: e },
            },
        };
        let mut acc = match self.accumulators(&assignments) {
            Ok(acc) => acc,
            Err(e) => return PointResult { metrics: None, status: e },
        };
        let counts_all = acc.iter().all(Accumulator::counts_all);
        let summaries = Summaries { acc: &mut acc, stop, until_check: 0, counts_all };
        // Metrics of modes alone need no simulation.
        let simulated = !self.sources.is_empty() || modes.is_empty();
        let result = run::Recording::scalars(&self.sources).and_then(|recording| {
            if !simulated {
                return Ok(run::Outcome { ended_early: None, counters: None, final_state: None });
            }
            let run = run::Run {
                name: &name,
                grid: &self.grid,
                assignments: &assignments,
                inputs: self.inputs.as_ref(),
                recording: &recording,
                debug_logging: false,
                initial_state: None,
                final_state: false,
            };
            run.execute(fmu, summaries)
        });
        match result {
            Err(e) => PointResult { metrics: None, status: e },
            Ok(outcome) => {
                if let Some(reason) = outcome.ended_early {
                    crate::note(&format!("{name}: {reason}; metrics are over the samples up to there"));
                }
                let values = self.metrics.evaluate_with_modes(&acc, &modes);
                let bad: Vec<String> = self
                    .metrics
                    .metrics
                    .iter()
                    .zip(&values)
                    .filter(|(_, v)| !v.is_finite())
                    .map(|((n, _), v)| format!("metric {n} is {v}"))
                    .collect();
                let status = if bad.is_empty() { "ok".to_owned() } else { bad.join("; ") };
                PointResult { metrics: Some(values), status }
            }
        }
    }

    /// The natural frequency and damping ratio (NaN for an integrator) of each mode of the
    /// point linearized at its initial state, by rising natural frequency; an error when it has
    /// fewer than `highest` modes, or the FMU was not loaded for Model Exchange.
    fn modes(&self, fmu: &Fmu, name: &str, assignments: &[(&Variable, Value)], highest: usize) -> Result<ModeList, String> {
        if fmu.interface != fmi_importer::Interface::ModelExchange {
            return Err("the metrics read modes of the linearized model, which needs the FMU's Model Exchange interface (--interface model-exchange)".to_owned());
        }
        let request = linear::Request { name, grid: &self.grid, assignments, at: None, prefer: JacobianSource::DirectionalDerivatives };
        let model = linear::linearize(fmu, &request)?;
        let modes = linear::modes(&linear::eigenvalues(&model.a)?);
        if modes.len() < highest {
            return Err(format!(
                "the metrics read mode {highest}, and the model linearized at its initial state has {} mode(s) (a real eigenvalue or a complex pair each)",
                modes.len()
            ));
        }
        Ok(modes.iter().map(|m| (m.natural_frequency, m.damping_ratio.unwrap_or(f64::NAN))).collect())
    }

    /// Runs every point on `threads` threads of this process and calls `deliver(i, result)` in
    /// point order as results arrive. Stops early when `stop()` turns true (the points in
    /// progress are abandoned) or `deliver` fails (its error is returned).
    pub fn execute(
        &self,
        fmu: &Fmu,
        threads: usize,
        stop: &(dyn Fn() -> bool + Sync),
        deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
    ) -> Result<(), String> {
        self.execute_range(fmu, 0..self.space.len, threads, stop, deliver)
    }

    /// [`Plan::execute`] for the points `points` only (a resumed sweep's missing ones).
    pub fn execute_range(
        &self,
        fmu: &Fmu,
        points: Range<usize>,
        threads: usize,
        stop: &(dyn Fn() -> bool + Sync),
        deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
    ) -> Result<(), String> {
        let points = points.start..points.end.min(self.space.len);
        on_threads(points, threads, stop, |i, point| self.run_point(fmu, i, point, stop), deliver)
    }
}

/// Runs `run(i, scratch)` for every point `i` of `points` on `threads` threads of this process
/// and calls `deliver(i, result)` in point order as results arrive. Stops early when `stop()`
/// turns true (the points in progress are abandoned) or `deliver` fails (its error is
/// returned). The threads' side of every in-process sweep (of an FMU, of a system).
pub fn on_threads(
    points: Range<usize>,
    threads: usize,
    stop: &(dyn Fn() -> bool + Sync),
    run: impl Fn(usize, &mut Vec<f64>) -> PointResult + Sync,
    mut deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
) -> Result<(), String> {
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let n = points.end;
    // Workers take points in order from a shared counter (dynamic scheduling: points differ
    // in cost), so results arrive nearly in order and the reorder buffer stays a few rows
    // long whatever the sweep's size.
    let next = AtomicUsize::new(points.start);
    let failed = AtomicBool::new(false);
    let halted = || failed.load(Ordering::Relaxed) || stop();
    let (sender, receiver) = mpsc::sync_channel::<(usize, PointResult)>(4 * threads);
    std::thread::scope(|scope| {
        scope.spawn(|| {
            pool.broadcast(|_| {
                let sender = sender.clone();
                let mut point = Vec::new();
                loop {
                    if halted() {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    let result = run(i, &mut point);
                    if sender.send((i, result)).is_err() {
                        break;
                    }
                }
            });
            drop(sender);
        });
        let mut waiting: BTreeMap<usize, PointResult> = BTreeMap::new();
        let mut row = points.start;
        let mut outcome = Ok(());
        for (i, result) in receiver.iter() {
            if outcome.is_err() || stop() {
                continue; // drain, so no worker blocks on a full channel
            }
            waiting.insert(i, result);
            while let Some(r) = waiting.remove(&row) {
                if let Err(e) = deliver(row, r) {
                    outcome = Err(e);
                    failed.store(true, Ordering::Relaxed);
                    break;
                }
                row += 1;
            }
        }
        outcome
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_include_stop_and_do_not_accumulate() {
        let (name, v) = parse_range("speed=1:50:0.5").unwrap();
        assert_eq!(name, "speed");
        assert_eq!(v.len(), 99);
        assert_eq!((v[0], v[98]), (1.0, 50.0));
        assert_eq!(parse_range("k=0:0.3:0.1").unwrap().1.len(), 4, "0.3/0.1 = 2.9999999999999996 must still give 4 points");
        assert_eq!(parse_range("k=1, 2.5,4").unwrap().1, vec![1.0, 2.5, 4.0]);
    }

    #[test]
    fn bad_ranges_are_explained() {
        assert!(parse_range("speed=5:1:0.5").unwrap_err().contains("below START"));
        assert!(parse_range("speed=1:5:0").unwrap_err().contains("STEP must be positive"));
        assert!(parse_range("speed=1:x:1").unwrap_err().contains("STOP 'x' is not a number"));
        assert!(parse_range("speed=1:2").unwrap_err().contains("START:STOP:STEP"));
        assert!(parse_range("speed").unwrap_err().contains("NAME=VALUE"));
    }

    #[test]
    fn cartesian_product_varies_the_last_fastest() {
        let space = Space::new(vec![("a".into(), vec![1.0, 2.0]), ("b".into(), vec![10.0, 20.0, 30.0])]).unwrap();
        let mut p = Vec::new();
        let points: Vec<Vec<f64>> = (0..space.len)
            .map(|i| {
                space.point(i, &mut p);
                p.clone()
            })
            .collect();
        assert_eq!(points, vec![vec![1.0, 10.0], vec![1.0, 20.0], vec![1.0, 30.0], vec![2.0, 10.0], vec![2.0, 20.0], vec![2.0, 30.0]]);
    }

    #[test]
    fn a_product_too_large_is_refused_before_anything_runs() {
        let big = |name: &str| (name.to_owned(), vec![0.0; 100_000]);
        let err = Space::new(vec![big("a"), big("b")]).err().unwrap();
        assert!(err.contains("100000 values of a x 100000 values of b"), "{err}");
        let err = Space::new(vec![big("a"), big("b"), big("c"), big("d")]).err().unwrap();
        assert!(err.contains("more than"), "overflowing products are caught too: {err}");
    }
}
