//! The validator's side, the same for both versions: the description's static checks (each
//! version's), the binaries the declared interfaces name, then every probe in child processes,
//! interface by interface, resuming after a crash where the probe allows it, and what a child
//! that died or hung means as a finding.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::fmi::{Fmi, Interface};
use crate::isolation::{CallRecord, End, Job, Message, Outcome, Supervisor};
use crate::model::Declared;
use crate::probe::{after_lifecycle, first_check, reference_path, resumable};
use crate::report::{Finding, Report, Severity};
use crate::table::Table;
use crate::{fmi2, fmi3, Options};

/// The message of an interrupted validation (the command line exits with 130 on it).
pub(crate) const INTERRUPTED: &str = "interrupted";

/// The version a description's `fmiVersion` names (FMI 2.0 unless it says 3 or 1).
pub(crate) fn version_of(fmi_version: Option<&str>) -> Fmi {
    match fmi_version {
        Some(v) if v.starts_with('3') => Fmi::Fmi3,
        Some(v) if v.starts_with('1') => Fmi::Fmi1,
        _ => Fmi::Fmi2,
    }
}

/// What the validator needs of a version.
struct Version {
    fmi: Fmi,
    /// Its platform folder for this machine.
    platform: &'static str,
    table: &'static Table,
}

/// Validates the FMU unpacked in `dir` (its description `xml`, of version `fmi`), adding to
/// `report`; `Err` when the validation could not run.
pub(crate) fn validate(fmi: Fmi, xml: &str, dir: &Path, work: &Path, options: &Options, report: &mut Report) -> Result<(), String> {
    let (declared, version) = match fmi {
        // FMI 1.0 has checks of its own (no probes).
        Fmi::Fmi1 => return crate::fmi1::validate(xml, dir, work, options, report),
        Fmi::Fmi2 => (fmi2::description::declared(xml), Version { fmi, platform: fmi2::PLATFORM, table: &fmi2::table::TABLE }),
        Fmi::Fmi3 => (fmi3::description::declared(xml), Version { fmi, platform: fmi3::PLATFORM, table: &fmi3::table::TABLE }),
    };
    let declared: Declared = match declared {
        Ok(declared) => declared,
        Err(e) => {
            report.findings.push(Finding::error("description.xml", format!("modelDescription.xml cannot be read: {e}")));
            report.findings.push(Finding::skipped("dynamic checks", "not run: there is no usable modelDescription.xml"));
            return Ok(());
        }
    };
    report.fmi_version = Some(declared.fmi_version.clone());
    report.model_name = Some(declared.model_name.clone());
    report.findings.extend(declared.findings);
    report.interfaces = declared.interfaces.iter().map(|(i, _)| i.title().to_owned()).collect();
    for interface in [Interface::CoSimulation, Interface::ModelExchange] {
        if !declared.interfaces.iter().any(|(i, _)| *i == interface) {
            let skipped = Finding::skipped("dynamic checks", format!("the FMU does not offer {}", interface.title()));
            report.findings.push(skipped.interface(Some(interface.title())));
        }
    }
    // The binaries, by file (both interfaces may share one).
    let mut binaries: BTreeMap<PathBuf, Vec<Interface>> = BTreeMap::new();
    for (interface, id) in &declared.interfaces {
        // The identifier names a file: with a '/' it could name any library on disk.
        if id.is_empty() || id.contains(['/', '\\', '\0']) || id == "." || id == ".." {
            report.findings.push(Finding::error(
                "archive.binary",
                format!(
                    "the {} modelIdentifier {:?} is not a file name, so no binary can be loaded",
                    interface.title(),
                    fmi_schema::escaped_and_cut(id, 100, "...")
                ),
            ));
            continue;
        }
        let relative = format!("binaries/{}/{id}.so", version.platform);
        if dir.join(&relative).is_file() {
            binaries.entry(dir.join(&relative)).or_default().push(*interface);
        } else {
            let message = format!(
                "no binary for this platform: {relative} is missing (binaries present: {})",
                fmi_importer::platforms(&dir.join("binaries"))
            );
            report.findings.push(Finding::error("archive.binary", message).interface(Some(interface.title())));
        }
    }
    if !binaries.is_empty() && binaries.values().map(Vec::len).sum::<usize>() == declared.interfaces.len() {
        let names: Vec<String> = binaries.keys().map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect();
        report.findings.push(Finding::passed("archive.binary", format!("a binary for this platform: {}", names.join(", "))));
    }
    let runs = work.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| format!("cannot create {}: {e}", runs.display()))?;
    let supervisor = Supervisor::new(options.command.clone(), work, options.timeout);
    let mut prober = Prober { options, supervisor, dir, runs: &runs, version: &version, report };
    let mut usable = Vec::new();
    for (binary, interfaces) in &binaries {
        let before = prober.report.findings.len();
        prober.probe(None, "binary", binary, interfaces)?;
        let loaded = !prober.report.findings[before..].iter().any(|f| f.check == "binary.load" && f.severity == Severity::Error);
        if loaded {
            usable.extend(interfaces.iter().map(|i| (*i, binary.clone())));
        }
    }
    // Co-Simulation first, as the reports have always listed them.
    usable.sort_by_key(|(interface, binary)| (*interface != Interface::CoSimulation, binary.clone()));
    for (interface, binary) in usable {
        prober.interface(interface, &binary, declared.event_mode)?;
    }
    Ok(())
}

