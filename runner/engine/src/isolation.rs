//! Runs in worker processes: the runner's own binary started again as a worker
//! ([`crate::worker::serve`]), one per thread, each loading the FMU once and running many
//! points. A worker that crashes (any signal, an `exit` inside the FMU), hangs past the timeout or
//! grows past its memory limit costs only the point it was running: that point is recorded as
//! failed with the signal and the FMI call it was in, and a new worker takes the dead one's place.
//!
//! Workers run in a process group of their own (a Ctrl-C at the terminal reaches only the
//! supervisor, which decides) and are killed by the kernel if the thread that started them dies,
//! so a killed runner leaves no workers behind. They must be started from one long-lived thread
//! (the one calling these functions), as that parent-death signal follows the starting thread.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::ops::Range;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, Sender};
use std::time::{Duration, Instant};

use fmi_importer::trace::{Call, CallSlot};
use fmi_importer::{Description, Interface, Reader};

use crate::protocol::{self, FmuSource, Reply, Request, RunJob};
use crate::run::{Outcome, Texts};
use crate::sweep::{Plan, PointResult, SweepSpec};
use crate::worker::SLOT_FD;

/// How to start a worker: a program (the runner's own binary) and its arguments.
#[derive(Debug, Clone)]
pub struct WorkerCommand {
    pub program: PathBuf,
    pub args: Vec<String>,
}

/// How runs are isolated.
#[derive(Debug, Clone)]
pub struct Isolation {
    /// How to start a worker.
    pub command: WorkerCommand,
    /// A point or run taking longer is stopped and recorded as timed out.
    pub timeout: Option<Duration>,
    /// Address space a worker may use (bytes); a worker whose resident memory passes half of it
    /// after a point is replaced before its next one (an FMU that leaks).
    pub memory_limit: Option<u64>,
}

/// True if the FMU declares, for `interface`, that it can be instantiated only once per process.
pub fn once_per_process(description: &Description, interface: Interface) -> bool {
    description.interface(interface).is_some_and(|c| c.can_be_instantiated_only_once_per_process)
}

/// The name of signal `signal` (`SIGSEGV`), as the status column shows it.
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

/// Where a worker was: `in fmi2DoStep at t = 0.31`.
fn place((call, time): (Call, Option<f64>)) -> String {
    match (call, time) {
        (Call::None, _) => "before its first FMI call".to_owned(),
        (Call::Load, _) => "while loading the FMU's binary".to_owned(),
        (call, Some(t)) => format!("in {} at t = {t}", call.name()),
        (call, None) => format!("in {}", call.name()),
    }
}

/// The status of a point whose worker ended with `status` while at `at`.
fn death(status: ExitStatus, at: (Call, Option<f64>)) -> String {
    match (status.signal(), status.code()) {
        (Some(signal), _) => format!("crashed: {} {}", signal_name(signal), place(at)),
        (None, Some(code)) => format!("exited: the worker process ended with code {code} {}", place(at)),
        (None, None) => format!("crashed: the worker ended ({status}) {}", place(at)),
    }
}

fn timed_out(limit: Duration, at: (Call, Option<f64>)) -> String {
    format!("timed out after {} s {}", limit.as_secs_f64(), place(at))
}

/// The page a worker records its FMI calls in, mapped in the supervisor too.
struct SharedSlot {
    fd: libc::c_int,
    page: *mut libc::c_void,
}

impl SharedSlot {
    fn new() -> Result<SharedSlot, String> {
        let error = |what: &str| format!("cannot create the memory shared with a worker ({what}): {}", std::io::Error::last_os_error());
        // SAFETY: plain system calls; the page is checked before use and unmapped on drop.
        unsafe {
            let fd = libc::memfd_create(c"runner-call-slot".as_ptr(), libc::MFD_CLOEXEC);
            if fd < 0 {
                return Err(error("memfd_create"));
            }
            if libc::ftruncate(fd, 4096) != 0 {
                libc::close(fd);
                return Err(error("ftruncate"));
            }
            let page = libc::mmap(std::ptr::null_mut(), 4096, libc::PROT_READ | libc::PROT_WRITE, libc::MAP_SHARED, fd, 0);
            if page == libc::MAP_FAILED {
                libc::close(fd);
                return Err(error("mmap"));
            }
            let slot = SharedSlot { fd, page };
            slot.slot().clear();
            Ok(slot)
        }
    }

