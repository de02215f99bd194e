//! The log of every FMI call the importer makes (`runner simulate --log-fmi-calls`): one line per
//! call with its arguments, the status it returned and how long it took, e.g.
//!
//! ```text
//! fmi2DoStep(currentCommunicationPoint=0.1, communicationStepSize=0.1, noSetFMUStatePriorToCurrentPoint=fmi2True) -> fmi2OK [3 us]
//! ```
//!
//! A call's line is written, and reaches the file, before the FMU is called; its status is added
//! when the call returns. An FMU that crashes the process thus leaves the call it crashed in as
//! the last, unfinished line. Messages the FMU logs during a call end the pending line; the
//! status then follows on a line of its own that names the call again.
//!
//! The log belongs to the process (a worker writes its own run's calls). Without it, each call
//! costs one load of a flag.

use std::fmt::{Debug, Write as _};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use serde::{Deserialize, Serialize};

/// Where the call log goes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub enum CallLogTarget {
    /// Standard error, among the FMU's messages.
    Stderr,
    /// This file, appended to ([`create`] empties it first).
    File(PathBuf),
}

/// Arrays longer than this are shortened in the log, with a count of the values left out.
const SHOWN: usize = 10;

static ON: AtomicBool = AtomicBool::new(false);
static LOG: Mutex<Option<Log>> = Mutex::new(None);

struct Log {
    out: Box<dyn Write + Send>,
    /// FMU messages are copied into the log (a file: on stderr they are printed anyway).
    copy_messages: bool,
    /// The call whose line waits for its status.
    pending: Option<&'static str>,
}

/// Creates (or empties) the call log file `path`: the check that it can be written, made before
/// a run starts.
pub fn create(path: &Path) -> Result<(), String> {
    std::fs::File::create(path).map(drop).map_err(|e| format!("cannot write the FMI call log {}: {e}", path.display()))
}

/// Logs every FMI call of this process to `target` until [`stop`].
pub fn start(target: &CallLogTarget) -> Result<(), String> {
    let (out, copy_messages): (Box<dyn Write + Send>, bool) = match target {
        CallLogTarget::Stderr => (Box::new(std::io::stderr()), false),
        CallLogTarget::File(path) => {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(path)
                .map_err(|e| format!("cannot write the FMI call log {}: {e}", path.display()))?;
            (Box::new(file), true)
        }
    };
    let mut log = LOG.lock().map_err(|_| "the FMI call log is poisoned".to_owned())?;
    *log = Some(Log { out, copy_messages, pending: None });
    ON.store(true, Ordering::Relaxed);
    Ok(())
}

/// Ends the call log (a pending line is ended as it is).
pub fn stop() {
    ON.store(false, Ordering::Relaxed);
    if let Ok(mut log) = LOG.lock() {
        if let Some(mut log) = log.take() {
            if log.pending.is_some() {
                let _ = log.out.write_all(b"\n");
            }
            let _ = log.out.flush();
        }
    }
}

/// Runs `f` with the call log to `target` on (when there is one), and stops it after.
pub fn logging<T>(target: Option<&CallLogTarget>, f: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
    let Some(target) = target else { return f() };
    start(target)?;
    let result = f();
    stop();
    result
}

/// A call whose line is written, waiting for its status.
pub(crate) struct Entered {
    name: &'static str,
    start: Instant,
}

/// Writes the line of FMI function `name` with its arguments (made only when logging), before the
/// call.
#[inline(always)]
pub(crate) fn enter(name: &'static str, arguments: impl FnOnce() -> String) -> Option<Entered> {
    if !ON.load(Ordering::Relaxed) {
        return None;
    }
    Some(write_entry(name, &arguments()))
}

/// Adds the status (named only when logging: naming costs a run that does not log) to the line
/// of an [`enter`]ed call.
#[inline(always)]
pub(crate) fn returned(entered: Option<Entered>, status: impl FnOnce() -> &'static str) {
    if let Some(entered) = entered {
        write_return(entered, status(), "");
    }
}

/// [`returned`] with what the call gave back (`results`, made only when logging).
#[inline(always)]
pub(crate) fn returned_with(entered: Option<Entered>, status: impl FnOnce() -> &'static str, results: impl FnOnce() -> String) {
    if let Some(entered) = entered {
        write_return(entered, status(), &results());
    }
}

/// Whether FMI calls are logged. For a caller that passes many arguments to [`call`]: branching
/// on it first keeps the arguments' captures (stored to the stack before the flag is tested,
/// when the compiler builds them for the logged path) out of the calls that are not logged.
#[inline(always)]
pub(crate) fn on() -> bool {
    ON.load(Ordering::Relaxed)
}

/// Runs `call` (an FMI function: its status and what it gave back, by value), logged when the log
/// is on. For the calls of every step: without the log this is one test of a flag before the
/// call, the logging kept out of line.
#[inline(always)]
pub(crate) fn call<R: Copy>(
    name: &'static str,
    arguments: impl FnOnce() -> String,
    call: impl FnOnce() -> R,
    status: impl FnOnce(R) -> &'static str,
    results: impl FnOnce(R) -> String,
) -> R {
    if !ON.load(Ordering::Relaxed) {
        return call();
    }
    logged(name, arguments, call, status, results)
}

