//! The probe process, a worker of the sandbox: for each job the binary loaded (its
//! initializers bounded by the timeout like any call), then one probe run. The `binary`
//! probe checks the binary itself: loadable, every function its version requires exported,
//! the version texts it returns.

use std::path::Path;

use fmi_c::Library;
use runner_sandbox::worker::{Incoming, Serving};

use crate::fmi::{Fmi, Interface, Version};
use crate::fmi2::Fmi2;
use crate::fmi3::Fmi3;
use crate::instance::{Binary, Tracer};
use crate::isolation::{CallRecord, Job, Message, Out, Outcome, Probes, Progress, CELL_MARK};
use crate::model::Model;
use crate::probe::{first_check, known, Ctx};
use crate::report::{Finding, Severity};
use crate::{fmi2, fmi3, probes};

/// FMI 1.0 FMUs get no probes: their checks are the description's and a lifecycle run
/// ([`crate::fmi1`]).
const FMI1_IN_PROCESS: &str = "FMI 1.0 FMUs are not probed (their lifecycle is checked through the importer)";

/// The probe process: serves the supervisor's jobs, one probe each (a fresh process for each,
/// the sandbox's `one job per worker`).
pub(crate) fn serve() -> Result<(), String> {
    let mut serving = Serving::<Probes>::start()?;
    let progress = Progress::over(serving.shared());
    while let Some(request) = serving.receive()? {
        match request {
            Incoming::Setup(()) => serving.ready(Ok(()))?,
            Incoming::Job { id, job } => {
                // What the FMU prints from now on is this probe's.
                eprintln!("{CELL_MARK}start");
                let outcome = {
                    let out = Out::new(|message| {
                        let _ = serving.send(message);
                    });
                    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| run(&job, progress, &out))) {
                        Ok(Ok(())) => Outcome::Finished,
                        Ok(Err(e)) => Outcome::Internal(e),
                        Err(panic) => {
                            let text =
                                panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned());
                            Outcome::Internal(format!("panic: {}", text.unwrap_or_default()))
                        }
                    }
                };
                runner_sandbox::worker::flush();
                serving.finish(id, outcome, false)?;
            }
        }
    }
    Ok(())
}

/// Runs the probe `job` names on the FMU unpacked by the parent, its calls recorded in
/// `progress`; its messages go to `out`.
fn run(job: &Job, progress: Progress<'static>, out: &Out) -> Result<(), String> {
    let fmi = job.fmi;
    if fmi == Fmi::Fmi1 {
        return crate::fmi1::lifecycle(job, progress, out);
    }
    let xml = std::fs::read_to_string(job.dir.join("modelDescription.xml")).map_err(|e| format!("cannot read the description: {e}"))?;
    // The probe process lives for one probe: what every instance refers to lives as long.
    let model: &'static Model = Box::leak(Box::new(match fmi {
        Fmi::Fmi2 => fmi2::description::model(&xml)?,
        Fmi::Fmi3 => fmi3::description::model(&xml)?,
        Fmi::Fmi1 => return Err(FMI1_IN_PROCESS.to_owned()),
    }));
    let tracer = Tracer { progress, slot: 0, timeout: job.timeout };
    let shown = job.binary.strip_prefix(&job.dir).unwrap_or(&job.binary).display().to_string();
    if job.probe == "binary" {
        out.send(&Message::Cell { check: "binary.load".into(), index: 0, crash: Severity::Error });
    }
    // Loading runs the library's initializers: a call like any other, bounded by the timeout.
    let record = CallRecord { call: "dlopen".into(), state: "(loading the binary)".into(), variable: None, value: Some(shown.clone()) };
    let loaded = tracer.traced(&record, || load(fmi, &job.binary, model, &job.dir, tracer));
    let binary: &'static dyn Binary = match loaded {
        Ok(binary) => binary,
        Err(e) => {
            let check = first_check(&job.probe, fmi);
            out.send(&Message::finding(&Finding::error(check, format!("{shown} cannot be loaded: {e}"))));
            return Ok(());
        }
    };
    if job.probe == "binary" {
        check_binary(binary, &job.interfaces, &shown, out);
        return Ok(());
    }
    if !known(&job.probe) {
        return Err(format!("unknown probe {:?}", job.probe));
    }
    let interface = *job.interfaces.first().ok_or("no interface")?;
    let mut ctx = Ctx::new(binary, interface, out, &job.runs, job.resume);
    probes::run(&job.probe, &mut ctx)
}