    fn slot(&self) -> &CallSlot {
        // SAFETY: a mapped, zero-initialized page outlives the borrow; CallSlot is atomics only.
        unsafe { &*(self.page as *const CallSlot) }
    }
}

impl Drop for SharedSlot {
    fn drop(&mut self) {
        // SAFETY: the page and descriptor are ours.
        unsafe {
            libc::munmap(self.page, 4096);
            libc::close(self.fd);
        }
    }
}

/// What a worker's reader thread reports.
enum Event {
    Reply(Reply),
    /// The worker closed its reply pipe: it exited or died.
    Gone,
}

/// A running worker.
struct Worker {
    id: u64,
    child: Child,
    /// `None` once closed (the worker then exits when idle).
    requests: Option<ChildStdin>,
    slot: SharedSlot,
    /// Ready replies still to come (to Load and Sweep): until then the worker is starting, and a
    /// point's time limit restarts when it is ready, so that a slow start is not the point's.
    unready: u8,
}

impl Worker {
    /// Sends a request. A failure means the worker is gone (a full pipe only blocks), and its
    /// reader thread reports that, with what the worker said last (a load that failed), so the
    /// error itself is not needed.
    fn send(&mut self, request: &Request) {
        if let Some(pipe) = self.requests.as_mut() {
            let _ = protocol::send(pipe, request);
        }
    }

    /// Kills the worker's process group now and reaps it.
    fn kill(mut self) -> ExitStatus {
        // SAFETY: signalling the process group we created for this worker (its pid).
        unsafe { libc::kill(-(self.child.id() as libc::pid_t), libc::SIGKILL) };
        let _ = self.child.kill();
        self.requests = None;
        self.child.wait().unwrap_or_else(|_| ExitStatus::from_raw(libc::SIGKILL))
    }

    /// Lets an idle worker go: it drops its parent-death signal (an alarm of its own ends it within
    /// seconds should the FMU hang on unloading), acknowledges, and exits, unloading the FMU (and
    /// removing its unpacked copy, if it made one) while the runner goes on; a thread reaps it.
    /// Returns its id, for [`Pool::await_released`]: until the acknowledgement the worker still
    /// dies with the runner.
    fn release(mut self) -> u64 {
        self.send(&Request::Release);
        self.detach()
    }

    /// [`Worker::release`] for a worker already sent Release.
    fn detach(self) -> u64 {
        let Worker { id, mut child, .. } = self;
        std::thread::spawn(move || {
            let _ = child.wait();
        });
        id
    }
}

/// Starts workers and gathers what they say in one channel.
struct Pool<'a> {
    config: &'a Isolation,
    /// What a new worker loads; `None` until the supervisor has unpacked the FMU.
    source: Option<FmuSource>,
    sender: Sender<(u64, Event)>,
    events: Receiver<(u64, Event)>,
    next_id: u64,
    /// One worker per instance: the FMU declares canBeInstantiatedOnlyOncePerProcess.
    once_per_process: bool,
}

