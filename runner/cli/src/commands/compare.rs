//! `runner compare`: Ex. 4's question "which solver is cheapest for a given accuracy?",
//! answered through the FMI interface alone: under Co-Simulation each run sets the toolkit's
//! solver controls (`solver`, `fixed_step`, tolerance, `abs_tol`) and reads the counters
//! `n_steps`, `n_rhs`; under Model Exchange (`--interface model-exchange`, any ME FMU) the
//! runner's own integrator runs with those settings and counts its own steps and evaluations.
//! Every method does its natural work: Euler and RK4 their fixed steps, the adaptive methods
//! the steps their error control takes across the communication points. Errors are measured
//! against the model's closed-form solution where its experiment.toml gives one
//! (`[compare.reference]`), else against DOP853 at a tolerance far below the table's. Given
//! several models, it also answers Ex. 4's discussion question 1: how the step counts of
//! Euler and DOPRI5 compare on each (the fifth-order quarter car against the second-order
//! system of Ex. 1).

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use fmi_importer::{Causality, Description, Interface, Kind, Solver, Value, Variability, Variable};
use formulas::Formula;
use runner_engine::exec::Runs;
use runner_engine::request::RunRequest;
use runner_engine::run::{Grid, Recording};
use runner_engine::variables;
use solvers::controls::Control;
use solvers::Method;

use crate::experiment::{self, RunDefaults};
use crate::integration::Integration;
use crate::interrupt;
use crate::report::progress::Progress;
use crate::report::{self, output};
use crate::workers;
use plots::lines::{LinePlot, Mark, Series};

/// The method of the reference run: DOP853, whose error at `REFERENCE_RTOL` is far below any
/// the table reports (its tightest tolerance is 1e-11).
pub const REFERENCE_METHOD: Method = Method::Dop853;
/// Relative tolerance of the reference run.
pub const REFERENCE_RTOL: f64 = 1e-13;

/// Options of `runner compare`.
pub struct Options {
    /// Model names or `.fmu` paths (FMUs of this toolkit: they need the solver controls).
    pub models: Vec<String>,
    /// Solvers to compare, by name: euler, rk4, dopri5, bs23, dop853.
    pub solvers: Vec<String>,
    /// The error each solver must reach (max over outputs of the error relative to the output's peak).
    pub target_error: f64,
    /// Grid and assignments from the command line.
    pub run: RunDefaults,
    /// Work-precision table (CSV); `None`: `<MODEL>_compare.csv`. Only for a single model.
    pub out: Option<PathBuf>,
    /// Work-precision plot (SVG); `None`: `<MODEL>_compare.svg`. Only for a single model.
    pub plot: Option<PathBuf>,
    /// The interface (the runner's integrator settings are the table's, not given here).
    pub integration: Integration,
    /// Runs in this process instead of a worker process.
    pub in_process: bool,
    /// A run taking longer (seconds) is recorded as timed out (needs a worker process).
    pub point_timeout: Option<f64>,
}

/// The comparison of one model.
#[derive(Debug, Clone)]
pub struct Comparison {
    /// The model's name (its modelName).
    pub model: String,
    /// Every run, in the order of the solvers and their settings.
    pub rows: Vec<Row>,
}

impl Comparison {
    /// The cheapest run (fewest right-hand-side evaluations) of `solver` that reaches `target`.
    pub fn cheapest(&self, solver: &str, target: f64) -> Option<&Row> {
        self.rows.iter().filter(|r| r.solver == solver && r.error <= target).min_by(|a, b| a.n_rhs.total_cmp(&b.n_rhs))
    }
}

/// One run of the work-precision table.
#[derive(Debug, Clone)]
pub struct Row {
    pub solver: String,
    /// "fixed_step" or "tolerance".
    pub setting: &'static str,
    pub value: f64,
    pub n_steps: f64,
    pub n_rhs: f64,
    pub seconds: f64,
    /// Max over outputs and samples of |y - y_ref| / max|y_ref| (infinite when the run failed).
    pub error: f64,
    pub status: String,
}

