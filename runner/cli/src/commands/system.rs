//! `runner simulate SYSTEM` and `runner sweep SYSTEM`: an SSP system (`.ssp`, `.ssd`, or a
//! folder holding `SystemStructure.ssd`) run by the fixed-step master of `fmi-systems`.
//!
//! Systems run in this process, on threads: a system's components exchange values at every
//! communication step, so components in separate worker processes would pay a message round
//! trip per component and step, several times the step of a small FMU (the master's budget is
//! a tenth of it, tests/bench), and the worker protocol carries one FMU per job.

use std::path::Path;

use fmi_systems::{Bound, Coupling, Master, Outcome, System};
use runner_engine::metrics::Metrics;
use runner_engine::run::Grid;
use runner_engine::sweep::{parse_range, Space};
use runner_engine::variables;

use crate::experiment::RunDefaults;
use crate::report::output;

/// The master named on the command line (`None`: Jacobi).
pub fn master(name: Option<&str>) -> Result<Master, String> {
    match name {
        None => Ok(Master::Jacobi),
        Some(n) => Master::from_name(n).ok_or_else(|| format!("--master '{n}': choose jacobi or gauss-seidel")),
    }
}

/// The master and the coupling named on the command line (`--master`, `--coupling`).
#[derive(Clone, Copy, Default)]
pub struct Algorithm<'a> {
    pub master: Option<&'a str>,
    pub coupling: Option<&'a str>,
}

/// The system bound for runs under the master and coupling named on the command line.
fn bind<'a>(system: &'a System, algorithm: Algorithm) -> Result<Bound<'a>, String> {
    let Algorithm { master: master_name, coupling: coupling_name } = algorithm;
    let coupling = match coupling_name {
        None => None,
        Some(n) => Some(Coupling::from_name(n).ok_or_else(|| format!("--coupling '{n}': choose hold or polynomial"))?),
    };
    let mut bound = Bound::new(system, master(master_name)?)?;
    bound.set_coupling(coupling);
    if coupling == Some(Coupling::Polynomial) && bound.polynomial_connections().is_empty() {
        eprintln!(
            "warning: --coupling polynomial: no connection of the system can pass a polynomial (that needs a Co-Simulation source with output derivatives and a continuous Real input of an FMI 2.0 FMU that interpolates inputs): every input holds"
        );
    }
    Ok(bound)
}

/// The grid: the command line, then the SSD's DefaultExperiment and step annotation, then the
/// components' DefaultExperiments (the latest stop, the smallest step), then 500 intervals.
pub fn grid(system: &System, run: &RunDefaults) -> Result<Grid, String> {
    let e = system.structure.experiment;
    let defaults: Vec<_> = system.components.iter().filter_map(|c| c.fmu.description.default_experiment).collect();
    let start = e.start.unwrap_or(0.0);
    let stop = run.stop_time.or(e.stop).or_else(|| defaults.iter().filter_map(|d| d.stop_time).reduce(f64::max)).unwrap_or(start + 1.0);
    let interval = run
        .output_interval
        .or(e.step)
        .or_else(|| defaults.iter().filter_map(|d| d.step_size).reduce(f64::min))
        .unwrap_or((stop - start) / 500.0);
    Grid::checked(start, stop, interval, run.tolerance)
}

fn number(x: f64) -> String {
    format!("{x}")
}

/// `runner simulate SYSTEM`: one run, CSV `time,COMPONENT.VARIABLE,...`.
pub fn simulate(path: &Path, run: &RunDefaults, algorithm: Algorithm, out: Option<&Path>) -> Result<(), String> {
    let system = System::open(path)?;
    let bound = bind(&system, algorithm)?;
    if let Some(w) = &bound.warning {
        eprintln!("warning: {w}");
    }
    let grid = grid(&system, run)?;
    let sets = bound.parse_sets(&run.set)?;
    let mut writer = output::csv_writer(out)?;
    let mut header = vec!["time".to_owned()];
    header.extend(bound.columns.iter().cloned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    let mut row = Vec::with_capacity(header.len());
    let result = bound.run("system", &grid, &sets, |t, values| {
        row.clear();
        row.push(number(t));
        row.extend(values.iter().map(|&x| number(x)));
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))
    });
    // The rows before a failure are kept, as for single FMUs.
    let kept = writer.get_ref().describe();
    output::finish_csv(writer)?;
    match result {
        Ok(Outcome::Finished) => Ok(()),
        Ok(Outcome::Ended(why)) => {
            eprintln!("the simulation ended early: {why}");
            Ok(())
        }
        Err(failure) => Err(format!("{failure} (the rows before it are in {kept})")),
    }
}

