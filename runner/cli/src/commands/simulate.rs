//! `runner simulate`: one run, written as CSV in fmpy's layout (`time`, then the outputs), and
//! optionally a plot: one panel per variable on a shared time axis (or against `--plot-x`), in
//! the FMU's display units, events marked; `--overlay` repeats the run for several values of
//! one parameter and draws them over each other. The FMU runs in a worker process by default, so
//! that a crash is reported with its signal and call.

use std::path::{Path, PathBuf};

use fmi_importer::{Causality, Description, FmiVersion, Kind, Value, Variable};
use runner_engine::run::{Grid, Recording};
use runner_engine::variables::{self, UnitConversion};

use crate::experiment::{self, RunDefaults};
use crate::integration::Integration;
use crate::report::figure::{self, Curve, Figure, Format, Note, Panel, VLine};
use crate::report::output;
use crate::trace::{self, Event, Trace};
use crate::workers::{self, Executor, Held};

/// Options of `runner simulate`.
#[derive(Default)]
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// Grid and assignments from the command line.
    pub run: RunDefaults,
    /// CSV destination (stdout when absent).
    pub out: Option<PathBuf>,
    /// Plot destination (`.svg` or `.png`).
    pub plot: Option<PathBuf>,
    /// Turns the FMU's debug logging on.
    pub log: bool,
    /// Variables to plot (default: the continuous Real outputs).
    pub plot_vars: Vec<String>,
    /// Plot against this variable instead of time (a phase portrait).
    pub plot_x: Option<String>,
    /// `NAME=V1,V2,...`: one run per value, overlaid.
    pub overlay: Option<String>,
    /// Also writes a row at each event a step stops at (FMI 3.0), before the event is handled.
    pub record_events: bool,
    /// The interface, and the runner's integrator for Model Exchange.
    pub integration: Integration,
    /// Each run fails if it takes longer (seconds; needs a worker process).
    pub timeout: Option<f64>,
    /// Runs the FMU in this process.
    pub in_process: bool,
    /// Inputs over time (`--input-file`: fmpy's CSV convention).
    pub input_file: Option<PathBuf>,
    /// The master algorithm for a system (`--master`).
    pub master: Option<String>,
}

/// `runner simulate SYSTEM`, refusing the options that are for single FMUs.
fn run_system(options: &Options) -> Result<(), String> {
    let single = [
        ("--plot", options.plot.is_some()),
        ("--overlay", options.overlay.is_some()),
        ("--input-file", options.input_file.is_some()),
        ("--timeout", options.timeout.is_some()),
        ("--record-events", options.record_events),
        ("--log", options.log),
    ];
    if let Some((flag, _)) = single.iter().find(|(_, given)| *given) {
        return Err(format!("{flag} is for single FMUs; a system takes --stop-time, --output-interval, --tolerance, --set COMPONENT.VARIABLE=VALUE, --master and --out"));
    }
    crate::commands::system::simulate(Path::new(&options.fmu), &options.run, options.master.as_deref(), options.out.as_deref())
}

/// One run of an overlay: its label and the assignment that makes it.
struct Case<'a> {
    label: Option<String>,
    assignment: Option<(&'a Variable, Value)>,
    si: f64,
}

/// Parses `--overlay NAME=V1,V2,...`; each value may carry a declared unit (`15deg`).
fn overlay_cases<'a>(description: &'a Description, text: &str) -> Result<(&'a Variable, Vec<Case<'a>>), String> {
    let (name, values) = variables::split_assignment(text, "--overlay")?;
    let variable = variables::find(description, name)?;
    variables::check_settable(variable)?;
    if variable.causality == Causality::StructuralParameter {
        return Err(format!(
            "--overlay {text}: '{name}' sizes arrays, so the runs would not share one CSV layout: overlay another parameter"
        ));
    }
    let mut cases = Vec::new();
    for item in values.split(',').map(str::trim) {
        if item.is_empty() {
            return Err(format!("--overlay {text}: an empty value between commas"));
        }
        let value = variables::parse_quantity(description, variable, item)?;
        let si = value.as_number().unwrap_or(f64::NAN);
        cases.push(Case { label: Some(format!("{name} = {}", spaced_unit(item))), assignment: Some((variable, value)), si });
    }
    if cases.len() < 2 {
        return Err(format!("--overlay {text}: give at least two values, separated by commas"));
    }
    Ok((variable, cases))
}

/// `15deg` as `15 deg`, for labels.
fn spaced_unit(text: &str) -> String {
    match text.find(|c: char| c.is_alphabetic() && c != 'e' && c != 'E') {
        Some(i) if i > 0 && !text[..i].ends_with(' ') => format!("{} {}", &text[..i], &text[i..]),
        _ => text.to_owned(),
    }
}

/// A variable as plotted: its column name, the unit it is shown in and the conversion.
#[derive(Debug, Clone)]
pub struct Axis {
    pub name: String,
    pub label: String,
    pub conversion: Option<UnitConversion>,
}

