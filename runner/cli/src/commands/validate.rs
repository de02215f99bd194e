//! `runner validate FMU...`: static and dynamic checks of any FMU (crate fmi-validate), with a
//! readable report on stdout, and JSON and JUnit files for CI. Each probe of an FMU runs in a
//! worker process of the sandbox: this binary started again with the hidden `__validate-probe`
//! command.

use std::path::{Path, PathBuf};
use std::time::Duration;

use fmi_validate::{Report, WorkerCommand};

use crate::experiment;
use crate::interrupt;
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
}

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
            Ok(report) => {
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
