//! `runner linearize`: a Model Exchange FMU (ours or any other) linearized at its initial state
//! or at a time of a simulation, x' = A x + B u, y = C x + D u over its states, continuous Real
//! inputs and outputs: the matrices and where they came from (directional derivatives or
//! central differences), the eigenvalues with each mode's natural frequency and damping ratio,
//! `--out` as JSON, and `--bode INPUT:OUTPUT` frequency responses as CSV and a plot. The
//! computing is the engine's ([`runner_engine::linear`]); this resolves, runs (in a worker
//! process by default, as simulate does, so that a crash is reported with its signal and call)
//! and reports.

use std::path::{Path, PathBuf};

use fmi_importer::call_log::CallLogTarget;
use fmi_importer::exchange::JacobianSource;
use plots::figure::{self, Curve, Figure, Panel};
use plots::trace::short;
use runner_engine::exec::{Held, Runs};
use runner_engine::linear::{self, Complex, Linear, Mode};
use runner_engine::request::{FmuSource, LinearizeRequest};
use runner_engine::run::Grid;
use runner_engine::variables;

use crate::experiment::{self, RunDefaults};
use crate::integration::Integration;
use crate::interrupt;
use crate::report::{self, output};
use crate::workers;

/// Options of `runner linearize`.
#[derive(Default)]
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// Stop time (the latest `--at`), tolerance and assignments.
    pub run: RunDefaults,
    /// The runner's integrator, for a simulation to `--at`.
    pub integration: Integration,
    /// Simulate to this time and linearize there (default: the initial state).
    pub at: Option<f64>,
    /// Central differences even when the FMU provides directional derivatives.
    pub finite_differences: bool,
    /// The JSON file to write.
    pub out: Option<PathBuf>,
    /// `INPUT:OUTPUT` pairs whose frequency responses are written.
    pub bode: Vec<String>,
    /// The frequencies in Hz: `F1,F2,...` or `FROM:TO:COUNT` (log-spaced).
    pub frequencies: Option<String>,
    /// The frequency responses' CSV (default `<identifier>_bode.csv`).
    pub bode_out: Option<PathBuf>,
    /// The frequency responses' plot (`.svg` or `.png`).
    pub plot: Option<PathBuf>,
    /// The linearization fails if it takes longer (seconds; needs a worker process).
    pub timeout: Option<f64>,
    /// Runs the FMU in this process.
    pub in_process: bool,
    /// Log every FMI call there (`--log-fmi-calls`).
    pub log_fmi_calls: Option<CallLogTarget>,
}

/// The frequency responses asked for: (input, output) indices and their names.
struct Pair {
    input: usize,
    output: usize,
    label: String,
}

