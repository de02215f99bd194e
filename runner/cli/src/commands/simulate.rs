//! `runner simulate`: one run, written as CSV in fmpy's layout (`time`, then the outputs), and
//! optionally a plot: one panel per variable on a shared time axis (or against `--plot-x`), in
//! the FMU's display units, events marked; `--overlay` repeats the run for several values of
//! one parameter and draws them over each other. The FMU runs in a worker process by default, so
//! that a crash is reported with its signal and call.

use std::path::{Path, PathBuf};

use fmi_importer::call_log::CallLogTarget;
use fmi_importer::number_text;
use fmi_importer::{Causality, Description, Kind, Value, Variable};
use runner_engine::exec::{Held, Runs};
use runner_engine::input::InputTable;
use runner_engine::request::RunRequest;
use runner_engine::run::{Grid, Recording};
use runner_engine::variables;

use crate::experiment::{self, RunDefaults, Target};
use crate::integration::Integration;
use crate::interrupt;
use crate::reference;
use crate::report::{self, output};
use crate::workers;
use plots::outputs::{figure, Axis};
use plots::trace::{self, Event, Trace};

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
    /// Start time (`--start-time`; default: the FMU's DefaultExperiment, else 0).
    pub start_time: Option<f64>,
    /// Record exactly these variables (`--output-variable`; default: the outputs).
    pub output_variables: Vec<String>,
    /// Communication points on a logarithmic time scale (`--log-time-scale`).
    pub log_time_scale: bool,
    /// Check the run against reference results (`--reference-file`; `Some(None)`: the ones
    /// the FMU ships under LS-REF).
    pub reference_file: Option<Option<PathBuf>>,
    /// The tolerances of the reference check (`--rtol`, `--atol`).
    pub rtol: Option<f64>,
    pub atol: Option<f64>,
    /// Go on from the state saved in this file (`--initial-fmu-state-file`).
    pub initial_fmu_state_file: Option<PathBuf>,
    /// Save the state at the stop time into this file (`--final-fmu-state-file`).
    pub final_fmu_state_file: Option<PathBuf>,
    /// How a system's connections pass Real values (`--coupling`).
    pub coupling: Option<String>,
    /// Log every FMI call there (`--log-fmi-calls`).
    pub log_fmi_calls: Option<CallLogTarget>,
}

/// `runner simulate SYSTEM`, refusing the options that are for single FMUs.
fn run_system(options: &Options) -> Result<(), String> {
    let single = [
        ("--overlay", options.overlay.is_some()),
        ("--record-events", options.record_events),
        ("--log", options.log),
        ("--start-time", options.start_time.is_some()),
        ("--output-variable", !options.output_variables.is_empty()),
        ("--log-time-scale", options.log_time_scale),
        ("--reference-file", options.reference_file.is_some()),
        ("--initial-fmu-state-file", options.initial_fmu_state_file.is_some()),
        ("--final-fmu-state-file", options.final_fmu_state_file.is_some()),
        ("--log-fmi-calls", options.log_fmi_calls.is_some()),
    ];
    if let Some((flag, _)) = single.iter().find(|(_, given)| *given) {
        return Err(format!("{flag} is for single FMUs; a system takes --stop-time, --output-interval, --tolerance, --set COMPONENT.VARIABLE=VALUE, --input-file, --master, --coupling, --timeout, --in-process, --out, --plot, --plot-vars and --plot-x"));
    }
    let timeout = runner_sandbox::timeout("--timeout", options.timeout)?;
    let isolation = match options.in_process {
        true if timeout.is_some() => {
            return Err("--timeout needs a worker process (a run in this process cannot be stopped): drop --in-process".to_owned())
        }
        true => None,
        false => Some(crate::commands::system::isolation(timeout, runner_sandbox::default_memory_mib(1))?),
    };
    crate::commands::system::simulate(
        Path::new(&options.fmu),
        &options.run,
        &crate::commands::system::Algorithm::new(options.master.clone(), options.coupling.clone(), options.input_file.as_deref())?,
        options.out.as_deref(),
        isolation,
        options.plot.as_deref().map(|path| crate::commands::system::Plot { path, vars: &options.plot_vars, x: options.plot_x.as_deref() }),
    )
}