impl<'a> Pool<'a> {
    fn new(config: &'a Isolation, source: Option<FmuSource>) -> Pool<'a> {
        let (sender, events) = mpsc::channel();
        Pool { config, source, sender, events, next_id: 0, once_per_process: false }
    }

    /// Starts a worker and, once the source is known, asks it to load the FMU (it answers Ready
    /// or Failed later).
    fn spawn(&mut self) -> Result<Worker, String> {
        let slot = SharedSlot::new()?;
        let (memfd, limit, parent) = (slot.fd, self.config.memory_limit, std::process::id());
        let command = &self.config.command;
        let mut cmd = Command::new(&command.program);
        cmd.args(&command.args).stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::inherit()).process_group(0);
        // SAFETY: only async-signal-safe calls between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) != 0 || libc::getppid() != parent as libc::pid_t {
                    return Err(std::io::Error::other("the runner is gone"));
                }
                // dup2 onto the slot's number clears close-on-exec; if it already has that
                // number, clear the flag itself.
                let moved = if memfd == SLOT_FD { libc::fcntl(memfd, libc::F_SETFD, 0) } else { libc::dup2(memfd, SLOT_FD) };
                if moved < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                if let Some(bytes) = limit {
                    let rlimit = libc::rlimit { rlim_cur: bytes as libc::rlim_t, rlim_max: bytes as libc::rlim_t };
                    if libc::setrlimit(libc::RLIMIT_AS, &rlimit) != 0 {
                        return Err(std::io::Error::last_os_error());
                    }
                }
                Ok(())
            });
        }
        let mut child = cmd.spawn().map_err(|e| format!("cannot start a worker process ({}): {e}", command.program.display()))?;
        let id = self.next_id;
        self.next_id += 1;
        let replies = child.stdout.take().expect("piped");
        let sender = self.sender.clone();
        std::thread::spawn(move || {
            let mut replies = std::io::BufReader::new(replies);
            loop {
                match protocol::receive::<Reply>(&mut replies) {
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
        let requests = child.stdin.take();
        let mut worker = Worker { id, child, requests, slot, unready: 1 };
        if let Some(source) = &self.source {
            worker.send(&Request::Load(source.clone()));
        }
        Ok(worker)
    }

    /// The next event, or `None` after `wait`.
    fn next(&self, wait: Duration) -> Option<(u64, Event)> {
        self.events.recv_timeout(wait).ok()
    }

    /// Waits (a second at most) until the released workers `ids` acknowledged, so that none is
    /// killed half-way through its cleanup when this process exits.
    fn await_released(&self, ids: &mut Vec<u64>) {
        let deadline = Instant::now() + Duration::from_secs(1);
        while !ids.is_empty() {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.next(left) {
                Some((id, Event::Reply(Reply::Released) | Event::Gone)) => ids.retain(|&i| i != id),
                Some((_, Event::Reply(Reply::Log(line)))) => fmi_importer::print_line(&line),
                Some(_) => {}
                None => return,
            }
        }
    }

    /// True if a worker that reported `resident` bytes should be replaced before its next job.
    fn worn_out(&self, resident: u64) -> bool {
        self.once_per_process || self.config.memory_limit.is_some_and(|limit| resident > limit / 2)
    }
}

/// How long the supervisor waits for an event before it looks at the clock and Ctrl-C again.
const TICK: Duration = Duration::from_millis(50);

/// How long a worker may take to start (to load the FMU's binary, running its initializers) when
/// the time limit is shorter: a point's limit counts from when its worker is ready.
pub const START_LIMIT: Duration = Duration::from_secs(60);

/// The time limit of a job on `worker`, given the configured `limit`.
fn limit_for(worker: Option<&Worker>, limit: Duration) -> Duration {
    if worker.is_some_and(|w| w.unready > 0) {
        limit.max(START_LIMIT)
    } else {
        limit
    }
}

/// Points a worker has been sent at most: the one it runs and the next, so that it never waits
/// for the runner between points (each wait is a wake-up of three threads: milliseconds on a
/// busy machine). One when each instance needs a process of its own.
const DEPTH: usize = 2;

/// One thread's worker and the points sent to it.
#[derive(Default)]
struct Lane {
    worker: Option<Worker>,
    /// The points sent, in order: the first is running.
    sent: VecDeque<usize>,
    /// When the first of `sent` started: when it was sent, or when the one before it ended.
    started: Option<Instant>,
    /// The worker gets no more points: it retired or was told to release.
    closed: bool,
    /// Release was sent after its last point.
    releasing: bool,
}

impl Lane {
    fn busy(&self) -> Option<(usize, Instant)> {
        self.sent.front().copied().zip(self.started)
    }
}

/// Worker processes started ahead of a sweep, before the FMU is even unpacked: the processes
/// start while the supervisor unpacks it, and load it (from that copy) while the supervisor reads
/// the description and checks the plan (a worker's start costs about as much as ten of the
/// handbook's runs).
pub struct Workers<'a> {
    pool: Pool<'a>,
    ready: Vec<Worker>,
}

impl<'a> Workers<'a> {
    /// Starts `count` workers (at least one); they wait for [`Workers::load`].
    pub fn start(config: &'a Isolation, count: usize) -> Result<Workers<'a>, String> {
        let mut pool = Pool::new(config, None);
        let ready = (0..count.max(1)).map(|_| pool.spawn()).collect::<Result<Vec<_>, _>>()?;
        Ok(Workers { pool, ready })
    }

    /// Has the workers load the FMU from `source`, as will the workers that replace them.
    pub fn load(&mut self, source: &FmuSource) {
        self.pool.source = Some(source.clone());
        for worker in &mut self.ready {
            worker.send(&Request::Load(source.clone()));
        }
    }

    /// Gives every instance a worker of its own (the FMU declares
    /// canBeInstantiatedOnlyOncePerProcess): a worker is replaced after each point.
    pub fn one_instance_per_process(&mut self, once: bool) {
        self.pool.once_per_process = once;
    }
}

impl Drop for Workers<'_> {
    fn drop(&mut self) {
        let mut released: Vec<u64> = self.ready.drain(..).map(Worker::release).collect();
        self.pool.await_released(&mut released);
    }
}

/// Runs the points `points` of `plan` (made from `spec`) in worker processes, as many as were
/// started, and calls `deliver(i, result)` in point order, like [`Plan::execute_range`]. Stops
/// when `stop()` turns true (the points in progress are abandoned and their workers killed) or
/// `deliver` fails.
///
/// Each worker is sent its next point while it runs one ([`DEPTH`]), except for the last few
/// points of the sweep, which go one at a time to whichever worker is free, so that the sweep
/// ends as evenly as on threads; after the last point a worker is sent Release at once. A point
/// sent to a worker that crashed, timed out or retired before starting it is run again by
/// another worker: only the point a worker was in is charged with its end.
pub fn execute_sweep(
    plan: &Plan,
    spec: &SweepSpec,
    mut workers: Workers,
    points: Range<usize>,
    stop: &dyn Fn() -> bool,
    mut deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
) -> Result<(), String> {
    if workers.pool.source.is_none() {
        return Err("the workers were not told which FMU to load".to_owned());
    }
    let end = points.end.min(plan.space.len);
    let lane_count = workers.ready.len().min(end.saturating_sub(points.start)).max(1);
    let config = workers.pool.config;
    let once = workers.pool.once_per_process;
    let depth = if once { 1 } else { DEPTH };
    // The worker itself stops at the limit the runner would replace it at, since the next point
    // is already on its way when the runner hears of its memory.
    let retire_above = if once { Some(0) } else { config.memory_limit.map(|limit| limit / 2) };
    let sweep = Request::Sweep { spec: spec.clone(), retire_above };
    let mut lanes: Vec<Lane> = (0..lane_count).map(|_| Lane::default()).collect();
    for (lane, mut worker) in lanes.iter_mut().zip(workers.ready.drain(..lane_count)) {
        worker.send(&sweep);
        worker.unready += 1;
        lane.worker = Some(worker);
    }
    let pool = &mut workers.pool;
    let mut released: Vec<u64> = Vec::new();
    let mut next = points.start;
    // Points to run again: sent to a worker that ended before it started them.
    let mut again: BTreeSet<usize> = BTreeSet::new();
    let mut row = points.start;
    let mut waiting: BTreeMap<usize, PointResult> = BTreeMap::new();
    let outcome = (|| -> Result<(), String> {
        loop {
            if stop() {
                return Ok(());
            }
            for lane in lanes.iter_mut() {
                loop {
                    let left = again.len() + end.saturating_sub(next);
                    // The last points go one at a time, to whichever worker is free first.
                    let room = if left >= lane_count { depth } else { 1 };
                    if left == 0 || lane.sent.len() >= room || (lane.closed && lane.worker.is_some()) {
                        break;
                    }
                    if lane.worker.is_none() {
                        let mut worker = pool.spawn()?;
                        worker.send(&sweep);
                        worker.unready += 1;
                        lane.worker = Some(worker);
                        lane.closed = false;
                        lane.releasing = false;
                    }
                    let i = again.pop_first().unwrap_or_else(|| {
                        next += 1;
                        next - 1
                    });
                    lane.worker.as_mut().expect("started above").send(&Request::Point(i as u64));
                    if lane.sent.is_empty() {
                        lane.started = Some(Instant::now());
                    }
                    lane.sent.push_back(i);
                }
            }
            let nothing_left = again.is_empty() && next >= end;
            for lane in lanes.iter_mut() {
                // Done with a worker: let it go now, after the points it has, so that it
                // acknowledges right after its last one instead of a round trip later.
                if nothing_left || lane.closed {
                    if let Some(worker) = lane.worker.as_mut() {
                        if !lane.releasing {
                            worker.send(&Request::Release);
                            lane.releasing = true;
                            lane.closed = true;
                        }
                    }
                }
                if lane.closed && lane.sent.is_empty() {
                    if let Some(worker) = lane.worker.take() {
                        released.push(worker.detach());
                    }
                }
            }
            if lanes.iter().all(|l| l.sent.is_empty()) && nothing_left {
                return Ok(());
            }
            // Wake for the first deadline, or a tick to look at Ctrl-C.
            let now = Instant::now();
            let wait = lanes
                .iter()
                .filter_map(|l| {
                    l.busy()
                        .zip(config.timeout)
                        .map(|((_, started), limit)| (started + limit_for(l.worker.as_ref(), limit)).saturating_duration_since(now))
                })
                .fold(TICK, Duration::min);
            if let Some((id, event)) = pool.next(wait) {
                let lane = lanes.iter_mut().find(|l| l.worker.as_ref().is_some_and(|w| w.id == id));
                match (lane, event) {
                    (_, Event::Reply(Reply::Log(line))) => fmi_importer::print_line(&line),
                    (Some(_), Event::Reply(Reply::Failed(e))) => return Err(e),
                    (Some(lane), Event::Reply(Reply::Ready)) => {
                        let worker = lane.worker.as_mut().expect("matched by id");
                        worker.unready = worker.unready.saturating_sub(1);
                        if worker.unready == 0 && !lane.sent.is_empty() {
                            lane.started = Some(Instant::now());
                        }
                    }
                    (Some(lane), Event::Reply(Reply::Point { index, result, resident })) => {
                        if lane.sent.front().map(|&i| i as u64) == Some(index) {
                            waiting.insert(index as usize, result);
                            lane.sent.pop_front();
                            // The next point started as this one ended.
                            lane.started = Some(Instant::now());
                            if pool.worn_out(resident) {
                                // It runs no more points and exits, returning its memory.
                                lane.closed = true;
                            }
                        }
                    }
                    (Some(lane), Event::Reply(Reply::Skipped(index))) => {
                        if let Some(k) = lane.sent.iter().position(|&i| i as u64 == index) {
                            again.insert(lane.sent.remove(k).expect("found"));
                            lane.closed = true;
                        }
                    }
                    (Some(lane), Event::Gone) => {
                        let worker = lane.worker.take().expect("matched by id");
                        let at = worker.slot.slot().read();
                        let status = worker.kill();
                        // The point it was in is charged; those it had not started run again.
                        // An idle worker that ended is replaced at its next point.
                        if let Some(i) = lane.sent.pop_front() {
                            waiting.insert(i, PointResult { metrics: None, status: death(status, at) });
                        }
                        again.extend(lane.sent.drain(..));
                        lane.started = None;
                    }
                    (None, Event::Gone | Event::Reply(Reply::Released)) => released.retain(|&i| i != id),
                    (_, Event::Reply(_)) => {} // Released, or a late word from a worker already replaced
                }
            }
            if let Some(limit) = config.timeout {
                for lane in lanes.iter_mut() {
                    if let Some((i, started)) = lane.busy() {
                        let limit = limit_for(lane.worker.as_ref(), limit);
                        if started.elapsed() >= limit {
                            let worker = lane.worker.take().expect("a busy lane has a worker");
                            let at = worker.slot.slot().read();
                            worker.kill();
                            lane.sent.pop_front();
                            again.extend(lane.sent.drain(..));
                            lane.started = None;
                            waiting.insert(i, PointResult { metrics: None, status: timed_out(limit, at) });
                        }
                    }
                }
            }
            while let Some(result) = waiting.remove(&row) {
                deliver(row, result)?;
                row += 1;
            }
        }
    })();
    for lane in lanes {
        if let Some(worker) = lane.worker {
            if !lane.sent.is_empty() {
                worker.kill();
            } else if lane.releasing {
                released.push(worker.detach());
            } else {
                released.push(worker.release());
            }
        }
    }
    pool.await_released(&mut released);
    outcome
}

/// Runs one job after another in a worker process (simulate, the runs of a comparison),
/// replacing the worker after a crash.
pub struct Runs<'a> {
    pool: Pool<'a>,
    worker: Option<Worker>,
    /// Workers let go, until they acknowledge.
    released: Vec<u64>,
}

