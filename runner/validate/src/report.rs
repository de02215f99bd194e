//! What `runner validate` found: findings (each naming the call, state, variable and value),
//! one report per FMU, and the three ways to show them: readable text grouped into errors,
//! warnings and passed checks, JSON for machines, and JUnit XML for CI dashboards.

use serde::{Deserialize, Serialize};

/// How a finding counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// The FMU breaks a rule of the standard, crashes, hangs or computes wrong numbers.
    Error,
    /// The FMU is fragile or unusual where the standard leaves it free (`--strict` fails on it).
    Warning,
    /// A check that ran and found nothing wrong.
    Passed,
    /// A check that did not apply or could not run because of an earlier error.
    Skipped,
}

impl Severity {
    /// The word used in the text report.
    pub fn word(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
            Severity::Passed => "passed",
            Severity::Skipped => "skipped",
        }
    }
}

/// One result of one check.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Finding {
    /// The check's stable identifier, e.g. `state-machine.illegal`.
    pub check: String,
    pub severity: Severity,
    /// `Co-Simulation` or `Model Exchange` for the dynamic checks of one interface.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub interface: Option<String>,
    /// One sentence: what happened and why it matters.
    pub message: String,
    /// The FMI function called, e.g. `fmi2SetReal`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub call: Option<String>,
    /// The state of the instance when it was called, e.g. `StepComplete`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<String>,
    /// The variable (or variables) involved.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub variable: Option<String>,
    /// The value passed or found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub value: Option<String>,
    /// What the FMU logged during the call, if anything.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub log: Option<String>,
}

impl Finding {
    /// A finding of `check` with `severity` and `message`, nothing else named yet.
    pub fn new(check: &str, severity: Severity, message: impl Into<String>) -> Finding {
        Finding {
            check: check.to_owned(),
            severity,
            interface: None,
            message: message.into(),
            call: None,
            state: None,
            variable: None,
            value: None,
            log: None,
        }
    }

    /// An error.
    pub fn error(check: &str, message: impl Into<String>) -> Finding {
        Finding::new(check, Severity::Error, message)
    }

    /// A warning.
    pub fn warning(check: &str, message: impl Into<String>) -> Finding {
        Finding::new(check, Severity::Warning, message)
    }

    /// A passed check.
    pub fn passed(check: &str, message: impl Into<String>) -> Finding {
        Finding::new(check, Severity::Passed, message)
    }

    /// A skipped check.
    pub fn skipped(check: &str, message: impl Into<String>) -> Finding {
        Finding::new(check, Severity::Skipped, message)
    }

    /// Names the FMI function.
    pub fn call(mut self, call: impl Into<String>) -> Finding {
        self.call = Some(call.into());
        self
    }

    /// Names the instance's state.
    pub fn state(mut self, state: impl Into<String>) -> Finding {
        self.state = Some(state.into());
        self
    }

    /// Names the variable.
    pub fn variable(mut self, variable: impl Into<String>) -> Finding {
        self.variable = Some(variable.into());
        self
    }

    /// Names the value.
    pub fn value(mut self, value: impl Into<String>) -> Finding {
        self.value = Some(value.into());
        self
    }

    /// Attaches what the FMU logged (nothing when empty).
    pub fn log(mut self, log: Option<String>) -> Finding {
        self.log = log.filter(|l| !l.is_empty());
        self
    }

    /// Names the interface.
    pub fn interface(mut self, interface: Option<&str>) -> Finding {
        self.interface = interface.map(str::to_owned);
        self
    }

    /// True for errors, and for warnings when `strict`.
    pub fn fails(&self, strict: bool) -> bool {
        self.severity == Severity::Error || (strict && self.severity == Severity::Warning)
    }
}

/// Everything found in one FMU.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// The FMU file as given.
    pub fmu: String,
    /// `fmiVersion` of its description, when readable.
    pub fmi_version: Option<String>,
    /// `modelName`, when readable.
    pub model_name: Option<String>,
    /// The interfaces it declares.
    pub interfaces: Vec<String>,
    /// In the order the checks ran.
    pub findings: Vec<Finding>,
    /// Wall time of the validation.
    pub seconds: f64,
}

impl Report {
    /// An empty report for the FMU at `fmu`.
    pub fn new(fmu: &str) -> Report {
        Report { fmu: fmu.to_owned(), fmi_version: None, model_name: None, interfaces: Vec::new(), findings: Vec::new(), seconds: 0.0 }
    }