/// The variables `--output-variable` names, in order: any variable with a value (parameters,
/// locals and inputs too), each once.
fn recorded_variables<'a>(md: &'a Description, names: &[String]) -> Result<Vec<&'a Variable>, String> {
    let mut chosen: Vec<&Variable> = Vec::with_capacity(names.len());
    for name in names.iter().map(|n| n.trim()) {
        let variable = variables::find(md, name)?;
        if variable.kind == Kind::Clock {
            return Err(format!("--output-variable {name}: a Clock has no value to record"));
        }
        if chosen.iter().any(|v| v.name == variable.name) {
            return Err(format!("--output-variable {name} is given twice"));
        }
        chosen.push(variable);
    }
    Ok(chosen)
}

/// Refuses saving or restoring the state of an FMU that does not declare it can.
fn check_state_capability(held: &Held) -> Result<(), String> {
    let md = held.description();
    match md.interface(held.interface()).is_some_and(|c| c.can_get_and_set_fmu_state && c.can_serialize_fmu_state) {
        true => Ok(()),
        false => Err(format!(
            "{} does not declare canGetAndSetFMUState and canSerializeFMUState for {}, so its state cannot be saved or restored",
            md.model_name,
            held.interface()
        )),
    }
}

/// Largest state file read (a state of more is not one this runner wrote).
const MAX_STATE_FILE_BYTES: u64 = fmi_importer::state::MAX_STATE_BYTES as u64 + (1 << 20);

