//! `runner compare`: Ex. 4's question "which solver is cheapest for a given accuracy?",
//! answered through the FMI interface alone: each run sets the toolkit's solver controls
//! (`solver`, `fixed_step`, tolerance, `abs_tol`) and reads the counters `n_steps`, `n_rhs`.
//! Errors are measured against the model's closed-form solution where its experiment.toml gives
//! one (`[compare.reference]`), else against DOPRI5 at a tolerance far below the table's.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use fmi_importer::{Causality, Description, Fmu, Kind, Value, Variability, Variable};
use runner_engine::metrics::Formula;
use runner_engine::run::{self as sim, Grid};
use runner_engine::variables;
use solvers::controls::Control;
use solvers::Method;

use crate::experiment::{self, RunDefaults};
use crate::interrupt;
use crate::report::output;
use crate::report::plot::{self, Mark, Series};
use crate::report::progress::Progress;

/// Relative tolerance of the reference run (DOPRI5): far below any error the table reports.
pub const REFERENCE_RTOL: f64 = 1e-12;

/// Options of `runner compare`.
pub struct Options {
    /// Model name or `.fmu` path (an FMU of this toolkit: it needs the solver controls).
    pub fmu: String,
    /// Solvers to compare, by name: euler, rk4, dopri5.
    pub solvers: Vec<String>,
    /// The error each solver must reach (max over outputs of the error relative to the output's peak).
    pub target_error: f64,
    /// Grid and assignments from the command line.
    pub run: RunDefaults,
    /// Work-precision table (CSV).
    pub out: PathBuf,
    /// Work-precision plot (SVG).
    pub plot: PathBuf,
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
/// RK4 by 2x, matching their orders), DOPRI5 tolerances by decades.
fn settings(solver: &str, interval: f64) -> Result<Trials, String> {
    let method = Method::from_name(solver).ok_or_else(|| {
        let names: Vec<&str> = Method::ALL.iter().map(|m| m.name()).collect();
        format!("unknown solver '{solver}': use {}", names.join(", "))
    })?;
    Ok(match method {
        Method::Euler => (method.code(), Control::FixedStep.name(), (0..8).map(|k| interval / 4f64.powi(k)).collect()),
        Method::Rk4 => (method.code(), Control::FixedStep.name(), (0..6).map(|k| interval / 2f64.powi(k)).collect()),
        Method::Dopri5 | Method::Bs23 | Method::Dop853 => (method.code(), "tolerance", (3..=11).map(|k| 10f64.powi(-k)).collect()),
    })
}

fn control(description: &Description, control: Control) -> Result<&Variable, String> {
    let name = control.name();
    description.variable(name).ok_or_else(|| {
        format!("{} has no variable '{name}': `runner compare` needs the solver controls of this toolkit's FMUs", description.model_name)
    })
}

/// Runs one setting; returns the sampled compared outputs and the final counters.
fn run_once(
    fmu: &Fmu,
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
    let outcome = sim::run(fmu, "compare", grid, &assignments, &recorded, false, |_, values| {
        samples.push(values[..n].to_vec());
        last = (values[n], values[n + 1]);
        Ok(())
    })?;
    if let Some(reason) = outcome.ended_early {
        return Err(format!("the run ended early: {reason}"));
    }
    Ok((samples, last.0, last.1))
}

/// The outputs named in `[compare.reference]` and their exact values on the grid. A formula
/// reads `t` and parameters: their start values, overridden by the assignments `base`.
fn closed_form<'a>(
    md: &'a Description,
    formulas: &BTreeMap<String, String>,
    base: &[(&Variable, Value)],
    grid: &Grid,
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
                Some(Value::Real(x)) => Some(*x),
                Some(Value::Integer(i)) => Some(*i as f64),
                Some(Value::Boolean(b)) => Some(*b as i32 as f64),
                Some(Value::String(_)) => None,
                None => variable.start.as_ref().and_then(|s| s.as_number()),
            };
            bound.push(Some(value.ok_or_else(|| format!("[compare.reference] {output}: parameter '{name}' has no numeric value"))?));
        }
        compared.push(v);
        parsed.push((formula, bound));
    }
    let mut values = Vec::new();
    let reference = (0..=grid.steps())
        .map(|i| {
            let t = grid.time(i);
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

/// Runs the comparison and returns the table (also written to CSV and SVG).
pub fn run(options: &Options) -> Result<Vec<Row>, String> {
    if !(options.target_error.is_finite() && options.target_error > 0.0) {
        return Err(format!("--target-error {} must be a positive number", options.target_error));
    }
    // Both files are written after the runs.
    output::check_destination(&options.out)?;
    output::check_destination(&options.plot)?;
    let target = experiment::resolve(&options.fmu)?;
    let fmu = Fmu::load(&target.path)?;
    let md = &fmu.description;
    let grid = Grid::choose(md, &[options.run.grid(), target.experiment.simulate.grid()])?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(target.experiment.compare.set.iter().cloned());
    set_texts.extend(options.run.set.iter().cloned());
    let base = variables::parse_sets(md, &set_texts)?;
    let (solver, fixed_step, abs_tol) = (control(md, Control::Solver)?, control(md, Control::FixedStep)?, control(md, Control::AbsTol)?);
    let counters = [control(md, Control::NSteps)?, control(md, Control::NRhs)?];
    let compared: Vec<&Variable> = md.outputs().filter(|v| v.kind == Kind::Real && v.variability == Variability::Continuous).collect();
    if compared.is_empty() {
        return Err(format!("{} has no continuous Real outputs to compare", md.model_name));
    }
    let plan: Vec<(String, Trials)> =
        options.solvers.iter().map(|s| settings(s.trim(), grid.interval).map(|p| (s.trim().to_owned(), p))).collect::<Result<_, _>>()?;

    let analytical = &target.experiment.compare;
    let (compared, reference, reference_name) = if analytical.reference.is_empty() || !options.run.set.is_empty() {
        if !analytical.reference.is_empty() {
            eprintln!("note: the closed-form reference in experiment.toml holds for its own parameter values; with --set the reference is DOPRI5 at rtol {REFERENCE_RTOL:e}");
        }
        let reference_grid = Grid { tolerance: Some(REFERENCE_RTOL), ..grid };
        let reference_settings = [(solver, Value::Integer(Method::Dopri5.code())), (abs_tol, Value::Real(REFERENCE_RTOL * 1e-2))];
        let (reference, _, _) = run_once(&fmu, &reference_grid, &base, &reference_settings, &compared, &counters)
            .map_err(|e| format!("the reference run (DOPRI5 at rtol {REFERENCE_RTOL}) failed: {e}"))?;
        (compared, reference, format!("DOPRI5 at rtol {REFERENCE_RTOL:e}"))
    } else {
        let (compared, reference) = closed_form(md, &analytical.reference, &base, &grid)?;
        (compared, reference, "the closed-form solution of experiment.toml".to_owned())
    };

    let mut rows = Vec::new();
    let progress = Progress::start(plan.iter().map(|(_, (_, _, v))| v.len() as u64).sum(), "runs");
    for (name, (code, setting, values)) in &plan {
        for &value in values {
            if interrupt::requested() {
                return Err(format!("interrupted after {} runs; no file written", rows.len()));
            }
            let (run_grid, extra) = if *setting == Control::FixedStep.name() {
                (grid, vec![(solver, Value::Integer(*code)), (fixed_step, Value::Real(value))])
            } else {
                (Grid { tolerance: Some(value), ..grid }, vec![(solver, Value::Integer(*code)), (abs_tol, Value::Real(value * 1e-3))])
            };
            let started = Instant::now();
            let result = run_once(&fmu, &run_grid, &base, &extra, &compared, &counters);
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

    let mut writer = output::csv_writer(Some(&options.out))?;
    let csv_err = |e: csv::Error| format!("cannot write {}: {e}", options.out.display());
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
    for (name, _) in &plan {
        let best = rows.iter().filter(|r| &r.solver == name && r.error <= options.target_error).min_by(|a, b| a.n_rhs.total_cmp(&b.n_rhs));
        match best {
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
    plot::lines(
        &options.plot,
        &format!("{}: work-precision (error against right-hand-side evaluations)", md.model_name),
        "log10(rhs evaluations)",
        "log10(max relative error)",
        &series,
        &marks,
    )?;
    println!("wrote {} and {}", options.out.display(), options.plot.display());
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::relative_error;

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
