//! `runner simulate`: one run, written as CSV in fmpy's layout (`time`, then the outputs).

use std::path::PathBuf;

use fmi_importer::{FmiVersion, Fmu, Kind, Variable};
use runner_engine::run::{self as sim, Grid, Recording};
use runner_engine::variables;

use crate::experiment::{self, RunDefaults};
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
    /// Also writes a row at each event a step stops at (FMI 3.0), before the event is handled.
    pub record_events: bool,
}

/// Runs `runner simulate`.
pub fn run(options: &Options) -> Result<(), String> {
    if let Some(plot) = &options.plot {
        output::check_destination(plot)?;
    }
    let target = experiment::resolve(&options.fmu)?;
    let fmu = Fmu::load(&target.path)?;
    let grid = Grid::choose(&fmu.description, &[options.run.grid(), target.experiment.simulate.grid()])?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(&fmu.description, &set_texts)?;
    // FMI 2.0 String outputs are left out, as fmpy leaves them out; FMI 3.0's Strings and
    // Binaries (hexadecimal) are written. Clocks have no value to record.
    let recordable = |v: &&Variable| match fmu.description.fmi_version {
        FmiVersion::Fmi2 => v.kind.is_numeric(),
        FmiVersion::Fmi3 => v.kind != Kind::Clock,
    };
    let outputs: Vec<&Variable> = fmu.description.outputs().filter(recordable).collect();
    let mut recording = Recording::new(&fmu.description, &outputs, &assignments)?;
    recording.events = options.record_events;
    let mut writer = output::csv_writer(options.out.as_deref())?;
    let mut header = vec!["time".to_owned()];
    header.extend(recording.names.iter().cloned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    // Only a plot needs the trajectory kept; the CSV is written as the samples arrive.
    let columns = recording.names.len();
    let mut kept: Vec<Vec<(f64, f64)>> = vec![Vec::new(); if options.plot.is_some() { columns } else { 0 }];
    let mut row = Vec::with_capacity(columns + 1);
    let outcome = sim::run_recording(&fmu, &fmu.identifier, &grid, &assignments, &recording, options.log, |t, values, reader| {
        row.clear();
        row.push(format!("{t:?}"));
        row.extend((0..columns).map(|c| reader.text(c, values)));
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
        // One unit per column: an array's elements share its unit.
        let units: Vec<Option<&str>> =
            outputs.iter().zip(&recording.sizes).flat_map(|(v, &n)| std::iter::repeat_n(v.unit.as_deref(), n)).collect();
        let shared_unit = units.first().copied().flatten().filter(|u| units.iter().all(|x| *x == Some(*u)));
        let series: Vec<Series> = recording
            .names
            .iter()
            .zip(kept)
            .zip(&units)
            .filter(|((_, points), _)| points.iter().all(|p| !p.1.is_nan()))
            .map(|((name, points), unit)| Series {
                label: match (shared_unit, unit) {
                    (None, Some(u)) => format!("{name} ({u})"),
                    _ => name.clone(),
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