impl Axis {
    /// `variable` in its display unit when the FMU declares one, else in its own unit.
    pub fn of(description: &Description, variable: &Variable) -> Axis {
        let conversion = variables::display_unit_of(description, variable);
        let unit = conversion.as_ref().map(|c| c.name.clone()).or_else(|| variable.unit.clone());
        let label = match unit {
            Some(u) if u != "1" => format!("{} ({u})", variable.name),
            _ => variable.name.clone(),
        };
        Axis { name: variable.name.clone(), label, conversion }
    }

    /// A value of this variable, in the unit shown.
    pub fn show(&self, si: f64) -> f64 {
        self.conversion.as_ref().map_or(si, |c| c.from_si(si))
    }

    /// The column of this variable in `trace`, converted.
    pub fn values(&self, trace: &Trace) -> Result<Vec<f64>, String> {
        Ok(trace.get(&self.name)?.iter().map(|&v| self.show(v)).collect())
    }
}

/// Panels per column before the figure gets another column.
const ROWS_PER_COLUMN: usize = 6;

/// Builds the figure of `runs` (one trace per case): one panel per y axis, all sharing the x
/// axis (time, or `x`), events as vertical lines (or marked points against `x`).
pub fn figure(title: String, runs: &[(Option<String>, &Trace, Vec<Event>)], ys: &[Axis], x: Option<&Axis>) -> Result<Figure, String> {
    let xs: Vec<Vec<f64>> = runs.iter().map(|(_, t, _)| x.map_or(Ok(t.time.clone()), |a| a.values(t))).collect::<Result<_, _>>()?;
    let x_values = xs.iter().flatten().copied();
    let x_range = if x.is_some() { figure::padded_range(x_values) } else { figure::exact_range(x_values) };
    let x_label = x.map_or("time (s)".to_owned(), |a| a.label.clone());
    let columns = ys.len().div_ceil(ROWS_PER_COLUMN).max(1);
    let rows = ys.len().div_ceil(columns);
    let mut panels = Vec::new();
    for (k, y) in ys.iter().enumerate() {
        let mut panel = Panel { y_label: y.label.clone(), x_range: Some(x_range.clone()), ..Panel::default() };
        // Only the bottom panel of each column names the shared axis.
        let bottom = k / columns == rows - 1 || k + columns >= ys.len();
        panel.x_label = if bottom { x_label.clone() } else { String::new() };
        for (i, ((label, run, events), run_x)) in runs.iter().zip(&xs).enumerate() {
            let values = y.values(run)?;
            let color = figure::color(if runs.len() > 1 { i } else { 0 });
            let mut curve = Curve::line(
                label.clone().unwrap_or_else(|| y.name.clone()),
                run_x.iter().copied().zip(values.iter().copied()).collect(),
                color,
            );
            // One legend for the overlaid runs, in the first panel; a single run needs none.
            if runs.len() == 1 || k > 0 {
                curve.label = None;
            }
            panel.curves.push(curve);
            let event_color = if runs.len() > 1 { color } else { figure::color(3) };
            for e in events {
                match x {
                    None => panel.vlines.push(VLine {
                        x: e.time,
                        label: (k == 0).then(|| format!("{} (t = {} s)", e.text, trace::short(e.time))),
                        color: event_color,
                    }),
                    Some(_) => panel.notes.push(Note {
                        at: (run_x[e.index], values[e.index]),
                        text: if k == 0 { e.text.clone() } else { String::new() },
                        color: event_color,
                    }),
                }
            }
        }
        panels.push(panel);
    }
    let width = if columns == 1 { 900 } else { 620 };
    let height = if ys.len() == 1 { 460 } else { 210 };
    Ok(Figure { title: Some(title), panels, columns, panel_size: (width, height) })
}

/// Checks a plot destination before any run: its extension and its directory.
pub fn check_plot_path(path: &Path) -> Result<Format, String> {
    let format = Format::of(path)?;
    output::check_destination(path)?;
    Ok(format)
}

