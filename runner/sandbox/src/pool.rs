//! Starting workers with their limits, and hearing what they say: every worker's replies arrive
//! in one channel, read by a thread per worker, so a supervisor waits on one queue whatever the
//! number of workers.

use std::ffi::OsString;
use std::fs::File;
use std::io::BufReader;
use std::os::fd::{AsFd, AsRawFd, OwnedFd, RawFd};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

use crate::frame::{self, Reply, Request};
use crate::shared::SharedMemory;
use crate::Service;

/// The descriptors a worker finds its shared memory, its requests and its replies at.
pub(crate) const SHARED_FD: RawFd = 3;
pub(crate) const REQUESTS_FD: RawFd = 4;
pub(crate) const REPLIES_FD: RawFd = 5;

/// How to start a worker: a program (the supervisor's own binary, usually) with the arguments
/// and environment that put it in worker mode.
#[derive(Debug, Clone)]
pub struct WorkerCommand {
    /// The program.
    pub program: PathBuf,
    /// Its arguments.
    pub args: Vec<OsString>,
    /// Variables added to the worker's environment.
    pub env: Vec<(OsString, OsString)>,
}

impl WorkerCommand {
    /// This process's own program with `args`: the usual worker.
    pub fn this_program(args: &[&str]) -> Result<WorkerCommand, String> {
        let program = std::env::current_exe().map_err(|e| format!("cannot find this program's own binary to start workers: {e}"))?;
        Ok(WorkerCommand { program, args: args.iter().map(OsString::from).collect(), env: Vec::new() })
    }
}

/// How workers are started and what they may use.
#[derive(Debug, Clone)]
pub struct Config {
    /// How to start a worker.
    pub command: WorkerCommand,
    /// A job taking longer is stopped and its worker killed (the time a worker takes to start
    /// does not count: see [`START_LIMIT`]).
    pub timeout: Option<Duration>,
    /// Address space a worker may use (bytes); a worker whose resident memory passes half of it
    /// after a job is replaced before its next one (an FMU that leaks).
    pub memory_limit: Option<u64>,
    /// Bytes of memory each worker shares with its supervisor (whole pages).
    pub shared_bytes: usize,
    /// Where workers' standard error (and standard output) goes: `None`, the supervisor's own;
    /// else this file, appended to (a validator quotes what an FMU printed before it crashed).
    pub log_file: Option<PathBuf>,
    /// Prints a worker's log line (an FMU's message) where the supervisor's own go.
    pub print: fn(&str),
}

impl Config {
    /// Workers started by `command`, with no time or memory limit, one page shared, printing
    /// log lines on stderr.
    pub fn new(command: WorkerCommand) -> Config {
        Config { command, timeout: None, memory_limit: None, shared_bytes: 4096, log_file: None, print: eprint_line }
    }
}

fn eprint_line(line: &str) {
    eprintln!("{line}");
}

/// How long a worker may take to start (to load an FMU's binary, running its initializers)
/// when the time limit is shorter: a job's limit counts from when its worker is ready.
pub const START_LIMIT: Duration = Duration::from_secs(60);

/// What a worker's reader thread reports.
pub(crate) enum Event<S: Service> {
    /// A reply.
    Reply(ReplyOf<S>),
    /// The worker closed its reply pipe: it exited or died.
    Gone,
}

/// A reply of `S`'s workers.
pub(crate) type ReplyOf<S> = Reply<<S as Service>::Message, <S as Service>::Outcome>;

/// A running worker.
pub(crate) struct Worker<S: Service> {
    pub(crate) id: u64,
    child: Child,
    /// `None` once closed (the worker then exits when idle).
    requests: Option<File>,
    pub(crate) shared: SharedMemory,
    /// Ready replies still to come: until then the worker is starting, and a job's time limit
    /// restarts when it is ready, so that a slow start is not the job's.
    pub(crate) unready: u8,
    _service: std::marker::PhantomData<S>,
}

impl<S: Service> Worker<S> {
    /// Sends a request. A failure means the worker is gone (a full pipe only blocks), and its
    /// reader thread reports that, with what the worker said last (a setup that failed), so the
    /// error itself is not needed.
    pub(crate) fn send(&mut self, request: &Request<S::Setup, S::Job>) {
        if let Some(pipe) = self.requests.as_mut() {
            let _ = frame::send(pipe, request);
        }
    }

    /// Sends `setup`, to be answered before the jobs sent after it.
    pub(crate) fn setup(&mut self, setup: &S::Setup, retire_above: Option<u64>) {
        self.send(&Request::Setup { setup: setup.clone(), retire_above });
        self.unready = self.unready.saturating_add(1);
    }

