//! The worker's side: a process its supervisor started (see [`crate::pool`]) that takes setups
//! and jobs one at a time ([`Serving::receive`]) and answers each. If the FMU it runs crashes or
//! hangs, only this process is lost; what it was doing is in the memory it shares with the
//! supervisor ([`Serving::shared`]).
//!
//! A client's worker loop reads:
//! ```no_run
//! # use runner_sandbox::{worker::{Incoming, Serving}, Failure, Service, SharedMemory};
//! # struct Echo;
//! # impl Service for Echo {
//! #     type Setup = String; type Job = u64; type Message = u64; type Outcome = u64;
//! #     fn failed(_: &u64, _: &Failure, _: &SharedMemory) -> u64 { 0 }
//! # }
//! let mut serving = Serving::<Echo>::start()?;
//! while let Some(request) = serving.receive()? {
//!     match request {
//!         Incoming::Setup(setup) => serving.ready(Ok(()))?,
//!         Incoming::Job { id, job } => {
//!             serving.send(&job)?;
//!             serving.finish(id, job * 2, false)?;
//!         }
//!     }
//! }
//! # Ok::<(), String>(())
//! ```

use std::fs::File;
use std::io::{BufReader, Write};
use std::os::fd::FromRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, Once};
use std::time::Duration;

use crate::frame::{self, Reply, Request};
use crate::pool::{REPLIES_FD, REQUESTS_FD, SHARED_FD};
use crate::shared::SharedMemory;
use crate::Service;

/// Where replies go: the pipe the supervisor reads (never stdout, which an FMU may print to).
static REPLIES: Mutex<Option<File>> = Mutex::new(None);

fn reply<S: Service>(message: &Reply<S::Message, S::Outcome>) -> Result<(), String> {
    let mut replies = REPLIES.lock().map_err(|_| "the reply pipe is poisoned".to_owned())?;
    let pipe = replies.as_mut().ok_or("the worker has no reply pipe")?;
    frame::send(pipe, message).map_err(|e| format!("cannot reply to the supervisor: {e}"))
}

/// Sends a line for the user (an FMU's log message) to the supervisor, which prints it where its
/// own lines go. A log printer: never panics, and does nothing outside a worker.
pub fn log(line: &str) {
    if let Ok(mut replies) = REPLIES.lock() {
        if let Some(pipe) = replies.as_mut() {
            let _ = frame::send(pipe, &Reply::<(), ()>::Log(line.to_owned()));
        }
    }
}

/// A request for the client's worker loop.
pub enum Incoming<S: Service> {
    /// Prepare for the jobs that follow; answer with [`Serving::ready`].
    Setup(S::Setup),
    /// Run this job; stream its messages with [`Serving::send`], end it with [`Serving::finish`].
    Job { id: u64, job: S::Job },
}

/// A worker serving its supervisor's requests.
pub struct Serving<S: Service> {
    requests: BufReader<File>,
    shared: &'static SharedMemory,
    /// /proc/self/statm kept open: one read per job rather than an open, a read and a close.
    statm: Option<File>,
    /// Set by the last setup: past this resident memory after a job, run no more.
    retire_above: Option<u64>,
    /// Runs no more jobs: its memory passed `retire_above`, or its process is tainted.
    retired: bool,
    _service: std::marker::PhantomData<S>,
}

impl<S: Service> Serving<S> {
    /// Takes the descriptors the supervisor set up: the request and reply pipes and the shared
    /// memory. Crashes write no core files (one per crash of an FMU would fill a disk).
    pub fn start() -> Result<Serving<S>, String> {
        // SAFETY: fcntl only looks at the descriptors; setrlimit with a valid struct.
        let present = |fd| unsafe { libc::fcntl(fd, libc::F_GETFD) } >= 0;
        if ![SHARED_FD, REQUESTS_FD, REPLIES_FD].into_iter().all(present) {
            return Err("a worker is started by its supervisor, which passes it descriptors 3, 4 and 5".to_owned());
        }
        let no_core = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        unsafe { libc::setrlimit(libc::RLIMIT_CORE, &no_core) };
        let shared: &'static SharedMemory = Box::leak(Box::new(SharedMemory::inherit(SHARED_FD)?));
        // SAFETY: descriptors the supervisor passed for exactly this, owned by this process from
        // now on (and made close-on-exec: nothing the FMU starts inherits them).
        let (requests, replies) = unsafe {
            libc::fcntl(REQUESTS_FD, libc::F_SETFD, libc::FD_CLOEXEC);
            libc::fcntl(REPLIES_FD, libc::F_SETFD, libc::FD_CLOEXEC);
            (File::from_raw_fd(REQUESTS_FD), File::from_raw_fd(REPLIES_FD))
        };
        *REPLIES.lock().map_err(|_| "the reply pipe is poisoned")? = Some(replies);
        Ok(Serving {
            requests: BufReader::new(requests),
            shared,
            statm: File::open("/proc/self/statm").ok(),
            retire_above: None,
            retired: false,
            _service: std::marker::PhantomData,
        })
    }

