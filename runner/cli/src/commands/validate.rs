//! `runner validate FMU...`: static and dynamic checks of any FMU (crate fmi-validate), with a
//! readable report on stdout, and JSON and JUnit files for CI. Each probe of an FMU runs in a
//! worker process of the sandbox: this binary started again with the hidden `__validate-probe`
//! command.

use std::path::{Path, PathBuf};
use std::time::Duration;

use fmi_validate::{Finding, Report, Severity, WorkerCommand};

use crate::commands::simulate;
use crate::experiment::{self, Target};
use crate::interrupt;
use crate::reference;
use crate::report::output;

/// The hidden command a probe process runs.
pub const PROBE_COMMAND: &str = "__validate-probe";

/// Exit code when every FMU is clean.
pub const CLEAN: i32 = 0;
/// Exit code when some FMU has errors (or warnings, with `--strict`).
pub const FAILED: i32 = 1;
/// Exit code when some FMU could not be validated at all.
pub const COULD_NOT_RUN: i32 = 2;

/// The options of `runner validate`.
pub struct Options {
    /// FMU files or model names of this workspace.
    pub fmus: Vec<String>,
    /// Seconds any one FMI call may take.
    pub timeout: Option<f64>,
    /// Write the findings as JSON here.
    pub report: Option<PathBuf>,
    /// Write a JUnit XML file here.
    pub junit: Option<PathBuf>,
    /// Warnings fail the run too.
    pub strict: bool,
    /// Check a run of each FMU against these reference results (`--reference-file`); without
    /// it, against the result an FMU ships under LS-REF, if it ships one.
    pub reference_file: Option<PathBuf>,
    /// The tolerances of the reference check (`--rtol`, `--atol`).
    pub rtol: Option<f64>,
    pub atol: Option<f64>,
}

/// The reference check's name in the reports.
const REFERENCE_CHECK: &str = "reference-result";

/// The timeout in seconds as a duration, refused unless it is a positive number.
fn timeout(seconds: Option<f64>) -> Result<Duration, String> {
    match seconds {
        None => Ok(fmi_validate::DEFAULT_TIMEOUT),
        Some(s) if s.is_finite() && s > 0.0 && s <= 86_400.0 => Ok(Duration::from_secs_f64(s)),
        Some(s) => Err(format!("--timeout {s}: the timeout must be a number of seconds above 0 (and at most a day)")),
    }
}

/// Runs the command; returns the exit code (0 clean, 1 errors, 2 could not run, 130 on
/// Ctrl-C).
pub fn run(options: &Options) -> i32 {
    match validate_all(options) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            if interrupt::requested() {
                interrupt::EXIT_CODE
            } else {
                COULD_NOT_RUN
            }
        }
    }
}

fn validate_all(options: &Options) -> Result<i32, String> {
    if options.fmus.is_empty() {
        return Err("name at least one FMU to validate".to_owned());
    }
    let timeout = timeout(options.timeout)?;
    if options.reference_file.is_none() && (options.rtol.is_some() || options.atol.is_some()) {
        return Err("--rtol and --atol are the tolerances of --reference-file: give it too".to_owned());
    }
    let tube = reference::Tube::new(options.rtol, options.atol)?;
    // Read once, before any FMU is validated, so a missing or malformed file costs no run.
    let given = options.reference_file.as_deref().map(reference::Reference::read).transpose()?;
    for path in [&options.report, &options.junit].into_iter().flatten() {
        output::check_destination(path)?;
    }
    let validate_options =
        fmi_validate::Options { timeout, command: WorkerCommand::this_program(&[PROBE_COMMAND])?, cancelled: interrupt::requested };
    let mut reports: Vec<Report> = Vec::new();
    let mut could_not_run = false;
    for fmu in &options.fmus {
        let path = match experiment::resolve(fmu) {
            Ok(target) => target.path,
            Err(e) => {
                eprintln!("error: {e}");
                could_not_run = true;
                continue;
            }
        };
        match fmi_validate::validate(&path, &validate_options) {
            Ok(mut report) => {
                if let Some(finding) = reference_finding(&path, &report, given.as_ref(), tube) {
                    report.findings.push(finding);
                }
                if interrupt::requested() {
                    return Err(format!("interrupted while validating {}; no report written", path.display()));
                }
                print!("{}", report.to_text());
                reports.push(report);
            }
            Err(e) if fmi_validate::is_interrupted(&e) || interrupt::requested() => {
                return Err(format!("interrupted while validating {}; no report written", path.display()));
            }
            Err(e) => {
                eprintln!("error: {}: {e}", Path::new(fmu).display());
                could_not_run = true;
            }
        }
    }
    if let Some(path) = &options.report {
        output::write_file(path, fmi_validate::to_json(&reports).as_bytes())?;
    }
    if let Some(path) = &options.junit {
        output::write_file(path, fmi_validate::to_junit(&reports, options.strict).as_bytes())?;
    }
    let failing = reports.iter().filter(|r| r.fails(options.strict)).count();
    if options.fmus.len() > 1 {
        println!(
            "validated {} of {} FMU(s): {} clean, {failing} with {}",
            reports.len(),
            options.fmus.len(),
            reports.len() - failing,
            if options.strict { "errors or warnings" } else { "errors" }
        );
    }
    Ok(if could_not_run {
        COULD_NOT_RUN
    } else if failing > 0 {
        FAILED
    } else {
        CLEAN
    })
}