    /// Kills the worker's process group now and reaps it; returns how it ended and its shared
    /// memory, as it left it.
    pub(crate) fn kill(mut self) -> (ExitStatus, SharedMemory) {
        // SAFETY: signalling the process group we created for this worker (its pid).
        unsafe { libc::kill(-(self.child.id() as libc::pid_t), libc::SIGKILL) };
        let _ = self.child.kill();
        self.requests = None;
        let status = self.child.wait().unwrap_or_else(|_| ExitStatus::from_raw(libc::SIGKILL));
        (status, self.shared)
    }

    /// Lets an idle worker go: it drops its parent-death signal (an alarm of its own ends it
    /// within seconds should it hang on its way out), acknowledges, and exits (unloading an FMU,
    /// removing files it made) while the supervisor goes on; a thread reaps it. Returns its id,
    /// for [`Pool::await_released`]: until the acknowledgement the worker still dies with the
    /// supervisor.
    pub(crate) fn release(mut self) -> u64 {
        self.send(&Request::Release);
        self.detach()
    }

    /// [`Worker::release`] for a worker already sent Release.
    pub(crate) fn detach(self) -> u64 {
        let Worker { id, mut child, .. } = self;
        std::thread::spawn(move || {
            let _ = child.wait();
        });
        id
    }

    /// The time limit of a job on this worker, given the configured `limit`: at least
    /// [`START_LIMIT`] while it is starting.
    pub(crate) fn limit(&self, limit: Duration) -> Duration {
        if self.unready > 0 {
            limit.max(START_LIMIT)
        } else {
            limit
        }
    }
}

/// Starts workers and gathers what they say in one channel.
pub(crate) struct Pool<S: Service> {
    pub(crate) config: Config,
    /// What every new worker is told first, in order.
    setups: Vec<(S::Setup, Option<u64>)>,
    sender: Sender<(u64, Event<S>)>,
    events: Receiver<(u64, Event<S>)>,
    next_id: u64,
    /// One job per worker: each is replaced after its job (an FMU that allows one instance per
    /// process, canBeInstantiatedOnlyOncePerProcess).
    pub(crate) one_job_per_worker: bool,
}

impl<S: Service> Pool<S> {
    /// A pool starting workers as `config` says; none is started yet.
    pub(crate) fn new(config: Config) -> Pool<S> {
        let (sender, events) = mpsc::channel();
        Pool { config, setups: Vec::new(), sender, events, next_id: 0, one_job_per_worker: false }
    }

    /// The configuration workers start with.
    pub(crate) fn config(&self) -> &Config {
        &self.config
    }

    /// Tells every worker started from now on `setup` (after the setups before it).
    pub(crate) fn add_setup(&mut self, setup: &S::Setup, retire_above: Option<u64>) {
        self.setups.push((setup.clone(), retire_above));
    }

    /// True once a setup is known (a worker started now is told what to do).
    pub(crate) fn has_setup(&self) -> bool {
        !self.setups.is_empty()
    }