/// Resolves the options (FMU, grid, assignments), linearizes (in a worker process unless
/// `--in-process`), and reports: `--out`, `--bode`'s CSV and `--plot` first, then stdout, so
/// that a reader that closes stdout early (`| head -1`) costs no file.
pub fn run(options: &Options) -> Result<Linear, String> {
    if options.bode.is_empty() && (options.plot.is_some() || options.bode_out.is_some() || options.frequencies.is_some()) {
        return Err("--plot, --bode-out and --frequencies are for frequency responses: give --bode INPUT:OUTPUT too".to_owned());
    }
    if let Some(plot) = &options.plot {
        report::check_plot(plot)?;
    }
    for path in options.out.iter().chain(&options.bode_out) {
        output::check_destination(path)?;
    }
    crate::workers::create_call_log(options.log_fmi_calls.as_ref())?;
    let timeout = runner_sandbox::timeout("--timeout", options.timeout)?;
    if options.in_process && timeout.is_some() {
        return Err("--timeout needs a worker process (a linearization in this process cannot be stopped): drop --in-process".to_owned());
    }
    let target = experiment::resolve(&options.fmu)?;
    // In a worker, only the description is read here: the FMU's binary runs in the worker alone.
    let (held, source) = open_model_exchange(&target.path, &options.integration, options.in_process)?;
    let (md, identifier) = (held.description(), held.identifier());
    let mut grid = Grid::choose(md, &[options.run.grid(), target.experiment.simulate.grid()])?;
    grid.solver = options.integration.solver()?;
    let mut set_texts = target.experiment.simulate.set.clone();
    set_texts.extend(options.run.set.iter().cloned());
    let assignments = variables::parse_sets(md, &set_texts)?;
    let prefer = if options.finite_differences { JacobianSource::FiniteDifferences } else { JacobianSource::DirectionalDerivatives };
    let request = LinearizeRequest {
        log_fmi_calls: options.log_fmi_calls.clone(),
        ..LinearizeRequest::new(identifier, grid, &assignments, options.at, prefer)
    };
    // Checked before linearizing: the pairs name variables, whatever their values.
    let pairs = bode_pairs(md, &options.bode)?;
    let frequencies = options.frequencies.as_deref().map(parse_frequencies).transpose()?;
    let config = workers::isolation(timeout, runner_sandbox::default_memory_mib(1))?;
    let linear = Runs::new(&held, &config, &source).linearize(&request, &interrupt::requested)?;
    let eigenvalues = linear::eigenvalues(&linear.a)?;
    let modes = linear::modes(&eigenvalues);
    let mut written = Vec::new();
    if let Some(path) = &options.out {
        output::write_file(path, json(&linear, &eigenvalues, &modes).as_bytes())?;
        written.push(path.clone());
    }
    if !pairs.is_empty() {
        let pairs: Vec<Pair> = pairs
            .iter()
            .map(|(i, o)| Ok(Pair { input: linear.input(i)?, output: linear.output(o)?, label: format!("{o}/{i}") }))
            .collect::<Result<_, String>>()?;
        let hz = frequencies.unwrap_or_else(|| {
            let (from, to) = linear::default_range(&modes);
            let decades = (to / from).log10().round().max(1.0) as usize;
            linear::log_spaced(from, to, 50 * decades + 1).iter().map(|w| w / std::f64::consts::TAU).collect()
        });
        let omegas: Vec<f64> = hz.iter().map(|f| std::f64::consts::TAU * f).collect();
        let responses: Vec<Vec<Complex<f64>>> =
            pairs.iter().map(|p| linear.frequency_response(p.input, p.output, &omegas)).collect::<Result<_, String>>()?;
        let csv_path = options.bode_out.clone().unwrap_or_else(|| PathBuf::from(format!("{identifier}_bode.csv")));
        write_bode(&csv_path, &pairs, &hz, &omegas, &responses)?;
        written.push(csv_path);
        if let Some(path) = &options.plot {
            report::write_plot(path, &bode_figure(identifier, &pairs, &hz, &responses))?;
            written.push(path.clone());
        }
    }
    print_summary(&summary(identifier, &linear, &modes))?;
    for path in written {
        eprintln!("wrote {}", path.display());
    }
    Ok(linear)
}

/// Writes `text` to stdout. A reader that closed it (`| head -1`) is not an error: it has read
/// what it wanted, and the files are written already.
fn print_summary(text: &str) -> Result<(), String> {
    use std::io::Write;
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(format!("cannot write to standard output: {e}")),
        _ => Ok(()),
    }
}

/// Opens the FMU at `path` for Model Exchange (loaded here when `in_process`, else only
/// described), refusing one that does not offer it.
fn open_model_exchange(path: &Path, integration: &Integration, in_process: bool) -> Result<(Held, FmuSource), String> {
    workers::open(path, integration, in_process).map_err(|e| {
        if e.contains("does not support Model Exchange") {
            format!(
                "{}: runner linearize needs Model Exchange (the states and their derivatives), and this FMU offers Co-Simulation only",
                path.display()
            )
        } else {
            e
        }
    })
}

/// `--bode INPUT:OUTPUT` pairs, each name checked against the FMU's continuous Real inputs and
/// outputs.
fn bode_pairs(description: &fmi_importer::Description, texts: &[String]) -> Result<Vec<(String, String)>, String> {
    texts
        .iter()
        .map(|text| {
            let (input, output) =
                text.split_once(':').ok_or_else(|| format!("--bode {text}: give INPUT:OUTPUT, an input and an output of the FMU"))?;
            let (input, output) = (input.trim(), output.trim());
            for (name, what) in [(input, "input"), (output, "output")] {
                let v = variables::find(description, name).map_err(|e| format!("--bode {text}: {e}"))?;
                let causality = if what == "input" { fmi_importer::Causality::Input } else { fmi_importer::Causality::Output };
                if v.causality != causality || v.kind != fmi_importer::Kind::Real || v.variability != fmi_importer::Variability::Continuous
                {
                    return Err(format!("--bode {text}: '{name}' is not a continuous Real {what} of the FMU"));
                }
            }
            Ok((input.to_owned(), output.to_owned()))
        })
        .collect()
}

