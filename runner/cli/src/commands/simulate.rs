//! `runner simulate`: one run, written as CSV in fmpy's layout (`time`, then the outputs).

use std::path::PathBuf;

use fmi_importer::Fmu;
use runner_engine::run::{self as sim, Grid};
use runner_engine::variables;

use crate::experiment::{self, RunDefaults};
use crate::integration::Integration;
use crate::report::output;
use crate::report::plot::{self, Series};

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
    /// The interface, and the runner's integrator for Model Exchange.
    pub integration: Integration,
}

/// Runs `runner simulate`.
pub fn run(options: &Options) -> Result<(), String> {
    if let Some(plot) = &options.plot {
        output::check_destination(plot)?;
    }
    let target = experiment::resolve(&options.fmu)?;
    let fmu: Fmu = options.integration.load(&target.path)?;
    let mut grid = Grid::choose(&fmu.description, &[options.run.grid(), target.experiment.simulate.grid()])?;
    grid.solver = options.integration.solver()?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(&fmu.description, &set_texts)?;
    let outputs: Vec<_> = fmu.description.outputs().filter(|v| v.kind.is_numeric()).collect();
    let mut writer = output::csv_writer(options.out.as_deref())?;
    let mut header = vec!["time".to_owned()];
    header.extend(outputs.iter().map(|v| v.name.clone()));
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    // Only a plot needs the trajectory kept; the CSV is written as the samples arrive.
    let mut kept: Vec<Vec<(f64, f64)>> = vec![Vec::new(); if options.plot.is_some() { outputs.len() } else { 0 }];
    let mut row = Vec::with_capacity(outputs.len() + 1);
    let outcome = sim::run(&fmu, &fmu.identifier, &grid, &assignments, &outputs, options.log, |t, values| {
        row.clear();
        row.push(format!("{t:?}"));
        row.extend(values.iter().map(|v| format!("{v:?}")));
        for (series, &v) in kept.iter_mut().zip(values) {
            series.push((t, v));
        }
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))
    })?;
    output::finish_csv(writer)?;
    if let Some(reason) = &outcome.ended_early {
        eprintln!("{}: stopped before the stop time {} s: {reason}", fmu.identifier, grid.stop);
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
        plot::lines(path, &format!("{}: outputs", fmu.description.model_name), "time (s)", &y_label, &series, &[])?;
    }
    Ok(())
}
