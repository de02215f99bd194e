//! Every probe of an FMU's binary runs in a child process, so a crash or a hang in the FMU is a
//! finding, never the validator's own death.
//!
//! The child is the validator's own program started again with a probe's arguments (see
//! [`Launcher`]): a fresh process, as a real importer would load the FMU, with nothing shared
//! but two channels. Findings come back as JSON lines on a pipe. Before each FMI call the child
//! writes the call (function, state, variable, value) and a deadline into a small shared
//! memory file ([`Progress`]); the parent watches the deadlines, kills a child whose call
//! overran `--timeout`, and after a crash or a kill reads which call was running. Writing that
//! record costs no system call, so a run of 100,000 steps stays fast.
//!
//! fork() without exec was the alternative: cheaper by a few milliseconds, but the child of a
//! multi-threaded parent (a test harness, the progress thread) inherits every lock another
//! thread held at the fork, and one held allocator or stdio lock hangs the child in the
//! validator's own code, which would then read as the FMU's hang.

use std::ffi::OsString;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::report::{Finding, Severity};

/// How to start a probe child: a program and the arguments that put it in probe mode (for the
/// `runner` binary: itself and its hidden `__validate-probe` command); the probe's own
/// arguments follow.
#[derive(Debug, Clone)]
pub struct Launcher {
    pub program: PathBuf,
    pub args: Vec<OsString>,
}

/// What a child sends back, one JSON object per line.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) enum Message {
    /// The probe starts its cell `index` (the unit a crashed probe resumes after), which
    /// belongs to check `check`; a crash in it is a finding of severity `crash`.
    Cell { check: String, index: usize, crash: Severity },
    /// A finding.
    Finding(Finding),
    /// The probe finished all its cells.
    Done,
    /// The validator itself failed in the child (a bug, or a broken installation).
    Internal(String),
}

/// The call a child was in (or last made), as it recorded it.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct CallRecord {
    pub call: String,
    pub state: String,
    pub variable: Option<String>,
    pub value: Option<String>,
}

/// How a child ended.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum End {
    /// It sent `Done` and exited normally.
    Finished,
    /// Killed by a signal it raised (SIGSEGV, SIGABRT, ...): its name.
    Crashed(String),
    /// It exited with a code before finishing (the FMU called exit()).
    Exited(i32),
    /// A call did not return within the timeout; the child was killed.
    TimedOut,
    /// The user interrupted the validation.
    Cancelled,
}

/// Everything one child run produced.
pub(crate) struct ChildRun {
    pub messages: Vec<Message>,
    pub end: End,
    /// The call in progress when the child ended, if it ended inside one.
    pub in_call: Option<CallRecord>,
    /// The last call it started, finished or not.
    pub last_call: Option<CallRecord>,
    /// The last lines the child wrote to stderr (the FMU's log and output).
    pub log_tail: Option<String>,
}

/// Threads of one child that may call the FMU at once, each with its own record.
pub(crate) const SLOTS: usize = 8;
const HEADER: usize = 64;
const SLOT_SIZE: usize = 512;
/// Size of the shared progress file.
const PROGRESS_SIZE: usize = HEADER + SLOTS * SLOT_SIZE;
const RECORD_MAX: usize = SLOT_SIZE - 12;

/// CLOCK_MONOTONIC in nanoseconds: the one clock both processes read alike.
fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: a valid timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The shared progress file mapped into this process.
pub(crate) struct Progress {
    base: *mut u8,
}

// The mapping is only touched through atomics (deadlines, counter) and through a slot's own
// thread (its record), so it may be shared between threads.
unsafe impl Send for Progress {}
unsafe impl Sync for Progress {}