/// Runs `runner simulate`.
pub fn run(options: &Options) -> Result<(), String> {
    if fmi_systems::is_system(Path::new(&options.fmu)) {
        return run_system(options);
    }
    if let Some(plot) = &options.plot {
        check_plot_path(plot)?;
    } else if !options.plot_vars.is_empty() || options.plot_x.is_some() {
        return Err("--plot-vars and --plot-x choose what --plot FILE draws: give --plot too".to_owned());
    }
    let timeout = workers::timeout("--timeout", options.timeout)?;
    if options.in_process && timeout.is_some() {
        return Err("--timeout needs a worker process (a run in this process cannot be stopped): drop --in-process".to_owned());
    }
    let target = experiment::resolve(&options.fmu)?;
    // In a worker, only the description is read here: the FMU's binary runs in the worker alone.
    let (held, source) = Held::open(&target.path, &options.integration, options.in_process)?;
    let config = workers::isolation(timeout, workers::default_memory_mib(1))?;
    let mut executor = Executor::new(&held, &config, &source);
    let (md, identifier) = (held.description(), held.identifier());
    let mut grid = Grid::choose(md, &[options.run.grid(), target.experiment.simulate.grid()])?;
    grid.solver = options.integration.solver()?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(md, &set_texts)?;
    let inputs = workers::input_file(options.input_file.as_deref(), md, held.interface())?;

    let (overlaid, cases) = match &options.overlay {
        Some(text) => {
            let (v, cases) = overlay_cases(md, text)?;
            (Some(v), cases)
        }
        None => (None, vec![Case { label: None, assignment: None, si: f64::NAN }]),
    };

    // What the plot needs, checked before running: the y variables, x, and the event flags.
    let numeric = |name: &str| trace::numeric_variable(md, name);
    let (plotted, x_variable, flags) = if options.plot.is_some() {
        let plotted: Vec<&Variable> = if options.plot_vars.is_empty() {
            trace::continuous_outputs(md)
        } else {
            options.plot_vars.iter().map(|n| numeric(n.trim())).collect::<Result<_, _>>()?
        };
        if plotted.is_empty() {
            return Err(format!("{} has no continuous Real outputs to plot: choose variables with --plot-vars", md.model_name));
        }
        let x = options.plot_x.as_deref().map(|n| numeric(n.trim())).transpose()?;
        (plotted, x, trace::event_variables(md))
    } else {
        (Vec::new(), None, Vec::new())
    };

    // FMI 2.0 String outputs are left out, as fmpy leaves them out; FMI 3.0's Strings and
    // Binaries (hexadecimal) are written. Clocks have no value to record.
    let recordable = |v: &&Variable| match md.fmi_version {
        FmiVersion::Fmi2 => v.kind.is_numeric(),
        FmiVersion::Fmi3 => v.kind != Kind::Clock,
    };
    let outputs: Vec<&Variable> = md.outputs().filter(recordable).collect();
    // One CSV column per output, an array's elements each.
    let output_columns = Recording::new(md, &outputs, &assignments)?.names;
    // The CSV has the outputs; the plot may also read other variables, recorded after them.
    let mut recorded = outputs.clone();
    for v in plotted.iter().chain(x_variable.iter()).chain(flags.iter()) {
        if !recorded.iter().any(|r| r.name == v.name) {
            recorded.push(v);
        }
    }
    let mut writer = output::csv_writer(options.out.as_deref())?;
    let mut header: Vec<String> = overlaid.iter().map(|v| v.name.clone()).collect();
    header.push("time".to_owned());
    header.extend(output_columns.iter().cloned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    let mut row = Vec::with_capacity(header.len());
    let mut traces = Vec::new();
    for case in &cases {
        let mut case_assignments = assignments.clone();
        case_assignments.extend(case.assignment.clone());
        let recording = Trace::recording(md, &recorded, &case_assignments, options.record_events)?;
        let mut trace = Trace::empty(&recording, &grid);
        let keep = options.plot.is_some();
        let outcome = executor.run_with_inputs(
            md,
            identifier,
            &grid,
            &case_assignments,
            inputs.as_ref(),
            &recording,
            options.log,
            |t, values, texts| {
                if keep {
                    trace.push(t, values);
                }
                row.clear();
                if overlaid.is_some() {
                    row.push(format!("{:?}", case.si));
                }
                row.push(format!("{t:?}"));
                // Exactly as the FMU gave them: 64-bit integers in full, Binary in hexadecimal.
                row.extend((0..output_columns.len()).map(|c| texts.text(c, values)));
                writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))
            },
        )?;
        trace.ended_early = outcome.ended_early;
        if let Some(reason) = &trace.ended_early {
            let which = case.label.as_ref().map(|l| format!(" ({l})")).unwrap_or_default();
            eprintln!("{identifier}{which}: stopped before the stop time {} s: {reason}", grid.stop);
        }
        if options.plot.is_some() {
            traces.push(trace);
        }
    }
    output::finish_csv(writer)?;

    if let Some(path) = &options.plot {
        let ys: Vec<Axis> = plotted.iter().map(|v| Axis::of(md, v)).collect();
        let x = x_variable.map(|v| Axis::of(md, v));
        let runs: Vec<(Option<String>, &Trace, Vec<Event>)> =
            cases.iter().zip(&traces).map(|(c, t)| (c.label.clone(), t, trace::events(t, &flags))).collect();
        let mut title = format!("{}: outputs", md.model_name);
        if let Some(x) = &x {
            title.push_str(&format!(" against {}", x.name));
        }
        if let Some(v) = overlaid {
            let values: Vec<String> =
                cases.iter().filter_map(|c| c.label.as_ref()).map(|l| l.split(" = ").nth(1).unwrap_or("").to_owned()).collect();
            title.push_str(&format!(" for {} = {}", v.name, values.join(", ")));
        }
        figure::write(path, &figure(title, &runs, &ys, x.as_ref())?)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::spaced_unit;

    #[test]
    fn labels_put_a_space_before_the_unit() {
        assert_eq!(spaced_unit("15deg"), "15 deg");
        assert_eq!(spaced_unit("1.5e-3m"), "1.5e-3 m");
        assert_eq!(spaced_unit("10 rpm"), "10 rpm");
        assert_eq!(spaced_unit("2"), "2");
    }
}