#[cold]
#[inline(never)]
fn logged<R: Copy>(
    name: &'static str,
    arguments: impl FnOnce() -> String,
    call: impl FnOnce() -> R,
    status: impl FnOnce(R) -> &'static str,
    results: impl FnOnce(R) -> String,
) -> R {
    let entered = write_entry(name, &arguments());
    let returned = call();
    write_return(entered, status(returned), &results(returned));
    returned
}

/// Adds what an instantiation returned, the instance's address or NULL, to its line.
#[inline(always)]
pub(crate) fn returned_instance<T>(entered: Option<Entered>, instance: *const T) {
    if let Some(entered) = entered {
        let returned = if instance.is_null() { "NULL".to_owned() } else { format!("{instance:p}") };
        write_return(entered, &returned, "");
    }
}

/// Notes an FMU's log message: it ends a pending line, and is copied into a log file.
pub(crate) fn message(line: &str) {
    if !ON.load(Ordering::Relaxed) {
        return;
    }
    with_log(|log| {
        let mut text = String::new();
        if log.pending.take().is_some() {
            text.push('\n');
        }
        if log.copy_messages {
            text.push_str(line);
            text.push('\n');
        }
        text
    });
}

#[cold]
#[inline(never)]
fn write_entry(name: &'static str, arguments: &str) -> Entered {
    with_log(|log| {
        let ended = if log.pending.is_some() { "\n" } else { "" };
        log.pending = Some(name);
        format!("{ended}{name}({arguments})")
    });
    // Started after the line is out: the time is the FMU's, not the log's.
    Entered { name, start: Instant::now() }
}

#[cold]
#[inline(never)]
fn write_return(entered: Entered, status: &str, results: &str) {
    let duration = duration(entered.start.elapsed().as_secs_f64() * 1e6);
    with_log(|log| {
        let results = if results.is_empty() { String::new() } else { format!(" {results}") };
        match log.pending.take() {
            Some(name) if name == entered.name => format!(" -> {status}{results} [{duration}]\n"),
            // The line was ended by a message: name the call again.
            _ => format!("{} -> {status}{results} [{duration}]\n", entered.name),
        }
    });
}

/// Writes what `make` returns (which may change the log's state) at once; never panics (it runs
/// around C calls and in C callbacks).
fn with_log(make: impl FnOnce(&mut Log) -> String) {
    let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        if let Ok(mut log) = LOG.lock() {
            if let Some(log) = log.as_mut() {
                let text = make(log);
                // Unbuffered: the line is out before the FMU runs.
                let _ = log.out.write_all(text.as_bytes());
                let _ = log.out.flush();
            }
        }
    }));
}

/// A duration in microseconds, as the log prints it: whole microseconds, a tenth below ten.
fn duration(us: f64) -> String {
    match us < 10.0 {
        true => format!("{us:.1} us"),
        false => format!("{us:.0} us"),
    }
}

/// `[a, b, c]`, shortened past [`SHOWN`] values with a count of those left out.
pub(crate) fn list<T: Debug>(values: &[T]) -> String {
    let mut text = String::from("[");
    for (k, v) in values.iter().take(SHOWN).enumerate() {
        if k > 0 {
            text.push_str(", ");
        }
        let _ = write!(text, "{v:?}");
    }
    if values.len() > SHOWN {
        let _ = write!(text, ", ... ({} values in all)", values.len());
    }
    text.push(']');
    text
}

/// An FMI Boolean argument as the standard writes it (`fmiTrue` in FMI 1.0, `fmi2True`,
/// `fmi3False`).
pub(crate) fn boolean(version: u8, value: bool) -> String {
    let value = if value { "True" } else { "False" };
    match version {
        1 => format!("fmi{value}"),
        _ => format!("fmi{version}{value}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_arrays_are_shortened_with_their_count() {
        assert_eq!(list(&[1u32, 2, 3]), "[1, 2, 3]");
        assert_eq!(list::<f64>(&[]), "[]");
        let many: Vec<f64> = (0..25).map(f64::from).collect();
        assert_eq!(list(&many), "[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, ... (25 values in all)]");
        assert_eq!(list(&[1e-12, 0.5]), "[1e-12, 0.5]", "floats in the shortest form that reads back");
    }

    #[test]
    fn booleans_are_named_as_their_fmi_version_writes_them() {
        assert_eq!(boolean(1, true), "fmiTrue", "FMI 1.0 has no version in its names");
        assert_eq!(boolean(1, false), "fmiFalse");
        assert_eq!(boolean(2, true), "fmi2True");
        assert_eq!(boolean(3, false), "fmi3False");
    }

    #[test]
    fn durations_keep_two_digits_or_more() {
        assert_eq!(duration(0.42), "0.4 us");
        assert_eq!(duration(12.4), "12 us");
        assert_eq!(duration(1234.0), "1234 us");
    }
}
