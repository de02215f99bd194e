//! Where the FMUs' log messages go: every message is printed (through a printer the
//! application may replace, e.g. to keep progress bars intact) and the last problem an
//! instance reported is kept for the error message of the call that failed.

use std::sync::{Mutex, RwLock};

/// The function that prints each log line; `eprintln!` until [`set_log_printer`] replaces it.
static PRINTER: RwLock<fn(&str)> = RwLock::new(default_printer);

fn default_printer(line: &str) {
    eprintln!("{line}");
}

/// Sends every FMU log line (`[instance] level (category): text`) to `printer` from now on;
/// returns the printer it replaces.
pub fn set_log_printer(printer: fn(&str)) -> fn(&str) {
    match PRINTER.write() {
        Ok(mut p) => std::mem::replace(&mut *p, printer),
        Err(_) => default_printer,
    }
}

/// Prints one line through the current printer (the one FMU log lines go through); never
/// panics (it runs inside C callbacks).
pub fn print_line(line: &str) {
    let printer = PRINTER.read().map(|p| *p).unwrap_or(default_printer as fn(&str));
    let _ = std::panic::catch_unwind(|| printer(line));
}

/// What an error says when the FMU logged nothing: many FMUs log only with debug logging on.
pub(crate) const NO_REASON: &str = "the FMU logged no reason; with debug logging on (the runner's --log) it may say more";

/// The word for a status code in a log line.
pub(crate) fn level(status: i32) -> &'static str {
    match status {
        0 => "info",
        1 => "warning",
        2 => "discard",
        3 => "error",
        4 => "fatal",
        _ => "log",
    }
}

/// What the logger knows about one instance: the last problem it reported, for error messages,
/// and the last message of any status, for the reason of a terminateSimulation.
#[derive(Default)]
pub struct LogContext {
    last_problem: Mutex<Option<String>>,
    last_message: Mutex<Option<String>>,
}

impl LogContext {
    /// Prints a message and remembers it, and problems (discard and worse) apart.
    pub(crate) fn receive(&self, instance: &str, status: i32, category: &str, text: &str) {
        let line = format!("[{instance}] {} ({category}): {text}", level(status));
        crate::call_log::message(&line);
        print_line(&line);
        if status >= 2 {
            if let Ok(mut last) = self.last_problem.lock() {
                *last = Some(text.to_owned());
            }
        }
        if let Ok(mut last) = self.last_message.lock() {
            *last = Some(text.to_owned());
        }
    }

    /// The last problem reported since the previous call, if any.
    pub fn take_problem(&self) -> Option<String> {
        self.last_problem.lock().ok().and_then(|mut l| l.take())
    }

    /// Why a call failed or the model ended the simulation: the last problem, else the last
    /// message (an FMU may log its reason as information), since the previous call.
    pub fn take_reason(&self) -> Option<String> {
        let message = self.last_message.lock().ok().and_then(|mut l| l.take());
        self.take_problem().or(message)
    }
}