    /// The memory shared with the supervisor, mapped for the rest of the process.
    pub fn shared(&self) -> &'static SharedMemory {
        self.shared
    }

    /// The next setup or job; `None` when the supervisor released this worker (acknowledged)
    /// or closed the pipe. Jobs sent after the worker retired are answered here, not run.
    pub fn receive(&mut self) -> Result<Option<Incoming<S>>, String> {
        loop {
            let request = frame::receive::<Request<S::Setup, S::Job>>(&mut self.requests)
                .map_err(|e| format!("cannot read the supervisor's request: {e}"))?;
            match request {
                None => return Ok(None),
                Some(Request::Release) => {
                    // From now on the supervisor may exit first: the parent-death signal would
                    // kill this process while it cleans up (unloads an FMU, removes its files).
                    // An alarm bounds a cleanup that hangs.
                    // SAFETY: prctl and alarm on this process.
                    unsafe {
                        libc::prctl(libc::PR_SET_PDEATHSIG, 0);
                        libc::alarm(10);
                    }
                    reply::<S>(&Reply::Released)?;
                    return Ok(None);
                }
                Some(Request::Setup { setup, retire_above }) => {
                    self.retire_above = retire_above;
                    return Ok(Some(Incoming::Setup(setup)));
                }
                Some(Request::Job { id, job }) => {
                    if self.retired {
                        reply::<S>(&Reply::Skipped(id))?;
                        continue;
                    }
                    return Ok(Some(Incoming::Job { id, job }));
                }
            }
        }
    }

    /// Answers the last setup: ready, or why not (the worker should then end).
    pub fn ready(&mut self, result: Result<(), String>) -> Result<(), String> {
        match result {
            Ok(()) => reply::<S>(&Reply::Ready),
            Err(e) => reply::<S>(&Reply::Failed(e)),
        }
    }

    /// Sends a message of the running job.
    pub fn send(&self, message: &S::Message) -> Result<(), String> {
        // A reference serializes as what it points at: the supervisor reads the service's reply.
        let mut replies = REPLIES.lock().map_err(|_| "the reply pipe is poisoned".to_owned())?;
        let pipe = replies.as_mut().ok_or("the worker has no reply pipe")?;
        frame::send(pipe, &Reply::<&S::Message, ()>::Message(message)).map_err(|e| format!("cannot reply to the supervisor: {e}"))
    }

    /// Ends job `id` with `outcome`. `tainted`: this process must run no more jobs (an FMU
    /// returned fmiFatal); it answers those already sent as skipped, and its supervisor replaces
    /// it.
    pub fn finish(&mut self, id: u64, outcome: S::Outcome, tainted: bool) -> Result<(), String> {
        let resident = resident_bytes(self.statm.as_ref());
        self.retired = tainted || self.retire_above.is_some_and(|limit| resident > limit);
        reply::<S>(&Reply::Done { id, outcome, resident, tainted })
    }
}

/// How long a job's streamed rows may wait in the worker before they are sent: a worker that
/// crashes or hangs loses at most the rows of its last tenth of a second (as a killed sweep loses
/// at most those of its partial file's last flush), not a whole frame's worth, which for a model
/// whose rows come slowly was all of them.
pub const SEND_EVERY: Duration = Duration::from_millis(100);

/// When a job streaming rows sends those it holds: once a frame's worth of values is waiting,
/// or at its first row after each tick of a thread that ticks every [`SEND_EVERY`]. A row costs
/// a load of the tick's mark, not a read of the clock (26 ns, a tenth of a fast model's row).
pub struct Pacer {
    frame: usize,
}

/// Set by the ticking thread every [`SEND_EVERY`], cleared by a send.
static TICKED: AtomicBool = AtomicBool::new(false);

impl Pacer {
    /// Frames of `frame` values; starts the ticking thread on first use (without it, if it
    /// cannot start, rows go a frame at a time).
    pub fn new(frame: usize) -> Pacer {
        static TICKING: Once = Once::new();
        TICKING.call_once(|| {
            let _ = std::thread::Builder::new().name("send-every".to_owned()).stack_size(64 << 10).spawn(|| loop {
                std::thread::sleep(SEND_EVERY);
                TICKED.store(true, Ordering::Relaxed);
            });
        });
        Pacer { frame }
    }

    /// True when the `waiting` values are to be sent now.
    pub fn due(&mut self, waiting: usize) -> bool {
        if waiting < self.frame && !TICKED.load(Ordering::Relaxed) {
            return false;
        }
        TICKED.store(false, Ordering::Relaxed);
        true
    }
}

/// Resident memory of this process in bytes (0 if unknown), from `statm`.
fn resident_bytes(statm: Option<&File>) -> u64 {
    use std::os::unix::fs::FileExt;
    let mut buffer = [0u8; 128];
    let text = match statm.map(|f| f.read_at(&mut buffer, 0)) {
        Some(Ok(n)) => String::from_utf8_lossy(&buffer[..n]).into_owned(),
        _ => std::fs::read_to_string("/proc/self/statm").unwrap_or_default(),
    };
    let pages: u64 = text.split_whitespace().nth(1).and_then(|p| p.parse().ok()).unwrap_or(0);
    // SAFETY: sysconf has no preconditions.
    pages * unsafe { libc::sysconf(libc::_SC_PAGESIZE) }.max(0) as u64
}

/// Flushes standard error before a worker ends (the FMU's last lines).
pub fn flush() {
    let _ = std::io::stderr().flush();
}
