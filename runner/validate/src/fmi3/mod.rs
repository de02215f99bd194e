//! The FMI 3.0 set of checks, written from the FMI 3.0.2 standard: the static ones on the
//! description (the schema's rules, the instantiationToken) and the binary (every one of the
//! 75 functions of fmi3Functions.h exported, fmi3GetVersion "3.0"), then the dynamic probes,
//! each in its own child process, for each declared interface (Co-Simulation with Event Mode
//! and early return where offered, Model Exchange): the lifecycle and the state machine
//! (probes.rs), then FMU state, NULL arguments, threads and String variables
//! (capabilities.rs). Scheduled Execution is not probed.

mod capabilities;
mod probes;
mod raw;

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Duration;

use fmi_schema::fmi3::ModelDescription;

use crate::fmi2::{death, Out};
use crate::isolation::{self, CallRecord, End, Message, Progress};
use crate::report::{Finding, Report, Severity};
use crate::Options;
use probes::Model;
use raw::Interface;

/// FMI 3.0's platform folder for this machine (the importer's).
const PLATFORM: &str = fmi_importer::fmi3::PLATFORM;

/// Validates the FMI 3.0 FMU unpacked in `dir` (its description `xml`), adding to `report`;
/// `Err` when the validation could not run.
pub(crate) fn validate(xml: &str, dir: &Path, work: &Path, options: &Options, report: &mut Report) -> Result<(), String> {
    let md = match ModelDescription::from_xml(xml) {
        Ok(md) => md,
        Err(e) => {
            report.findings.push(Finding::error("description.xml", format!("modelDescription.xml cannot be read: {}", e.message())));
            report.findings.push(Finding::skipped("dynamic checks", "not run: there is no usable modelDescription.xml"));
            return Ok(());
        }
    };
    report.fmi_version = Some(md.fmi_version.clone());
    report.model_name = Some(md.model_name.clone());
    report.findings.push(Finding::passed("description.xml", "modelDescription.xml is a well-formed FMI 3.0 description"));
    static_checks(&md, &mut report.findings);
    let declared: Vec<(Interface, String)> = [
        (Interface::CoSimulation, md.co_simulation.as_ref().map(|c| c.common.model_identifier.clone())),
        (Interface::ModelExchange, md.model_exchange.as_ref().map(|m| m.common.model_identifier.clone())),
    ]
    .into_iter()
    .filter_map(|(i, id)| Some((i, id?)))
    .collect();
    report.interfaces = declared.iter().map(|(i, _)| i.title().to_owned()).collect();
    if md.scheduled_execution.is_some() {
        report.findings.push(Finding::skipped(
            "dynamic checks",
            "Scheduled Execution is declared but not probed: the validator drives Co-Simulation and Model Exchange",
        ));
    }
    for interface in [Interface::CoSimulation, Interface::ModelExchange] {
        if !declared.iter().any(|(i, _)| *i == interface) {
            let skipped = Finding::skipped("dynamic checks", format!("the FMU does not offer {}", interface.title()));
            report.findings.push(skipped.interface(Some(interface.title())));
        }
    }
    let mut binaries: Vec<(PathBuf, Vec<Interface>)> = Vec::new();
    for (interface, id) in &declared {
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
        let relative = format!("binaries/{PLATFORM}/{id}.so");
        let path = dir.join(&relative);
        if path.is_file() {
            match binaries.iter_mut().find(|(p, _)| *p == path) {
                Some((_, list)) => list.push(*interface),
                None => binaries.push((path, vec![*interface])),
            }
        } else {
            report.findings.push(
                Finding::error("archive.binary", format!("no binary for this platform: {relative} is missing"))
                    .interface(Some(interface.title())),
            );
        }
    }
    if !binaries.is_empty() && binaries.iter().map(|(_, l)| l.len()).sum::<usize>() == declared.len() {
        let names: Vec<String> = binaries.iter().map(|(p, _)| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect();
        report.findings.push(Finding::passed("archive.binary", format!("a binary for this platform: {}", names.join(", "))));
    }
    let mut prober = Prober { options, work, dir, report };
    let mut usable = Vec::new();
    for (binary, interfaces) in &binaries {
        let list = interfaces.iter().map(|i| i.arg()).collect::<Vec<_>>().join(",");
        let before = prober.report.findings.len();
        prober.probe(None, "binary", binary, &list)?;
        let loaded = !prober.report.findings[before..].iter().any(|f| f.check == "binary.load" && f.severity == Severity::Error);
        if loaded {
            usable.extend(interfaces.iter().map(|i| (*i, binary.clone())));
        }
    }
    usable.sort();
    for (interface, binary) in usable {
        let before = prober.report.findings.len();
        prober.probe(Some(interface), "lifecycle", &binary, interface.arg())?;
        let failed = |check: &str| prober.report.findings[before..].iter().any(|f| f.severity == Severity::Error && f.check == check);
        let (instantiated, ran) = (!failed("lifecycle.instantiate"), !failed("lifecycle.run"));
        if instantiated {
            for probe in &probes::PROBES[1..] {
                if !ran && probes::runs_the_experiment(probe) {
                    let skipped = Finding::skipped(
                        probes::first_check(probe),
                        "not run: the run it repeats failed (see lifecycle.run), and would fail here alike",
                    );
                    prober.report.findings.push(skipped.interface(Some(interface.title())));
                    continue;
                }
                prober.probe(Some(interface), probe, &binary, interface.arg())?;
            }
        } else {
            let skipped = Finding::skipped(
                "dynamic checks",
                "the state machine, capabilities and arguments were not probed: the FMU cannot be instantiated (see lifecycle)",
            );
            prober.report.findings.push(skipped.interface(Some(interface.title())));
        }
    }
    Ok(())
}

/// The description's static checks: the schema's rules and the instantiationToken.
fn static_checks(md: &ModelDescription, findings: &mut Vec<Finding>) {
    let problems = md.check();
    for p in &problems {
        findings.push(Finding::error("description.rules", p.clone()));
    }
    if problems.is_empty() {
        findings.push(Finding::passed(
            "description.rules",
            "the schema's rules: header, unique names and value references, causality, variability and initial, start values, units, types, array dimensions, ModelStructure",
        ));
    }
    let token = &md.instantiation_token;
    if token.trim().is_empty() {
        findings.push(Finding::error(
            "description.token",
            "instantiationToken is empty: it is a mandatory attribute the FMU may check at instantiation",
        ));
    } else if token.trim() != token || token.chars().any(char::is_control) {
        findings.push(
            Finding::error(
                "description.token",
                "instantiationToken has surrounding blanks or control characters, which importers may strip before passing it",
            )
            .value(fmi_schema::escaped_and_cut(token, 100, "...")),
        );
    } else {
        findings.push(Finding::passed("description.token", "instantiationToken is a non-empty string without surrounding blanks"));
    }
    if !(md.fmi_version == "3.0" || md.fmi_version.starts_with("3.0.")) {
        findings.push(Finding::error("description.rules", format!("fmiVersion is {:?}; FMI 3.0 descriptions say \"3.0\"", md.fmi_version)));
    }
}

/// Runs probes in child processes and gathers what they find.
struct Prober<'a> {
    options: &'a Options,
    work: &'a Path,
    dir: &'a Path,
    report: &'a mut Report,
}