/// What is tried for one solver: its `solver` code, the setting varied and its values.
type Trials = (i32, &'static str, Vec<f64>);

/// The settings tried for each solver: fixed steps from the output interval down (Euler by 4x,
/// RK4 by 2x, matching their orders), tolerances by decades from 1e-2 for the adaptive methods,
/// to 1e-10 for BS23 (a third-order method needs 10x the steps per 1000x in tolerance) and the
/// implicit BDF and ESDIRK (orders up to 5 and 3), and 1e-11 for the others.
fn settings(solver: &str, interval: f64) -> Result<Trials, String> {
    let method = Method::from_name(solver).ok_or_else(|| {
        let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        format!("unknown solver '{solver}': use {}", names.join(", "))
    })?;
    Ok(match method {
        Method::Euler => (method.code(), Control::FixedStep.name(), (0..8).map(|k| interval / 4f64.powi(k)).collect()),
        Method::Rk4 => (method.code(), Control::FixedStep.name(), (0..6).map(|k| interval / 2f64.powi(k)).collect()),
        Method::Dopri5 | Method::Dop853 => (method.code(), "tolerance", (2..=11).map(|k| 10f64.powi(-k)).collect()),
        Method::Bs23 | Method::Bdf | Method::Esdirk => (method.code(), "tolerance", (2..=10).map(|k| 10f64.powi(-k)).collect()),
    })
}

pub(crate) fn control(description: &Description, control: Control) -> Result<&Variable, String> {
    let name = control.name();
    description.variable(name).ok_or_else(|| {
        let hint = if description.model_exchange.is_some() {
            "; it offers Model Exchange, which the runner integrates with its own solvers: add --interface model-exchange"
        } else {
            ""
        };
        format!(
            "{} has no variable '{name}': `runner compare` on Co-Simulation needs the solver controls of this toolkit's FMUs{hint}",
            description.model_name
        )
    })
}

/// The grid and assignments of a run at the reference accuracy: `REFERENCE_METHOD` at `rtol`
/// (absolute tolerance a hundredth of it), through the runner's integrator for Model Exchange
/// or, given the FMU's solver `controls` (the solver and absolute-tolerance variables of this
/// toolkit's FMUs), inside the FMU under Co-Simulation.
pub(crate) fn reference_accuracy<'a>(
    grid: Grid,
    controls: Option<(&'a Variable, &'a Variable)>,
    rtol: f64,
) -> (Grid, Vec<(&'a Variable, Value)>) {
    let solver = Solver { method: REFERENCE_METHOD, abs_tol: rtol * 1e-2, ..Solver::default() };
    let settings = match controls {
        Some((method, abs_tol)) => vec![(method, Value::Integer(REFERENCE_METHOD.code())), (abs_tol, Value::Real(rtol * 1e-2))],
        None => Vec::new(),
    };
    (Grid { tolerance: Some(rtol), solver, ..grid }, settings)
}

/// Runs one setting; returns the sampled compared outputs and the final counters: the FMU's
/// `counters` (`n_steps`, `n_rhs`) under Co-Simulation, the runner's integrator's when
/// `counters` is empty (Model Exchange: evaluations plus directional-derivative calls).
fn run_once(
    runs: &mut Runs,
    md: &Description,
    grid: &Grid,
    base: &[(&Variable, Value)],
    extra: &[(&Variable, Value)],
    compared: &[&Variable],
    counters: &[&Variable],
) -> Result<(Vec<Vec<f64>>, f64, f64), String> {
    let mut recorded: Vec<&Variable> = compared.to_vec();
    recorded.extend_from_slice(counters);
    let mut assignments: Vec<(&Variable, Value)> = base.to_vec();
    assignments.extend_from_slice(extra);
    let mut samples = Vec::with_capacity(grid.steps() + 1);
    let mut last = (0.0, 0.0);
    let n = compared.len();
    let recording = Recording::new(md, &recorded, &assignments)?;
    let request = RunRequest::new("compare", *grid, &assignments, &recording, false);
    let outcome = runs.run(&request, &interrupt::requested, |_, values, _| {
        samples.push(values[..n].to_vec());
        if !counters.is_empty() {
            last = (values[n], values[n + 1]);
        }
        Ok(())
    })?;
    if let Some(reason) = outcome.ended_early {
        return Err(format!("the run ended early: {reason}"));
    }
    if counters.is_empty() {
        // The implicit methods' directional-derivative calls are work as an evaluation is (one
        // Jacobian column each, as a difference column costs one evaluation): without them a
        // method using the FMU's derivatives would look cheaper than it is.
        let c = outcome.counters.unwrap_or_default();
        last = (c.n_steps as f64, (c.n_rhs + c.n_directional) as f64);
    }
    Ok((samples, last.0, last.1))
}

/// The outputs named in `[compare.reference]` and their exact values at `times`, one row per
/// time. A formula reads `t` and parameters: their start values, overridden by the assignments
/// `base`.
pub(crate) fn closed_form<'a>(
    md: &'a Description,
    formulas: &BTreeMap<String, String>,
    base: &[(&Variable, Value)],
    times: &[f64],
) -> Result<(Vec<&'a Variable>, Vec<Vec<f64>>), String> {
    let mut compared = Vec::new();
    let mut parsed = Vec::new();
    for (output, text) in formulas {
        let v = variables::find(md, output)?;
        if !(v.kind == Kind::Real && v.causality == Causality::Output) {
            return Err(format!("[compare.reference] gives '{output}', which is not a Real output of {}", md.model_name));
        }
        let formula = Formula::parse(text).map_err(|e| format!("[compare.reference] {output}: {e}"))?;
        // Bind each name once: `t` varies per sample, parameters are constants of the run.
        let mut bound = Vec::new();
        for name in &formula.names {
            if name == "t" {
                bound.push(None);
                continue;
            }
            let variable = md.variable(name).filter(|p| p.causality == Causality::Parameter).ok_or_else(|| {
                format!("[compare.reference] {output} = {text}: '{name}' is neither t nor a parameter of {}", md.model_name)
            })?;
            let value = match base.iter().rev().find(|(p, _)| p.name == *name).map(|(_, value)| value) {
                Some(value) => value.as_number(),
                None => variable.start.as_ref().and_then(|s| s.as_number()),
            };
            bound.push(Some(value.ok_or_else(|| format!("[compare.reference] {output}: parameter '{name}' has no numeric value"))?));
        }
        compared.push(v);
        parsed.push((formula, bound));
    }
    let mut values = Vec::new();
    let reference = times
        .iter()
        .map(|&t| {
            parsed
                .iter()
                .map(|(formula, bound)| {
                    values.clear();
                    values.extend(bound.iter().map(|b| b.unwrap_or(t)));
                    formula.evaluate(&values)
                })
                .collect()
        })
        .collect();
    Ok((compared, reference))
}

