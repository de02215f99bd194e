//! Every probe of an FMU's binary runs in a worker process of the runner's sandbox (crate
//! `runner-sandbox`), so a crash or a hang in the FMU is a finding, never the validator's own
//! death: a fresh worker for every probe, as a real importer would load the FMU. This is the
//! validator's service of it: the jobs (one probe), the messages they stream (cells and
//! findings), their outcomes, and what the probes record in the memory each worker shares with
//! its supervisor ([`Progress`]).
//!
//! Before each FMI call the probe writes the call (function, state, variable, value) and a
//! deadline into its thread's slot of the shared memory; the validator's watchdog kills a
//! worker whose call overran `--timeout` (or that stopped calling at all), and after a crash or
//! a kill reads which call was running. Writing that record costs no system call, so a run of
//! 100,000 steps stays fast. What the FMU prints goes to a log file, whose lines since the
//! crashed cell began a death's finding quotes.

use std::io::{Read, Seek, SeekFrom};
use std::marker::PhantomData;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use runner_sandbox::{Config, Failure, Service, Session, SharedMemory, WorkerCommand};
use serde::{Deserialize, Serialize};

use crate::fmi::{Fmi, Interface};
use crate::report::{Finding, Severity};

/// One probe of one binary: what the probe process needs besides the FMU unpacked in `dir`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Job {
    pub fmi: Fmi,
    pub dir: PathBuf,
    /// Where the lifecycle probe keeps its reference run for the others.
    pub runs: PathBuf,
    pub binary: PathBuf,
    pub interfaces: Vec<Interface>,
    /// The longest one FMI call may take.
    pub timeout: Duration,
    pub probe: String,
    /// The cell to start at (after one that crashed).
    pub resume: usize,
}

/// What a probe sends while it runs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) enum Message {
    /// The probe starts its cell `index` (the unit a crashed probe resumes after), which
    /// belongs to check `check`; a crash in it is a finding of severity `crash`.
    Cell { check: String, index: usize, crash: Severity },
    /// A finding, as JSON: the report's absent fields are left out of it, which a frame of the
    /// sandbox (not self-describing) could not carry.
    Finding(String),
}

impl Message {
    /// The message of `finding`.
    pub(crate) fn finding(finding: &Finding) -> Message {
        Message::Finding(serde_json::to_string(finding).expect("findings are plain data"))
    }
}

/// Where a probe's messages go (to the supervisor, through the worker's reply pipe): sent at
/// once, so that a crash right after loses none.
pub(crate) struct Out<'a> {
    send: Box<dyn Fn(&Message) + Sync + 'a>,
}

impl<'a> Out<'a> {
    /// Messages handed to `send`.
    pub(crate) fn new(send: impl Fn(&Message) + Sync + 'a) -> Out<'a> {
        Out { send: Box::new(send) }
    }

    pub(crate) fn send(&self, message: &Message) {
        (self.send)(message)
    }
}

/// The call a probe was in (or last made), as it recorded it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub(crate) struct CallRecord {
    pub call: String,
    pub state: String,
    pub variable: Option<String>,
    pub value: Option<String>,
}

/// How a probe process ended before it finished.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) enum End {
    /// Killed by a signal it raised (SIGSEGV, SIGABRT, ...): its name.
    Crashed(String),
    /// It exited with a code (the FMU called exit()).
    Exited(i32),
    /// A call did not return within the timeout, or it stopped calling; it was killed.
    TimedOut,
}

/// How a probe ended.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) enum Outcome {
    /// It ran all its cells.
    Finished,
    /// The validator itself failed in it (a bug, or a broken installation).
    Internal(String),
    /// Its process ended before it finished: how, the call in progress then (if it was inside
    /// one) and the last call it started.
    Died { end: End, in_call: Option<CallRecord>, last_call: Option<CallRecord> },
}

/// The validator's service of the sandbox.
pub(crate) struct Probes;

impl Service for Probes {
    type Setup = ();
    type Job = Job;
    type Message = Message;
    type Outcome = Outcome;

