//! `runner simulate`: one run, written as CSV in fmpy's layout (`time`, then the outputs), in a
//! worker process by default so that a crash of the FMU is reported with its signal and call.

use std::path::PathBuf;

use runner_engine::isolation::{self, Runs};
use runner_engine::protocol::{FmuSource, RunJob};
use runner_engine::run::{self as sim, Grid};
use runner_engine::variables;

use crate::experiment::{self, RunDefaults};
use crate::interrupt;
use crate::report::output;
use crate::report::plot::{self, Series};
use crate::workers;

/// Options of `runner simulate`.
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// Grid and assignments from the command line.
    pub run: RunDefaults,
    /// CSV destination (stdout when absent).
    pub out: Option<PathBuf>,
    /// SVG destination.
    pub plot: Option<PathBuf>,
    /// Turns the FMU's debug logging on.
    pub log: bool,
    /// The run fails if it takes longer (seconds; needs a worker process).
    pub timeout: Option<f64>,
    /// Runs the FMU in this process.
    pub in_process: bool,
}

/// Runs `runner simulate`.
pub fn run(options: &Options) -> Result<(), String> {
    if let Some(plot) = &options.plot {
        output::check_destination(plot)?;
    }
    let timeout = workers::timeout("--timeout", options.timeout)?;
    if options.in_process && timeout.is_some() {
        return Err("--timeout needs a worker process (a run in this process cannot be stopped): drop --in-process".to_owned());
    }
    let target = experiment::resolve(&options.fmu)?;
    let source = FmuSource::new(&target.path);
    // In a worker, only the description is read here: the FMU's binary runs in the worker alone.
    let (fmu, unpacked, source) = match options.in_process {
        true => (Some(source.load()?), None, source),
        false => source.open().map(|(unpacked, for_workers)| (None, Some(unpacked), for_workers))?,
    };
    let (description, identifier, interface) = match (&fmu, &unpacked) {
        (Some(f), _) => (&f.description, &f.identifier, f.interface),
        (None, Some(u)) => (&u.description, &u.identifier, u.interface),
        (None, None) => unreachable!("one of them is held"),
    };
    let grid = Grid::choose(description, &[options.run.grid(), target.experiment.simulate.grid()])?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(description, &set_texts)?;
    let outputs: Vec<_> = description.outputs().filter(|v| v.kind.is_numeric()).collect();
    let mut writer = output::csv_writer(options.out.as_deref())?;
    let mut header = vec!["time".to_owned()];
    header.extend(outputs.iter().map(|v| v.name.clone()));
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    // Only a plot needs the trajectory kept; the CSV is written as the samples arrive.
    let mut kept: Vec<Vec<(f64, f64)>> = vec![Vec::new(); if options.plot.is_some() { outputs.len() } else { 0 }];
    let mut row = Vec::with_capacity(outputs.len() + 1);
    let sample = |t: f64, values: &[f64]| {
        row.clear();
        row.push(format!("{t:?}"));
        row.extend(values.iter().map(|v| format!("{v:?}")));
        for (series, &v) in kept.iter_mut().zip(values) {
            series.push((t, v));
        }
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))
    };
    let outcome = match &fmu {
        Some(fmu) => sim::run(fmu, identifier, &grid, &assignments, &outputs, options.log, sample)?,
        None => {
            let config = workers::isolation(timeout, workers::default_memory_mib(1))?;
            let mut runs = Runs::new(&config, &source, isolation::once_per_process(description, interface));
            let job = RunJob::new(identifier, grid, &assignments, &outputs, options.log);
            runs.run(&job, &interrupt::requested, sample)?
        }
    };
    output::finish_csv(writer)?;
    if let Some(reason) = &outcome.ended_early {
        eprintln!("{identifier}: stopped before the stop time {} s: {reason}", grid.stop);
    }
    if let Some(path) = &options.plot {
        let units: Vec<Option<&str>> = outputs.iter().map(|v| v.unit.as_deref()).collect();
        let shared_unit = units.first().copied().flatten().filter(|u| units.iter().all(|x| *x == Some(*u)));
        let series: Vec<Series> = outputs
            .iter()
            .zip(kept)
            .zip(&units)
            .map(|((v, points), unit)| Series {
                label: match (shared_unit, unit) {
                    (None, Some(u)) => format!("{} ({u})", v.name),
                    _ => v.name.clone(),
                },
                points,
            })
            .collect();
        let y_label = match shared_unit {
            Some(u) => format!("value ({u})"),
            None => "value (SI units, see legend)".to_owned(),
        };
        plot::lines(path, &format!("{}: outputs", description.model_name), "time (s)", &y_label, &series, &[])?;
    }
    Ok(())
}
