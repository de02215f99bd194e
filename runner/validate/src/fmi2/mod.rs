//! The FMI 2.0 set of checks: the static ones on the description and the binary's exports,
//! then the dynamic probes, each in its own child process, for each declared interface.
//! (FMI 3.0 gets a module of its own beside this one, with its own tables and probes.)

mod model;
mod probes;
mod raw;
mod rules;
mod run;
mod table;

use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Duration;

use fmi_schema::fmi2::ModelDescription;

use crate::isolation::{self, CallRecord, End, Message, Progress};
use crate::report::{Finding, Report, Severity};
use crate::Options;
use model::Model;
use probes::Ctx;
pub(crate) use probes::Out;
use table::{Function, Interface, State};

/// FMI 2.0's platform folder for this machine (the importer's).
const PLATFORM: &str = fmi_importer::fmi2::PLATFORM;

/// The message of an interrupted validation (the command line exits with 130 on it).
pub(crate) const INTERRUPTED: &str = "interrupted";

/// Validates the FMI 2.0 FMU unpacked in `dir` (its description `xml`), adding to `report`;
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
    report.findings.push(Finding::passed("description.xml", "modelDescription.xml is a well-formed FMI 2.0 description"));
    rules::check(&md, &mut report.findings);
    let declared: Vec<(Interface, String)> = [
        (Interface::CoSimulation, md.co_simulation.as_ref().map(|c| c.common.model_identifier.clone())),
        (Interface::ModelExchange, md.model_exchange.as_ref().map(|m| m.common.model_identifier.clone())),
    ]
    .into_iter()
    .filter_map(|(i, id)| Some((i, id?)))
    .collect();
    report.interfaces = declared.iter().map(|(i, _)| i.title().to_owned()).collect();
    for interface in [Interface::CoSimulation, Interface::ModelExchange] {
        if !declared.iter().any(|(i, _)| *i == interface) {
            let skipped = Finding::skipped("dynamic checks", format!("the FMU does not offer {}", interface.title()));
            report.findings.push(skipped.interface(Some(interface.title())));
        }
    }
    // The binaries, by file (both interfaces may share one).
    let mut binaries: BTreeMap<PathBuf, Vec<Interface>> = BTreeMap::new();
    for (interface, id) in &declared {
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
        let relative = format!("binaries/{PLATFORM}/{id}.so");
        if dir.join(&relative).is_file() {
            binaries.entry(dir.join(&relative)).or_default().push(*interface);
        } else {
            report.findings.push(
                Finding::error(
                    "archive.binary",
                    format!("no binary for this platform: {relative} is missing (binaries present: {})", platforms(dir)),
                )
                .interface(Some(interface.title())),
            );
        }
    }
    if !binaries.is_empty() && binaries.values().map(Vec::len).sum::<usize>() == declared.len() {
        let names: Vec<String> = binaries.keys().map(|p| p.strip_prefix(dir).unwrap_or(p).display().to_string()).collect();
        report.findings.push(Finding::passed("archive.binary", format!("a binary for this platform: {}", names.join(", "))));
    }
    let runs = work.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| format!("cannot create {}: {e}", runs.display()))?;
    let mut prober = Prober { options, work, dir, runs: &runs, report };
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
    usable.sort_by_key(|(i, _)| *i != Interface::CoSimulation);
    for (interface, binary) in usable {
        prober.interface(interface, &binary)?;
    }
    Ok(())
}

/// The platform folders under binaries/, for messages.
fn platforms(dir: &Path) -> String {
    let mut found: Vec<String> = std::fs::read_dir(dir.join("binaries"))
        .map(|d| d.filter_map(|e| e.ok()).map(|e| e.file_name().to_string_lossy().into_owned()).collect())
        .unwrap_or_default();
    found.sort();
    if found.is_empty() {
        "none".to_owned()
    } else {
        found.join(", ")
    }
}

/// Runs probes in child processes and gathers what they find.
struct Prober<'a> {
    options: &'a Options,
    work: &'a Path,
    dir: &'a Path,
    runs: &'a Path,
    report: &'a mut Report,
}