/// Max over outputs of the sample-wise error relative to the output's peak in the reference.
fn relative_error(run: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    if run.len() != reference.len() {
        return f64::INFINITY;
    }
    let n = reference.first().map_or(0, |r| r.len());
    (0..n)
        .map(|j| {
            let peak = reference.iter().map(|r| r[j].abs()).fold(0.0, f64::max);
            let scale = if peak > 0.0 { peak } else { 1.0 };
            // f64::max would drop a NaN sample; a run that produced one has failed.
            run.iter()
                .zip(reference)
                .map(|(a, b)| (a[j] - b[j]).abs() / scale)
                .fold(0.0, |m: f64, e| if e.is_nan() { f64::INFINITY } else { m.max(e) })
        })
        .fold(0.0, f64::max)
}

/// The table and plot files of each model: the options' for a single model, else
/// `<MODEL>_compare.csv` and `.svg` (MODEL: the name or the `.fmu` file's stem).
fn destinations(options: &Options) -> Result<Vec<(PathBuf, PathBuf)>, String> {
    if options.models.len() > 1 && (options.out.is_some() || options.plot.is_some()) {
        return Err(format!(
            "--out and --plot name the files of one model, but {} models were given: leave them out to write <MODEL>_compare.csv and <MODEL>_compare.svg for each",
            options.models.len()
        ));
    }
    options
        .models
        .iter()
        .map(|m| {
            let stem = std::path::Path::new(m).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "compare".into());
            let out = options.out.clone().unwrap_or_else(|| PathBuf::from(format!("{stem}_compare.csv")));
            let plot = options.plot.clone().unwrap_or_else(|| PathBuf::from(format!("{stem}_compare.svg")));
            // Both files are written after the runs.
            output::check_destination(&out)?;
            report::check_plot(&plot)?;
            Ok((out, plot))
        })
        .collect()
}

