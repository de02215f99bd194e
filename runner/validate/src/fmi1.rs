//! FMI 1.0: the description's static checks (the schema's FMI 1.0 rules), the binary (it loads,
//! exports every function of its interface under the `<modelIdentifier>_` prefix, says "1.0"
//! and "standard32"), and one lifecycle run through the importer in a probe process: instantiate
//! with the FMU's GUID, initialize, a few steps of the DefaultExperiment (Co-Simulation with
//! `fmiDoStep`, Model Exchange integrated by the runner's solver with its events), the outputs
//! finite, terminate and free. The FMI 2.0 and 3.0 probes (state machine, arguments,
//! capabilities) are not run: FMI 1.0 has other state machines.

use std::path::Path;

use fmi_c::fmi1 as c;
use fmi_c::Library;
use fmi_importer::{Fmu, Interface as ImporterInterface, Reader, Step};
use fmi_schema::fmi1::ModelDescription;

use crate::fmi::{Fmi, Interface};
use crate::isolation::{CallRecord, Job, Message, Out, Outcome, Progress, Supervisor};
use crate::report::{Finding, Report, Severity};
use crate::Options;

/// FMI 1.0's platform folder for this machine.
const PLATFORM: &str = "linux64";

/// The probe that runs the lifecycle.
pub(crate) const PROBE: &str = "fmi1-lifecycle";

/// How many communication steps the lifecycle run takes at most.
const STEPS: usize = 10;

/// Validates the FMI 1.0 FMU unpacked in `dir` (its description `xml`), adding to `report`.
pub(crate) fn validate(xml: &str, dir: &Path, work: &Path, options: &Options, report: &mut Report) -> Result<(), String> {
    let md = match ModelDescription::from_xml(xml) {
        Ok(md) => md,
        Err(e) => {
            report.findings.push(Finding::error("description.xml", format!("modelDescription.xml cannot be read: {e}")));
            report.findings.push(Finding::skipped("dynamic checks", "not run: there is no usable modelDescription.xml"));
            return Ok(());
        }
    };
    report.fmi_version = Some(md.fmi_version.clone());
    report.model_name = Some(md.model_name.clone());
    let interface = if md.co_simulation.is_some() { Interface::CoSimulation } else { Interface::ModelExchange };
    report.interfaces = vec![interface.title().to_owned()];
    report.findings.push(Finding::passed("description.xml", "modelDescription.xml is a well-formed FMI 1.0 description"));
    let problems = md.check();
    if problems.is_empty() {
        report.findings.push(Finding::passed("description.rules", "the description follows the FMI 1.0 rules the schema checks"));
    }
    report.findings.extend(problems.into_iter().map(|p| Finding::error("description.rules", p)));
    let other = if interface == Interface::CoSimulation { Interface::ModelExchange } else { Interface::CoSimulation };
    let note = format!("an FMI 1.0 FMU offers one interface: this one {}", interface.title());
    report.findings.push(Finding::skipped("dynamic checks", note).interface(Some(other.title())));
    if md.co_simulation.as_ref().is_some_and(|cs| cs.needs_tool) {
        let skipped = Finding::skipped("dynamic checks", "not run: the FMU wraps a simulation tool (CoSimulation_Tool)");
        report.findings.push(skipped.interface(Some(interface.title())));
        return Ok(());
    }
    let id = &md.model_identifier;
    if id.is_empty() || id.contains(['/', '\\', '\0']) || id == "." || id == ".." {
        let shown = fmi_schema::escaped_and_cut(id, 100, "...");
        report.findings.push(Finding::error(
            "archive.binary",
            format!("the modelIdentifier {shown:?} is not a file name, so no binary can be loaded"),
        ));
        return Ok(());
    }
    let relative = format!("binaries/{PLATFORM}/{id}.so");
    let binary = dir.join(&relative);
    if !binary.is_file() {
        let message = format!(
            "no binary for this platform: {relative} is missing (binaries present: {})",
            fmi_importer::platforms(&dir.join("binaries"))
        );
        report.findings.push(Finding::error("archive.binary", message).interface(Some(interface.title())));
        return Ok(());
    }
    report.findings.push(Finding::passed("archive.binary", format!("a binary for this platform: {relative}")));
    let runs = work.join("runs");
    std::fs::create_dir_all(&runs).map_err(|e| format!("cannot create {}: {e}", runs.display()))?;
    let mut supervisor = Supervisor::new(options.command.clone(), work, options.timeout);
    let job = Job {
        fmi: Fmi::Fmi1,
        dir: dir.to_path_buf(),
        runs,
        binary,
        interfaces: vec![interface],
        timeout: options.timeout,
        probe: PROBE.to_owned(),
        resume: 0,
    };
    let run =
        supervisor.run(job, &options.cancelled).map_err(|e| if e == "interrupted" { crate::parent::INTERRUPTED.to_owned() } else { e })?;
    let mut cell: Option<(String, Severity)> = None;
    for message in run.messages {
        match message {
            Message::Cell { check, crash, .. } => cell = Some((check, crash)),
            Message::Finding(json) => {
                let finding = serde_json::from_str(&json)
                    .map_err(|e| format!("the probe process sent a finding the validator cannot read ({e}): {json}"))?;
                report.findings.push(finding);
            }
        }
    }
    match run.outcome {
        Outcome::Finished => Ok(()),
        Outcome::Internal(e) => Err(format!("the validator failed in its probe process ({PROBE}): {e}")),
        Outcome::Died { end, in_call, last_call } => {
            let (check, severity) = cell.unwrap_or_else(|| ("binary.load".to_owned(), Severity::Error));
            let finding = crate::parent::death(&end, in_call.as_ref(), last_call.as_ref(), options.timeout, &check, severity)
                .log(run.log_tail)
                .interface(Some(interface.title()));
            report.findings.push(finding);
            Ok(())
        }
    }
}