    /// Starts a worker and sends it the setups known so far (it answers Ready or Failed later).
    pub(crate) fn spawn(&mut self) -> Result<Worker<S>, String> {
        let config = &self.config;
        let shared = SharedMemory::new(config.shared_bytes)?;
        let (requests_read, requests) = std::io::pipe().map_err(|e| format!("cannot create a pipe to a worker: {e}"))?;
        let (replies, replies_write) = std::io::pipe().map_err(|e| format!("cannot create a pipe from a worker: {e}"))?;
        let fds = [shared.fd(), requests_read.as_raw_fd(), replies_write.as_raw_fd()];
        let (limit, parent) = (config.memory_limit, std::process::id());
        let command = &config.command;
        let mut cmd = Command::new(&command.program);
        cmd.args(&command.args).envs(command.env.iter().map(|(k, v)| (k, v))).stdin(Stdio::null()).process_group(0);
        // The worker's standard output joins its standard error: an FMU that prints cannot
        // corrupt anything, the protocol has descriptors of its own.
        let log: OwnedFd = match &config.log_file {
            Some(path) => std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(path)
                .map_err(|e| format!("cannot open the workers' log {}: {e}", path.display()))?
                .into(),
            None => std::io::stderr().as_fd().try_clone_to_owned().map_err(|e| format!("cannot pass standard error to a worker: {e}"))?,
        };
        let log_copy = log.try_clone().map_err(|e| format!("cannot pass standard error to a worker: {e}"))?;
        cmd.stdout(Stdio::from(log)).stderr(Stdio::from(log_copy));
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 || libc::getppid() != parent as libc::pid_t {
                    return Err(std::io::Error::other("the supervisor is gone"));
                }
                place_descriptors(&fds)?;
                if let Some(bytes) = limit {
                    let rlimit = libc::rlimit { rlim_cur: bytes as libc::rlim_t, rlim_max: bytes as libc::rlim_t };
                    if libc::setrlimit(libc::RLIMIT_AS, &rlimit) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                }
                Ok(())
            });
        }
        let child = cmd.spawn().map_err(|e| format!("cannot start a worker process ({}): {e}", command.program.display()))?;
        // The worker's ends, now its own: closed here, so that its exit closes the pipes.
        drop((requests_read, replies_write));
        let id = self.next_id;
        self.next_id += 1;
        let sender = self.sender.clone();
        std::thread::spawn(move || {
            let mut replies = BufReader::new(replies);
            loop {
                match frame::receive::<ReplyOf<S>>(&mut replies) {
                    Ok(Some(reply)) => {
                        if sender.send((id, Event::Reply(reply))).is_err() {
                            return;
                        }
                    }
                    _ => {
                        let _ = sender.send((id, Event::Gone));
                        return;
                    }
                }
            }
        });
        let mut worker = Worker {
            id,
            child,
            requests: Some(File::from(OwnedFd::from(requests))),
            shared,
            unready: 0,
            _service: std::marker::PhantomData,
        };
        for (setup, retire_above) in &self.setups {
            worker.setup(setup, *retire_above);
        }
        if self.setups.is_empty() {
            // Started ahead of its setup: it is starting until told what to do.
            worker.unready = 1;
        }
        Ok(worker)
    }

    /// The next event, or `None` after `wait`. Log lines are printed here, as they arrive.
    pub(crate) fn next(&self, wait: Duration) -> Option<(u64, Event<S>)> {
        let deadline = Instant::now() + wait;
        loop {
            match self.events.recv_timeout(deadline.saturating_duration_since(Instant::now())).ok()? {
                (_, Event::Reply(Reply::Log(line))) => (self.config.print)(&line),
                event => return Some(event),
            }
        }
    }

    /// Waits (a second at most) until the released workers `ids` acknowledged, so that none is
    /// killed half-way through its cleanup when this process exits.
    pub(crate) fn await_released(&self, ids: &mut Vec<u64>) {
        let deadline = Instant::now() + Duration::from_secs(1);
        while !ids.is_empty() {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.next(left) {
                Some((id, Event::Reply(Reply::Released) | Event::Gone)) => ids.retain(|&i| i != id),
                Some(_) => {}
                None => return,
            }
        }
    }

    /// True if a worker that reported `resident` bytes (and `tainted`) after a job must be
    /// replaced before its next one.
    pub(crate) fn worn_out(&self, resident: u64, tainted: bool) -> bool {
        tainted || self.one_job_per_worker || self.config.memory_limit.is_some_and(|limit| resident > limit / 2)
    }

    /// The memory a worker retires itself at after a job: where the supervisor would replace
    /// it, as the next job is already on its way when the supervisor hears of its memory.
    pub(crate) fn retire_above(&self) -> Option<u64> {
        if self.one_job_per_worker {
            Some(0)
        } else {
            self.config.memory_limit.map(|limit| limit / 2)
        }
    }
}

/// Moves the worker's descriptors `fds` (shared memory, requests, replies) to their fixed
/// numbers [`SHARED_FD`], [`REQUESTS_FD`] and [`REPLIES_FD`], inheritable. Runs between fork and
/// exec: system calls only.
fn place_descriptors(fds: &[RawFd; 3]) -> std::io::Result<()> {
    // First above the fixed numbers, so that no move overwrites a descriptor still to be moved.
    let mut high = [0; 3];
    for (slot, &fd) in high.iter_mut().zip(fds) {
        // SAFETY: duplicating a descriptor this process holds.
        *slot = unsafe { libc::fcntl(fd, libc::F_DUPFD_CLOEXEC, 10) };
        if *slot < 0 {
            return Err(std::io::Error::last_os_error());
        }
    }
    for (&from, to) in high.iter().zip([SHARED_FD, REQUESTS_FD, REPLIES_FD]) {
        // SAFETY: dup2 onto a fixed number clears close-on-exec there; `from` is ours to close.
        unsafe {
            if libc::dup2(from, to) < 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::close(from);
        }
    }
    Ok(())
}
