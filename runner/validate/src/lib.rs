//! `runner validate`: static and dynamic checks of any FMU, made for CI.
//!
//! Static: the archive (layout, path escapes, a binary for this platform, documentation
//! links), the description (the schema's `check()` and more), the binary's exports. Dynamic:
//! probes that call the FMU (lifecycle, the state machine cell by cell, NULL and unknown
//! arguments, FMU state, variable steps, threads, String variables, reproducibility, Model
//! Exchange events), each in a child process ([`isolation`]) so that a crash or a hang is a
//! finding.
//!
//! The FMI 2.0 set lives in `fmi2/`, the FMI 3.0 set in `fmi3/`, chosen by the description's
//! `fmiVersion`.

// A probe's `Failure` (the findings' call, state, variable, value and log) is 160 bytes; it is
// built once per finding, and boxing it would only add an allocation to the happy path's
// neighbours, which pass it through `?`.
#![allow(clippy::result_large_err)]

mod archive;
mod concurrent;
mod fmi2;
mod fmi3;
mod isolation;
pub mod report;

use std::ffi::OsString;
use std::path::Path;
use std::time::{Duration, Instant};

pub use isolation::Launcher;
pub use report::{to_json, to_junit, Finding, Report, Severity};

/// How to validate.
pub struct Options {
    /// The longest any single FMI call may take before it counts as a hang.
    pub timeout: Duration,
    /// How to start a probe process (see [`probe_main`]).
    pub launcher: Launcher,
    /// Polled while probes run: true to stop (the validation then returns
    /// [`is_interrupted`] as its error).
    pub cancelled: fn() -> bool,
}

/// The default `--timeout`: a few seconds, far above any call of a sane FMU on the grid of its
/// own DefaultExperiment.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

/// True for the error of a validation stopped by [`Options::cancelled`].
pub fn is_interrupted(error: &str) -> bool {
    error == fmi2::INTERRUPTED
}

/// The `fmiVersion` attribute of a description, read without parsing the rest.
fn fmi_version(xml: &str) -> Option<String> {
    let root = xml.find("<fmiModelDescription")?;
    let end = xml[root..].find('>').map_or(xml.len(), |e| root + e);
    let tag = &xml[root..end];
    let at = tag.find("fmiVersion")?;
    let rest = tag[at + "fmiVersion".len()..].trim_start().strip_prefix('=')?.trim_start();
    let quote = rest.chars().next().filter(|q| *q == '"' || *q == '\'')?;
    rest[1..].split(quote).next().map(str::to_owned)
}

/// Validates the FMU at `path`. `Err` when the validation could not run (the FMU file is
/// missing, the validator cannot start its probes, an interrupt); everything wrong
/// with the FMU itself is a finding in the report.
pub fn validate(path: &Path, options: &Options) -> Result<Report, String> {
    let started = Instant::now();
    if !path.is_file() {
        return Err(format!("FMU file {} does not exist", path.display()));
    }
    let work =
        tempfile::Builder::new().prefix("runner-validate-").tempdir().map_err(|e| format!("cannot create a temporary directory: {e}"))?;
    let dir = work.path().join("fmu");
    std::fs::create_dir(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let mut report = Report::new(&path.display().to_string());
    let archive = archive::check_and_extract(path, &dir, &mut report.findings);
    match archive.and_then(|a| a.xml) {
        None => report.findings.push(Finding::skipped("dynamic checks", "not run: the archive or its modelDescription.xml is unusable")),
        Some(xml) => match fmi_version(&xml) {
            Some(v) if v.starts_with('3') => fmi3::validate(&xml, &dir, work.path(), options, &mut report)?,
            _ => fmi2::validate(&xml, &dir, work.path(), options, &mut report)?,
        },
    }
    report.settle();
    report.seconds = started.elapsed().as_secs_f64();
    Ok(report)
}

/// The probe process's entry point: the program a [`Launcher`] starts calls this with the
/// arguments after its own, and exits with the code it returns. Its stdout carries the
/// findings; whatever the FMU prints goes to its stderr.
pub fn probe_main(args: &[OsString]) -> i32 {
    use std::os::fd::FromRawFd;
    // The protocol gets its own descriptor; fd 1 becomes stderr, so an FMU's printf cannot
    // corrupt it.
    // SAFETY: plain descriptor duplication at start-up, before any other thread exists.
    let protocol = unsafe { libc::dup(1) };
    if protocol < 0 || unsafe { libc::dup2(2, 1) } < 0 {
        eprintln!("runner validate probe: cannot set up its output");
        return 3;
    }
    // SAFETY: a descriptor this process just created and owns.
    let out = fmi2::probes_out(unsafe { std::fs::File::from_raw_fd(protocol) });
    // The FMI version's own probes.
    let version = args.iter().position(|a| a == "--fmi").and_then(|i| args.get(i + 1)).map(|v| v.to_string_lossy().into_owned());
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match version.as_deref() {
        Some("2") => fmi2::child(args, &out),
        Some("3") => fmi3::child(args, &out),
        other => Err(format!("no probes for FMI version {other:?}")),
    }));
    match result {
        Ok(Ok(())) => {
            out.send(&isolation::Message::Done);
            0
        }
        Ok(Err(e)) => {
            out.send(&isolation::Message::Internal(e));
            3
        }
        Err(panic) => {
            let text = panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned());
            out.send(&isolation::Message::Internal(format!("panic: {}", text.unwrap_or_default())));
            3
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_version_is_read_from_the_root_element() {
        assert_eq!(super::fmi_version(r#"<?xml version="1.0"?><fmiModelDescription fmiVersion="3.0" x="1">"#).as_deref(), Some("3.0"));
        assert_eq!(super::fmi_version("<fmiModelDescription\n  fmiVersion = '2.0'>").as_deref(), Some("2.0"));
        assert_eq!(super::fmi_version("<fmiModelDescription>"), None);
    }
}
