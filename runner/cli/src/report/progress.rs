//! Progress bars on stderr for long commands, and printing that does not tear them: FMU log
//! lines and warnings from worker threads go above the bar.

use std::io::IsTerminal;
use std::sync::Mutex;

use indicatif::{ProgressBar, ProgressStyle};

/// The bar being drawn, if any (one long command runs at a time).
static ACTIVE: Mutex<Option<ProgressBar>> = Mutex::new(None);

/// A progress bar counting `len` items called `what`; drawn only when stderr is a terminal.
/// Removed from the screen when dropped.
pub struct Progress {
    bar: ProgressBar,
}

impl Progress {
    /// Starts a bar.
    pub fn start(len: u64, what: &str) -> Progress {
        let bar = if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new(len);
            if let Ok(style) =
                ProgressStyle::with_template(&format!("{{bar:40}} {{pos}}/{{len}} {what}, {{elapsed}} elapsed, ~{{eta}} left"))
            {
                bar.set_style(style);
            }
            bar
        } else {
            ProgressBar::hidden()
        };
        if let Ok(mut active) = ACTIVE.lock() {
            *active = Some(bar.clone());
        }
        Progress { bar }
    }

    /// Counts `n` more items done.
    pub fn inc(&self, n: u64) {
        self.bar.inc(n);
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        if let Ok(mut active) = ACTIVE.lock() {
            *active = None;
        }
        self.bar.finish_and_clear();
    }
}

/// Prints a line on stderr, above the progress bar when one is drawn. Never panics: a failed
/// write to stderr has nowhere to be reported (and this runs inside FMU callbacks).
pub fn eprint_line(text: &str) {
    use std::io::Write;
    let bar = ACTIVE.lock().ok().and_then(|a| a.clone());
    let print = || {
        let _ = writeln!(std::io::stderr(), "{text}");
    };
    match bar {
        Some(bar) => bar.suspend(print),
        None => print(),
    }
}