/// Runs the comparison of every model (each table also written to CSV and SVG) and prints how
/// their step counts compare (Ex. 4, discussion question 1).
pub fn run(options: &Options) -> Result<Vec<Comparison>, String> {
    if !(options.target_error.is_finite() && options.target_error > 0.0) {
        return Err(format!("--target-error {} must be a positive number", options.target_error));
    }
    if options.models.is_empty() {
        return Err("no model given: name one or more models or .fmu files".to_owned());
    }
    if options.integration.solver.is_some() || options.integration.fixed_step.is_some() || options.integration.abs_tolerance.is_some() {
        return Err(
            "compare runs every solver of --solvers over its own settings: --solver, --fixed-step and --abs-tolerance do not apply"
                .to_owned(),
        );
    }
    if options.in_process && options.point_timeout.is_some() {
        return Err("--point-timeout needs worker processes (a run in this process cannot be stopped): drop --in-process".to_owned());
    }
    let files = destinations(options)?;
    let mut comparisons = Vec::new();
    for (model, (out, plot)) in options.models.iter().zip(&files) {
        if !comparisons.is_empty() {
            println!();
        }
        comparisons.push(compare_one(model, options, out, plot)?);
    }
    println!("\n{}", step_counts(&comparisons, &options.solvers, options.target_error));
    Ok(comparisons)
}

/// The steps `solver` needs for an error of exactly `target`: interpolated log-log on its
/// work-precision curve between the two settings tried on either side of it (the error of a
/// method of order p goes as steps^-p, a straight line there). `Bound::AtMost` when even the
/// coarsest setting tried is more accurate (Euler and RK4 cannot take fewer steps than
/// communication points), `None` when no setting reached it.
pub fn steps_for(rows: &[Row], solver: &str, target: f64) -> Option<Steps> {
    let runs: Vec<&Row> = rows.iter().filter(|r| r.solver == solver && r.error.is_finite() && r.error > 0.0).collect();
    let first = runs.first()?;
    if first.error <= target {
        return Some(Steps::AtMost(first.n_steps));
    }
    runs.windows(2).find(|w| w[0].error > target && w[1].error <= target).map(|w| {
        let (a, b) = (w[0], w[1]);
        let slope = (b.n_steps.ln() - a.n_steps.ln()) / (b.error.ln() - a.error.ln());
        Steps::About((a.n_steps.ln() + slope * (target.ln() - a.error.ln())).exp())
    })
}

/// A number of steps found by [`steps_for`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Steps {
    /// Interpolated between two settings tried.
    About(f64),
    /// The coarsest setting tried already reaches the error, with this many steps.
    AtMost(f64),
}

impl Steps {
    /// The number.
    pub fn value(self) -> f64 {
        match self {
            Steps::About(n) | Steps::AtMost(n) => n,
        }
    }
}

impl std::fmt::Display for Steps {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Steps::About(n) => write!(f, "{:.0}", n),
            Steps::AtMost(n) => write!(f, "<= {n:.0}"),
        }
    }
}