/// The probe process's side: the binary's checks, then the lifecycle run through the importer,
/// each call recorded in `progress` so that a crash or a hang names it.
pub(crate) fn lifecycle(job: &Job, progress: Progress<'static>, out: &Out) -> Result<(), String> {
    let send = |f: Finding| out.send(&Message::finding(&f));
    let cell = |check: &str, index: usize| out.send(&Message::Cell { check: check.into(), index, crash: Severity::Error });
    let interface = *job.interfaces.first().ok_or("no interface")?;
    let title = Some(interface.title());
    let xml = std::fs::read_to_string(job.dir.join("modelDescription.xml")).map_err(|e| format!("cannot read the description: {e}"))?;
    let md = ModelDescription::from_xml(&xml).map_err(|e| e.message().to_owned())?;
    let id = md.model_identifier.as_str();
    let shown = job.binary.strip_prefix(&job.dir).unwrap_or(&job.binary).display().to_string();
    let tracer = crate::instance::Tracer { progress, slot: 0, timeout: job.timeout };
    let record = |call: &str, state: &str| CallRecord { call: call.into(), state: state.into(), variable: None, value: None };

    cell("binary.load", 0);
    // SAFETY: loading runs the library's initializers, which is what this process is for.
    let loaded = tracer.traced(&record("dlopen", "(loading the binary)"), || unsafe { Library::open(&job.binary) });
    let library = match loaded {
        Ok(library) => library,
        Err(e) => {
            send(Finding::error("binary.load", format!("{shown} cannot be loaded: {e}")).interface(title));
            return Ok(());
        }
    };
    send(Finding::passed("binary.load", format!("{shown} loads")).interface(title));
    cell("binary.exports", 1);
    let functions = c::Functions::resolve_prefixed(&library, id);
    let own = match interface {
        Interface::CoSimulation => c::CO_SIMULATION_FUNCTIONS.as_slice(),
        Interface::ModelExchange => c::MODEL_EXCHANGE_FUNCTIONS.as_slice(),
    };
    let missing: Vec<String> =
        c::COMMON_FUNCTIONS.iter().chain(own).filter(|f| !functions.exports(f)).map(|f| format!("{id}_{f}")).collect();
    for f in &missing {
        let message = format!("{shown} does not export {f} (FMI 1.0 requires it of a {} FMU)", interface.title());
        send(Finding::error("binary.exports", message).call(f.clone()).interface(title));
    }
    if missing.is_empty() {
        let n = c::COMMON_FUNCTIONS.len() + own.len();
        send(
            Finding::passed("binary.exports", format!("{shown} exports the {n} functions of FMI 1.0 {}", interface.title()))
                .interface(title),
        );
    }
    cell("binary.version", 2);
    let version = functions.get_version.map(|f| tracer.traced(&record(&format!("{id}_fmiGetVersion"), "(no instance)"), || text(f)));
    let types = match interface {
        Interface::CoSimulation => functions.get_types_platform.map(|f| ("fmiGetTypesPlatform", f)),
        Interface::ModelExchange => functions.get_model_types_platform.map(|f| ("fmiGetModelTypesPlatform", f)),
    }
    .map(|(name, f)| (name, tracer.traced(&record(&format!("{id}_{name}"), "(no instance)"), || text(f))));
    match (&version, &types) {
        (Some(v), Some((_, t))) if v == "1.0" && t == "standard32" => send(
            Finding::passed("binary.version", format!("{id}_fmiGetVersion returns \"1.0\", the types platform \"standard32\""))
                .interface(title),
        ),
        _ => {
            if let Some(v) = version.filter(|v| v != "1.0") {
                send(Finding::error("binary.version", format!("{id}_fmiGetVersion returned {v:?}, not \"1.0\"")).interface(title));
            }
            if let Some((name, t)) = types.filter(|(_, t)| t != "standard32") {
                send(Finding::error("binary.version", format!("{id}_{name} returned {t:?}, not \"standard32\"")).interface(title));
            }
        }
    }
    drop(library);
    if !missing.is_empty() {
        send(Finding::skipped("lifecycle.run", "not run: the binary lacks functions of its interface").interface(title));
        return Ok(());
    }
    cell("lifecycle.run", 3);
    match tracer.traced(&record("(the lifecycle run)", "(the importer's calls)"), || run(&job.dir, interface)) {
        Ok(summary) => send(Finding::passed("lifecycle.run", summary).interface(title)),
        Err(e) => send(Finding::error("lifecycle.run", e).interface(title)),
    }
    Ok(())
}