impl Prober<'_> {
    /// Every dynamic check of one interface: the lifecycle first, then, if it produced a
    /// reference run, the probes that build on it.
    fn interface(&mut self, interface: Interface, binary: &Path) -> Result<(), String> {
        let arg = interface.arg();
        self.probe(Some(interface), "lifecycle", binary, arg)?;
        let reference = self.runs.join(format!("{arg}-reference.bin"));
        let mut probes: Vec<String> = vec!["reproducible".into()];
        probes.extend(State::reachable(interface).iter().map(|s| format!("state-machine:{}", s.name())));
        probes.extend(["arguments", "strings", "fmu-state", "serialize"].map(String::from));
        if interface == Interface::CoSimulation {
            probes.push("variable-step".into());
        }
        probes.push("threads".into());
        if !reference.is_file() {
            let skipped = Finding::skipped(
                "dynamic checks",
                "the state machine, arguments, capability and reproducibility checks did not run: the basic run failed (see lifecycle)",
            );
            self.report.findings.push(skipped.interface(Some(interface.title())));
            return Ok(());
        }
        for probe in &probes {
            self.probe(Some(interface), probe, binary, arg)?;
        }
        if interface == Interface::CoSimulation {
            let skipped = Finding::skipped(
                "state-machine.legal",
                "StepFailed, StepCanceled and StepInProgress are not probed call by call: the validator steps synchronously and cannot make a model fail a step",
            );
            self.report.findings.push(skipped.interface(Some(interface.title())));
        }
        Ok(())
    }

    /// Runs `probe` in children until it finishes, resuming after a crash where the probe
    /// allows it.
    fn probe(&mut self, interface: Option<Interface>, probe: &str, binary: &Path, interfaces: &str) -> Result<(), String> {
        let timeout = self.options.timeout;
        let mut resume = 0;
        let mut failures = 0;
        let mut timeouts = 0;
        loop {
            let args: Vec<OsString> = [
                "--fmi".into(),
                "2".into(),
                "--dir".into(),
                self.dir.as_os_str().to_owned(),
                "--runs".into(),
                self.runs.as_os_str().to_owned(),
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
            ]
            .to_vec();
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
            if child.end == End::Finished {
                return Ok(());
            }
            if child.end == End::Cancelled {
                return Err(INTERRUPTED.to_owned());
            }
            let (check, index, severity) = cell.unwrap_or_else(|| (probes::first_check(probe).to_owned(), resume, Severity::Error));
            let finding = death(&child.end, child.in_call.as_ref(), child.last_call.as_ref(), timeout, &check, severity)
                .log(child.log_tail)
                .interface(interface.map(|i| i.title()));
            self.report.findings.push(finding);
            failures += 1;
            timeouts += (child.end == End::TimedOut) as usize;
            // A probe whose cells are independent resumes after the one that died, within
            // bounds: an FMU that hangs in every call would otherwise cost a timeout per cell.
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
        End::Finished | End::Cancelled => unreachable!("not a death"),
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

/// The arguments of a probe process.
struct ProbeArgs {
    progress: PathBuf,
    dir: PathBuf,
    runs: PathBuf,
    binary: PathBuf,
    interfaces: Vec<Interface>,
    timeout: Duration,
    probe: String,
    resume: usize,
}

impl ProbeArgs {
    fn parse(args: &[OsString]) -> Result<ProbeArgs, String> {
        let mut map = std::collections::HashMap::new();
        let mut it = args.iter();
        while let Some(key) = it.next() {
            let key = key.to_string_lossy().into_owned();
            let value = it.next().ok_or_else(|| format!("{key} needs a value"))?;
            map.insert(key, value.clone());
        }
        let take = |key: &str| map.get(key).cloned().ok_or_else(|| format!("the probe needs {key}"));
        let text = |key: &str| take(key).map(|v| v.to_string_lossy().into_owned());
        let interfaces = text("--interface")?
            .split(',')
            .map(|a| Interface::from_arg(a).ok_or_else(|| format!("unknown interface {a:?}")))
            .collect::<Result<Vec<_>, _>>()?;
        if text("--fmi")? != "2" {
            return Err("an FMI 2.0 probe was started for another FMI version".to_owned());
        }
        let probe = text("--probe")?;
        if probe != "binary" && !probes::known(&probe) {
            return Err(format!("unknown probe {probe:?}"));
        }
        Ok(ProbeArgs {
            progress: take("--progress")?.into(),
            dir: take("--dir")?.into(),
            runs: take("--runs")?.into(),
            binary: take("--binary")?.into(),
            interfaces,
            timeout: Duration::from_millis(text("--timeout-ms")?.parse().map_err(|_| "--timeout-ms needs a number")?),
            probe,
            resume: text("--resume")?.parse().map_err(|_| "--resume needs a number")?,
        })
    }
}

/// The writer of a probe process's messages.
pub(crate) fn probes_out(file: std::fs::File) -> Out {
    Out::new(file)
}

/// The probe process: runs one probe on the FMU unpacked by the parent.
pub(crate) fn child(args: &[OsString], out: &Out) -> Result<(), String> {
    let args = ProbeArgs::parse(args)?;
    let xml = std::fs::read_to_string(args.dir.join("modelDescription.xml")).map_err(|e| format!("cannot read the description: {e}"))?;
    let md = ModelDescription::from_xml(&xml).map_err(|e| e.message().to_owned())?;
    let model = Model::new(md);
    let progress = Progress::open(&args.progress)?;
    let shown = args.binary.strip_prefix(&args.dir).unwrap_or(&args.binary).display().to_string();
    if args.probe == "binary" {
        out.send(&Message::Cell { check: "binary.load".into(), index: 0, crash: Severity::Error });
    }
    // Loading runs the library's initializers: a call like any other, bounded by the timeout.
    let record = CallRecord { call: "dlopen".into(), state: "(loading the binary)".into(), variable: None, value: Some(shown.clone()) };
    progress.begin(0, &record, args.timeout);
    let loaded = raw::Api::load(&args.binary);
    progress.end(0);
    let api = match loaded {
        Ok(api) => api,
        Err(e) => {
            let check = if args.probe == "binary" { "binary.load" } else { probes::first_check(&args.probe) };
            out.send(&Message::Finding(Finding::error(check, format!("{shown} cannot be loaded: {e}"))));
            return Ok(());
        }
    };
    if args.probe == "binary" {
        binary(&api, &model, &args.interfaces, &shown, &progress, args.timeout, out);
        return Ok(());
    }
    let interface = *args.interfaces.first().ok_or("no interface")?;
    let fmu = raw::Fmu::new(api, model, interface, &args.dir, progress, args.timeout)?;
    let mut ctx = Ctx::new(&fmu, out, &args.runs, args.resume);
    probes::run(&args.probe, &mut ctx)
}

/// The binary: loadable, every function its interfaces require exported, the version and
/// types platform FMI 2.0 fixes.
fn binary(api: &raw::Api, model: &Model, interfaces: &[Interface], shown: &str, progress: &Progress, timeout: Duration, out: &Out) {
    let send = |f: Finding| out.send(&Message::Finding(f));
    send(Finding::passed("binary.load", format!("{shown} loads")));
    out.send(&Message::Cell { check: "binary.exports".into(), index: 1, crash: Severity::Error });
    let mut missing = 0;
    let mut required = 0;
    let mut seen = std::collections::HashSet::new();
    for interface in interfaces {
        for f in Function::of(*interface) {
            if !seen.insert(f) {
                continue;
            }
            required += 1;
            if !api.exports(f.name()) {
                missing += 1;
                send(
                    Finding::error(
                        "binary.exports",
                        format!(
                            "{shown} does not export {}, which {} requires (FMI 2.0: every function of a declared interface, even for capabilities it lacks)",
                            f.name(),
                            interface.title()
                        ),
                    )
                    .call(f.name()),
                );
            }
        }
    }
    if missing == 0 {
        send(Finding::passed(
            "binary.exports",
            format!("all {required} functions of {} exported", interfaces.iter().map(|i| i.title()).collect::<Vec<_>>().join(" and ")),
        ));
    }
    out.send(&Message::Cell { check: "binary.version".into(), index: 2, crash: Severity::Error });
    let mut fine = true;
    for (f, expected) in [(Function::GetVersion, "2.0"), (Function::GetTypesPlatform, "default")] {
        let getter = if f == Function::GetVersion { api.get_version } else { api.get_types_platform };
        let Some(getter) = getter else { continue };
        let record = CallRecord { call: f.name().into(), state: "(no instance)".into(), variable: None, value: None };
        progress.begin(0, &record, timeout);
        // SAFETY: both return a static C string per the standard (NULL is checked).
        let text = unsafe {
            let p = getter();
            (!p.is_null()).then(|| std::ffi::CStr::from_ptr(p).to_string_lossy().into_owned())
        };
        progress.end(0);
        if text.as_deref() != Some(expected) {
            fine = false;
            let shown_text = text.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 60, "...")));
            send(
                Finding::error("binary.version", format!("{} returned {shown_text}, not \"{expected}\"", f.name()))
                    .call(f.name())
                    .value(shown_text),
            );
        }
    }
    if fine {
        send(Finding::passed("binary.version", "fmi2GetVersion returns \"2.0\" and fmi2GetTypesPlatform \"default\""));
    }
    let _ = model;
}