/// Ex. 4's discussion question 1 across the models compared: the steps each solver needs for
/// the error `target` (interpolated, see [`steps_for`]) and how many times DOPRI5's that is,
/// per model; then how the Euler/DOPRI5 ratio of the first model compares with each other's.
pub fn step_counts(comparisons: &[Comparison], solvers: &[String], target: f64) -> String {
    let solvers: Vec<&str> = solvers.iter().map(|s| s.trim()).collect();
    let mut text =
        format!("steps for an error of {target:e}, interpolated between the settings tried (in parentheses: x DOPRI5's)\n{:<24}", "model");
    for s in &solvers {
        text.push_str(&format!(" {s:>22}"));
    }
    let dopri5 = Method::Dopri5.name();
    for c in comparisons {
        text.push_str(&format!("\n{:<24}", c.model));
        let reference = steps_for(&c.rows, dopri5, target);
        for s in &solvers {
            let cell = match (steps_for(&c.rows, s, target), reference) {
                (Some(n), Some(d)) => format!("{n} ({:.3}x)", n.value() / d.value()),
                (Some(n), None) => format!("{n}"),
                (None, _) => "not reached".to_owned(),
            };
            text.push_str(&format!(" {cell:>22}"));
        }
    }
    // Euler's steps over DOPRI5's, and whether that is only a lower bound (DOPRI5's coarsest
    // setting was already more accurate).
    let ratio = |c: &Comparison| match (steps_for(&c.rows, Method::Euler.name(), target), steps_for(&c.rows, dopri5, target)) {
        (Some(Steps::About(e)), Some(d)) => Some((e / d.value(), matches!(d, Steps::AtMost(_)))),
        _ => None,
    };
    let times = |(r, lower_bound): (f64, bool)| if lower_bound { format!("at least {r:.0}x") } else { format!("{r:.0}x") };
    let (first, others) = comparisons.split_first().expect("at least one comparison");
    match ratio(first) {
        Some(r0) => {
            text.push_str(&format!("\nforward Euler needs {} the steps of DOPRI5 on {}", times(r0), first.model));
            for c in others {
                match ratio(c) {
                    Some(r) => {
                        let wider = r0.0 / r.0;
                        let bound = match (r0.1, r.1) {
                            (false, false) => "",
                            (true, false) => "at least ",
                            (false, true) => "at most ",
                            (true, true) => "(bounds only) ",
                        };
                        text.push_str(&format!(
                            " and {} on {}: the gap is {bound}{wider:.1}x as wide on {} as on {}",
                            times(r),
                            c.model,
                            first.model,
                            c.model
                        ))
                    }
                    None => text.push_str(&format!("; on {} the Euler/DOPRI5 ratio cannot be told at this error", c.model)),
                }
            }
        }
        None => text.push_str(&format!(
            "\nthe Euler/DOPRI5 step ratio on {} cannot be told at this error (a setting of each on both sides of it is needed): \
             try a larger --target-error",
            first.model
        )),
    }
    text
}