impl Prober<'_> {
    /// Runs `probe` in children until it finishes, resuming after a crash where the probe
    /// allows it.
    fn probe(&mut self, interface: Option<Interface>, probe: &str, binary: &Path, interfaces: &str) -> Result<(), String> {
        let timeout = self.options.timeout;
        let (mut resume, mut failures, mut timeouts) = (0, 0, 0);
        loop {
            let args: Vec<OsString> = vec![
                "--fmi".into(),
                "3".into(),
                "--dir".into(),
                self.dir.as_os_str().to_owned(),
                "--binary".into(),
                binary.as_os_str().to_owned(),
                "--interface".into(),
                interfaces.into(),
                "--timeout-ms".into(),
                (timeout.as_millis().max(1) as u64).to_string().into(),
                "--probe".into(),
                probe.into(),
                "--resume".into(),
                resume.to_string().into(),
            ];
            let child = isolation::run_child(&self.options.launcher, &args, self.work, timeout, &self.options.cancelled)?;
            let mut cell: Option<(String, usize, Severity)> = None;
            for message in child.messages {
                match message {
                    Message::Cell { check, index, crash } => cell = Some((check, index, crash)),
                    Message::Finding(f) => self.report.findings.push(f),
                    Message::Done => {}
                    Message::Internal(e) => return Err(format!("the validator failed in its probe process ({probe}): {e}")),
                }
            }
            match child.end {
                End::Finished => return Ok(()),
                End::Cancelled => return Err(crate::fmi2::INTERRUPTED.to_owned()),
                _ => {}
            }
            let first = if probe == "binary" { "binary.load" } else { probes::first_check(probe) };
            let (check, index, severity) = cell.unwrap_or_else(|| (first.to_owned(), resume, Severity::Error));
            let finding = death(&child.end, child.in_call.as_ref(), child.last_call.as_ref(), timeout, &check, severity)
                .log(child.log_tail)
                .interface(interface.map(|i| i.title()));
            self.report.findings.push(finding);
            failures += 1;
            timeouts += (child.end == End::TimedOut) as usize;
            if !probes::resumable(probe) || failures >= 20 || timeouts >= 2 {
                if probes::resumable(probe) && (failures >= 20 || timeouts >= 2) {
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

/// What a probe process works with.
pub(crate) struct Child<'a> {
    pub api: &'a raw::Api,
    pub model: Model,
    /// The resources directory as FMI 3.0 passes it: an absolute path ending in '/'.
    pub resources: String,
    pub progress: &'a Progress,
    pub timeout: Duration,
    pub out: &'a Out,
}

/// The probe process: runs one probe on the FMU unpacked by the parent.
pub(crate) fn child(args: &[OsString], out: &Out) -> Result<(), String> {
    let mut map = std::collections::HashMap::new();
    let mut it = args.iter();
    while let Some(key) = it.next() {
        let value = it.next().ok_or_else(|| format!("{} needs a value", key.to_string_lossy()))?;
        map.insert(key.to_string_lossy().into_owned(), value.clone());
    }
    let take = |key: &str| map.get(key).cloned().ok_or_else(|| format!("the probe needs {key}"));
    let text = |key: &str| take(key).map(|v| v.to_string_lossy().into_owned());
    let dir: PathBuf = take("--dir")?.into();
    let binary: PathBuf = take("--binary")?.into();
    let progress = Progress::open(Path::new(&take("--progress")?))?;
    let timeout = Duration::from_millis(text("--timeout-ms")?.parse().map_err(|_| "--timeout-ms needs a number")?);
    let resume: usize = text("--resume")?.parse().map_err(|_| "--resume needs a number")?;
    let probe = text("--probe")?;
    let interfaces = text("--interface")?
        .split(',')
        .map(|a| Interface::from_arg(a).ok_or_else(|| format!("unknown interface {a:?}")))
        .collect::<Result<Vec<_>, _>>()?;
    if probe != "binary" && !probes::known(&probe) {
        return Err(format!("unknown probe {probe:?}"));
    }
    let xml = std::fs::read_to_string(dir.join("modelDescription.xml")).map_err(|e| format!("cannot read the description: {e}"))?;
    let md = ModelDescription::from_xml(&xml).map_err(|e| e.message().to_owned())?;
    let shown = binary.strip_prefix(&dir).unwrap_or(&binary).display().to_string();
    let send = |f: Finding| out.send(&Message::Finding(f));
    if probe == "binary" {
        out.send(&Message::Cell { check: "binary.load".into(), index: 0, crash: Severity::Error });
    }
    let record = CallRecord { call: "dlopen".into(), state: "(loading the binary)".into(), variable: None, value: Some(shown.clone()) };
    progress.begin(0, &record, timeout);
    let loaded = raw::Api::load(&binary);
    progress.end(0);
    let api = match loaded {
        Ok(api) => api,
        Err(e) => {
            let check = if probe == "binary" { "binary.load" } else { probes::first_check(&probe) };
            send(Finding::error(check, format!("{shown} cannot be loaded: {e}")));
            return Ok(());
        }
    };
    if probe == "binary" {
        send(Finding::passed("binary.load", format!("{shown} loads")));
        exports(&api, &shown, &progress, timeout, out);
        return Ok(());
    }
    let interface = *interfaces.first().ok_or("no interface")?;
    let resources = format!("{}/", dir.join("resources").display());
    let child = Child { api: &api, model: Model::new(md), resources, progress: &progress, timeout, out };
    let mut ctx = probes::Ctx::new(&child, interface, resume);
    probes::run(&probe, &mut ctx)
}

/// Every function of fmi3Functions.h exported (section 2.5: "The FMU must implement all API
/// functions declared in fmi3Functions.h, even if they are only needed for interface types or
/// optional capabilities that the FMU does not support"), and fmi3GetVersion "3.0".
fn exports(api: &raw::Api, shown: &str, progress: &Progress, timeout: Duration, out: &Out) {
    use fmi_c::fmi3 as c;
    let send = |f: Finding| out.send(&Message::Finding(f));
    out.send(&Message::Cell { check: "binary.exports".into(), index: 1, crash: Severity::Error });
    let all: Vec<&str> = c::COMMON_FUNCTIONS
        .iter()
        .chain(&c::MODEL_EXCHANGE_FUNCTIONS)
        .chain(&c::CO_SIMULATION_FUNCTIONS)
        .chain(&c::SCHEDULED_EXECUTION_FUNCTIONS)
        .copied()
        .collect();
    let missing: Vec<&str> = all.iter().copied().filter(|f| !api.exports(f)).collect();
    for f in &missing {
        send(
            Finding::error(
                "binary.exports",
                format!("{shown} does not export {f}: FMI 3.0 requires all {} functions of fmi3Functions.h, even for interfaces and capabilities the FMU lacks", all.len()),
            )
            .call(*f),
        );
    }
    if missing.is_empty() {
        send(Finding::passed("binary.exports", format!("all {} functions of fmi3Functions.h exported", all.len())));
    }
    out.send(&Message::Cell { check: "binary.version".into(), index: 2, crash: Severity::Error });
    let Some(get_version) = api.get_version else { return };
    let record = CallRecord { call: "fmi3GetVersion".into(), state: "(no instance)".into(), variable: None, value: None };
    progress.begin(0, &record, timeout);
    // SAFETY: returns a static C string per the standard (NULL is checked).
    let version = unsafe {
        let p = get_version();
        (!p.is_null()).then(|| std::ffi::CStr::from_ptr(p).to_string_lossy().into_owned())
    };
    progress.end(0);
    if version.as_deref() == Some("3.0") {
        send(Finding::passed("binary.version", "fmi3GetVersion returns \"3.0\""));
    } else {
        let shown = version.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 60, "...")));
        send(
            Finding::error(
                "binary.version",
                format!("fmi3GetVersion returned {shown}, not \"3.0\" (section 2.2.4: \"this function returns 3.0\")"),
            )
            .call("fmi3GetVersion")
            .value(shown),
        );
    }
}