/// Runs probes in child processes and gathers what they find.
struct Prober<'a> {
    options: &'a Options,
    supervisor: Supervisor,
    dir: &'a Path,
    runs: &'a Path,
    version: &'a Version,
    report: &'a mut Report,
}

impl Prober<'_> {
    /// Every dynamic check of one interface: the lifecycle first, then, if it produced a
    /// reference run, the probes that build on it.
    fn interface(&mut self, interface: Interface, binary: &Path, event_mode: bool) -> Result<(), String> {
        self.probe(Some(interface), "lifecycle", binary, &[interface])?;
        if !reference_path(self.runs, interface).is_file() {
            let skipped = Finding::skipped(
                "dynamic checks",
                "the state machine, arguments, capability and reproducibility checks did not run: the basic run failed (see lifecycle)",
            );
            self.report.findings.push(skipped.interface(Some(interface.title())));
            return Ok(());
        }
        let table = self.version.table;
        for probe in after_lifecycle(&table.states(interface, event_mode && interface == Interface::CoSimulation), interface) {
            self.probe(Some(interface), &probe, binary, &[interface])?;
        }
        if let (Interface::CoSimulation, Some((_, unreached))) = (interface, table.unreached) {
            let skipped = Finding::skipped("state-machine.legal", unreached);
            self.report.findings.push(skipped.interface(Some(interface.title())));
        }
        Ok(())
    }

    /// Runs `probe` in children until it finishes, resuming after a crash where the probe
    /// allows it.
    fn probe(&mut self, interface: Option<Interface>, probe: &str, binary: &Path, interfaces: &[Interface]) -> Result<(), String> {
        let timeout = self.options.timeout;
        let (mut resume, mut failures, mut timeouts) = (0, 0, 0);
        loop {
            let job = Job {
                fmi: self.version.fmi,
                dir: self.dir.to_path_buf(),
                runs: self.runs.to_path_buf(),
                binary: binary.to_path_buf(),
                interfaces: interfaces.to_vec(),
                timeout,
                probe: probe.to_owned(),
                resume,
            };
            let run =
                self.supervisor
                    .run(job, &self.options.cancelled)
                    .map_err(|e| if e == "interrupted" { INTERRUPTED.to_owned() } else { e })?;
            let mut cell: Option<(String, usize, Severity)> = None;
            for message in run.messages {
                match message {
                    Message::Cell { check, index, crash } => cell = Some((check, index, crash)),
                    Message::Finding(json) => {
                        let finding = serde_json::from_str(&json)
                            .map_err(|e| format!("the probe process sent a finding the validator cannot read ({e}): {json}"))?;
                        self.report.findings.push(finding);
                    }
                }
            }
            let (end, in_call, last_call) = match run.outcome {
                Outcome::Finished => return Ok(()),
                Outcome::Internal(e) => return Err(format!("the validator failed in its probe process ({probe}): {e}")),
                Outcome::Died { end, in_call, last_call } => (end, in_call, last_call),
            };
            let first = first_check(probe, self.version.fmi);
            let (check, index, severity) = cell.unwrap_or_else(|| (first.to_owned(), resume, Severity::Error));
            let finding = death(&end, in_call.as_ref(), last_call.as_ref(), timeout, &check, severity)
                .log(run.log_tail)
                .interface(interface.map(|i| i.title()));
            self.report.findings.push(finding);
            failures += 1;
            timeouts += (end == End::TimedOut) as usize;
            // A probe whose cells are independent resumes after the one that died, within
            // bounds: an FMU that hangs in every call would otherwise cost a timeout per cell.
            let given_up = failures >= 20 || timeouts >= 2;
            if !resumable(probe) || given_up {
                if resumable(probe) && given_up {
                    self.report.findings.push(
                        Finding::skipped(&check, format!("the rest of the {probe} probe was not run after {failures} crashes or hangs"))
                            .interface(interface.map(|i| i.title())),
                    );
                }
                return Ok(());
            }
            resume = index + 1;
        }
    }
}