    fn failed(_job: &Job, failure: &Failure, shared: &SharedMemory) -> Outcome {
        use std::os::unix::process::ExitStatusExt;
        let end = match failure {
            Failure::Ended(status) => match (status.signal(), status.code()) {
                (Some(signal), _) => End::Crashed(signal_name(signal)),
                (None, code) => End::Exited(code.unwrap_or(-1)),
            },
            Failure::TimedOut(_) => End::TimedOut,
        };
        let progress = Progress::over(shared);
        Outcome::Died {
            end,
            in_call: progress.earliest_deadline().and_then(|(slot, _)| progress.record(slot)),
            last_call: progress.record(0),
        }
    }
}

/// The name of a signal, for messages.
fn signal_name(signal: i32) -> String {
    let what = match signal {
        libc::SIGSEGV | libc::SIGBUS => " (invalid memory access)",
        libc::SIGABRT => " (abort)",
        libc::SIGFPE => " (arithmetic exception)",
        libc::SIGILL => " (illegal instruction)",
        _ => "",
    };
    format!("{}{what}", runner_sandbox::signal_name(signal))
}

/// Threads of one probe that may call the FMU at once, each with its own record.
pub(crate) const SLOTS: usize = 8;
const HEADER: usize = 64;
const SLOT_SIZE: usize = 512;
/// Size of the shared progress record.
pub(crate) const PROGRESS_SIZE: usize = HEADER + SLOTS * SLOT_SIZE;
const RECORD_MAX: usize = SLOT_SIZE - 12;

/// CLOCK_MONOTONIC in nanoseconds: the one clock both processes read alike.
fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: a valid timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// The calls a probe records, laid over the memory a worker shares with its supervisor: per
/// slot a deadline and the call's record, and a counter of calls started.
#[derive(Clone, Copy)]
pub(crate) struct Progress<'a> {
    base: *mut u8,
    _memory: PhantomData<&'a SharedMemory>,
}

// The memory is only touched through atomics (deadlines, counter) and through a slot's own
// thread (its record), so it may be shared between threads.
unsafe impl Send for Progress<'_> {}
unsafe impl Sync for Progress<'_> {}