impl Progress {
    /// Maps the progress file at `path` (created with [`PROGRESS_SIZE`] bytes by the parent).
    pub(crate) fn open(path: &Path) -> Result<Progress, String> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .map_err(|e| format!("cannot open the progress file {}: {e}", path.display()))?;
        let len = file.metadata().map_err(|e| format!("{}: {e}", path.display()))?.len();
        if len < PROGRESS_SIZE as u64 {
            return Err(format!("the progress file {} is too short", path.display()));
        }
        use std::os::fd::AsRawFd;
        // SAFETY: a shared read-write mapping of a file we opened read-write, at least as long
        // as the mapping; the file may be closed afterwards.
        let base = unsafe {
            libc::mmap(std::ptr::null_mut(), PROGRESS_SIZE, libc::PROT_READ | libc::PROT_WRITE, libc::MAP_SHARED, file.as_raw_fd(), 0)
        };
        if base == libc::MAP_FAILED {
            return Err(format!("cannot map the progress file {}: {}", path.display(), std::io::Error::last_os_error()));
        }
        Ok(Progress { base: base as *mut u8 })
    }

    fn atomic(&self, offset: usize) -> &AtomicU64 {
        // SAFETY: offset is 8-aligned inside the mapping (page-aligned base), which lives as
        // long as self; AtomicU64 has the layout of u64.
        unsafe { &*(self.base.add(offset) as *const AtomicU64) }
    }

    fn deadline(&self, slot: usize) -> &AtomicU64 {
        self.atomic(HEADER + slot * SLOT_SIZE)
    }

    /// Counts calls started, so the parent can tell a busy child from a stuck one.
    fn counter(&self) -> &AtomicU64 {
        self.atomic(8)
    }

    /// Records that the thread of `slot` now calls `call`, due back within `timeout`.
    pub(crate) fn begin(&self, slot: usize, record: &CallRecord, timeout: Duration) {
        let text = format!(
            "{}\u{1f}{}\u{1f}{}\u{1f}{}",
            record.call,
            record.state,
            record.variable.as_deref().unwrap_or(""),
            record.value.as_deref().unwrap_or("")
        );
        let mut bytes = text.as_bytes();
        if bytes.len() > RECORD_MAX {
            let mut cut = RECORD_MAX;
            while !text.is_char_boundary(cut) {
                cut -= 1;
            }
            bytes = &bytes[..cut];
        }
        let at = HEADER + slot * SLOT_SIZE;
        // SAFETY: the slot's record area belongs to this slot's thread; the parent reads it only
        // after the child stopped.
        unsafe {
            std::ptr::copy_nonoverlapping((bytes.len() as u32).to_le_bytes().as_ptr(), self.base.add(at + 8), 4);
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), self.base.add(at + 12), bytes.len());
        }
        self.counter().fetch_add(1, Ordering::Relaxed);
        let timeout_ns = u64::try_from(timeout.as_nanos()).unwrap_or(u64::MAX / 2);
        self.deadline(slot).store(monotonic_ns().saturating_add(timeout_ns).max(1), Ordering::Release);
    }

    /// Records that the call of `slot` returned.
    pub(crate) fn end(&self, slot: usize) {
        self.deadline(slot).store(0, Ordering::Release);
    }

    /// The record of `slot` (read once the child stopped writing).
    fn record(&self, slot: usize) -> Option<CallRecord> {
        let at = HEADER + slot * SLOT_SIZE;
        let mut len = [0u8; 4];
        // SAFETY: inside the mapping; the writer is stopped.
        unsafe { std::ptr::copy_nonoverlapping(self.base.add(at + 8), len.as_mut_ptr(), 4) };
        let len = (u32::from_le_bytes(len) as usize).min(RECORD_MAX);
        if len == 0 {
            return None;
        }
        let mut bytes = vec![0u8; len];
        // SAFETY: as above.
        unsafe { std::ptr::copy_nonoverlapping(self.base.add(at + 12), bytes.as_mut_ptr(), len) };
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let mut parts = text.split('\u{1f}');
        let mut next = || parts.next().filter(|s| !s.is_empty()).map(str::to_owned);
        let call = next()?;
        Some(CallRecord { call, state: next().unwrap_or_default(), variable: next(), value: next() })
    }

    /// The earliest deadline of a call still running, if any.
    fn earliest_deadline(&self) -> Option<(usize, u64)> {
        (0..SLOTS).map(|s| (s, self.deadline(s).load(Ordering::Acquire))).filter(|(_, d)| *d != 0).min_by_key(|(_, d)| *d)
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        // SAFETY: unmapping the mapping made in open.
        unsafe { libc::munmap(self.base as *mut libc::c_void, PROGRESS_SIZE) };
    }
}