/// Compares the solvers on one model, writing its table to `out` and its plot to `plot`.
fn compare_one(model: &str, options: &Options, out: &std::path::Path, plot_path: &std::path::Path) -> Result<Comparison, String> {
    let timeout = runner_sandbox::timeout("--point-timeout", options.point_timeout)?;
    let target = experiment::resolve(model)?;
    // With workers, only the description is read here: the FMU's binary runs in them alone.
    let (held, source) = workers::open(&target.path, &options.integration, options.in_process)?;
    let md = held.description();
    if options.in_process && held.once_per_process() {
        return Err(format!(
            "{} declares canBeInstantiatedOnlyOncePerProcess, so its runs cannot share a process: drop --in-process",
            md.model_name
        ));
    }
    let config = workers::isolation(timeout, runner_sandbox::default_memory_mib(1))?;
    let mut runs = Runs::new(&held, &config, &source);
    let grid = Grid::choose(md, &[options.run.grid(), target.experiment.simulate.grid()])?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(target.experiment.compare.set.iter().cloned());
    set_texts.extend(options.run.set.iter().cloned());
    let base = variables::parse_sets(md, &set_texts)?;
    // Co-Simulation: the FMU's own solver controls and counters, which only this toolkit's
    // FMUs have. Model Exchange: the runner's integrator, for any FMU.
    let exchange = held.interface() == Interface::ModelExchange;
    let controls = if exchange {
        None
    } else {
        Some((control(md, Control::Solver)?, control(md, Control::FixedStep)?, control(md, Control::AbsTol)?))
    };
    let counters: Vec<&Variable> = if exchange { Vec::new() } else { vec![control(md, Control::NSteps)?, control(md, Control::NRhs)?] };
    let compared: Vec<&Variable> = md.outputs().filter(|v| v.kind == Kind::Real && v.variability == Variability::Continuous).collect();
    if compared.is_empty() {
        return Err(format!("{} has no continuous Real outputs to compare", md.model_name));
    }
    let plan: Vec<(String, Trials)> =
        options.solvers.iter().map(|s| settings(s.trim(), grid.interval).map(|p| (s.trim().to_owned(), p))).collect::<Result<_, _>>()?;

    let analytical = &target.experiment.compare;
    let (compared, reference, reference_name) = if analytical.reference.is_empty() || !options.run.set.is_empty() {
        let reference_name = format!("{} at rtol {REFERENCE_RTOL:e}", REFERENCE_METHOD.name().to_uppercase());
        if !analytical.reference.is_empty() {
            eprintln!("note: the closed-form reference in experiment.toml holds for its own parameter values; with --set the reference is {reference_name}");
        }
        let (reference_grid, reference_settings) =
            reference_accuracy(grid, controls.map(|(solver, _, abs_tol)| (solver, abs_tol)), REFERENCE_RTOL);
        let (reference, _, _) = run_once(&mut runs, md, &reference_grid, &base, &reference_settings, &compared, &counters)
            .map_err(|e| format!("the reference run ({reference_name}) failed: {e}"))?;
        (compared, reference, reference_name)
    } else {
        let times: Vec<f64> = (0..=grid.steps()).map(|i| grid.time(i)).collect();
        let (compared, reference) = closed_form(md, &analytical.reference, &base, &times)?;
        (compared, reference, "the closed-form solution of experiment.toml".to_owned())
    };

    let mut rows = Vec::new();
    let progress = Progress::start(plan.iter().map(|(_, (_, _, v))| v.len() as u64).sum(), "runs");
    for (name, (code, setting, values)) in &plan {
        for &value in values {
            if interrupt::requested() {
                return Err(format!("interrupted after {} runs; no file written", rows.len()));
            }
            let method = Method::from_code(*code).expect("a method's own code");
            let fixed = *setting == Control::FixedStep.name();
            let (run_grid, extra) = match (controls, fixed) {
                (Some((solver, fixed_step, _)), true) => (grid, vec![(solver, Value::Integer(*code)), (fixed_step, Value::Real(value))]),
                (Some((solver, _, abs_tol)), false) => {
                    (Grid { tolerance: Some(value), ..grid }, vec![(solver, Value::Integer(*code)), (abs_tol, Value::Real(value * 1e-3))])
                }
                (None, true) => (Grid { solver: Solver { method, fixed_step: value, ..Solver::default() }, ..grid }, Vec::new()),
                (None, false) => {
                    let solver = Solver { method, abs_tol: value * 1e-3, ..Solver::default() };
                    (Grid { tolerance: Some(value), solver, ..grid }, Vec::new())
                }
            };
            let started = Instant::now();
            let result = run_once(&mut runs, md, &run_grid, &base, &extra, &compared, &counters);
            let seconds = started.elapsed().as_secs_f64();
            rows.push(match result {
                Ok((samples, n_steps, n_rhs)) => Row {
                    solver: name.clone(),
                    setting,
                    value,
                    n_steps,
                    n_rhs,
                    seconds,
                    error: relative_error(&samples, &reference),
                    status: "ok".into(),
                },
                Err(e) => Row {
                    solver: name.clone(),
                    setting,
                    value,
                    n_steps: f64::NAN,
                    n_rhs: f64::NAN,
                    seconds,
                    error: f64::INFINITY,
                    status: e,
                },
            });
            progress.inc(1);
        }
    }
    drop(progress);

    let mut writer = output::csv_writer(Some(out))?;
    let csv_err = |e: csv::Error| format!("cannot write {}: {e}", out.display());
    writer.write_record(["solver", "setting", "value", "n_steps", "n_rhs", "seconds", "max_relative_error", "status"]).map_err(csv_err)?;
    for r in &rows {
        writer
            .write_record([
                r.solver.clone(),
                r.setting.into(),
                r.value.to_string(),
                r.n_steps.to_string(),
                r.n_rhs.to_string(),
                format!("{:.6}", r.seconds),
                r.error.to_string(),
                r.status.clone(),
            ])
            .map_err(csv_err)?;
    }
    output::finish_csv(writer)?;

    let names: Vec<&str> = compared.iter().map(|v| v.name.as_str()).collect();
    println!("{}: error = max over {} of |y - y_ref| / max|y_ref|, y_ref from {reference_name}", md.model_name, names.join(", "));
    println!("cheapest setting tried that reaches the target error {:e}:", options.target_error);
    println!("{:<8} {:<24} {:>10} {:>12} {:>10} {:>12}", "solver", "setting", "steps", "rhs evals", "time (s)", "error");
    let comparison = Comparison { model: md.model_name.clone(), rows };
    let rows = &comparison.rows;
    for (name, _) in &plan {
        match comparison.cheapest(name, options.target_error) {
            Some(r) => println!(
                "{:<8} {:<24} {:>10} {:>12} {:>10.4} {:>12.3e}",
                name,
                format!("{} = {:e}", r.setting, r.value),
                r.n_steps,
                r.n_rhs,
                r.seconds,
                r.error
            ),
            None => {
                let closest = rows.iter().filter(|r| &r.solver == name).map(|r| r.error).fold(f64::INFINITY, f64::min);
                println!("{name:<8} not reached by any setting tried (smallest error {closest:.3e})");
            }
        }
    }

    let series: Vec<Series> = plan
        .iter()
        .map(|(name, _)| Series {
            label: name.clone(),
            points: rows
                .iter()
                .filter(|r| &r.solver == name && r.error.is_finite() && r.error > 0.0)
                .map(|r| (r.n_rhs.log10(), r.error.log10()))
                .collect(),
        })
        .collect();
    let marks: Vec<Mark> = series
        .iter()
        .filter_map(|s| {
            s.points
                .iter()
                .copied()
                .find(|p| p.1 <= options.target_error.log10())
                .map(|at| Mark { at, text: format!("{} reaches {:e}", s.label, options.target_error) })
        })
        .collect();
    let title = format!("{}: work-precision (error against right-hand-side evaluations)", md.model_name);
    let plot =
        LinePlot { title: &title, x_label: "log10(rhs evaluations)", y_label: "log10(max relative error)", series: &series, marks: &marks };
    report::write_plot(plot_path, &plot)?;
    println!("wrote {} and {}", out.display(), plot_path.display());
    Ok(comparison)
}

