//! A problem a probe ran into, ready to become a finding: what went wrong, and the call, state,
//! variable and value it happened at.

use crate::fmi::{Outcome, State};
use crate::report::{Finding, Severity};

/// A problem a probe ran into.
#[derive(Debug, Clone)]
pub(crate) struct Failure {
    /// The check it belongs to, when not the probe's own.
    pub check: Option<&'static str>,
    pub message: String,
    pub call: Option<String>,
    pub state: Option<String>,
    pub variable: Option<String>,
    pub value: Option<String>,
    pub log: Option<String>,
}

impl Failure {
    /// A problem described by `message` alone.
    pub(crate) fn new(message: impl Into<String>) -> Failure {
        Failure { check: None, message: message.into(), call: None, state: None, variable: None, value: None, log: None }
    }

    /// A call to `call` in `state` that returned `outcome`'s code where success was due.
    pub(crate) fn refused<T>(call: &str, state: State, outcome: &Outcome<T>, what: &str) -> Failure {
        Failure {
            message: format!("{call} {what} returned {}", outcome.code.name()),
            call: Some(call.to_owned()),
            state: Some(state.name().to_owned()),
            log: outcome.log.clone(),
            ..Failure::new("")
        }
    }

    /// Reported under `check`, whatever probe meets it.
    pub(crate) fn check(mut self, check: &'static str) -> Failure {
        self.check = Some(check);
        self
    }

    pub(crate) fn variable(mut self, variable: impl Into<String>) -> Failure {
        self.variable = Some(variable.into());
        self
    }

    pub(crate) fn value(mut self, value: impl Into<String>) -> Failure {
        self.value = Some(value.into());
        self
    }

    /// Names `call` (an instantiation) as the call, made before any instance exists.
    pub(crate) fn at_instantiate(mut self, call: &str) -> Failure {
        self.call = Some(call.to_owned());
        self.state = Some("(no instance)".to_owned());
        self
    }

    /// Names the call and the state it was made in.
    pub(crate) fn at(mut self, call: &str, state: State) -> Failure {
        self.call = Some(call.to_owned());
        self.state = Some(state.name().to_owned());
        self
    }

    /// Attaches what the FMU logged, if it logged anything.
    pub(crate) fn with_log(mut self, log: Option<String>) -> Failure {
        if log.is_some() {
            self.log = log;
        }
        self
    }

    /// The finding, under `default_check` unless the failure names its own.
    pub(crate) fn finding(self, default_check: &str, severity: Severity) -> Finding {
        let mut f = Finding::new(self.check.unwrap_or(default_check), severity, self.message).log(self.log);
        f.call = self.call;
        f.state = self.state;
        f.variable = self.variable;
        f.value = self.value;
        f
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::{Code, Fmi};

    #[test]
    fn a_failure_becomes_a_finding_naming_everything_it_knows() {
        let outcome = Outcome { code: Code::error_of(Fmi::Fmi2), value: (), log: Some("no".into()) };
        let f = Failure::refused("fmi2DoStep", State::StepComplete, &outcome, "").value("t = 0").finding("lifecycle.run", Severity::Error);
        assert_eq!(f.message, "fmi2DoStep  returned fmi2Error");
        assert_eq!(
            (f.call.as_deref(), f.state.as_deref(), f.value.as_deref(), f.log.as_deref()),
            (Some("fmi2DoStep"), Some("StepComplete"), Some("t = 0"), Some("no"))
        );
        let own = Failure::new("x").check("health.finite").finding("lifecycle.run", Severity::Warning);
        assert_eq!((own.check.as_str(), own.severity), ("health.finite", Severity::Warning));
        assert_eq!(Failure::new("b").with_log(None).log, None);
    }
}
