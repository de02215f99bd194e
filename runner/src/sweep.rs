//! `runner sweep`: the cartesian product of parameter ranges, one FMU instance per point run in
//! parallel (rayon, one dlopen for the whole sweep), metrics per point, one CSV row per point.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::Instant;

use fmu::description::{ScalarVariable, TypeKind};

use crate::experiment::{self, RunDefaults};
use crate::fmi::{Fmu, Value};
use crate::interrupt;
use crate::metrics::Metrics;
use crate::output;
use crate::plot::{self, Mark, Series};
use crate::progress::{self, Progress};
use crate::sim::{self, Grid};
use crate::variables;

/// Options of `runner sweep`; empty lists and `None`s fall back to the model's experiment.toml.
#[derive(Default)]
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// `NAME=START:STOP:STEP` or `NAME=V1,V2,...`.
    pub params: Vec<String>,
    /// `NAME=EXPR`.
    pub metrics: Vec<String>,
    /// Worker threads (default: the number of cores).
    pub threads: Option<usize>,
    /// Grid and fixed assignments.
    pub run: RunDefaults,
    /// CSV destination.
    pub out: Option<PathBuf>,
    /// SVG destination.
    pub plot: Option<PathBuf>,
}

/// Values of one `--param`: `START:STOP:STEP` (inclusive, STEP > 0) or a comma list.
pub fn parse_range(text: &str) -> Result<(String, Vec<f64>), String> {
    let (name, spec) = variables::split_assignment(text, "--param")?;
    let number = |s: &str, what: &str| -> Result<f64, String> {
        s.trim().parse::<f64>().ok().filter(|x| x.is_finite()).ok_or_else(|| format!("--param {text}: {what} '{}' is not a number", s.trim()))
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
struct Space {
    ranges: Vec<(String, Vec<f64>)>,
    len: usize,
}

impl Space {
    fn new(ranges: Vec<(String, Vec<f64>)>) -> Result<Space, String> {
        let len = ranges.iter().try_fold(1usize, |n, (_, v)| n.checked_mul(v.len())).filter(|&n| n <= MAX_POINTS);
        let len = len.ok_or_else(|| {
            let sizes: Vec<String> = ranges.iter().map(|(n, v)| format!("{} values of {n}", v.len())).collect();
            format!("the sweep has more than {MAX_POINTS} points ({}); narrow the ranges", sizes.join(" x "))
        })?;
        Ok(Space { ranges, len })
    }

    /// The parameter values of point `i`, in `--param` order.
    fn point(&self, mut i: usize, out: &mut Vec<f64>) {
        out.clear();
        out.resize(self.ranges.len(), 0.0);
        for (slot, (_, values)) in out.iter_mut().zip(&self.ranges).rev() {
            *slot = values[i % values.len()];
            i /= values.len();
        }
    }
}

/// Result of one point: its metric values (when it ran) and `ok` or the error.
struct PointResult {
    metrics: Option<Vec<f64>>,
    status: String,
}

/// Runs one point in its own instance.
fn run_point(fmu: &Fmu, name: &str, grid: &Grid, assignments: &[(&ScalarVariable, Value)], metrics: &Metrics, sources: &[&ScalarVariable]) -> PointResult {
    let mut acc = metrics.accumulators();
    let result = sim::run(fmu, name, grid, assignments, sources, false, |t, values| {
        if interrupt::requested() {
            return Err("interrupted".to_owned());
        }
        for (a, &x) in acc.iter_mut().zip(values) {
            a.add(t, x);
        }
        Ok(())
    });
    match result {
        Err(e) => PointResult { metrics: None, status: e },
        Ok(outcome) => {
            if let Some(reason) = outcome.ended_early {
                progress::eprint_line(&format!("{name}: {reason}; metrics are over the samples up to there"));
            }
            let values = metrics.evaluate(&acc);
            let bad: Vec<String> = metrics.metrics.iter().zip(&values).filter(|(_, v)| !v.is_finite()).map(|((n, _), v)| format!("metric {n} is {v}")).collect();
            let status = if bad.is_empty() { "ok".to_owned() } else { bad.join("; ") };
            PointResult { metrics: Some(values), status }
        }
    }
}

/// What a finished sweep reports.
pub struct Summary {
    /// Number of points.
    pub points: usize,
    /// Points whose status is not `ok`.
    pub failed: usize,
}

/// Where the CSV and the plot go. The experiment's CSV and plot are one default: naming the CSV
/// on the command line drops the default plot too, rather than writing it beside the CSV's
/// default place.
fn output_paths(options: &Options, defaults: &experiment::SweepDefaults) -> (Option<PathBuf>, Option<PathBuf>) {
    let out = options.out.clone().or_else(|| defaults.out.clone());
    let plot = options.plot.clone().or_else(|| if options.out.is_none() { defaults.plot.clone() } else { None });
    (out, plot)
}

/// Runs `runner sweep`. The CSV is streamed in point order as points finish; it is renamed into
/// place only when complete, and an interrupted sweep (Ctrl-C) commits nothing.
pub fn run(options: &Options) -> Result<Summary, String> {
    let target = experiment::resolve(&options.fmu)?;
    let defaults = &target.experiment.sweep;
    let pick = |cli: &Vec<String>, file: &Vec<String>| if cli.is_empty() { file.clone() } else { cli.clone() };
    let param_texts = pick(&options.params, &defaults.param);
    let metric_texts = pick(&options.metrics, &defaults.metric);
    if param_texts.is_empty() {
        return Err("nothing to sweep: give --param NAME=START:STOP:STEP or NAME=V1,V2,...".to_owned());
    }
    if metric_texts.is_empty() {
        return Err("no metric: give --metric NAME=EXPR, e.g. --metric 'amplitude=max(x)'".to_owned());
    }
    let ranges = param_texts.iter().map(|p| parse_range(p)).collect::<Result<Vec<_>, _>>()?;
    let metrics = Metrics::parse(&metric_texts)?;
    let fmu = Fmu::load(&target.path)?;
    let d = &fmu.description;
    let grid = Grid::choose(&fmu, &options.run, &defaults.run())?;
    let mut set_texts = defaults.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let fixed = variables::parse_sets(d, &set_texts)?;

    // Check every name and value before the first run, so a typo costs nothing.
    let mut swept = Vec::new();
    for (name, values) in &ranges {
        let v = variables::find(d, name)?;
        if swept.iter().any(|w: &&ScalarVariable| std::ptr::eq(*w, v)) {
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
            if v.type_kind() == TypeKind::String {
                return Err(format!("'{}' is a String variable; metrics need numbers", v.name));
            }
            Ok(v)
        })
        .collect::<Result<Vec<_>, String>>()?;
    let space = Space::new(ranges)?;
    let n = space.len;

    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let (out_path, plot_path) = output_paths(options, defaults);
    if let Some(plot) = &plot_path {
        output::check_destination(plot)?;
    }
    let mut writer = output::csv_writer(out_path.as_deref())?;
    let mut header: Vec<String> = space.ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;

    // Workers take points in order from a shared counter (dynamic scheduling: points differ in
    // cost), so results arrive nearly in order and the reorder buffer stays a few rows long
    // whatever the sweep's size. Only the metric values are kept, for the peaks and the plot.
    let next = AtomicUsize::new(0);
    let stop = AtomicBool::new(false);
    let (sender, receiver) = mpsc::sync_channel::<(usize, PointResult)>(4 * threads);
    let progress = Progress::start(n as u64, "points");
    let clock = Instant::now();
    let m = metrics.metrics.len();
    let mut kept: Vec<f64> = Vec::with_capacity(n * m);
    let mut failed = 0usize;
    let written: Result<(), String> = std::thread::scope(|scope| {
        scope.spawn(|| {
            pool.broadcast(|_| {
                let sender = sender.clone();
                let mut point = Vec::new();
                loop {
                    if stop.load(Ordering::Relaxed) || interrupt::requested() {
                        break;
                    }
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    if i >= n {
                        break;
                    }
                    space.point(i, &mut point);
                    let mut assignments = fixed.clone();
                    let mut label = Vec::with_capacity(point.len());
                    for (v, &x) in swept.iter().zip(&point) {
                        // Checked above, before any run.
                        let value = variables::number_value(v, x).expect("value checked before the sweep");
                        assignments.push((*v, value));
                        // The shortest form that reads back as x, as in the CSV: Display would
                        // spell 1e308 with 309 digits.
                        label.push(format!("{}={x:?}", v.name));
                    }
                    let name = format!("{}[{}]", fmu.identifier, label.join(","));
                    let result = run_point(&fmu, &name, &grid, &assignments, &metrics, &sources);
                    if sender.send((i, result)).is_err() {
                        break;
                    }
                }
            });
            drop(sender);
        });
        let mut waiting: BTreeMap<usize, PointResult> = BTreeMap::new();
        let mut row_index = 0;
        let mut point = Vec::new();
        let mut row: Vec<String> = Vec::with_capacity(header.len());
        let mut outcome = Ok(());
        for (i, result) in receiver.iter() {
            if outcome.is_err() || interrupt::requested() {
                continue; // drain, so no worker blocks on a full channel
            }
            waiting.insert(i, result);
            while let Some(r) = waiting.remove(&row_index) {
                space.point(row_index, &mut point);
                row.clear();
                row.extend(point.iter().map(|x| format!("{x:?}")));
                match &r.metrics {
                    Some(values) => {
                        row.extend(values.iter().map(|x| format!("{x:?}")));
                        kept.extend(values);
                    }
                    None => {
                        row.extend(std::iter::repeat_n(String::new(), m));
                        kept.extend(std::iter::repeat_n(f64::NAN, m));
                    }
                }
                failed += usize::from(r.status != "ok");
                row.push(r.status);
                if let Err(e) = writer.write_record(&row) {
                    outcome = Err(format!("cannot write CSV: {e}"));
                    stop.store(true, Ordering::Relaxed);
                    break;
                }
                row_index += 1;
                progress.inc(1);
            }
        }
        outcome
    });
    drop(progress);
    written?;
    let elapsed = clock.elapsed().as_secs_f64();
    if interrupt::requested() {
        let done = kept.len() / m.max(1);
        return Err(format!("interrupted after {done} of {n} points{}", if out_path.is_some() { "; no file written" } else { "" }));
    }
    let destination = writer.get_ref().describe();
    let csv_on_stdout = matches!(writer.get_ref(), output::Output::Stdout(_));
    output::finish_csv(writer)?;

    eprintln!("{n} points in {elapsed:.2} s on {threads} thread(s); {failed} failed; wrote {destination}");
    let metric_of = |i: usize, k: usize| kept[i * m + k];
    let mut point = Vec::new();
    for (k, (name, _)) in metrics.metrics.iter().enumerate() {
        let best = (0..n).filter(|&i| metric_of(i, k).is_finite()).max_by(|&a, &b| metric_of(a, k).total_cmp(&metric_of(b, k)));
        if let Some(i) = best {
            space.point(i, &mut point);
            let at: Vec<String> = space.ranges.iter().zip(&point).map(|((n, _), x)| format!("{n} = {x}")).collect();
            let line = format!("{name}: peak {:?} at {}", metric_of(i, k), at.join(", "));
            // Keep a CSV on stdout clean: the summary goes to stderr then.
            if csv_on_stdout {
                eprintln!("{line}");
            } else {
                println!("{line}");
            }
        }
    }
    if let Some(path) = plot_path {
        let x_name = &space.ranges[0].0;
        let x_unit = d.unit_of(swept[0]).map_or(String::new(), |u| format!(" {u}"));
        let mut series = Vec::new();
        let mut marks = Vec::new();
        for (k, (metric, _)) in metrics.metrics.iter().enumerate() {
            // One line per combination of the other parameters, in point order.
            let mut lines: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
            for i in 0..n {
                space.point(i, &mut point);
                let others: Vec<String> = space.ranges.iter().zip(&point).skip(1).map(|((n, _), x)| format!("{n}={x}")).collect();
                let label = if others.is_empty() { metric.clone() } else { format!("{metric} ({})", others.join(", ")) };
                match lines.iter_mut().find(|(l, _)| *l == label) {
                    Some((_, pts)) => pts.push((point[0], metric_of(i, k))),
                    None => lines.push((label, vec![(point[0], metric_of(i, k))])),
                }
            }
            for (label, points) in lines {
                if let Some(&(x, y)) = points.iter().filter(|p| p.1.is_finite()).max_by(|a, b| a.1.total_cmp(&b.1)) {
                    marks.push(Mark { at: (x, y), text: format!(" peak {y:.4} at {x_name} = {x}{x_unit}") });
                }
                series.push(Series { label, points });
            }
        }
        let x_label = match d.unit_of(swept[0]) {
            Some(u) => format!("{x_name} ({u})"),
            None => x_name.clone(),
        };
        let y_label = if metrics.metrics.len() == 1 { metric_texts[0].replace('=', " = ") } else { "metric".to_owned() };
        let title = format!("{}: {} against {x_name}", d.model_name, metrics.metrics.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", "));
        plot::lines(&path, &title, &x_label, &y_label, &series, &marks)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(Summary { points: n, failed })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn naming_the_csv_drops_the_experiments_default_plot() {
        let defaults = experiment::SweepDefaults { out: Some("e.csv".into()), plot: Some("e.svg".into()), ..Default::default() };
        let paths = |out: Option<&str>, plot: Option<&str>| {
            let options = Options { out: out.map(PathBuf::from), plot: plot.map(PathBuf::from), ..Default::default() };
            let (o, p) = output_paths(&options, &defaults);
            (o.map(|p| p.display().to_string()), p.map(|p| p.display().to_string()))
        };
        let s = |x: &str| Some(x.to_owned());
        assert_eq!(paths(None, None), (s("e.csv"), s("e.svg")));
        assert_eq!(paths(Some("x.csv"), None), (s("x.csv"), None));
        assert_eq!(paths(None, Some("x.svg")), (s("e.csv"), s("x.svg")));
        assert_eq!(paths(Some("x.csv"), Some("x.svg")), (s("x.csv"), s("x.svg")));
    }

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
        let points: Vec<Vec<f64>> = (0..space.len).map(|i| {
            space.point(i, &mut p);
            p.clone()
        }).collect();
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