/// The state file `path` of `--initial-fmu-state-file`, checked to be of the FMU `held`.
fn read_state(path: &Path, held: &Held) -> Result<(Vec<u8>, fmi_importer::state::SavedState), String> {
    check_state_capability(held)?;
    let size = std::fs::metadata(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?.len();
    if size > MAX_STATE_FILE_BYTES {
        return Err(format!("{} has {size} bytes, more than a saved state may have", path.display()));
    }
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let identity = fmi_importer::state::Identity::of(held.description(), held.interface());
    let saved = fmi_importer::state::SavedState::from_bytes(&bytes, identity).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((bytes, saved))
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

/// A simulation resolved against the FMU: one run request per case (one, or one per
/// `--overlay` value), the CSV's columns, and what the plot draws.
struct Simulation<'a> {
    grid: Grid,
    /// The `--overlay` parameter, whose value (SI) is the CSV's first column.
    overlaid: Option<&'a Variable>,
    cases: Vec<Case<'a>>,
    /// Per case: its columns (the outputs, then what only the plot reads) and its request.
    runs: Vec<(Recording<'a>, RunRequest)>,
    /// The CSV's header.
    header: Vec<String>,
    /// The CSV's output columns, first in each sample.
    output_columns: usize,
    /// Per output column: its number is its value (not a String's or a Binary's).
    comparable: Vec<bool>,
    /// Drawn against time (or `x`), with these event flags.
    plotted: Vec<&'a Variable>,
    x: Option<&'a Variable>,
    flags: Vec<&'a Variable>,
}

/// Resolves the options against the FMU `held`: the grid, the assignments (the experiment's,
/// then the options'), the input file, the overlay's cases, the recorded columns and the plot's.
fn resolve<'a>(options: &Options, target: &Target, held: &'a Held) -> Result<Simulation<'a>, String> {
    let (md, identifier) = (held.description(), held.identifier());
    let mut settings = options.run.grid();
    settings.start_time = options.start_time;
    let initial_state = match &options.initial_fmu_state_file {
        Some(path) => {
            let (bytes, saved) = read_state(path, held)?;
            // The run goes on from the state's time: that is its start.
            match options.start_time {
                Some(start) if !runner_engine::input::same_time(start, saved.time) => {
                    return Err(format!(
                        "{} holds the state at t = {} s, so the run starts there, not at --start-time {start}",
                        path.display(),
                        saved.time
                    ))
                }
                _ => settings.start_time = Some(saved.time),
            }
            Some(bytes)
        }
        None => None,
    };
    if options.final_fmu_state_file.is_some() {
        check_state_capability(held)?;
    }
    let sources = [settings, target.experiment.simulate.grid()];
    let mut grid = match options.log_time_scale {
        true => Grid::choose_logarithmic(md, &sources)?,
        false => Grid::choose(md, &sources)?,
    };
    grid.solver = options.integration.solver()?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(md, &set_texts)?;
    let inputs: Option<InputTable> = workers::input_file(options.input_file.as_deref(), md, held.interface())?;

    let (overlaid, cases) = match &options.overlay {
        Some(text) => {
            let (v, cases) = overlay_cases(md, text)?;
            (Some(v), cases)
        }
        None => (None, vec![Case { label: None, assignment: None, si: f64::NAN }]),
    };

    // What the plot needs, checked before running: the y variables, x, and the event flags.
    let numeric = |name: &str| trace::numeric_variable(md, name);
    let (plotted, x, flags) = if options.plot.is_some() {
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

    // One convention for both versions: Strings written as they are, Binaries in hexadecimal,
    // integers as integers. Clocks have no value to record.
    let recordable = |v: &&Variable| v.kind != Kind::Clock;
    let outputs: Vec<&Variable> = match options.output_variables.is_empty() {
        true => md.outputs().filter(recordable).collect(),
        false => recorded_variables(md, &options.output_variables)?,
    };
    // One CSV column per output, an array's elements each.
    let output_recording = Recording::new(md, &outputs, &assignments)?;
    // The columns whose numbers are their values (what a reference check compares).
    let comparable = output_recording
        .variables
        .iter()
        .zip(&output_recording.sizes)
        .flat_map(|(v, &n)| std::iter::repeat_n(!matches!(v.kind, Kind::String | Kind::Binary), n))
        .collect();
    let output_columns = output_recording.names;
    // The CSV has the outputs; the plot may also read other variables, recorded after them.
    let mut recorded = outputs.clone();
    for v in plotted.iter().chain(x.iter()).chain(flags.iter()) {
        if !recorded.iter().any(|r| r.name == v.name) {
            recorded.push(v);
        }
    }
    let mut header: Vec<String> = overlaid.iter().map(|v| v.name.clone()).collect();
    header.push("time".to_owned());
    header.extend(output_columns.iter().cloned());
    let mut runs = Vec::new();
    for case in &cases {
        let mut case_assignments = assignments.clone();
        case_assignments.extend(case.assignment.clone());
        let recording = Trace::recording(md, &recorded, &case_assignments, options.record_events)?;
        let mut request = RunRequest::new(identifier, grid, &case_assignments, &recording, options.log).with_inputs(inputs.clone());
        request.initial_state = initial_state.clone();
        request.final_state = options.final_fmu_state_file.is_some();
        request.log_fmi_calls = options.log_fmi_calls.clone();
        runs.push((recording, request));
    }
    Ok(Simulation { grid, overlaid, cases, runs, header, output_columns: output_columns.len(), comparable, plotted, x, flags })
}

/// Runs `runner simulate`.
pub fn run(options: &Options) -> Result<(), String> {
    if let Some(plot) = &options.plot {
        report::check_plot(plot)?;
    } else if !options.plot_vars.is_empty() || options.plot_x.is_some() {
        return Err("--plot-vars and --plot-x choose what --plot FILE draws: give --plot too".to_owned());
    }
    if fmi_systems::is_system(Path::new(&options.fmu)) {
        return run_system(options);
    }
    let timeout = runner_sandbox::timeout("--timeout", options.timeout)?;
    if options.in_process && timeout.is_some() {
        return Err("--timeout needs a worker process (a run in this process cannot be stopped): drop --in-process".to_owned());
    }
    if options.reference_file.is_none() && (options.rtol.is_some() || options.atol.is_some()) {
        return Err("--rtol and --atol are the tolerances of --reference-file: give it too".to_owned());
    }
    if options.reference_file.is_some() && options.overlay.is_some() {
        return Err("--reference-file checks one run: drop --overlay".to_owned());
    }
    if options.overlay.is_some() && (options.initial_fmu_state_file.is_some() || options.final_fmu_state_file.is_some()) {
        return Err("--initial-fmu-state-file and --final-fmu-state-file are for one run: drop --overlay".to_owned());
    }
    let tube = reference::Tube::new(options.rtol, options.atol)?;
    workers::create_call_log(options.log_fmi_calls.as_ref())?;
    let target = experiment::resolve(&options.fmu)?;
    // The reference is read before running, so a missing or malformed one costs no run.
    let checked = match &options.reference_file {
        None => None,
        Some(None) => Some(reference::shipped_required(&target.path)?),
        Some(Some(path)) => Some(reference::Reference::read(path)?),
    };
    // The standard's check reads the description again with the validator's own parser: on the
    // other core while this one loads the FMU, its warning printed before the run starts (or
    // before the error of a run that could not start).
    let outcome = std::thread::scope(|scope| {
        let check = scope.spawn(|| fmi_validate::archive_description_problems(&target.path));
        let mut check = Some(check);
        let mut warn = || {
            if let Some(check) = check.take() {
                warn_if_nonstandard(&target.path, check.join().unwrap_or_default());
            }
        };
        let outcome = simulate(options, &target, checked.as_ref(), tube, &mut warn);
        warn();
        outcome
    })?;
    if let (Some(reference), Some(outcome)) = (&checked, outcome) {
        let verdict = outcome.map_err(|mismatch| format!("reference check failed: {mismatch}"))?;
        eprintln!("reference check passed: {}", passed(&verdict, reference, tube));
    }
    Ok(())
}

/// What a passed check compared, in one line.
pub fn passed(verdict: &reference::Verdict, reference: &reference::Reference, tube: reference::Tube) -> String {
    let skipped = match verdict.skipped.is_empty() {
        true => String::new(),
        false => format!("; not compared: {}", verdict.skipped.join(", ")),
    };
    format!("{} at the {} times of {} within {}{skipped}", verdict.compared.join(", "), verdict.times, reference.label, tube.describe())
}

/// The run (or runs, with `--overlay`) of `target` that `options` ask for, its CSV written and
/// its plot drawn; with `checked`, the outcome of the run's check against it with `tube` (`Err`
/// of the outer result: the run itself failed). `runner validate --reference-file` makes its
/// check through this too. `before_run` is called once the FMU is loaded, before it runs.
pub fn simulate(
    options: &Options,
    target: &Target,
    checked: Option<&reference::Reference>,
    tube: reference::Tube,
    before_run: &mut dyn FnMut(),
) -> Result<Option<Result<reference::Verdict, reference::Mismatch>>, String> {
    // In a worker, only the description is read here: the FMU's binary runs in the worker alone.
    let (held, source) = workers::open(&target.path, &options.integration, options.in_process)?;
    let timeout = runner_sandbox::timeout("--timeout", options.timeout)?;
    let config = workers::isolation(timeout, runner_sandbox::default_memory_mib(1))?;
    let mut runs = Runs::new(&held, &config, &source);
    let simulation = resolve(options, target, &held)?;
    before_run();
    let mut samples = checked.map(|_| Vec::new());
    let traces = execute(&simulation, &mut runs, options, held.identifier(), samples.as_mut())?;
    if let Some(path) = &options.plot {
        plot(path, &simulation, &traces, held.description())?;
    }
    Ok(checked.zip(samples).map(|(reference, samples)| {
        let names = &simulation.header[simulation.header.len() - simulation.output_columns..];
        reference::check(reference, names, &simulation.comparable, &samples, tube)
    }))
}

/// The numbers of a run's CSV output columns at each time, kept for the reference check.
type Samples = Vec<(f64, Vec<f64>)>;

/// Warns in one line when the FMU's description breaks the standard (`problems`, what `runner
/// validate`'s static checks find): the runner may run what fmpy and others refuse.
fn warn_if_nonstandard(fmu: &Path, problems: Vec<String>) {
    if let Some(first) = problems.first() {
        let more = match problems.len() {
            1 => String::new(),
            n => format!(" (and {} more)", n - 1),
        };
        let first: String = first.chars().map(|c| if c.is_control() { ' ' } else { c }).collect();
        eprintln!(
            "warning: {}: its modelDescription.xml breaks the FMI standard, so other importers may refuse it: {first}{more}; `runner validate {}` lists every problem",
            fmu.display(),
            fmu.display()
        );
    }
}

/// Runs every case, writing the CSV rows as the samples arrive; the traces the plot draws.
fn execute(
    simulation: &Simulation,
    runs: &mut Runs,
    options: &Options,
    identifier: &str,
    mut samples: Option<&mut Samples>,
) -> Result<Vec<Trace>, String> {
    let mut writer = output::CsvRows::open(options.out.as_deref(), &simulation.header)?;
    let mut traces = Vec::new();
    let keep = options.plot.is_some();
    // The rows written so far and the last one's time, for the message of a failed run.
    let (mut rows, mut last) = (0usize, f64::NAN);
    for (case, (recording, request)) in simulation.cases.iter().zip(&simulation.runs) {
        let mut trace = Trace::empty(recording, &simulation.grid);
        let outcome = runs.run(request, &interrupt::requested, |t, values, texts| {
            if keep {
                trace.push(t, values);
            }
            rows += 1;
            last = t;
            if simulation.overlaid.is_some() {
                number_text::push_f64(case.si, writer.field());
            }
            number_text::push_f64(t, writer.field());
            // Exactly as the FMU gave them: 64-bit integers in full, Binary in hexadecimal.
            for (c, &x) in values[..simulation.output_columns].iter().enumerate() {
                if texts.needs_text(c) {
                    writer.text(&texts.text(c, values));
                } else {
                    texts.push_number_text(c, x, writer.field());
                }
            }
            if let Some(samples) = samples.as_deref_mut() {
                samples.push((t, values[..simulation.output_columns].to_vec()));
            }
            writer.end_row()
        });
        let outcome = match outcome {
            Ok(outcome) => outcome,
            Err(error) => return Err(keep_rows(writer, error, options.out.as_deref(), rows, last)),
        };
        if let (Some(path), Some(state)) = (&options.final_fmu_state_file, &outcome.final_state) {
            std::fs::write(path, state).map_err(|e| format!("cannot write the final state to {}: {e}", path.display()))?;
        }
        if let Some(c) = outcome.counters {
            let which = case.label.as_ref().map(|l| format!(" ({l})")).unwrap_or_default();
            eprintln!("{identifier}{which}: {}", crate::integration::work(&c, simulation.grid.solver.method));
        }
        trace.ended_early = outcome.ended_early;
        if let Some(reason) = &trace.ended_early {
            let which = case.label.as_ref().map(|l| format!(" ({l})")).unwrap_or_default();
            eprintln!("{identifier}{which}: stopped before the stop time {} s: {reason}", simulation.grid.stop);
            if let Some(path) = &options.final_fmu_state_file {
                writer.finish()?;
                return Err(format!(
                    "{} is not written: the model ended the run before the stop time, where its state would be saved",
                    path.display()
                ));
            }
        }
        if keep {
            traces.push(trace);
        }
    }
    writer.finish()?;
    Ok(traces)
}

/// A failed or interrupted run's error, after the rows written before it are put in place:
/// `--out` gets them as standard output has them (every row up to the failure or Ctrl-C, then
/// the error), and the message says how many there are, as a system's run keeps them.
fn keep_rows(writer: output::CsvRows, error: String, out: Option<&Path>, rows: usize, last: f64) -> String {
    let Some(path) = out else {
        return error;
    };
    let (ended, end) = if interrupt::requested() { ("was interrupted", "interruption") } else { ("failed", "failure") };
    match writer.finish() {
        Ok(()) if rows == 0 => format!("{error}\n{} has the header only: the run {ended} before its first row", path.display()),
        Ok(()) => format!("{error}\n{} keeps the {rows} row(s) before the {end}, up to t = {last}", path.display()),
        Err(e) => format!("{error}\n(the rows before the failure are lost too: {e})"),
    }
}

/// Draws the runs' figure into `path`.
fn plot(path: &Path, simulation: &Simulation, traces: &[Trace], md: &Description) -> Result<(), String> {
    let ys: Vec<Axis> = simulation.plotted.iter().map(|v| Axis::of(md, v)).collect();
    let x = simulation.x.map(|v| Axis::of(md, v));
    let runs: Vec<(Option<String>, &Trace, Vec<Event>)> =
        simulation.cases.iter().zip(traces).map(|(c, t)| (c.label.clone(), t, trace::events(t, &simulation.flags))).collect();
    let mut title = format!("{}: outputs", md.model_name);
    if let Some(x) = &x {
        title.push_str(&format!(" against {}", x.name));
    }
    if let Some(v) = simulation.overlaid {
        let values: Vec<String> =
            simulation.cases.iter().filter_map(|c| c.label.as_ref()).map(|l| l.split(" = ").nth(1).unwrap_or("").to_owned()).collect();
        title.push_str(&format!(" for {} = {}", v.name, values.join(", ")));
    }
    report::write_plot(path, &figure(title, &runs, &ys, x.as_ref())?)
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