/// The finding for a probe process that died or was killed.
pub(crate) fn death(
    end: &End,
    in_call: Option<&CallRecord>,
    last_call: Option<&CallRecord>,
    timeout: Duration,
    check: &str,
    severity: Severity,
) -> Finding {
    let during = |record: Option<&CallRecord>| match record {
        Some(r) => format!("in {} ({})", r.call, r.state),
        None => "before its first FMI call".to_owned(),
    };
    let message = match end {
        End::Crashed(signal) => match (in_call, last_call) {
            // The arguments it was given, where the record has them: they may be the problem (a
            // NULL the probe passed).
            (Some(r), _) => match &r.value {
                Some(value) => format!("the FMU crashed with {signal} in {} ({value})", r.call),
                None => format!("the FMU crashed with {signal} in {}", r.call),
            },
            (None, Some(r)) => format!("the probe process crashed with {signal} after {} returned", r.call),
            (None, None) => format!("the probe process crashed with {signal} before its first FMI call"),
        },
        End::Exited(code) => format!("the FMU ended the probe process (exit code {code}) {}", during(in_call.or(last_call))),
        End::TimedOut => match in_call {
            Some(r) => format!("{} did not return within {} s (--timeout); the probe process was killed", r.call, timeout.as_secs_f64()),
            None => "the probe process stopped making progress between FMI calls and was killed".to_owned(),
        },
    };
    let mut finding = Finding::new(check, severity, message);
    if let Some(r) = in_call.or(last_call) {
        finding.call = Some(r.call.clone());
        finding.state = Some(r.state.clone());
        finding.variable = r.variable.clone();
        finding.value = r.value.clone();
    }
    finding
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(call: &str, value: Option<&str>) -> CallRecord {
        CallRecord { call: call.into(), state: "StepComplete".into(), variable: None, value: value.map(str::to_owned) }
    }

    /// A death names the call it happened in, with its arguments, and the kind of death.
    #[test]
    fn a_death_names_the_call() {
        let timeout = Duration::from_millis(500);
        let get = record("fmi2GetReal", Some("vr NULL, nvr 1, value NULL"));
        let crash = death(
            &End::Crashed("SIGSEGV (invalid memory access)".into()),
            Some(&get),
            None,
            timeout,
            "arguments.null-arrays",
            Severity::Warning,
        );
        assert_eq!(crash.message, "the FMU crashed with SIGSEGV (invalid memory access) in fmi2GetReal (vr NULL, nvr 1, value NULL)");
        assert_eq!(
            (crash.severity, crash.call.as_deref(), crash.state.as_deref()),
            (Severity::Warning, Some("fmi2GetReal"), Some("StepComplete"))
        );
        let step = record("fmi2DoStep", None);
        let hang = death(&End::TimedOut, Some(&step), None, timeout, "lifecycle.run", Severity::Error);
        assert_eq!(hang.message, "fmi2DoStep did not return within 0.5 s (--timeout); the probe process was killed");
        let exit = death(&End::Exited(3), None, Some(&step), timeout, "lifecycle.run", Severity::Error);
        assert_eq!(exit.message, "the FMU ended the probe process (exit code 3) in fmi2DoStep (StepComplete)");
        let after = death(&End::Crashed("SIGABRT (abort)".into()), None, Some(&step), timeout, "x", Severity::Error);
        assert!(after.message.contains("after fmi2DoStep returned"), "{}", after.message);
        let stuck = death(&End::TimedOut, None, None, timeout, "x", Severity::Error);
        assert!(stuck.message.contains("stopped making progress") && stuck.call.is_none());
    }

    #[test]
    fn the_version_is_three_or_one_only_when_it_says_so() {
        assert_eq!(version_of(Some("3.0")), Fmi::Fmi3);
        assert_eq!(version_of(Some("2.0")), Fmi::Fmi2);
        assert_eq!(version_of(Some("1.0")), Fmi::Fmi1);
        assert_eq!(version_of(None), Fmi::Fmi2);
    }
}
