//! Log categories and the per-instance logger that honours `fmi2SetDebugLogging`.

/// Status codes, numbered as FMI 2.0 and 3.0 number them (3.0 has no `Pending`): the C
/// interface's one [`fmi_c::Status`].
pub use fmi_c::Status;

/// A log category declared in `LogCategories`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Category {
    pub name: &'static str,
    pub description: &'static str,
    /// A debug category: delivered only while debug logging is on.
    pub debug: bool,
}

/// Events: mode changes, located crossings, early ends of a step.
pub const LOG_EVENTS: Category =
    Category { name: "logEvents", description: "Events: located crossings, mode changes, early ends", debug: true };
/// Every FMI call with its arguments (verbose).
pub const LOG_CALLS: Category = Category { name: "logCalls", description: "Every FMI function call and its arguments", debug: true };
/// Warnings.
pub const LOG_WARNING: Category = Category { name: "logStatusWarning", description: "Calls that returned fmi2Warning", debug: false };
/// A step ended early or a value was refused but the instance can go on.
pub const LOG_DISCARD: Category = Category { name: "logStatusDiscard", description: "Calls that returned fmi2Discard", debug: false };
/// Errors: illegal call sequences, refused arguments or parameters, solver failures.
pub const LOG_ERROR: Category = Category { name: "logStatusError", description: "Calls that returned fmi2Error", debug: false };
/// Fatal errors.
pub const LOG_FATAL: Category = Category { name: "logStatusFatal", description: "Calls that returned fmi2Fatal", debug: false };

/// All categories, in the order `LogCategories` declares them.
pub const CATEGORIES: &[Category] = &[LOG_EVENTS, LOG_CALLS, LOG_WARNING, LOG_DISCARD, LOG_ERROR, LOG_FATAL];

/// Where an instance's messages go: the importer's logger (or a test's closure).
pub type Sink = Box<dyn FnMut(Status, &'static str, &str) + Send>;

/// Filters messages by category as `fmi2SetDebugLogging` asks.
///
/// Status categories (warning, discard, error, fatal) are always delivered unless the importer
/// explicitly switched them off, because an importer must learn why a call failed; debug
/// categories (events, calls) are delivered only while debug logging is on.
pub struct Logger {
    sink: Option<Sink>,
    debug_on: bool,
    /// `enabled[i]` for `CATEGORIES[i]`.
    enabled: [bool; CATEGORIES.len()],
}

impl Logger {
    /// A logger delivering to `sink`, with debug logging as `fmi2Instantiate`'s `loggingOn`.
    pub fn new(sink: Option<Sink>, debug_on: bool) -> Logger {
        Logger { sink, debug_on, enabled: [true; CATEGORIES.len()] }
    }

    /// Applies `fmi2SetDebugLogging`: with no categories, all are switched; an unknown
    /// category name is an error naming it and the known ones.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> Result<(), String> {
        if categories.is_empty() {
            self.debug_on = on;
            self.enabled = [true; CATEGORIES.len()];
            return Ok(());
        }
        let mut indices = Vec::with_capacity(categories.len());
        for name in categories {
            match CATEGORIES.iter().position(|c| c.name == *name) {
                Some(i) => indices.push(i),
                None => {
                    let known: Vec<&str> = CATEGORIES.iter().map(|c| c.name).collect();
                    return Err(format!("unknown log category '{name}'; this FMU declares {}", known.join(", ")));
                }
            }
        }
        for i in indices {
            self.enabled[i] = on;
        }
        if on {
            self.debug_on = true;
        }
        Ok(())
    }

    /// True when a message of `category` would be delivered (lets callers skip formatting).
    /// Always inlined: fmi2DoStep asks it for every call, and with a constant category the
    /// usual answer (debug logging off) is two tests.
    #[inline(always)]
    pub fn wants(&self, category: Category) -> bool {
        // Asked before every call is traced: the cheap tests come first, the one that usually
        // decides (debug logging off) before the others.
        if (category.debug && !self.debug_on) || self.sink.is_none() {
            return false;
        }
        CATEGORIES.iter().position(|c| c.name == category.name).is_some_and(|i| self.enabled[i])
    }

    /// Delivers `message` if its category is enabled.
    pub fn log(&mut self, status: Status, category: Category, message: &str) {
        if self.wants(category) {
            if let Some(sink) = self.sink.as_mut() {
                sink(status, category.name, message);
            }
        }
    }

    /// Delivers a message whose category follows from its status.
    pub fn status(&mut self, status: Status, message: &str) {
        let category = match status {
            Status::Ok | Status::Pending => LOG_EVENTS,
            Status::Warning => LOG_WARNING,
            Status::Discard => LOG_DISCARD,
            Status::Error => LOG_ERROR,
            Status::Fatal => LOG_FATAL,
        };
        self.log(status, category, message);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::{Arc, Mutex};

    fn capture() -> (Logger, Arc<Mutex<Vec<String>>>) {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let s = seen.clone();
        let logger = Logger::new(Some(Box::new(move |_, cat, msg| s.lock().unwrap().push(format!("{cat}: {msg}")))), false);
        (logger, seen)
    }

    #[test]
    fn errors_always_reach_the_importer_debug_only_when_on() {
        let (mut logger, seen) = capture();
        logger.log(Status::Ok, LOG_EVENTS, "event");
        logger.status(Status::Error, "bad");
        assert_eq!(*seen.lock().unwrap(), vec!["logStatusError: bad".to_string()]);
        logger.set_debug_logging(true, &[]).unwrap();
        logger.log(Status::Ok, LOG_EVENTS, "event");
        assert_eq!(seen.lock().unwrap().len(), 2);
    }

    #[test]
    fn categories_can_be_switched_individually_and_unknown_ones_are_named() {
        let (mut logger, seen) = capture();
        logger.set_debug_logging(true, &["logCalls"]).unwrap();
        logger.set_debug_logging(false, &["logStatusError"]).unwrap();
        logger.status(Status::Error, "hidden");
        logger.log(Status::Ok, LOG_CALLS, "call");
        assert_eq!(*seen.lock().unwrap(), vec!["logCalls: call".to_string()]);
        let err = logger.set_debug_logging(true, &["logNope"]).unwrap_err();
        assert!(err.contains("logNope") && err.contains("logEvents"), "{err}");
    }
}
