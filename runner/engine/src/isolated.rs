//! The engine in worker processes, through the sandbox: the messages of its workers
//! ([`Engine`]), the worker's loop ([`serve`]), and the words for where a worker was when it
//! died (the importer records every FMI call and the model time in the memory each worker
//! shares with its supervisor).
//!
//! A worker loads the FMU once ([`Setup::Load`]) and then runs sweep points ([`Setup::Sweep`]
//! then [`Job::Point`]s) or runs ([`Job::Run`], its samples streamed back as
//! [`Samples`]) or linearizations ([`Job::Linearize`]). After a job in which an FMU returned fmiFatal the worker runs no more: the
//! standard trusts no instance of that FMU in the process any longer.

use std::time::Duration;

use fmi_importer::trace::{self, Call, CallSlot};
use fmi_importer::{Description, Interface};
use runner_sandbox::worker::{Incoming, Pacer, Serving};
use runner_sandbox::{Config, Failure, Service, SharedMemory, WorkerCommand};
use serde::{Deserialize, Serialize};

use crate::linear::Linear;
use crate::request::{FmuSource, LinearizeRequest, RunRequest, SweepRequest};
use crate::run::Texts;
use crate::sweep::{Plan, PointResult};

/// The engine's workers.
pub struct Engine;

/// What a worker is told before its jobs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Setup {
    /// Load the FMU (first, once per worker).
    Load(FmuSource),
    /// Plan this sweep, for the [`Job::Point`]s that follow.
    Sweep(Box<SweepRequest>),
}

/// A job of a worker.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Job {
    /// Run point `.0` of the sweep.
    Point(u64),
    /// Run this, streaming its samples (boxed: a sweep sends many points, each as small as it
    /// can be).
    Run(Box<RunRequest>),
    /// Linearize as this says.
    Linearize(Box<LinearizeRequest>),
}

/// Samples of a running [`Job::Run`]: `t` then the recorded values, repeated; and per sample, in
/// order, the texts of the columns whose numbers do not give them (`Reader::needs_text`).
#[derive(Debug, Serialize, Deserialize)]
pub struct Samples {
    /// `t` and the recorded values of each sample, one after another.
    pub values: Vec<f64>,
    /// The texts of the columns numbers do not give, sample after sample.
    pub texts: Vec<String>,
}

/// How a run ended in a worker: [`crate::run::Outcome`] on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunEnd {
    /// Why the model stopped before the stop time, if it did.
    pub ended_early: Option<String>,
    /// Model Exchange: the work of the runner's integrator (steps, evaluations, Jacobians).
    pub counters: Option<fmi_importer::exchange::Counters>,
    /// The state at the stop time, when asked for.
    #[serde(default)]
    pub final_state: Option<Vec<u8>>,
}

/// How a job ended.
#[derive(Debug, Serialize, Deserialize)]
pub enum Outcome {
    /// A sweep point's metrics and status.
    Point(PointResult),
    /// How a run ended, or the error that ended it.
    Run(Result<RunEnd, String>),
    /// The linear model, or the error that stopped the linearization.
    Linear(Result<Box<Linear>, String>),
}

impl Service for Engine {
    type Setup = Setup;
    type Job = Job;
    type Message = Samples;
    type Outcome = Outcome;

    fn failed(job: &Job, failure: &Failure, shared: &SharedMemory) -> Outcome {
        // SAFETY: the worker laid its call slot (atomics only) over the start of this memory.
        let at = place(unsafe { shared.view::<CallSlot>() }.read());
        match job {
            Job::Point(_) => Outcome::Point(PointResult { metrics: None, status: failure.describe(&at) }),
            Job::Run(request) => Outcome::Run(Err(format!("{}: {}", request.name, failure.describe(&at)))),
            Job::Linearize(request) => Outcome::Linear(Err(format!("{}: {}", request.name, failure.describe(&at)))),
        }
    }
}

/// Where a worker was: `in fmi2DoStep at t = 0.31`.
pub fn place((call, time): (Call, Option<f64>)) -> String {
    match (call, time) {
        (Call::None, _) => "before its first FMI call".to_owned(),
        (Call::Load, _) => "while loading the FMU's binary".to_owned(),
        (call, Some(t)) => format!("in {} at t = {t}", call.name()),
        (call, None) => format!("in {}", call.name()),
    }
}

/// True if the FMU declares, for `interface`, that it can be instantiated only once per process.
pub fn once_per_process(description: &Description, interface: Interface) -> bool {
    description.interface(interface).is_some_and(|c| c.can_be_instantiated_only_once_per_process)
}

/// The sandbox of runs in worker processes started by `command` (the runner's own binary with
/// its hidden worker command), each stopped after `timeout` and limited to `memory_mib` MiB.
pub fn config(command: WorkerCommand, timeout: Option<Duration>, memory_mib: u64) -> Result<Config, String> {
    if memory_mib < 64 {
        return Err(format!("--worker-memory {memory_mib} MiB is too little for a worker (at least 64)"));
    }
    Ok(Config { timeout, memory_limit: Some(memory_mib << 20), print: fmi_importer::print_line, ..Config::new(command) })
}