/// `--frequencies` in Hz: `F1,F2,...` or `FROM:TO:COUNT`, log-spaced; every one positive.
fn parse_frequencies(text: &str) -> Result<Vec<f64>, String> {
    let number = |s: &str| -> Result<f64, String> {
        s.trim()
            .parse::<f64>()
            .ok()
            .filter(|f| f.is_finite() && *f > 0.0)
            .ok_or_else(|| format!("--frequencies {text}: '{}' is not a positive frequency in Hz", s.trim()))
    };
    if text.contains(':') {
        let parts: Vec<&str> = text.split(':').collect();
        let [from, to, count] = parts[..] else {
            return Err(format!("--frequencies {text}: a range is FROM:TO:COUNT (Hz, Hz, points spaced evenly in log)"));
        };
        let (from, to) = (number(from)?, number(to)?);
        let count: usize = count
            .trim()
            .parse()
            .ok()
            .filter(|n| (2..=1_000_000).contains(n))
            .ok_or_else(|| format!("--frequencies {text}: COUNT must be a whole number from 2 to 1000000"))?;
        if to <= from {
            return Err(format!("--frequencies {text}: TO must be above FROM"));
        }
        Ok(linear::log_spaced(from, to, count))
    } else {
        text.split(',').map(number).collect()
    }
}

/// A number with six significant digits, as a table shows it.
fn num(x: f64) -> String {
    if x == 0.0 {
        "0".to_owned()
    } else if (1e-3..1e6).contains(&x.abs()) {
        let decimals = (5 - x.abs().log10().floor() as i32).max(0) as usize;
        format!("{x:.decimals$}")
    } else {
        format!("{x:.5e}")
    }
}

/// What stdout shows: where, how, the modes, and the matrices with their rows and columns named.
fn summary(identifier: &str, l: &Linear, modes: &[Mode]) -> String {
    let mut s = format!("{identifier} linearized at t = {} from {}\n", short(l.time), l.source.text());
    s.push_str(&format!("states:  {}\n", names(&l.states)));
    s.push_str(&format!("inputs:  {}\n", names(&l.inputs)));
    s.push_str(&format!("outputs: {}\n\n", names(&l.outputs)));
    s.push_str(&format!("{:<30} {:>14} {:>14} {:>14}\n", "eigenvalue", "wn (rad/s)", "wn (Hz)", "damping ratio"));
    for m in modes {
        let e = m.eigenvalue;
        let value = if e.im > 0.0 { format!("{} ± {}i", num(e.re), num(e.im)) } else { num(e.re) };
        let zeta = m.damping_ratio.map_or("-".to_owned(), num);
        s.push_str(&format!(
            "{value:<30} {:>14} {:>14} {zeta:>14}\n",
            num(m.natural_frequency),
            num(m.natural_frequency / std::f64::consts::TAU)
        ));
    }
    for (name, m, rows, columns) in [
        ("A", &l.a, &l.states, &l.states),
        ("B", &l.b, &l.states, &l.inputs),
        ("C", &l.c, &l.outputs, &l.states),
        ("D", &l.d, &l.outputs, &l.inputs),
    ] {
        if rows.is_empty() || columns.is_empty() {
            continue;
        }
        s.push_str(&format!("\n{name} (rows: {}; columns: {})\n", if name < "C" { "der(states)" } else { "outputs" }, names(columns)));
        for (label, row) in rows.iter().zip(m.iter()) {
            let cells: Vec<String> = row.iter().map(|v| format!("{:>13}", num(*v))).collect();
            s.push_str(&format!("  {label:<14}{}\n", cells.join(" ")));
        }
    }
    s
}

fn names(list: &[String]) -> String {
    if list.is_empty() {
        "none".to_owned()
    } else {
        list.join(", ")
    }
}

/// `--out`'s JSON: the names, the matrices (arrays of rows), the eigenvalues, the modes and the
/// source.
fn json(l: &Linear, eigenvalues: &[Complex<f64>], modes: &[Mode]) -> String {
    let value = serde_json::json!({
        "time": l.time,
        "states": l.states,
        "x": l.x,
        "inputs": l.inputs,
        "outputs": l.outputs,
        "A": l.a,
        "B": l.b,
        "C": l.c,
        "D": l.d,
        "eigenvalues": eigenvalues.iter().map(|e| serde_json::json!({"re": e.re, "im": e.im})).collect::<Vec<_>>(),
        "modes": modes.iter().map(|m| serde_json::json!({
            "re": m.eigenvalue.re,
            "im": m.eigenvalue.im,
            "natural_frequency": m.natural_frequency,
            "damping_ratio": m.damping_ratio,
        })).collect::<Vec<_>>(),
        "source": l.source.text(),
    });
    let mut text = serde_json::to_string_pretty(&value).expect("numbers and names serialize");
    text.push('\n');
    text
}