impl<'a> Runs<'a> {
    /// A supervisor for runs of `source`; no worker starts before the first run.
    pub fn new(config: &'a Isolation, source: &'a FmuSource, one_instance_per_process: bool) -> Runs<'a> {
        let mut pool = Pool::new(config, Some(source.clone()));
        pool.once_per_process = one_instance_per_process;
        Runs { pool, worker: None, released: Vec::new() }
    }

    /// Runs `job`, of the FMU `description` describes, in a worker, calling `sample(t, values,
    /// texts)` at every sample as [`crate::run::run_recording`] does. A crash, a timeout,
    /// `stop()` or a failing `sample` end the run with an error naming the signal and the FMI call.
    pub fn run(
        &mut self,
        description: &Description,
        job: &RunJob,
        stop: &dyn Fn() -> bool,
        mut sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
    ) -> Result<Outcome, String> {
        // The worker's columns, laid out here as there: the texts it sends are of the columns
        // whose numbers do not give them.
        let (_, recording) = job.resolve(description)?;
        let layout = Reader::with_sizes(description.fmi_version, &recording.variables, &recording.sizes)?;
        let lossy: Vec<usize> = (0..layout.len()).filter(|&c| layout.needs_text(c)).collect();
        let width = 1 + layout.len();
        let mut worker = match self.worker.take() {
            Some(w) => w,
            None => self.pool.spawn()?,
        };
        worker.unready = worker.unready.min(1);
        worker.slot.slot().clear();
        worker.send(&Request::Run(job.clone()));
        let mut started = Instant::now();
        let timeout = self.pool.config.timeout;
        loop {
            if stop() {
                worker.kill();
                return Err("interrupted".to_owned());
            }
            let timeout = timeout.map(|limit| limit_for(Some(&worker), limit));
            if let Some(limit) = timeout {
                if started.elapsed() >= limit {
                    let at = worker.slot.slot().read();
                    worker.kill();
                    return Err(format!("{}: {}", job.name, timed_out(limit, at)));
                }
            }
            let wait = timeout.map_or(TICK, |limit| (started + limit).saturating_duration_since(Instant::now()).min(TICK));
            let Some((id, event)) = self.pool.next(wait) else { continue };
            if id != worker.id {
                continue; // an earlier worker's last words
            }
            match event {
                Event::Reply(Reply::Log(line)) => fmi_importer::print_line(&line),
                // The worker has loaded the FMU: the run's time starts now.
                Event::Reply(Reply::Ready) => {
                    worker.unready = 0;
                    started = Instant::now();
                }
                Event::Reply(Reply::Failed(e)) => {
                    worker.kill();
                    return Err(e);
                }
                Event::Reply(Reply::Samples { values, texts }) => {
                    let samples = values.len() / width;
                    if values.len() % width != 0 || texts.len() != samples * lossy.len() {
                        worker.kill();
                        return Err(format!("{}: the worker sent a sample of the wrong size", job.name));
                    }
                    for (k, chunk) in values.chunks_exact(width).enumerate() {
                        let texts = Received { layout: &layout, lossy: &lossy, texts: &texts[k * lossy.len()..(k + 1) * lossy.len()] };
                        if let Err(e) = sample(chunk[0], &chunk[1..], &texts) {
                            worker.kill();
                            return Err(e);
                        }
                    }
                }
                Event::Reply(Reply::RunDone { result, resident }) => {
                    if self.pool.worn_out(resident) {
                        self.released.push(worker.release());
                    } else {
                        self.worker = Some(worker);
                    }
                    return result.map(|end| Outcome { ended_early: end.ended_early, counters: end.counters });
                }
                Event::Reply(_) => {}
                Event::Gone => {
                    let at = worker.slot.slot().read();
                    let status = worker.kill();
                    return Err(format!("{}: {}", job.name, death(status, at)));
                }
            }
        }
    }
}