/// Loads the binary at `path` with the function table of its version.
fn load(fmi: Fmi, path: &Path, model: &'static Model, dir: &Path, tracer: Tracer) -> Result<&'static dyn Binary, String> {
    // SAFETY: loading runs the library's initializers, which is what this process is for.
    let library = unsafe { Library::open(path) }.map_err(|e| {
        // The report names the binary by its place in the FMU, not in the temporary directory.
        let prefix = format!("cannot load {}: ", path.display());
        e.strip_prefix(&prefix).map_or(e.clone(), str::to_owned)
    })?;
    Ok(match fmi {
        Fmi::Fmi2 => Box::leak(Box::new(Fmi2::new(library, model, dir, tracer)?)),
        Fmi::Fmi3 => Box::leak(Box::new(Fmi3::new(library, model, dir, tracer)?)),
        Fmi::Fmi1 => return Err(FMI1_IN_PROCESS.to_owned()),
    })
}

/// The binary: loadable, every function its version requires exported, the version texts
/// the standard fixes.
fn check_binary(binary: &dyn Binary, interfaces: &[Interface], shown: &str, out: &Out) {
    let send = |f: Finding| out.send(&Message::finding(&f));
    send(Finding::passed("binary.load", format!("{shown} loads")));
    out.send(&Message::Cell { check: "binary.exports".into(), index: 1, crash: Severity::Error });
    let exports = binary.required_exports(interfaces);
    let mut missing = 0;
    for (f, why) in &exports.required {
        if !binary.exports(f) {
            missing += 1;
            send(Finding::error("binary.exports", format!("{shown} does not export {f}{why}")).call(*f));
        }
    }
    if missing == 0 {
        send(Finding::passed("binary.exports", exports.passed));
    }
    out.send(&Message::Cell { check: "binary.version".into(), index: 2, crash: Severity::Error });
    let interface = interfaces.first().copied().unwrap_or(Interface::CoSimulation);
    let mut fine = true;
    let mut said = Vec::new();
    for &(op, expected) in binary.fmi().identity() {
        let name = binary.table().name(op, interface);
        said.push(if said.is_empty() { format!("{name} returns \"{expected}\"") } else { format!("{name} \"{expected}\"") });
        let record = CallRecord { call: name.into(), state: "(no instance)".into(), variable: None, value: None };
        let Some(text) = binary.tracer().traced(&record, || binary.query(op)) else { continue };
        if text.as_deref() != Some(expected) {
            fine = false;
            let shown_text = text.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 60, "...")));
            send(
                Finding::error("binary.version", format!("{name} returned {shown_text}, not \"{expected}\"")).call(name).value(shown_text),
            );
        }
    }
    if fine {
        send(Finding::passed("binary.version", said.join(" and ")));
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    /// A job reaches the probe process as it was sent (through the sandbox's frames).
    #[test]
    fn a_job_travels_whole() {
        let job = Job {
            fmi: Fmi::Fmi3,
            dir: "d".into(),
            runs: "r".into(),
            binary: "d/binaries/x86_64-linux/m.so".into(),
            interfaces: vec![Interface::CoSimulation, Interface::ModelExchange],
            timeout: Duration::from_millis(500),
            probe: "state-machine:StepMode".into(),
            resume: 7,
        };
        let mut pipe = Vec::new();
        runner_sandbox::frame::send(&mut pipe, &job).unwrap();
        let back: Job = runner_sandbox::frame::receive(&mut &pipe[..]).unwrap().unwrap();
        assert_eq!(back, job);
    }

    /// A finding reaches the supervisor whole, its absent fields included (the reason it
    /// travels as JSON inside the frame).
    #[test]
    fn a_finding_travels_whole() {
        let finding = Finding::error("lifecycle.run", "fmi3DoStep returned fmi3Error").interface(Some("Co-Simulation"));
        let mut pipe = Vec::new();
        runner_sandbox::frame::send(&mut pipe, &Message::finding(&finding)).unwrap();
        let Some(Message::Finding(json)) = runner_sandbox::frame::receive(&mut &pipe[..]).unwrap() else { panic!("not a finding") };
        assert_eq!(serde_json::from_str::<Finding>(&json).unwrap(), finding);
    }
}
