//! The one place untrusted FMU code runs in child processes. A supervisor starts workers (its
//! own program started again in worker mode, [`WorkerCommand`]), sends them jobs and hears their
//! results; a worker that crashes (any signal, an `exit` inside the FMU), hangs past the time
//! limit, grows past its memory limit or is left unusable by an fmiFatal costs only the job it
//! was running, and a fresh worker takes its place.
//!
//! The sandbox knows nothing of FMUs. A client (the engine's runs and sweeps, the validator's
//! probes) names its messages by implementing [`Service`]: a setup each worker receives once
//! (load this FMU, plan this sweep), the jobs, the messages a job streams while it runs (samples)
//! and its outcome. The pieces:
//! - [`frame`]: the length-prefixed postcard frames on a pipe each way;
//! - [`shared`]: a page of memory each worker shares with its supervisor, where the client
//!   records what the worker is doing (the FMI call and the model time), read after a crash;
//! - [`pool`]: starting workers, their limits, and the events they send;
//! - [`worker`]: the worker's side ([`worker::Serving`]);
//! - [`batch`]: many independent jobs (a sweep's points) over a pool, delivered in order;
//! - [`session`]: one job at a time, its messages streamed (a simulation, the runs of a
//!   comparison);
//! - [`Failure`]: how a worker ended before it finished a job, in words.
//!
//! Workers run in a process group of their own (a Ctrl-C at the terminal reaches only the
//! supervisor, which decides) and are killed by the kernel if the thread that started them dies,
//! so a killed supervisor leaves no workers behind. They must be started from one long-lived
//! thread (the one calling these functions), as that parent-death signal follows the starting
//! thread.

pub mod batch;
pub mod frame;
pub mod pool;
pub mod session;
pub mod shared;
pub mod worker;

use std::os::unix::process::ExitStatusExt;
use std::process::ExitStatus;
use std::time::Duration;

use serde::de::DeserializeOwned;
use serde::Serialize;

pub use batch::{run_batch, Workers};
pub use pool::{Config, WorkerCommand};
pub use session::Session;
pub use shared::SharedMemory;

/// What one client's workers do: the messages between its supervisor and its workers. Both
/// ends are the same program, so the encoding needs no versioning: every option a job takes
/// travels as a field of these types.
pub trait Service: 'static {
    /// What a worker is told once before its jobs (several setups may follow one another: load
    /// an FMU, then plan a sweep of it). Each is answered ready or failed; a worker whose setup
    /// failed ends.
    type Setup: Serialize + DeserializeOwned + Clone + Send + 'static;
    /// One job.
    type Job: Serialize + DeserializeOwned + Clone + Send + 'static;
    /// What a job sends while it runs (a run's samples).
    type Message: Serialize + DeserializeOwned + Send + 'static;
    /// How a job ended.
    type Outcome: Serialize + DeserializeOwned + Send + 'static;

    /// The outcome of `job`, whose worker ended (or was stopped) before finishing it as
    /// `failure` says; `shared` is the worker's shared memory as it left it.
    fn failed(job: &Self::Job, failure: &Failure, shared: &SharedMemory) -> Self::Outcome;
}

/// How a worker ended before it finished its job.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Failure {
    /// The worker process ended: a signal (a crash, or a kill from outside) or an exit.
    Ended(ExitStatus),
    /// The job ran longer than the time limit; the worker was killed.
    TimedOut(Duration),
}

impl Failure {
    /// The failure in words, with where the worker was (`in fmi2DoStep at t = 0.31`, from the
    /// client's record in the shared memory): `crashed: SIGSEGV in fmi2DoStep at t = 0.31`.
    pub fn describe(&self, place: &str) -> String {
        match self {
            Failure::Ended(status) => match (status.signal(), status.code()) {
                (Some(signal), _) => format!("crashed: {} {place}", signal_name(signal)),
                (None, Some(code)) => format!("exited: the worker process ended with code {code} {place}"),
                (None, None) => format!("crashed: the worker ended ({status}) {place}"),
            },
            Failure::TimedOut(limit) => format!("timed out after {} s {place}", limit.as_secs_f64()),
        }
    }
}

/// The name of signal `signal` (`SIGSEGV`), as a sweep's status column shows it.
pub fn signal_name(signal: i32) -> String {
    let name = match signal {
        libc::SIGSEGV => "SIGSEGV",
        libc::SIGABRT => "SIGABRT",
        libc::SIGBUS => "SIGBUS",
        libc::SIGFPE => "SIGFPE",
        libc::SIGILL => "SIGILL",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGSYS => "SIGSYS",
        libc::SIGPIPE => "SIGPIPE",
        libc::SIGXCPU => "SIGXCPU",
        libc::SIGXFSZ => "SIGXFSZ",
        libc::SIGINT => "SIGINT",
        libc::SIGHUP => "SIGHUP",
        libc::SIGQUIT => "SIGQUIT",
        libc::SIGALRM => "SIGALRM",
        libc::SIGUSR1 => "SIGUSR1",
        libc::SIGUSR2 => "SIGUSR2",
        _ => return format!("signal {signal}"),
    };
    name.to_owned()
}

/// Physical memory in bytes, from /proc/meminfo (`None` if unreadable).
pub fn physical_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// The default memory limit of each of `workers` workers in MiB: together three quarters of the
/// machine's memory, so a leaking FMU fails its job before the machine starts to swap.
pub fn default_memory_mib(workers: usize) -> u64 {
    physical_memory().map_or(4096, |bytes| bytes / 4 * 3 / workers.max(1) as u64 / (1 << 20))
}

/// Checks a timeout given in seconds (by the command-line `option`).
pub fn timeout(option: &str, seconds: Option<f64>) -> Result<Option<Duration>, String> {
    match seconds {
        None => Ok(None),
        Some(s) if s.is_finite() && s > 0.0 && s < 1e9 => Ok(Some(Duration::from_secs_f64(s))),
        Some(s) => Err(format!("{option} {s} must be a positive number of seconds")),
    }
}

#[cfg(test)]
mod tests;