/// `runner sweep SYSTEM`: one system instance per point, points in parallel on `threads`;
/// CSV: the parameters, the metrics, the status.
pub fn sweep(
    path: &Path,
    run: &RunDefaults,
    algorithm: Algorithm,
    params: &[String],
    metric_texts: &[String],
    threads: Option<usize>,
    out: Option<&Path>,
) -> Result<(usize, usize), String> {
    use rayon::prelude::*;
    if metric_texts.is_empty() {
        return Err("no metric: give --metric NAME=EXPR, e.g. --metric 'amplitude=max(car.z_s)'".to_owned());
    }
    let system = System::open(path)?;
    let bound = bind(&system, algorithm)?;
    if let Some(w) = &bound.warning {
        eprintln!("warning: {w}");
    }
    let grid = grid(&system, run)?;
    let sets = bound.parse_sets(&run.set)?;
    let ranges = params.iter().map(|p| parse_range(p)).collect::<Result<Vec<_>, _>>()?;
    let mut swept = Vec::new();
    for (name, _) in &ranges {
        let (c, v) = bound.resolve(name)?;
        variables::check_settable(v).map_err(|e| format!("--param {name}: {e}"))?;
        swept.push((c, v));
    }
    let space = Space::new(ranges)?;
    let metrics = Metrics::parse(metric_texts)?;
    if metrics.needs_frequencies() {
        return Err("amplitude(...) reads its frequency from parameters of one FMU: it is for sweeps of an FMU, not of a system".to_owned());
    }
    if metrics.highest_mode().is_some() {
        return Err("natural_frequency(N) and damping(N) linearize one FMU: they are for sweeps of an FMU, not of a system".to_owned());
    }
    let sources = metrics
        .sources
        .iter()
        .map(|s| {
            bound
                .column(&s.variable)
                .ok_or_else(|| format!("metric variable '{}' is not a column of the system (COMPONENT.VARIABLE of an output)", s.variable))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let threads = threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let run_point = |i: usize| -> (Vec<f64>, Vec<f64>, String) {
        let mut point = Vec::new();
        space.point(i, &mut point);
        let mut assignments = sets.clone();
        for (&(c, v), &x) in swept.iter().zip(&point) {
            match variables::number_value(v, x) {
                Ok(value) => assignments.push((c, v, value)),
                Err(e) => return (point, vec![], e),
            }
        }
        let mut acc = metrics.accumulators();
        // Only the metrics' columns are read (and what feeds connections), as a single FMU's
        // sweep reads only its metrics' variables.
        let result = bound.run_recorded(&format!("point{i}"), &grid, &assignments, &sources, |t, values| {
            for (a, &x) in acc.iter_mut().zip(values) {
                a.add(t, x);
            }
            Ok(())
        });
        match result {
            Ok(Outcome::Finished) => (point, metrics.evaluate(&acc), "ok".to_owned()),
            Ok(Outcome::Ended(why)) => (point, metrics.evaluate(&acc), format!("ended early: {why}")),
            Err(failure) => (point, vec![], format!("failed: {failure}")),
        }
    };
    let results: Vec<_> = pool.install(|| (0..space.len).into_par_iter().map(run_point).collect());
    let mut writer = output::csv_writer(out)?;
    let mut header: Vec<String> = space.ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    let mut failed = 0;
    for (point, values, status) in &results {
        let mut row: Vec<String> = point.iter().map(|&x| number(x)).collect();
        if values.is_empty() {
            row.extend(metrics.metrics.iter().map(|_| String::new()));
        } else {
            row.extend(values.iter().map(|&x| number(x)));
        }
        if status.starts_with("failed") {
            failed += 1;
        }
        row.push(status.clone());
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))?;
    }
    output::finish_csv(writer)?;
    Ok((results.len(), failed))
}
