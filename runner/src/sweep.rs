//! `runner sweep`: the cartesian product of parameter ranges, one FMU instance per point run in
//! parallel (rayon, one dlopen for the whole sweep), metrics per point, one CSV row per point.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::time::Instant;

use fmu::description::{ScalarVariable, TypeKind};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::experiment::{self, RunDefaults};
use crate::fmi::{Fmu, Value};
use crate::metrics::Metrics;
use crate::plot::{self, Mark, Series};
use crate::sim::{self, Grid};
use crate::simulate::csv_writer;
use crate::variables;

/// Options of `runner sweep`; empty lists and `None`s fall back to the model's experiment.toml.
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

/// The points of the cartesian product, the last parameter varying fastest.
fn cartesian(values: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut points = vec![Vec::new()];
    for list in values {
        points = points.iter().flat_map(|p| list.iter().map(move |&v| [p.as_slice(), &[v]].concat())).collect();
    }
    points
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
        for (a, &x) in acc.iter_mut().zip(values) {
            a.add(t, x);
        }
        Ok(())
    });
    match result {
        Err(e) => PointResult { metrics: None, status: e },
        Ok(outcome) => {
            if let Some(reason) = outcome.ended_early {
                eprintln!("{name}: {reason}; metrics are over the samples up to there");
            }
            let values = metrics.evaluate(&acc);
            let bad: Vec<String> = metrics.metrics.iter().zip(&values).filter(|(_, v)| !v.is_finite()).map(|((n, _), v)| format!("metric {n} is {v}")).collect();
            let status = if bad.is_empty() { "ok".to_owned() } else { bad.join("; ") };
            PointResult { metrics: Some(values), status }
        }
    }
}

/// Runs `runner sweep`; returns the number of failed points.
pub fn run(options: &Options) -> Result<usize, String> {
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
    let points = cartesian(&ranges.iter().map(|(_, v)| v.clone()).collect::<Vec<_>>());

    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let progress = if std::io::stderr().is_terminal() {
        let bar = ProgressBar::new(points.len() as u64);
        if let Ok(style) = ProgressStyle::with_template("{bar:40} {pos}/{len} points, {elapsed} elapsed, ~{eta} left") {
            bar.set_style(style);
        }
        bar
    } else {
        ProgressBar::hidden()
    };
    let clock = Instant::now();
    let results: Vec<PointResult> = pool.install(|| {
        points
            .par_iter()
            .map(|point| {
                let mut assignments = fixed.clone();
                let mut label = Vec::new();
                for (v, &x) in swept.iter().zip(point) {
                    // Checked above, before any run.
                    let value = variables::number_value(v, x).expect("value checked before the sweep");
                    assignments.push((v, value));
                    label.push(format!("{}={x}", v.name));
                }
                let name = format!("{}[{}]", fmu.identifier, label.join(","));
                let r = run_point(&fmu, &name, &grid, &assignments, &metrics, &sources);
                progress.inc(1);
                r
            })
            .collect()
    });
    progress.finish_and_clear();
    let elapsed = clock.elapsed().as_secs_f64();

    let out = options.out.clone().or_else(|| defaults.out.clone());
    let mut writer = csv_writer(out.as_ref())?;
    let mut header: Vec<String> = ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    for (point, r) in points.iter().zip(&results) {
        let mut row: Vec<String> = point.iter().map(|x| format!("{x:?}")).collect();
        match &r.metrics {
            Some(values) => row.extend(values.iter().map(|x| format!("{x:?}"))),
            None => row.extend(metrics.metrics.iter().map(|_| String::new())),
        }
        row.push(r.status.clone());
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))?;
    }
    writer.flush().map_err(|e| format!("cannot write CSV: {e}"))?;
    drop(writer);

    let failed = results.iter().filter(|r| r.status != "ok").count();
    eprintln!("{} points in {elapsed:.2} s on {threads} thread(s); {failed} failed{}", points.len(), out.as_ref().map_or(String::new(), |p| format!("; wrote {}", p.display())));
    let x_name = &ranges[0].0;
    let x_unit = d.unit_of(swept[0]).map_or(String::new(), |u| format!(" {u}"));
    for (k, (name, _)) in metrics.metrics.iter().enumerate() {
        let best = points.iter().zip(&results).filter_map(|(p, r)| Some((p, r.metrics.as_ref()?[k]))).filter(|(_, v)| v.is_finite()).max_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((p, v)) = best {
            let at: Vec<String> = ranges.iter().zip(p).map(|((n, _), x)| format!("{n} = {x}")).collect();
            println!("{name}: peak {v:?} at {}", at.join(", "));
        }
    }
    let plot_path = options.plot.clone().or_else(|| defaults.plot.clone());
    if let Some(path) = plot_path {
        let mut series = Vec::new();
        let mut marks = Vec::new();
        for (k, (metric, _)) in metrics.metrics.iter().enumerate() {
            // One line per combination of the other parameters, in point order.
            let mut lines: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
            for (p, r) in points.iter().zip(&results) {
                let others: Vec<String> = ranges.iter().zip(p).skip(1).map(|((n, _), x)| format!("{n}={x}")).collect();
                let label = if others.is_empty() { metric.clone() } else { format!("{metric} ({})", others.join(", ")) };
                let y = r.metrics.as_ref().map_or(f64::NAN, |m| m[k]);
                match lines.iter_mut().find(|(l, _)| *l == label) {
                    Some((_, pts)) => pts.push((p[0], y)),
                    None => lines.push((label, vec![(p[0], y)])),
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
    Ok(failed)
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
        let p = cartesian(&[vec![1.0, 2.0], vec![10.0, 20.0, 30.0]]);
        assert_eq!(p, vec![vec![1.0, 10.0], vec![1.0, 20.0], vec![1.0, 30.0], vec![2.0, 10.0], vec![2.0, 20.0], vec![2.0, 30.0]]);
    }
}