/// Phases in degrees, unwrapped along the frequencies (no jump of more than 180 degrees).
fn unwrapped_phases(response: &[Complex<f64>]) -> Vec<f64> {
    let mut phases: Vec<f64> = Vec::with_capacity(response.len());
    for h in response {
        let mut p = h.arg().to_degrees();
        if let Some(&last) = phases.last() {
            p += 360.0 * ((last - p) / 360.0).round();
        }
        phases.push(p);
    }
    phases
}

/// The CSV: `frequency_hz`, `omega_rad_s`, then per pair `magnitude(OUT/IN)` and
/// `phase_deg(OUT/IN)` (unwrapped).
fn write_bode(path: &Path, pairs: &[Pair], hz: &[f64], omegas: &[f64], responses: &[Vec<Complex<f64>>]) -> Result<(), String> {
    let mut writer = output::csv_writer(Some(path))?;
    let mut header = vec!["frequency_hz".to_owned(), "omega_rad_s".to_owned()];
    for p in pairs {
        header.push(format!("magnitude({})", p.label));
        header.push(format!("phase_deg({})", p.label));
    }
    let cannot = |e: csv::Error| format!("cannot write {}: {e}", path.display());
    writer.write_record(&header).map_err(cannot)?;
    let phases: Vec<Vec<f64>> = responses.iter().map(|r| unwrapped_phases(r)).collect();
    for k in 0..hz.len() {
        let mut row = vec![format!("{:?}", hz[k]), format!("{:?}", omegas[k])];
        for (r, p) in responses.iter().zip(&phases) {
            row.push(format!("{:?}", r[k].norm()));
            row.push(format!("{:?}", p[k]));
        }
        writer.write_record(&row).map_err(cannot)?;
    }
    output::finish_csv(writer)
}

/// Magnitude (log) and phase against frequency (log), one curve per pair.
fn bode_figure(identifier: &str, pairs: &[Pair], hz: &[f64], responses: &[Vec<Complex<f64>>]) -> Figure {
    let x: Vec<f64> = hz.iter().map(|f| f.log10()).collect();
    let magnitude = Panel {
        x_label: "frequency (Hz)".into(),
        y_label: "magnitude".into(),
        log_x: true,
        log_y: true,
        curves: pairs
            .iter()
            .zip(responses)
            .enumerate()
            .map(|(i, (p, r))| {
                Curve::line(p.label.clone(), x.iter().zip(r).map(|(x, h)| (*x, h.norm().log10())).collect(), figure::color(i))
            })
            .collect(),
        ..Panel::default()
    };
    let phase = Panel {
        x_label: "frequency (Hz)".into(),
        y_label: "phase (deg)".into(),
        log_x: true,
        curves: pairs
            .iter()
            .zip(responses)
            .enumerate()
            .map(|(i, (p, r))| Curve::line(p.label.clone(), x.iter().copied().zip(unwrapped_phases(r)).collect(), figure::color(i)))
            .collect(),
        ..Panel::default()
    };
    Figure::column(Some(format!("{identifier}: frequency response")), vec![magnitude, phase], (900, 360))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frequencies_are_lists_or_log_ranges_of_positive_hz() {
        assert_eq!(parse_frequencies("0.5, 2").unwrap(), [0.5, 2.0]);
        let r = parse_frequencies("0.1:10:3").unwrap();
        assert!((r[1] - 1.0).abs() < 1e-12 && (r[2] - 10.0).abs() < 1e-12, "{r:?}");
        assert!(parse_frequencies("0:10:3").unwrap_err().contains("'0' is not a positive frequency"));
        assert!(parse_frequencies("1:10").unwrap_err().contains("FROM:TO:COUNT"));
        assert!(parse_frequencies("10:1:5").unwrap_err().contains("TO must be above FROM"));
    }

    /// A phase that crosses -180 degrees goes on to -190, not back to +170.
    #[test]
    fn phases_are_unwrapped() {
        let r = [Complex::from_polar(1.0, (-170f64).to_radians()), Complex::from_polar(1.0, (170f64).to_radians())];
        let p = unwrapped_phases(&r);
        assert!((p[0] + 170.0).abs() < 1e-9 && (p[1] + 190.0).abs() < 1e-9, "{p:?}");
    }
}