/// The texts of a sample a worker sent: its numbers printed by the layout's rules, and the
/// texts it sent for the columns numbers do not give.
struct Received<'a> {
    layout: &'a Reader,
    /// The columns that need text, ascending.
    lossy: &'a [usize],
    /// Their texts in this sample.
    texts: &'a [String],
}

impl Texts for Received<'_> {
    fn text(&self, c: usize, values: &[f64]) -> String {
        match self.lossy.binary_search(&c) {
            Ok(k) => self.texts[k].clone(),
            Err(_) => self.layout.text_of_number(c, values[c]),
        }
    }

    fn needs_text(&self, c: usize) -> bool {
        self.lossy.binary_search(&c).is_ok()
    }
}

impl Drop for Runs<'_> {
    fn drop(&mut self) {
        if let Some(worker) = self.worker.take() {
            self.released.push(worker.release());
        }
        self.pool.await_released(&mut self.released);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn statuses_name_the_signal_the_call_and_the_time() {
        let segv = ExitStatus::from_raw(libc::SIGSEGV);
        assert_eq!(death(segv, (Call::DoStep, Some(0.31))), "crashed: SIGSEGV in fmi2DoStep at t = 0.31");
        assert_eq!(death(ExitStatus::from_raw(libc::SIGABRT), (Call::Instantiate, None)), "crashed: SIGABRT in fmi2Instantiate");
        assert_eq!(
            death(ExitStatus::from_raw(3 << 8), (Call::DoStep, Some(1.0))),
            "exited: the worker process ended with code 3 in fmi2DoStep at t = 1"
        );
        assert_eq!(death(segv, (Call::Load, None)), "crashed: SIGSEGV while loading the FMU's binary");
        assert_eq!(timed_out(Duration::from_millis(500), (Call::DoStep, Some(2.5))), "timed out after 0.5 s in fmi2DoStep at t = 2.5");
        assert_eq!(signal_name(64), "signal 64");
    }
}