#[cfg(test)]
mod tests {
    use super::{relative_error, steps_for, Row, Steps};

    fn row(solver: &str, n_steps: f64, error: f64) -> Row {
        Row { solver: solver.into(), setting: "tolerance", value: 0.0, n_steps, n_rhs: n_steps, seconds: 0.0, error, status: "ok".into() }
    }

    /// On a work-precision line error = C steps^-p (any order p) the interpolation is exact;
    /// the coarsest setting already below the target is a bound, and no setting reaching the
    /// target is `None`.
    #[test]
    fn steps_for_an_error_are_interpolated_on_the_work_precision_line() {
        for p in [1.0, 4.0, 5.0] {
            let rows: Vec<Row> = [100.0, 400.0, 1600.0].iter().map(|&n| row("m", n, 1e3 * f64::powf(n, -p))).collect();
            let target = 1e3 * f64::powf(1000.0, -p);
            let Some(Steps::About(n)) = steps_for(&rows, "m", target) else { panic!("order {p}: no interpolation") };
            assert!((n / 1000.0 - 1.0).abs() < 1e-12, "order {p}: {n}");
            assert_eq!(steps_for(&rows, "m", 1e9), Some(Steps::AtMost(100.0)));
            assert_eq!(steps_for(&rows, "m", target * 1e-12), None);
            assert_eq!(steps_for(&rows, "other", target), None);
        }
    }

    #[test]
    fn error_is_relative_to_each_outputs_peak_and_nan_is_infinite() {
        let reference = vec![vec![1.0, 100.0], vec![2.0, -200.0]];
        let run = vec![vec![1.0, 100.0], vec![2.002, -200.0]];
        assert!((relative_error(&run, &reference) - 1e-3).abs() < 1e-12);
        let run = vec![vec![1.0, f64::NAN], vec![2.0, -200.0]];
        assert_eq!(relative_error(&run, &reference), f64::INFINITY);
        assert_eq!(relative_error(&run[..1], &reference), f64::INFINITY);
    }
}