/// The name of a signal, for messages.
fn signal_name(signal: i32) -> String {
    let name = match signal {
        libc::SIGSEGV => "SIGSEGV (invalid memory access)",
        libc::SIGBUS => "SIGBUS (invalid memory access)",
        libc::SIGABRT => "SIGABRT (abort)",
        libc::SIGFPE => "SIGFPE (arithmetic exception)",
        libc::SIGILL => "SIGILL (illegal instruction)",
        libc::SIGKILL => "SIGKILL",
        libc::SIGTERM => "SIGTERM",
        libc::SIGTRAP => "SIGTRAP",
        libc::SIGSYS => "SIGSYS",
        _ => return format!("signal {signal}"),
    };
    name.to_owned()
}

/// What a probe process writes to its stderr when a cell starts, so that a crash report quotes
/// only what the FMU logged in the cell that crashed.
pub(crate) const CELL_MARK: &str = "\u{1e}runner validate: cell ";

/// The last few lines a child wrote to stderr since its last cell started, made printable.
fn log_tail(path: &Path) -> Option<String> {
    let bytes = std::fs::read(path).ok()?;
    let text = String::from_utf8_lossy(&bytes[bytes.len().saturating_sub(1 << 16)..]).into_owned();
    let since = text.rfind(CELL_MARK).map_or(&text[..], |at| &text[at..]);
    let lines: Vec<&str> = since.lines().filter(|l| !l.trim().is_empty() && !l.starts_with(CELL_MARK)).collect();
    let tail = lines[lines.len().saturating_sub(3)..].join(" | ");
    (!tail.is_empty()).then(|| fmi_schema::printable(tail))
}

static CHILDREN: AtomicUsize = AtomicUsize::new(0);

/// True when the child `pid` has exited (it is left unreaped, for `wait` to collect).
fn exited(pid: libc::pid_t) -> bool {
    // SAFETY: a zeroed siginfo_t to fill; WNOWAIT leaves the child's status in place.
    let mut info: libc::siginfo_t = unsafe { std::mem::zeroed() };
    let found = unsafe { libc::waitid(libc::P_PID, pid as libc::id_t, &mut info, libc::WEXITED | libc::WNOHANG | libc::WNOWAIT) };
    // SAFETY: si_pid is set when waitid found a child.
    found == 0 && unsafe { info.si_pid() } == pid
}

