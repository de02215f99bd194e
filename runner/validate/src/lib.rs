//! `runner validate`: static and dynamic checks of any FMU, made for CI.
//!
//! Static: the archive (layout, path escapes, a binary for this platform, documentation
//! links), the description (the schema's `check()` and more), the binary's exports. Dynamic:
//! probes that call the FMU (lifecycle, the state machine cell by cell, NULL and unknown
//! arguments, FMU state, variable steps, threads, String variables, reproducibility, Model
//! Exchange events), each in a worker process of the runner's sandbox (`isolation`) so that
//! a crash or a hang is a finding.
//!
//! The probes are written once for FMI 2.0 and 3.0 (`probes`, over the framework of
//! `probe`); what differs between the versions is each version's module (`fmi2`,
//! `fmi3`): its C calls behind the `instance` traits, its state table as data
//! (`table`), its description's rules. The layers, from the bottom:
//!
//! - `fmi`, `model`, `failure`, `report`: the words both versions share.
//! - `isolation`: the validator's service of the sandbox (crate `runner-sandbox`): a probe as a
//!   job, its messages and outcomes, the call records in the memory each worker shares.
//! - `instance`, `table`: an FMU binary and its instances as the probes call them; the shape
//!   of a state table. `fmi2`, `fmi3` implement them.
//! - `exchange`, `run`: runs through the DefaultExperiment (Model Exchange integrated with
//!   state events located by bisection).
//! - `probe`, `probes`: the framework, and the probes.
//! - `parent` (the validator's side) and `child` (the probe process's).

// A probe's `Failure` (the findings' call, state, variable, value and log) is 160 bytes; it is
// built once per finding, and boxing it would only add an allocation to the happy path's
// neighbours, which pass it through `?`.
#![allow(clippy::result_large_err)]

mod archive;
mod child;
mod exchange;
mod failure;
mod fmi;
mod fmi1;
mod fmi2;
mod fmi3;
mod instance;
mod isolation;
mod model;
mod parent;
mod probe;
mod probes;
pub mod report;
mod run;
mod table;
#[cfg(test)]
mod testing;

use std::path::Path;
use std::time::{Duration, Instant};

pub use report::{to_json, to_junit, Finding, Report, Severity};
pub use runner_sandbox::WorkerCommand;

/// How to validate.
pub struct Options {
    /// The longest any single FMI call may take before it counts as a hang.
    pub timeout: Duration,
    /// How to start a probe process (see [`probe_worker`]).
    pub command: WorkerCommand,
    /// Polled while probes run: true to stop (the validation then returns
    /// [`is_interrupted`] as its error).
    pub cancelled: fn() -> bool,
}

/// The default `--timeout`: a few seconds, far above any call of a sane FMU on the grid of its
/// own DefaultExperiment.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);

/// True for the error of a validation stopped by [`Options::cancelled`].
pub fn is_interrupted(error: &str) -> bool {
    error == parent::INTERRUPTED
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
        Some(xml) => {
            let fmi = parent::version_of(fmi_version(&xml).as_deref());
            parent::validate(fmi, &xml, &dir, work.path(), options, &mut report)?
        }
    }
    report.settle();
    report.seconds = started.elapsed().as_secs_f64();
    Ok(report)
}

/// What the static checks of the description `xml` find against the standard (the errors
/// `runner validate` reports for it: the schema's rules, the GUID or instantiation token, the
/// ModelStructure), without the archive or the binary: for a warning before a run. A
/// description that cannot be read at all is one problem.
pub fn description_problems(xml: &str) -> Vec<String> {
    let declared = match fmi_version(xml) {
        Some(v) if v.starts_with('3') => fmi3::description::declared(xml),
        Some(v) if v.starts_with('1') => {
            return match fmi_schema::fmi1::ModelDescription::from_xml(xml) {
                Ok(md) => md.check(),
                Err(e) => vec![format!("modelDescription.xml cannot be read: {e}")],
            }
        }
        _ => fmi2::description::declared(xml),
    };
    match declared {
        Ok(declared) => declared.findings.into_iter().filter(|f| f.severity == Severity::Error).map(|f| f.message).collect(),
        Err(e) => vec![format!("modelDescription.xml cannot be read: {e}")],
    }
}

/// [`description_problems`] of the modelDescription.xml in the `.fmu` archive `fmu` (none when
/// it cannot be read again: the importer has read it before).
pub fn archive_description_problems(fmu: &Path) -> Vec<String> {
    use std::io::Read;
    let xml = (|| {
        let mut archive = zip::ZipArchive::new(std::fs::File::open(fmu).ok()?).ok()?;
        let entry = archive.by_name("modelDescription.xml").ok()?;
        let mut xml = String::new();
        // Far above any real description (the largest Reference FMU's is 30 kB).
        entry.take(256 << 20).read_to_string(&mut xml).ok()?;
        Some(xml)
    })();
    xml.map(|xml| description_problems(&xml)).unwrap_or_default()
}

/// The probe process: the program [`Options::command`] starts runs this and exits with the
/// code it returns (0 when its supervisor let it go, 1 when it could not serve). It is a worker
/// of the runner's sandbox: its jobs arrive and its findings leave on descriptors of their own,
/// and whatever the FMU prints goes to the validation's log.
pub fn probe_worker() -> i32 {
    match child::serve() {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("runner validate probe: {e}");
            1
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