    /// The findings of `severity`.
    pub fn with(&self, severity: Severity) -> impl Iterator<Item = &Finding> + '_ {
        self.findings.iter().filter(move |f| f.severity == severity)
    }

    /// How many findings of `severity`.
    pub fn count(&self, severity: Severity) -> usize {
        self.with(severity).count()
    }

    /// True when some finding fails the run (errors; warnings too when `strict`).
    pub fn fails(&self, strict: bool) -> bool {
        self.findings.iter().any(|f| f.fails(strict))
    }

    /// Drops the passed entry of a check that also has an error or warning in the same interface
    /// (a probe resumed after a crash can report both).
    pub fn settle(&mut self) {
        let troubled: std::collections::HashSet<(String, Option<String>)> = self
            .findings
            .iter()
            .filter(|f| matches!(f.severity, Severity::Error | Severity::Warning))
            .map(|f| (f.check.clone(), f.interface.clone()))
            .collect();
        self.findings.retain(|f| f.severity != Severity::Passed || !troubled.contains(&(f.check.clone(), f.interface.clone())));
    }

    /// The readable report: errors, warnings, passed and skipped checks, then a summary line.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        let what = match (&self.model_name, &self.fmi_version) {
            (Some(m), Some(v)) => format!(" ({m}, FMI {v}{})", interfaces_text(&self.interfaces)),
            _ => String::new(),
        };
        out.push_str(&format!("runner validate: {}{what}\n", self.fmu));
        for (severity, title) in
            [(Severity::Error, "Errors"), (Severity::Warning, "Warnings"), (Severity::Passed, "Passed"), (Severity::Skipped, "Skipped")]
        {
            let found: Vec<&Finding> = self.with(severity).collect();
            if found.is_empty() && matches!(severity, Severity::Passed | Severity::Skipped) {
                continue;
            }
            out.push_str(&format!("{title} ({})\n", found.len()));
            for f in found {
                out.push_str(&format!(
                    "  [{}] {}{}\n",
                    f.check,
                    f.interface.as_ref().map(|i| format!("{i}: ")).unwrap_or_default(),
                    f.message
                ));
                let mut named = Vec::new();
                for (label, field) in [("call", &f.call), ("state", &f.state), ("variable", &f.variable), ("value", &f.value)] {
                    if let Some(v) = field {
                        named.push(format!("{label} {v}"));
                    }
                }
                if !named.is_empty() && matches!(severity, Severity::Error | Severity::Warning) {
                    out.push_str(&format!("      {}\n", named.join("; ")));
                }
                if let Some(log) = &f.log {
                    if matches!(severity, Severity::Error | Severity::Warning) {
                        out.push_str(&format!("      the FMU logged: {log}\n"));
                    }
                }
            }
        }
        out.push_str(&format!(
            "Result: {} error(s), {} warning(s), {} passed, {} skipped ({:.1} s)\n",
            self.count(Severity::Error),
            self.count(Severity::Warning),
            self.count(Severity::Passed),
            self.count(Severity::Skipped),
            self.seconds
        ));
        out
    }
}

fn interfaces_text(interfaces: &[String]) -> String {
    if interfaces.is_empty() {
        String::new()
    } else {
        format!(", {}", interfaces.join(" and "))
    }
}

/// The machine-readable report of several FMUs: `{"reports": [...]}`.
pub fn to_json(reports: &[Report]) -> String {
    #[derive(Serialize)]
    struct All<'a> {
        reports: &'a [Report],
    }
    serde_json::to_string_pretty(&All { reports }).expect("reports are plain data") + "\n"
}

/// `text` safe inside XML attribute values and text.
fn xml_escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // XML 1.0 cannot carry most control characters, even escaped.
            c if (c as u32) < 0x20 && !matches!(c, '\n' | '\t' | '\r') => out.push_str(&format!("\\u{{{:x}}}", c as u32)),
            c => out.push(c),
        }
    }
    out
}

/// One line per finding, as the body of a JUnit failure.
fn finding_line(f: &Finding) -> String {
    let mut line = format!("{}: {}", f.severity.word(), f.message);
    for (label, field) in [("call", &f.call), ("state", &f.state), ("variable", &f.variable), ("value", &f.value), ("logged", &f.log)] {
        if let Some(v) = field {
            line.push_str(&format!("; {label} {v}"));
        }
    }
    line
}

/// A JUnit test case: a check and the interface it ran on.
type CaseKey = (String, Option<String>);