/// The reference check of the FMU at `fmu`: a run as `runner simulate` makes it by default,
/// checked against `given` (`--reference-file`), else against the result the FMU ships under
/// LS-REF; `None` when there is neither.
///
/// Against `--reference-file` a failure is an error: the user named the results the FMU must
/// reproduce. Against the FMU's own LS-REF result it is a warning (`--strict` fails on it): the
/// layered standard (1.0.0-alpha.1) declares no tolerance, so the tube is ours, not the
/// vendor's, and a result computed with a looser solver than the runner's may leave it without
/// the FMU breaking any rule; an unusable manifest (one naming a file the FMU does not hold) is
/// a warning for the same reason: LS-REF is an optional add-on, not part of FMI.
///
/// The run has no time limit of its own: it is made only when the validator's runs through the
/// DefaultExperiment (`lifecycle.run`, each FMI call under `--timeout`) went through, so a hang
/// or a crash there is that check's finding and this one is skipped.
fn reference_finding(fmu: &Path, report: &Report, given: Option<&reference::Reference>, tube: reference::Tube) -> Option<Finding> {
    let shipped;
    let (checked, severity) = match given {
        Some(given) => (given, Severity::Error),
        None => {
            shipped = match reference::shipped(fmu)
                .and_then(|s| s.map(|(label, text)| reference::Reference::parse(&text, &label)).transpose())
            {
                Ok(None) => return None,
                Ok(Some(shipped)) => shipped,
                Err(e) => return Some(Finding::warning(REFERENCE_CHECK, format!("the FMU's LS-REF reference result is not checked: {e}"))),
            };
            (&shipped, Severity::Warning)
        }
    };
    let fail = |message: String| Finding::new(REFERENCE_CHECK, severity, message);
    let run = |severity: Severity| report.findings.iter().any(|f| f.check == "lifecycle.run" && f.severity == severity);
    if run(Severity::Error) || !run(Severity::Passed) {
        return Some(Finding::skipped(
            REFERENCE_CHECK,
            "not run: the validator's own run through the DefaultExperiment failed (lifecycle.run)",
        ));
    }
    let work = match tempfile::Builder::new().prefix("runner-validate-reference-").tempdir() {
        Ok(work) => work,
        Err(e) => return Some(fail(format!("not run: cannot create a temporary directory: {e}"))),
    };
    // The run `runner simulate FMU --reference-file` makes, its CSV kept out of the report.
    let options =
        simulate::Options { fmu: fmu.display().to_string(), out: Some(work.path().join("run.csv")), ..simulate::Options::default() };
    let target = Target { path: fmu.to_path_buf(), experiment: Default::default() };
    // The FMU's messages during this run are not the report's (the run's error keeps its reason).
    let printer = fmi_importer::set_log_printer(|_| {});
    let outcome = simulate::simulate(&options, &target, Some(checked), tube, &mut || {})
        .and_then(|o| o.ok_or_else(|| "no check was made".to_owned()));
    fmi_importer::set_log_printer(printer);
    Some(match outcome {
        Err(e) => fail(format!("the run to compare with {} failed: {e}", checked.label)),
        Ok(Ok(verdict)) => Finding::passed(REFERENCE_CHECK, format!("the run matches {}", simulate::passed(&verdict, checked, tube))),
        Ok(Err(reference::Mismatch::Incomparable(message))) => fail(message),
        Ok(Err(reference::Mismatch::Outside(v))) => fail(v.message)
            .variable(v.column)
            .value(format!("{} at t = {} s (reference {}, bound {:e})", v.value, v.time, v.reference, v.bound)),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_timeout_must_be_positive() {
        assert_eq!(timeout(None).unwrap(), fmi_validate::DEFAULT_TIMEOUT);
        assert_eq!(timeout(Some(0.5)).unwrap(), Duration::from_millis(500));
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(timeout(Some(bad)).unwrap_err().contains("above 0"), "{bad}");
        }
    }
}