/// Samples per [`Samples`] message, in f64s: 64 KiB frames.
const BATCH: usize = 8192;

/// Runs the worker until its supervisor releases it or closes the pipe. Only a supervisor
/// starts this (the runner's hidden `worker` command), with the descriptors it set up.
pub fn serve() -> Result<(), String> {
    let mut serving = Serving::<Engine>::start()?;
    fmi_importer::set_log_printer(runner_sandbox::worker::log);
    // SAFETY: the call slot (atomics only) fits in the shared page, which lives for the rest of
    // the process.
    let slot: &'static CallSlot = unsafe { serving.shared().view::<CallSlot>() };
    slot.clear();
    trace::set_slot(slot);
    let source = match serving.receive()? {
        Some(Incoming::Setup(Setup::Load(source))) => source,
        // Let go before the FMU was known (started ahead, and the FMU turned out unusable).
        None => return Ok(()),
        Some(_) => return Err("the first request must be Load".to_owned()),
    };
    let fmu = match source.load() {
        Ok(fmu) => fmu,
        Err(e) => return serving.ready(Err(e)),
    };
    serving.ready(Ok(()))?;
    let mut plan: Option<Plan> = None;
    let mut point = Vec::new();
    let never = || false;
    while let Some(request) = serving.receive()? {
        slot.clear();
        match request {
            Incoming::Setup(Setup::Load(_)) => return Err("the FMU is loaded once per worker".to_owned()),
            Incoming::Setup(Setup::Sweep(request)) => match request.plan(&fmu.description, &fmu.identifier, fmu.interface) {
                Ok(p) => {
                    plan = Some(p);
                    serving.ready(Ok(()))?;
                }
                Err(e) => return serving.ready(Err(e)),
            },
            Incoming::Job { id, job: Job::Point(i) } => {
                let plan = plan.as_ref().ok_or("a Point request before the Sweep")?;
                let i = plan.space.index(i)?;
                let result = plan.run_point(&fmu, i, &mut point, &never);
                serving.finish(id, Outcome::Point(result), trace::fatal_seen())?;
            }
            Incoming::Job { id, job: Job::Run(request) } => {
                let result = fmi_importer::call_log::logging(request.log_fmi_calls.as_ref(), || run(&serving, &fmu, &request));
                serving.finish(id, Outcome::Run(result), trace::fatal_seen())?;
            }
            Incoming::Job { id, job: Job::Linearize(request) } => {
                let result = request.run(&fmu).map(Box::new);
                serving.finish(id, Outcome::Linear(result), trace::fatal_seen())?;
            }
        }
    }
    runner_sandbox::worker::flush();
    Ok(())
}

/// Runs `request` on `fmu`, sending its samples in batches ([`Pacer`]).
fn run(serving: &Serving<Engine>, fmu: &fmi_importer::Fmu, request: &RunRequest) -> Result<RunEnd, String> {
    let bound = request.bind(&fmu.description, fmu.interface, true)?;
    let mut samples: Vec<f64> = Vec::with_capacity(BATCH + 64);
    let mut texts = Vec::new();
    // The columns the supervisor cannot print from their numbers.
    let mut lossy: Option<Vec<usize>> = None;
    let mut pacer = Pacer::new(BATCH);
    let flush = |samples: &mut Vec<f64>, texts: &mut Vec<String>| {
        serving.send(&Samples { values: std::mem::take(samples), texts: std::mem::take(texts) })
    };
    let outcome = bound.run().execute(fmu, |t: f64, values: &[f64], reader: &dyn Texts| {
        samples.push(t);
        samples.extend_from_slice(values);
        let lossy = lossy.get_or_insert_with(|| (0..values.len()).filter(|&c| reader.needs_text(c)).collect());
        texts.extend(lossy.iter().map(|&c| reader.text(c, values)));
        if pacer.due(samples.len().max(texts.len())) {
            flush(&mut samples, &mut texts)?;
            samples.reserve(BATCH + 64);
        }
        Ok(())
    });
    if !samples.is_empty() {
        flush(&mut samples, &mut texts)?;
    }
    outcome.map(|o| RunEnd { ended_early: o.ended_early, counters: o.counters, final_state: o.final_state })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn places_name_the_call_and_the_time() {
        assert_eq!(place((Call::DoStep, Some(0.31))), "in fmi2DoStep at t = 0.31");
        assert_eq!(place((Call::Instantiate, None)), "in fmi2Instantiate");
        assert_eq!(place((Call::Load, None)), "while loading the FMU's binary");
        assert_eq!(place((Call::None, Some(1.0))), "before its first FMI call");
    }
}