/// JUnit XML: one test suite per FMU, one test case per check and interface; errors (and
/// warnings when `strict`) are failures, checks that did not apply are skipped.
pub fn to_junit(reports: &[Report], strict: bool) -> String {
    let mut suites = String::new();
    let (mut all_tests, mut all_failures) = (0, 0);
    for report in reports {
        // Test cases in the order their checks first appear.
        let mut cases: Vec<(CaseKey, Vec<&Finding>)> = Vec::new();
        for f in &report.findings {
            let key = (f.check.clone(), f.interface.clone());
            match cases.iter_mut().find(|(k, _)| *k == key) {
                Some((_, list)) => list.push(f),
                None => cases.push((key, vec![f])),
            }
        }
        let (mut failures, mut skipped) = (0, 0);
        let mut body = String::new();
        for ((check, interface), findings) in &cases {
            let classname = match interface {
                Some(i) => format!("{}.{}", report.fmu, i),
                None => report.fmu.clone(),
            };
            body.push_str(&format!("    <testcase classname=\"{}\" name=\"{}\">\n", xml_escape(&classname), xml_escape(check)));
            let failing: Vec<&&Finding> = findings.iter().filter(|f| f.fails(strict)).collect();
            if let Some(first) = failing.first() {
                failures += 1;
                let text: Vec<String> = failing.iter().map(|f| finding_line(f)).collect();
                body.push_str(&format!(
                    "      <failure type=\"{}\" message=\"{}\">{}</failure>\n",
                    first.severity.word(),
                    xml_escape(&first.message),
                    xml_escape(&text.join("\n"))
                ));
            } else if findings.iter().all(|f| f.severity == Severity::Skipped) {
                skipped += 1;
                body.push_str(&format!("      <skipped message=\"{}\"/>\n", xml_escape(&findings[0].message)));
            }
            let notes: Vec<String> =
                findings.iter().filter(|f| !f.fails(strict) && f.severity != Severity::Skipped).map(|f| finding_line(f)).collect();
            if !notes.is_empty() {
                body.push_str(&format!("      <system-out>{}</system-out>\n", xml_escape(&notes.join("\n"))));
            }
            body.push_str("    </testcase>\n");
        }
        all_tests += cases.len();
        all_failures += failures;
        suites.push_str(&format!(
            "  <testsuite name=\"{}\" tests=\"{}\" failures=\"{failures}\" errors=\"0\" skipped=\"{skipped}\" time=\"{:.3}\">\n{body}  </testsuite>\n",
            xml_escape(&report.fmu),
            cases.len(),
            report.seconds
        ));
    }
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"runner validate\" tests=\"{all_tests}\" failures=\"{all_failures}\" errors=\"0\">\n{suites}</testsuites>\n"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Report {
        let mut r = Report::new("m.fmu");
        r.model_name = Some("m".into());
        r.fmi_version = Some("2.0".into());
        r.interfaces = vec!["Co-Simulation".into()];
        r.findings.push(Finding::passed("archive.layout", "only the standard's entries"));
        r.findings.push(
            Finding::error("state-machine.illegal", "fmi2SetReal <accepted> an illegal call")
                .interface(Some("Co-Simulation"))
                .call("fmi2SetReal")
                .state("StepComplete")
                .variable("k")
                .value("2")
                .log(Some("ok & fine".into())),
        );
        r.findings.push(Finding::warning("capability.threads", "slow").interface(Some("Co-Simulation")));
        r.findings.push(Finding::skipped("model-exchange", "no Model Exchange"));
        r
    }

    #[test]
    fn text_groups_by_severity_and_names_call_state_variable_value() {
        let text = sample().to_text();
        let errors = text.find("Errors (1)").unwrap();
        let warnings = text.find("Warnings (1)").unwrap();
        let passed = text.find("Passed (1)").unwrap();
        let skipped = text.find("Skipped (1)").unwrap();
        assert!(errors < warnings && warnings < passed && passed < skipped, "{text}");
        assert!(text.contains("call fmi2SetReal; state StepComplete; variable k; value 2"), "{text}");
        assert!(text.contains("the FMU logged: ok & fine"), "{text}");
        assert!(text.contains("Result: 1 error(s), 1 warning(s), 1 passed, 1 skipped"), "{text}");
    }

    #[test]
    fn json_round_trips() {
        let reports = vec![sample()];
        let json = to_json(&reports);
        #[derive(Deserialize)]
        struct All {
            reports: Vec<Report>,
        }
        let back: All = serde_json::from_str(&json).unwrap();
        assert_eq!(back.reports, reports);
    }

    /// The JUnit file is well-formed XML (read back with quick-xml would need another
    /// dependency; the schema crate's reader is for modelDescription only), so check the
    /// escaping and the counts directly.
    #[test]
    fn junit_counts_failures_and_escapes() {
        let xml = to_junit(&[sample()], false);
        assert!(xml.contains("tests=\"4\" failures=\"1\""), "{xml}");
        assert!(xml.contains("fmi2SetReal &lt;accepted&gt; an illegal call"), "{xml}");
        assert!(xml.contains("<skipped message=\"no Model Exchange\"/>"), "{xml}");
        assert!(!xml.contains("ok & fine"), "{xml}");
        let strict = to_junit(&[sample()], true);
        assert!(strict.contains("failures=\"2\""), "warnings fail with --strict: {strict}");
        assert_eq!(xml_escape("a\u{1b}b"), "a\\u{1b}b");
    }

    #[test]
    fn settle_drops_a_pass_contradicted_by_an_error() {
        let mut r = Report::new("m.fmu");
        r.findings.push(Finding::error("x", "bad").interface(Some("Co-Simulation")));
        r.findings.push(Finding::passed("x", "fine").interface(Some("Co-Simulation")));
        r.findings.push(Finding::passed("x", "fine").interface(Some("Model Exchange")));
        r.settle();
        assert_eq!(r.findings.len(), 2);
        assert_eq!(r.findings[1].interface.as_deref(), Some("Model Exchange"));
    }
}
