//! The probe framework, the same for both versions: the probes there are, and the context a
//! probe runs in. A probe is a list of cells (one check each), reported to the parent as they
//! start, so that after a crash the parent knows what crashed and can resume after it; its
//! findings go to the parent as they are made.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::failure::Failure;
use crate::fmi::{Fmi, Interface, State, Version};
use crate::instance::{Binary, Instance};
use crate::isolation::{Message, Out, CELL_MARK};
use crate::model::Model;
use crate::report::{Finding, Severity};

/// The instance name of the reference run and of the runs compared with it.
pub(crate) const NAME: &str = "runner-validate";

/// The probes every interface gets after `lifecycle`, in the order they run; the state
/// machine is probed state by state (`state-machine:<State>`), each in a process of its own.
pub(crate) fn after_lifecycle(states: &[State], interface: Interface) -> Vec<String> {
    let mut probes: Vec<String> = vec!["reproducible".into()];
    probes.extend(states.iter().map(|s| format!("state-machine:{}", s.name())));
    probes.extend(["arguments", "strings", "fmu-state", "serialize"].map(String::from));
    if interface == Interface::CoSimulation {
        probes.push("variable-step".into());
    }
    probes.push("threads".into());
    probes
}

/// The probes there are, by name (`state-machine:<State>` takes the state's name); `binary`
/// checks the binary itself.
pub(crate) fn known(probe: &str) -> bool {
    matches!(
        probe,
        "binary" | "lifecycle" | "reproducible" | "arguments" | "strings" | "fmu-state" | "serialize" | "variable-step" | "threads"
    ) || probe.strip_prefix("state-machine:").and_then(State::from_name).is_some()
}

/// Whether a probe may resume after a crash in one of its cells (its cells are independent).
pub(crate) fn resumable(probe: &str) -> bool {
    probe == "arguments" || probe.starts_with("state-machine:")
}

/// The check of instantiation with the FMU's own token (and a wrong one).
pub(crate) fn instantiate_check(fmi: Fmi) -> &'static str {
    match fmi {
        Fmi::Fmi2 | Fmi::Fmi1 => "lifecycle.guid",
        Fmi::Fmi3 => "lifecycle.instantiate",
    }
}

/// The check a crash before a probe's first cell counts against.
pub(crate) fn first_check(probe: &str, fmi: Fmi) -> &'static str {
    match probe {
        "binary" => "binary.load",
        "lifecycle" => instantiate_check(fmi),
        "reproducible" => "health.reproducible",
        "arguments" => "arguments.unknown-vr",
        "strings" => "variables.string",
        "fmu-state" => "capability.fmu-state",
        "serialize" => "capability.serialize",
        "variable-step" => "capability.variable-step",
        "threads" => "capability.threads",
        _ => "state-machine.legal",
    }
}

/// Where the lifecycle probe of `interface` keeps its run (in the directory `runs`).
pub(crate) fn reference_path(runs: &Path, interface: Interface) -> PathBuf {
    runs.join(format!("{}-reference.bin", interface.name()))
}

/// What a probe works with, and where its findings go.
pub(crate) struct Ctx<'a> {
    pub binary: &'static dyn Binary,
    pub interface: Interface,
    out: &'a Out<'a>,
    runs: PathBuf,
    resume: usize,
    next_cell: usize,
    troubled: HashSet<String>,
}

impl<'a> Ctx<'a> {
    /// A probe of `binary`'s `interface` resuming at cell `resume`; the reference run is kept
    /// in `runs`.
    pub(crate) fn new(binary: &'static dyn Binary, interface: Interface, out: &'a Out<'a>, runs: &Path, resume: usize) -> Ctx<'a> {
        Ctx { binary, interface, out, runs: runs.to_path_buf(), resume, next_cell: 0, troubled: HashSet::new() }
    }

    pub(crate) fn fmi(&self) -> Fmi {
        self.binary.fmi()
    }

    pub(crate) fn model(&self) -> &'static Model {
        self.binary.model()
    }

    /// Starts the next cell, of `check`: false when it lies before the resume point and is to
    /// be skipped. A crash inside it becomes a finding of severity `crash`.
    pub(crate) fn cell(&mut self, check: &str, crash: Severity) -> bool {
        let index = self.next_cell;
        self.next_cell += 1;
        if index < self.resume {
            return false;
        }
        self.out.send(&Message::Cell { check: check.to_owned(), index, crash });
        eprintln!("{CELL_MARK}{index}");
        true
    }

    /// Reports a finding of this interface.
    pub(crate) fn report(&mut self, finding: Finding) {
        if finding.severity <= Severity::Warning {
            self.troubled.insert(finding.check.clone());
        }
        let finding = finding.interface(Some(self.interface.title()));
        self.out.send(&Message::finding(&finding));
    }

    /// Reports `failure` as an error of `check` (or of the failure's own check).
    pub(crate) fn fail(&mut self, check: &str, failure: Failure) {
        self.report(failure.finding(check, Severity::Error));
    }

    /// Reports `failure` as a warning.
    pub(crate) fn warn(&mut self, check: &str, failure: Failure) {
        self.report(failure.finding(check, Severity::Warning));
    }

    /// Reports `check` passed, unless it already has an error or warning.
    pub(crate) fn pass(&mut self, check: &str, message: impl Into<String>) {
        if !self.troubled.contains(check) {
            self.report(Finding::passed(check, message));
        }
    }

    /// Reports `check` skipped.
    pub(crate) fn skip(&mut self, check: &str, message: impl Into<String>) {
        self.report(Finding::skipped(check, message));
    }

    /// Where the lifecycle probe keeps its run for the probes that compare with it.
    pub(crate) fn reference_path(&self) -> PathBuf {
        reference_path(&self.runs, self.interface)
    }

    /// A new instance of this interface named `name`, its calls recorded in progress slot
    /// `slot`, or the failure of the instantiation.
    pub(crate) fn instantiate(&self, name: &str, slot: usize) -> Result<Box<dyn Instance>, Failure> {
        let model = self.model();
        let call = self.binary.table().name(crate::fmi::Op::Instantiate, self.interface);
        self.binary.instantiate(name, self.interface, &model.token, slot).map_err(|(code, log)| {
            let token = self.fmi().token();
            let what = if code.is_missing() { "is not exported".to_owned() } else { format!("returned NULL with the FMU's own {token}") };
            Failure { log, ..Failure::new(format!("{call} {what}")) }.at_instantiate(call).value(format!(
                "fmuType {}, {token} {}",
                self.interface.title(),
                model.token
            ))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_probes_are_known_and_say_what_a_crash_counts_against() {
        let states = [State::Instantiated, State::StepComplete];
        let probes = after_lifecycle(&states, Interface::CoSimulation);
        assert_eq!(probes[1], "state-machine:Instantiated");
        assert!(probes.iter().all(|p| known(p)), "{probes:?}");
        assert!(probes.contains(&"variable-step".to_owned()));
        assert!(!after_lifecycle(&states, Interface::ModelExchange).contains(&"variable-step".to_owned()));
        assert!(!known("state-machine:Nowhere") && !known("everything"));
        assert!(resumable("state-machine:EventMode") && resumable("arguments") && !resumable("lifecycle"));
        assert_eq!(first_check("lifecycle", Fmi::Fmi2), "lifecycle.guid");
        assert_eq!(first_check("lifecycle", Fmi::Fmi3), "lifecycle.instantiate");
        assert_eq!(first_check("state-machine:Terminated", Fmi::Fmi3), "state-machine.legal");
    }
}
