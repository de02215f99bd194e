//! `runner sweep`: the engine's sweep of a parameter space (one FMU instance per point, in
//! parallel), one CSV row per point streamed in point order, the peaks and a plot.

use std::path::PathBuf;
use std::time::Instant;

use fmi_importer::Fmu;
use runner_engine::metrics::Metrics;
use runner_engine::run::Grid;
use runner_engine::sweep::{parse_range, Plan};
use runner_engine::variables;

use crate::experiment::{self, RunDefaults};
use crate::integration::Integration;
use crate::interrupt;
use crate::report::output;
use crate::report::plot::{self, Mark, Series};
use crate::report::progress::Progress;

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
    /// The interface, and the runner's integrator for Model Exchange.
    pub integration: Integration,
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
    let fmu: Fmu = options.integration.load(&target.path)?;
    let d = &fmu.description;
    let mut grid = Grid::choose(d, &[options.run.grid(), defaults.run().grid()])?;
    grid.solver = options.integration.solver()?;
    let mut set_texts = defaults.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let fixed = variables::parse_sets(d, &set_texts)?;
    let plan = Plan::new(&fmu, grid, fixed, ranges, metrics)?;
    let (space, metrics, swept) = (&plan.space, &plan.metrics, &plan.swept);
    let n = space.len;

    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    let (out_path, plot_path) = output_paths(options, defaults);
    if let Some(plot) = &plot_path {
        output::check_destination(plot)?;
    }
    let mut writer = output::csv_writer(out_path.as_deref())?;
    let mut header: Vec<String> = space.ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;

    // Only the metric values are kept, for the peaks and the plot.
    let progress = Progress::start(n as u64, "points");
    let clock = Instant::now();
    let m = metrics.metrics.len();
    let mut kept: Vec<f64> = Vec::with_capacity(n * m);
    let mut failed = 0usize;
    let mut point = Vec::new();
    let mut row: Vec<String> = Vec::with_capacity(header.len());
    let written = plan.execute(threads, &interrupt::requested, |i, r| {
        space.point(i, &mut point);
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
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))?;
        progress.inc(1);
        Ok(())
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
        let x_unit = swept[0].unit.as_deref().map_or(String::new(), |u| format!(" {u}"));
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
        let x_label = match swept[0].unit.as_deref() {
            Some(u) => format!("{x_name} ({u})"),
            None => x_name.clone(),
        };
        let y_label = if metrics.metrics.len() == 1 { metric_texts[0].replace('=', " = ") } else { "metric".to_owned() };
        let title = format!(
            "{}: {} against {x_name}",
            d.model_name,
            metrics.metrics.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", ")
        );
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
}