/// Runs one probe child: `launcher` with `args`, its files in `work`, each FMI call bounded by
/// `timeout`. `cancelled` is polled; when it says so the child is killed.
pub(crate) fn run_child(
    launcher: &Launcher,
    args: &[OsString],
    work: &Path,
    timeout: Duration,
    cancelled: &dyn Fn() -> bool,
) -> Result<ChildRun, String> {
    let id = CHILDREN.fetch_add(1, Ordering::Relaxed);
    let progress_path = work.join(format!("progress-{id}"));
    let mut file = std::fs::File::create(&progress_path).map_err(|e| format!("cannot create {}: {e}", progress_path.display()))?;
    file.write_all(&[0u8; PROGRESS_SIZE]).map_err(|e| format!("cannot write {}: {e}", progress_path.display()))?;
    drop(file);
    let progress = Progress::open(&progress_path)?;
    let log_path = work.join(format!("child-{id}.log"));
    let log = std::fs::File::create(&log_path).map_err(|e| format!("cannot create {}: {e}", log_path.display()))?;
    let mut command = Command::new(&launcher.program);
    command.args(&launcher.args).arg("--progress").arg(&progress_path).args(args);
    command.stdin(Stdio::null()).stdout(Stdio::piped()).stderr(log);
    // Its own process group: Ctrl-C reaches only the validator, which then ends the child,
    // and a kill takes any process the FMU started with it.
    use std::os::unix::process::CommandExt;
    command.process_group(0);
    let mut child = command.spawn().map_err(|e| format!("cannot start the probe process {}: {e}", launcher.program.display()))?;
    let stdout = child.stdout.take().expect("stdout is piped");
    let (lines, received) = mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    let pid = child.id() as libc::pid_t;
    let kill = || {
        // SAFETY: signalling the process group of our own child.
        unsafe { libc::kill(-pid, libc::SIGKILL) };
    };
    let mut messages = Vec::new();
    let mut forced: Option<End> = None;
    // A child that makes no FMI call for this long while in none is stuck in the FMU's own
    // threads or in an exit handler; generous, since the validator's own work between calls
    // (comparing long runs) takes milliseconds.
    let stall_limit = (timeout * 10).max(Duration::from_secs(60));
    let (mut last_count, mut last_change) = (0, Instant::now());
    loop {
        match received.recv_timeout(Duration::from_millis(5)) {
            Ok(line) => {
                if let Ok(message) = serde_json::from_str::<Message>(&line) {
                    messages.push(message);
                }
                continue;
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => break,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
        }
        if exited(pid) {
            // Ended, but something it started still holds the pipe: end that too (the child
            // is not reaped yet, so its process group is still its own).
            kill();
            break;
        }
        if cancelled() {
            kill();
            forced = Some(End::Cancelled);
            break;
        }
        let now = monotonic_ns();
        if let Some((_, deadline)) = progress.earliest_deadline() {
            if deadline < now {
                kill();
                forced = Some(End::TimedOut);
                break;
            }
            last_change = Instant::now();
        } else {
            let count = progress.counter().load(Ordering::Relaxed);
            if count != last_count {
                (last_count, last_change) = (count, Instant::now());
            } else if last_change.elapsed() > stall_limit {
                kill();
                forced = Some(End::TimedOut);
                break;
            }
        }
    }
    let status = child.wait().map_err(|e| format!("cannot wait for the probe process: {e}"))?;
    let _ = reader.join();
    while let Ok(line) = received.try_recv() {
        if let Ok(message) = serde_json::from_str::<Message>(&line) {
            messages.push(message);
        }
    }
    let done = messages.iter().any(|m| matches!(m, Message::Done));
    use std::os::unix::process::ExitStatusExt;
    let end = match forced {
        Some(end) => end,
        None => match (status.signal(), status.code()) {
            (Some(signal), _) => End::Crashed(signal_name(signal)),
            (None, Some(0)) if done => End::Finished,
            (None, Some(code)) => End::Exited(code),
            (None, None) => End::Exited(-1),
        },
    };
    let in_call = progress.earliest_deadline().and_then(|(slot, _)| progress.record(slot));
    let last_call = progress.record(0);
    let log_tail = log_tail(&log_path);
    drop(progress);
    let _ = std::fs::remove_file(&progress_path);
    let _ = std::fs::remove_file(&log_path);
    Ok(ChildRun { messages, end, in_call, last_call, log_tail })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_written_in_one_mapping_is_read_in_another() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p");
        std::fs::write(&path, vec![0u8; PROGRESS_SIZE]).unwrap();
        let writer = Progress::open(&path).unwrap();
        let reader = Progress::open(&path).unwrap();
        assert_eq!(reader.earliest_deadline(), None);
        let record =
            CallRecord { call: "fmi2DoStep".into(), state: "StepComplete".into(), variable: None, value: Some("t = 1, h = 0.1".into()) };
        writer.begin(3, &record, Duration::from_secs(5));
        let (slot, deadline) = reader.earliest_deadline().unwrap();
        assert_eq!(slot, 3);
        assert!(deadline > monotonic_ns());
        assert_eq!(reader.record(3), Some(record));
        writer.end(3);
        assert_eq!(reader.earliest_deadline(), None);
        // A record longer than a slot is cut at a character boundary, not spilled.
        let long = CallRecord { call: "fmi2SetString".into(), state: "s".into(), variable: Some("é".repeat(600)), value: None };
        writer.begin(0, &long, Duration::from_secs(1));
        let back = reader.record(0).unwrap();
        assert!(back.variable.unwrap().len() <= RECORD_MAX);
        assert_eq!(reader.record(1), None);
    }
}