impl<'a> Progress<'a> {
    /// The record in `shared` (of at least [`PROGRESS_SIZE`] bytes).
    pub(crate) fn over(shared: &'a SharedMemory) -> Progress<'a> {
        assert!(shared.len() >= PROGRESS_SIZE, "the memory shared with a probe holds its progress record");
        Progress { base: shared.as_ptr(), _memory: PhantomData }
    }

    fn atomic(&self, offset: usize) -> &AtomicU64 {
        // SAFETY: offset is 8-aligned inside the region (page-aligned base), which lives as
        // long as 'a; AtomicU64 has the layout of u64.
        unsafe { &*(self.base.add(offset) as *const AtomicU64) }
    }

    fn deadline(&self, slot: usize) -> &AtomicU64 {
        self.atomic(HEADER + slot * SLOT_SIZE)
    }

    /// Counts calls started, so the supervisor can tell a busy probe from a stuck one.
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
        // SAFETY: the slot's record area belongs to this slot's thread; the supervisor reads it
        // only after the worker stopped.
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

    /// The record of `slot` (read once the worker stopped writing).
    fn record(&self, slot: usize) -> Option<CallRecord> {
        let at = HEADER + slot * SLOT_SIZE;
        let mut len = [0u8; 4];
        // SAFETY: inside the region; the writer is stopped.
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

/// What a probe process writes to its stderr when a job or a cell starts, so that a death's
/// finding quotes only what the FMU logged in the cell that died.
pub(crate) const CELL_MARK: &str = "\u{1e}runner validate: cell ";

/// The last few lines the workers wrote to `log` since the last cell began, made printable.
fn log_tail(log: &Path) -> Option<String> {
    const TAIL: u64 = 1 << 16;
    let mut file = std::fs::File::open(log).ok()?;
    let len = file.metadata().ok()?.len();
    file.seek(SeekFrom::Start(len.saturating_sub(TAIL))).ok()?;
    let mut bytes = Vec::new();
    file.read_to_end(&mut bytes).ok()?;
    let text = String::from_utf8_lossy(&bytes).into_owned();
    let since = text.rfind(CELL_MARK).map_or(&text[..], |at| &text[at..]);
    let lines: Vec<&str> = since.lines().filter(|l| !l.trim().is_empty() && !l.starts_with(CELL_MARK)).collect();
    let tail = lines[lines.len().saturating_sub(3)..].join(" | ");
    (!tail.is_empty()).then(|| fmi_schema::printable(tail))
}

/// The probes of one FMU, each in a fresh worker.
pub(crate) struct Supervisor {
    session: Session<Probes>,
    log: PathBuf,
    timeout: Duration,
}

/// Everything one probe produced.
pub(crate) struct ProbeRun {
    pub messages: Vec<Message>,
    pub outcome: Outcome,
    /// The last lines the probe process wrote to stderr (the FMU's log and output), when it
    /// died.
    pub log_tail: Option<String>,
}

impl Supervisor {
    /// Probes started by `command`, their output in `work`, each FMI call bounded by
    /// `timeout`.
    pub(crate) fn new(command: WorkerCommand, work: &Path, timeout: Duration) -> Supervisor {
        let log = work.join("probes.log");
        let config = Config { shared_bytes: PROGRESS_SIZE, log_file: Some(log.clone()), ..Config::new(command) };
        Supervisor { session: Session::new(config, &[], true), log, timeout }
    }

    /// Runs `job` in a fresh worker; `Err` when it could not run or `cancelled` said to stop
    /// (the error is then "interrupted").
    pub(crate) fn run(&mut self, job: Job, cancelled: &dyn Fn() -> bool) -> Result<ProbeRun, String> {
        let timeout = self.timeout;
        // A probe that makes no FMI call for this long while in none is stuck in the FMU's own
        // threads or in an exit handler; generous, since the validator's own work between calls
        // (comparing long runs) takes milliseconds.
        let stall_limit = (timeout * 10).max(Duration::from_secs(60));
        let (mut last_count, mut last_change) = (0, Instant::now());
        let mut watch = |shared: &SharedMemory| -> Option<Duration> {
            let progress = Progress::over(shared);
            if let Some((_, deadline)) = progress.earliest_deadline() {
                last_change = Instant::now();
                return (deadline < monotonic_ns()).then_some(timeout);
            }
            let count = progress.counter().load(Ordering::Relaxed);
            if count != last_count {
                (last_count, last_change) = (count, Instant::now());
            }
            (last_change.elapsed() > stall_limit).then_some(stall_limit)
        };
        let mut messages = Vec::new();
        let outcome = self.session.run_watched(job, cancelled, &mut watch, |message| {
            messages.push(message);
            Ok(())
        })?;
        let log_tail = matches!(outcome, Outcome::Died { .. }).then(|| log_tail(&self.log)).flatten();
        Ok(ProbeRun { messages, outcome, log_tail })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_record_written_in_one_view_is_read_in_another() {
        let memory = SharedMemory::new(PROGRESS_SIZE).unwrap();
        let (writer, reader) = (Progress::over(&memory), Progress::over(&memory));
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

    /// A death's finding quotes what the FMU printed in the cell that died, not before.
    #[test]
    fn the_log_tail_starts_at_the_last_cell() {
        let dir = tempfile::tempdir().unwrap();
        let log = dir.path().join("probes.log");
        std::fs::write(&log, format!("earlier\n{CELL_MARK}3\none\n\ntwo\nthree\nfour\u{1b}[0m\n")).unwrap();
        assert_eq!(log_tail(&log).as_deref(), Some("two | three | four\\u{1b}[0m"));
        std::fs::write(&log, format!("earlier\n{CELL_MARK}start\n")).unwrap();
        assert_eq!(log_tail(&log), None, "nothing since the probe started");
        assert_eq!(signal_name(libc::SIGSEGV), "SIGSEGV (invalid memory access)");
        assert_eq!(signal_name(libc::SIGKILL), "SIGKILL");
    }
}