/// The text a `const char *(void)` function returns (`NULL` shown as such).
fn text(f: unsafe extern "C" fn() -> *const std::ffi::c_char) -> String {
    // SAFETY: the standard's version queries return static C strings or NULL.
    let p = unsafe { f() };
    if p.is_null() {
        return "NULL".to_owned();
    }
    // SAFETY: non-NULL: a NUL-terminated string.
    unsafe { std::ffi::CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

/// The lifecycle through the importer: instantiate, initialize, up to [`STEPS`] steps of the
/// DefaultExperiment with the outputs read and finite after each, terminate and free.
fn run(dir: &Path, interface: Interface) -> Result<String, String> {
    let as_interface = match interface {
        Interface::CoSimulation => ImporterInterface::CoSimulation,
        Interface::ModelExchange => ImporterInterface::ModelExchange,
    };
    let fmu = Fmu::load_unpacked(&dir.join("modelDescription.xml"), dir, Some(as_interface))?;
    let d = &fmu.description;
    let experiment = d.default_experiment.unwrap_or_default();
    let start = experiment.start_time.unwrap_or(0.0);
    let stop = experiment.stop_time.filter(|s| *s > start).unwrap_or(start + 1.0);
    let outputs: Vec<_> = d.outputs().filter(|v| v.kind.is_numeric()).collect();
    let mut reader = Reader::new(d.fmi_version, &outputs)?;
    let mut values = vec![0.0; outputs.len()];
    let mut instance = fmu.instantiate("validate", false)?;
    instance.setup_experiment(experiment.tolerance, start, stop)?;
    instance.enter_initialization_mode()?;
    instance.exit_initialization_mode()?;
    let finite = |values: &[f64], t: f64| match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(format!("output {} is {} at t = {t}", outputs[i].name, values[i])),
        None => Ok(()),
    };
    instance.read(&mut reader, &mut values)?;
    finite(&values, start)?;
    let h = (stop - start) / STEPS as f64;
    let mut steps = 0;
    for k in 0..STEPS {
        let t = start + k as f64 * h;
        if let Step::Ended { reason, .. } = instance.do_step(t, h)? {
            return Ok(format!("instantiated, initialized, {steps} steps until the model ended the run ({reason}), terminated and freed"));
        }
        steps += 1;
        instance.read(&mut reader, &mut values)?;
        finite(&values, t + h)?;
    }
    drop(instance);
    Ok(format!(
        "instantiated with its GUID, initialized, {steps} steps to t = {stop} with the {} outputs finite, terminated and freed",
        outputs.len()
    ))
}
