//! `runner validate` end to end: a correct third-party FMU written in C (tests/c_fmu/faults.c)
//! is clean; the same FMU with one fault injected at build time is flagged with the finding
//! that names it, and nothing crashes; broken archives and descriptions are named; and the
//! Reference FMUs show exactly the deviations from the standard the README explains.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;
use serde_json::Value;

fn faults_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/c_fmu")
}

/// Compiles tests/c_fmu/faults.c with `flags` into a shared library; returns its bytes.
fn faults_binary(dir: &Path, name: &str, flags: &[&str]) -> Vec<u8> {
    let so = dir.join(format!("{name}.so"));
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", "-o"])
        .arg(&so)
        .arg(faults_dir().join("faults.c"))
        .args(flags)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed on faults.c with {flags:?}");
    std::fs::read(&so).unwrap()
}

fn faults_xml() -> Vec<u8> {
    std::fs::read(faults_dir().join("faults.xml")).unwrap()
}

/// The faults FMU built with `flags`, as `<dir>/<name>.fmu`, plus `extra` entries.
fn faults_fmu(dir: &Path, name: &str, flags: &[&str], extra: &[ZipItem]) -> PathBuf {
    let binary = faults_binary(dir, name, flags);
    let xml = faults_xml();
    let path = dir.join(format!("{name}.fmu"));
    let mut items = vec![ZipItem::File("modelDescription.xml", &xml), ZipItem::File("binaries/linux64/faults.so", &binary)];
    for item in extra {
        items.push(match item {
            ZipItem::File(n, b) => ZipItem::File(n, b),
            ZipItem::Link(n, t) => ZipItem::Link(n, t),
        });
    }
    write_zip(&path, &items);
    path
}

/// What one `runner validate` run gave.
struct Validated {
    code: i32,
    stdout: String,
    stderr: String,
    findings: Vec<Value>,
}

impl Validated {
    /// The errors and warnings as (severity, interface, check, call, state, variable).
    fn troubles(&self) -> BTreeSet<(String, String, String, String, String, String)> {
        let text = |f: &Value, key: &str| f[key].as_str().unwrap_or("").to_owned();
        self.findings
            .iter()
            .filter(|f| matches!(f["severity"].as_str(), Some("error" | "warning")))
            .map(|f| (text(f, "severity"), text(f, "interface"), text(f, "check"), text(f, "call"), text(f, "state"), text(f, "variable")))
            .collect()
    }

    /// The first finding of `check` (and `interface`, when given) with `severity`.
    fn find(&self, severity: &str, check: &str, interface: Option<&str>) -> &Value {
        self.findings
            .iter()
            .find(|f| f["severity"] == severity && f["check"] == check && interface.is_none_or(|i| f["interface"] == i))
            .unwrap_or_else(|| panic!("no {severity} of {check} ({interface:?}); the report:\n{}", self.stdout))
    }

    fn has_passed(&self, check: &str, interface: &str) -> bool {
        self.findings.iter().any(|f| f["severity"] == "passed" && f["check"] == check && f["interface"] == interface)
    }
}

/// Runs `runner validate` with `args` and the JSON report in `dir`.
fn validate(dir: &Path, args: &[&str]) -> Validated {
    let report = dir.join("report.json");
    let _ = std::fs::remove_file(&report);
    let mut all: Vec<&str> = vec!["validate", "--report", report.to_str().unwrap()];
    all.extend(args);
    let o = runner(dir, &all);
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    let stderr = stderr(&o);
    assert!(!stderr.contains("panicked"), "the validator panicked: {stderr}");
    let findings = match std::fs::read_to_string(&report) {
        Ok(text) => {
            let json: Value = serde_json::from_str(&text).expect("the report is JSON");
            json["reports"].as_array().unwrap().iter().flat_map(|r| r["findings"].as_array().unwrap().clone()).collect()
        }
        Err(_) => Vec::new(),
    };
    Validated { code: o.status.code().unwrap_or(-1), stdout, stderr, findings }
}

/// The faults FMU without a fault passes every check of both interfaces: the validator asks
/// nothing of an FMU that the standard does not (and that a careful one cannot give), so any
/// error or warning here is the validator's bug.
#[test]
fn a_correct_third_party_fmu_is_clean() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "clean", &[], &[]);
    let junit = dir.path().join("junit.xml");
    let v = validate(dir.path(), &[fmu.to_str().unwrap(), "--junit", junit.to_str().unwrap()]);
    assert_eq!(v.code, 0, "{}\n{}", v.stdout, v.stderr);
    assert!(v.troubles().is_empty(), "{:#?}", v.troubles());
    assert!(v.stdout.contains("Result: 0 error(s), 0 warning(s)"), "{}", v.stdout);
    for interface in ["Co-Simulation", "Model Exchange"] {
        for check in [
            "lifecycle.guid",
            "lifecycle.run",
            "lifecycle.reset",
            "health.finite",
            "health.reproducible",
            "health.instance-name",
            "state-machine.legal",
            "state-machine.illegal",
            "arguments.zero-length",
            "arguments.null-arrays",
            "arguments.unknown-vr",
            "arguments.null-instance",
            "variables.string",
            "capability.fmu-state",
            "capability.serialize",
            "capability.threads",
        ] {
            assert!(v.has_passed(check, interface), "{check} did not pass for {interface}:\n{}", v.stdout);
        }
    }
    assert!(v.has_passed("capability.variable-step", "Co-Simulation"));
    // x = exp(-t) crosses the threshold 0.5 once, at t = ln 2; RK4 with h = 0.01 puts the
    // crossing within 1e-10 of it (the integration error; the bisection adds ulps).
    let events = v.find("passed", "model-exchange.state-events", Some("Model Exchange"));
    let message = events["message"].as_str().unwrap();
    assert!(message.starts_with("1 state event(s)"), "{message}");
    let t: f64 = message.split("at t = ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!((t - 2f64.ln()).abs() < 1e-10, "the event at t = {t}, not ln 2");
    let xml = std::fs::read_to_string(&junit).unwrap();
    assert!(
        xml.contains("failures=\"0\"") && xml.contains("<testcase classname=") && xml.contains("name=\"state-machine.illegal\""),
        "{xml}"
    );
}

/// Builds the faults FMU with `flag`, validates it with a half-second timeout, and returns
/// the result after checking that the run ended with exit code 1 (errors, not "could not run").
fn fault(flag: &str) -> Validated {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "faulty", &[&format!("-DFAULT_{flag}")], &[]);
    let v = validate(dir.path(), &[fmu.to_str().unwrap(), "--timeout", "0.5"]);
    assert_eq!(v.code, 1, "{flag}: exit code\n{}\n{}", v.stdout, v.stderr);
    v
}

#[test]
fn a_crash_in_an_early_call_is_a_finding() {
    let v = fault("CRASH_EARLY");
    let f = v.find("error", "lifecycle.guid", Some("Co-Simulation"));
    assert!(f["message"].as_str().unwrap().contains("crashed with SIGSEGV"), "{f}");
    assert_eq!(f["call"], "fmi2Instantiate");
    // Nothing builds on an FMU that cannot be instantiated.
    assert!(v.findings.iter().any(|f| f["check"] == "dynamic checks" && f["severity"] == "skipped"), "{}", v.stdout);
}

#[test]
fn a_hang_is_a_finding_after_the_timeout() {
    let v = fault("HANG");
    let f = v.find("error", "lifecycle.run", Some("Co-Simulation"));
    assert!(f["message"].as_str().unwrap().contains("fmi2DoStep did not return within 0.5 s"), "{f}");
    assert_eq!((f["call"].as_str(), f["state"].as_str()), (Some("fmi2DoStep"), Some("StepComplete")));
    assert!(f["value"].as_str().unwrap().contains("currentCommunicationPoint 0"), "{f}");
}

#[test]
fn a_missing_export_is_named() {
    let v = fault("NO_EXPORT");
    let f = v.find("error", "binary.exports", None);
    assert_eq!(f["call"], "fmi2GetRealStatus");
    assert!(f["message"].as_str().unwrap().contains("does not export fmi2GetRealStatus, which Co-Simulation requires"), "{f}");
    // The rest still runs: the missing function is one the runs do not need.
    assert!(v.has_passed("lifecycle.run", "Co-Simulation"));
}

#[test]
fn a_wrong_guid_is_caught_both_ways() {
    // The binary expects another GUID than its modelDescription.xml gives.
    let v = fault("WRONG_GUID");
    let f = v.find("error", "lifecycle.guid", Some("Co-Simulation"));
    assert!(f["message"].as_str().unwrap().contains("returned NULL with the FMU's own GUID"), "{f}");
    assert!(f["log"].as_str().unwrap().contains("does not fit this binary"), "the FMU's own reason is quoted: {f}");
    // The binary accepts any GUID.
    let v = fault("ANY_GUID");
    let f = v.find("error", "lifecycle.guid", Some("Model Exchange"));
    assert!(f["message"].as_str().unwrap().contains("accepted a wrong GUID"), "{f}");
    assert_eq!(f["value"], "{5a0b6c1e-2f47-4d8e-9b3a-71c2d4e6f800}", "the wrong GUID it was given: {f}");
}

#[test]
fn a_rollback_that_restores_nothing_is_caught() {
    let v = fault("ROLLBACK");
    for interface in ["Co-Simulation", "Model Exchange"] {
        let f = v.find("error", "capability.fmu-state", Some(interface));
        assert_eq!((f["call"].as_str(), f["variable"].as_str()), (Some("fmi2SetFMUstate"), Some("x")), "{f}");
        assert!(f["message"].as_str().unwrap().contains("did not restore the state saved at t = 1.5"), "{f}");
        v.find("error", "capability.serialize", Some(interface));
    }
}

#[test]
fn an_illegal_call_accepted_is_caught() {
    let v = fault("ILLEGAL");
    let f = v.find("error", "state-machine.illegal", Some("Co-Simulation"));
    assert_eq!(
        (f["call"].as_str(), f["state"].as_str(), f["variable"].as_str()),
        (Some("fmi2SetReal"), Some("StepComplete"), Some("k")),
        "{f}"
    );
    assert_eq!(f["value"], "2");
    assert!(f["message"].as_str().unwrap().contains("returned fmi2OK") && f["message"].as_str().unwrap().contains("changed der(x)"), "{f}");
    let f = v.find("error", "state-machine.illegal", Some("Model Exchange"));
    assert_eq!(f["state"], "EventMode");
}

#[test]
fn nan_outputs_are_caught() {
    let v = fault("NAN");
    let f = v.find("error", "health.finite", Some("Co-Simulation"));
    assert_eq!((f["variable"].as_str(), f["value"].as_str()), (Some("x"), Some("NaN")), "{f}");
    assert!(f["message"].as_str().unwrap().contains("output x is NaN at t = 1"), "{f}");
}

#[test]
fn an_event_iteration_that_never_ends_is_caught() {
    let v = fault("EVENT_LOOP");
    let f = v.find("error", "model-exchange.event-iteration", Some("Model Exchange"));
    assert!(f["message"].as_str().unwrap().contains("did not converge"), "{f}");
    assert_eq!(f["call"], "fmi2NewDiscreteStates");
    // Co-Simulation has no event iteration and is unaffected.
    assert!(v.has_passed("lifecycle.run", "Co-Simulation"));
}

#[test]
fn an_fmu_that_ends_the_process_is_a_finding() {
    let v = fault("EXIT");
    let f = v.find("error", "lifecycle.run", Some("Co-Simulation"));
    assert_eq!(f["call"], "fmi2Terminate");
    assert!(f["message"].as_str().unwrap().contains("ended the probe process (exit code 3) in fmi2Terminate"), "{f}");
}

/// An FMU that prints (even text that looks like the probe's own messages) to stdout and stderr
/// disturbs nothing: the probes talk to the validator on a descriptor of their own.
#[test]
fn an_fmu_that_prints_is_still_clean() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "noisy", &["-DNOISY"], &[]);
    let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
    assert_eq!(v.code, 0, "{}", v.stdout);
    assert!(v.troubles().is_empty(), "{:#?}", v.troubles());
    assert!(!v.stdout.contains("fmi2DoStep at t"), "the FMU's output stays out of the report");
}

/// An FMU that starts a process outliving each probe process (which keeps the probe's pipe
/// open) neither stalls the validation nor counts as a hang: each probe's process group ends
/// with it.
#[test]
fn an_fmu_that_leaves_a_process_behind_is_still_clean() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "forks", &["-DFORKS"], &[]);
    let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
    assert_eq!(v.code, 0, "{}", v.stdout);
    assert!(v.troubles().is_empty(), "{:#?}", v.troubles());
}

#[test]
fn a_state_event_the_fmu_cannot_handle_is_caught() {
    let v = fault("NO_EVENTS");
    let f = v.find("error", "model-exchange.state-events", Some("Model Exchange"));
    assert_eq!((f["call"].as_str(), f["state"].as_str()), (Some("fmi2EnterEventMode"), Some("ContinuousTimeMode")), "{f}");
    // The event the validator located: x = exp(-t) reaches the threshold 0.5 at t = ln 2.
    assert!(f["message"].as_str().unwrap().contains("at t = 0.69314718"), "{f}");
}

/// A description that is not XML: one error naming the problem, and nothing loaded.
#[test]
fn bad_xml_is_an_error_and_nothing_runs() {
    let dir = tempfile::tempdir().unwrap();
    let binary = faults_binary(dir.path(), "bad", &[]);
    let xml = String::from_utf8(faults_xml()).unwrap().replace("</ModelVariables>", "</ModelVariable>");
    let path = dir.path().join("bad.fmu");
    write_zip(&path, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/faults.so", &binary)]);
    let v = validate(dir.path(), &[path.to_str().unwrap()]);
    assert_eq!(v.code, 1, "{}", v.stdout);
    let f = v.find("error", "description.xml", None);
    assert!(f["message"].as_str().unwrap().contains("ModelVariable"), "the parser's message names the element: {f}");
    assert!(!v.findings.iter().any(|f| f["check"].as_str().unwrap().starts_with("lifecycle")), "nothing ran: {}", v.stdout);
}

/// The archive checks: an entry that escapes, a top-level entry outside the layout, a broken
/// documentation link, each named.
#[test]
fn archive_faults_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let page =
        b"<html><a href=\"derivation.html\">derivation</a> <a href=\"https://fmi-standard.org\">FMI</a> <img src=\"missing.png\"></html>";
    let fmu = faults_fmu(
        dir.path(),
        "docs",
        &[],
        &[
            ZipItem::File("documentation/index.html", page),
            ZipItem::File("documentation/derivation.html", b"<p>x</p>"),
            ZipItem::File("notes.txt", b"x"),
        ],
    );
    let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
    assert_eq!(v.code, 1, "{}", v.stdout);
    let f = v.find("error", "archive.documentation", None);
    assert!(f["message"].as_str().unwrap().contains("links to 'missing.png', but the archive has no documentation/missing.png"), "{f}");
    assert_eq!(v.find("warning", "archive.layout", None)["value"], "notes.txt");
    // The FMU itself is still validated and clean.
    assert!(v.has_passed("capability.threads", "Model Exchange"));
    let escape = faults_fmu(dir.path(), "escape", &[], &[ZipItem::File("resources/../../evil.txt", b"x")]);
    let v = validate(dir.path(), &[escape.to_str().unwrap()]);
    assert_eq!(v.code, 1);
    let f = v.find("error", "archive.paths", None);
    assert!(f["message"].as_str().unwrap().contains("'resources/../../evil.txt' has a '..' component"), "{f}");
    assert!(!dir.path().parent().unwrap().join("evil.txt").exists());
}

/// --strict makes warnings fail: a stray top-level file is a warning only.
#[test]
fn warnings_fail_only_with_strict() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "stray", &[], &[ZipItem::File("notes.txt", b"x")]);
    let f = fmu.to_str().unwrap();
    let v = validate(dir.path(), &[f]);
    assert_eq!(v.code, 0, "{}", v.stdout);
    assert_eq!(v.troubles().len(), 1);
    let junit = dir.path().join("j.xml");
    let v = validate(dir.path(), &[f, "--strict", "--junit", junit.to_str().unwrap()]);
    assert_eq!(v.code, 1, "{}", v.stdout);
    assert!(std::fs::read_to_string(&junit).unwrap().contains("<failure type=\"warning\""));
}

/// Exit code 2 when the validation could not run at all; 2 also wins over 1 across FMUs.
#[test]
fn exit_code_2_when_it_could_not_run() {
    let dir = tempfile::tempdir().unwrap();
    let v = validate(dir.path(), &["no_such.fmu"]);
    assert_eq!(v.code, 2);
    assert!(v.stderr.contains("no_such.fmu does not exist"), "{}", v.stderr);
    let broken = faults_fmu(dir.path(), "illegal", &["-DFAULT_ILLEGAL"], &[]);
    let v = validate(dir.path(), &[broken.to_str().unwrap(), "no_such.fmu"]);
    assert_eq!(v.code, 2, "one FMU could not be validated");
    assert!(v.stdout.contains("validated 1 of 2 FMU(s): 0 clean, 1 with errors"), "{}", v.stdout);
    let v = validate(dir.path(), &[broken.to_str().unwrap(), "--timeout", "-1"]);
    assert_eq!(v.code, 2);
    assert!(v.stderr.contains("the timeout must be a number of seconds above 0"), "{}", v.stderr);
}

/// The FMI 2.0 probes the FMI 3.0 set had first (NULL instance, NULL FMUstate pointer, NULL
/// String element, String copies) and the NULL value references: each fault injected into the
/// correct C FMU is reported by the probe meant for it, naming the function and the problem,
/// and by no other probe. A crash on a NULL argument is a warning (the importer's error, which
/// a robust FMU survives), and the arguments probe goes on after it; a String not copied is an
/// error.
#[test]
fn fmi2_the_null_argument_and_string_probes_name_each_fault() {
    let dir = tempfile::tempdir().unwrap();
    // (severity, check, call, state of Co-Simulation, of Model Exchange, variable, words).
    type Expected<'a> = (&'a str, &'a str, &'a str, &'a str, &'a str, &'a str, &'a str);
    let cases: [(&str, Expected); 6] = [
        (
            "NULL_COMPONENT",
            ("warning", "arguments.null-instance", "fmi2EnterInitializationMode", "StepComplete", "EventMode", "", "a NULL fmi2Component"),
        ),
        ("NULL_VR", ("warning", "arguments.null-arrays", "fmi2GetReal", "StepComplete", "EventMode", "", "vr NULL, nvr 1")),
        ("NULL_STATE", ("warning", "arguments.null-arrays", "fmi2GetFMUstate", "StepComplete", "EventMode", "", "a NULL FMUstate pointer")),
        // A Model Exchange getter: Co-Simulation is unaffected (state "" marks no trouble there).
        (
            "NULL_OUTPUT",
            ("warning", "arguments.null-arrays", "fmi2GetDerivatives", "", "ContinuousTimeMode", "", "a NULL array of 1 values"),
        ),
        (
            "STRING_NULL_ELEMENT",
            (
                "warning",
                "arguments.null-arrays",
                "fmi2SetString",
                "InitializationMode",
                "InitializationMode",
                "label",
                "a NULL element in the values array",
            ),
        ),
        (
            "STRING_COPY",
            (
                "error",
                "variables.string",
                "fmi2SetString",
                "InitializationMode",
                "InitializationMode",
                "label",
                "fmi2GetString returned the caller's own buffer",
            ),
        ),
    ];
    for (fault, (severity, check, call, cs_state, me_state, variable, words)) in cases {
        let fmu = faults_fmu(dir.path(), fault, &[&format!("-DFAULT_{fault}")], &[]);
        let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
        assert_eq!(v.code, if severity == "error" { 1 } else { 0 }, "{fault}: {}", v.stdout);
        let troubled: Vec<(&str, &str)> =
            [("Co-Simulation", cs_state), ("Model Exchange", me_state)].into_iter().filter(|(_, state)| !state.is_empty()).collect();
        let want: BTreeSet<_> = troubled
            .iter()
            .map(|(i, state)| {
                (severity.to_owned(), i.to_string(), check.to_owned(), call.to_owned(), state.to_string(), variable.to_owned())
            })
            .collect();
        assert_eq!(v.troubles(), want, "{fault}: {}", v.stdout);
        for (interface, _) in &troubled {
            let f = v.find(severity, check, Some(interface));
            let message = f["message"].as_str().unwrap();
            assert!(message.contains(call) && message.contains(words), "{fault}: {check} names {call} and says {words:?}: {f}");
            if severity == "warning" {
                assert!(message.contains("crashed with SIGSEGV"), "{fault}: {f}");
                // The arguments probe resumed after the crash: its other checks passed.
                assert!(v.has_passed("arguments.unknown-vr", interface), "{fault} {interface}: {}", v.stdout);
            }
        }
    }
    // --strict, as tests/run validates the project's own FMUs: a crash on a NULL argument fails.
    let v = validate(dir.path(), &[dir.path().join("NULL_COMPONENT.fmu").to_str().unwrap(), "--strict"]);
    assert_eq!(v.code, 1, "{}", v.stdout);
}

/// The Reference FMUs (FMI 2.0) are validated to the end, and their only errors and warnings
/// are the deviations from the standard the README lists and explains, one by one: each is
/// confirmed in their source code (sources/ in each FMU).
#[test]
fn the_reference_fmus_show_exactly_their_known_deviations() {
    let reference = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi2");
    assert!(reference.is_dir(), "the Reference FMUs are test data this test needs: {} is missing", reference.display());
    let dir = tempfile::tempdir().unwrap();
    let cs = "Co-Simulation";
    let me = "Model Exchange";
    let e = |i: &str, check: &str, call: &str, state: &str, variable: &str| {
        ("error".to_owned(), i.to_owned(), check.to_owned(), call.to_owned(), state.to_owned(), variable.to_owned())
    };
    let w = |i: &str, check: &str, call: &str, state: &str, variable: &str| {
        ("warning".to_owned(), i.to_owned(), check.to_owned(), call.to_owned(), state.to_owned(), variable.to_owned())
    };
    // Every Reference FMU: fmi2GetDerivatives and fmi2GetNominalsOfContinuousStates refused in
    // Initialization Mode (their state masks omit it); NULL arrays crash the Boolean getter and
    // setter (GET_BOOLEAN_VARIABLES and SET_BOOLEAN_VARIABLES lack the NULL checks the others
    // have); fmi2GetFMUstate(c, NULL) crashes (getFMUState in cosimulation.c reallocates
    // *FMUstate unchecked, as its FMI 3.0 counterpart does). A NULL is the importer's error, so
    // these crashes are warnings, as on the FMI 3.0 side. Every NULL fmi2Component is refused
    // (BEGIN_FUNCTION returns fmi2Error for it).
    let common = |booleans: &[&str]| {
        let mut all = BTreeSet::new();
        for (i, state) in [(cs, "StepComplete"), (me, "EventMode")] {
            all.insert(w(i, "arguments.null-arrays", "fmi2GetBoolean", state, ""));
            all.insert(w(i, "arguments.null-arrays", "fmi2SetBoolean", state, ""));
            all.insert(w(i, "arguments.null-arrays", "fmi2GetFMUstate", state, ""));
            for b in booleans {
                all.insert(w(i, "arguments.null-arrays", "fmi2GetBoolean", state, b));
                all.insert(w(i, "arguments.null-arrays", "fmi2SetBoolean", state, b));
            }
        }
        all.insert(e(me, "state-machine.legal", "fmi2GetDerivatives", "InitializationMode", ""));
        all.insert(e(me, "state-machine.legal", "fmi2GetNominalsOfContinuousStates", "InitializationMode", ""));
        all
    };
    // fmi2SetTime accepted in Event Mode by the FMUs with continuous states (condition 8 allows
    // it only without them).
    let set_time = e(me, "state-machine.illegal", "fmi2SetTime", "EventMode", "");
    let expected: Vec<(&str, BTreeSet<_>)> = vec![
        ("BouncingBall", {
            let mut s = common(&[]);
            s.insert(e(cs, "state-machine.illegal", "fmi2SetReal", "StepComplete", "g"));
            s.insert(e(me, "state-machine.illegal", "fmi2SetReal", "EventMode", "h"));
            s.insert(set_time.clone());
            s.insert(w("", "description.model-structure", "", "", "der(v)"));
            s
        }),
        ("Dahlquist", {
            let mut s = common(&[]);
            s.insert(e(cs, "state-machine.illegal", "fmi2SetReal", "StepComplete", "x"));
            s.insert(e(cs, "state-machine.illegal", "fmi2SetReal", "StepComplete", "k"));
            s.insert(e(me, "state-machine.illegal", "fmi2SetReal", "EventMode", "x"));
            s.insert(set_time.clone());
            s
        }),
        ("Feedthrough", {
            let mut s = common(&["Boolean_input"]);
            // setString in model.c takes strlen of each value unchecked: a NULL element crashes.
            for i in [cs, me] {
                s.insert(w(i, "arguments.null-arrays", "fmi2SetString", "InitializationMode", "String_input"));
            }
            for (i, states) in
                [(cs, ["Instantiated", "InitializationMode", "StepComplete"]), (me, ["Instantiated", "InitializationMode", "EventMode"])]
            {
                for state in states {
                    s.insert(e(i, "state-machine.illegal", "fmi2SetBoolean", state, "Boolean_output"));
                }
            }
            s.insert(e(cs, "state-machine.illegal", "fmi2SetReal", "StepComplete", "Float64_fixed_parameter"));
            s
        }),
        ("Resource", common(&[])),
        ("Stair", {
            let mut s = common(&[]);
            s.insert(e(cs, "lifecycle.reset", "fmi2Reset", "Terminated", ""));
            s
        }),
        ("VanDerPol", {
            let mut s = common(&[]);
            for (i, state) in [(cs, "StepComplete"), (me, "EventMode")] {
                s.insert(e(i, "state-machine.illegal", "fmi2SetReal", state, "x0"));
                s.insert(e(i, "state-machine.illegal", "fmi2SetReal", state, "mu"));
            }
            s.insert(set_time.clone());
            s
        }),
    ];
    for (name, expected) in expected {
        let path = reference.join(format!("{name}.fmu"));
        let v = validate(dir.path(), &[path.to_str().unwrap()]);
        assert_eq!(v.code, 1, "{name}: {}", v.stderr);
        let found = v.troubles();
        let unexpected: Vec<_> = found.difference(&expected).collect();
        let missing: Vec<_> = expected.difference(&found).collect();
        assert!(unexpected.is_empty() && missing.is_empty(), "{name}: unexpected {unexpected:#?}\nmissing {missing:#?}\n{}", v.stdout);
        // Validated to the end: both interfaces' last probe ran.
        for interface in [cs, me] {
            assert!(v.has_passed("capability.threads", interface), "{name} {interface}: {}", v.stdout);
            assert!(v.has_passed("arguments.null-instance", interface), "{name} {interface}: {}", v.stdout);
            // Feedthrough alone has String variables: String_input (start "Set me!") read, set
            // after initialization to a text of the validator's, which it copied.
            let strings = v.has_passed("variables.string", interface);
            assert_eq!(strings, name == "Feedthrough", "{name} {interface} variables.string: {}", v.stdout);
        }
    }
}

/// The FMI 3.0 test FMU (tests/c_fmu/fmi3_faults.c) built with `flags`, as `<dir>/<name>.fmu`.
fn fmi3_fmu(dir: &Path, name: &str, flags: &[&str]) -> PathBuf {
    let so = dir.join(format!("{name}.so"));
    let status = Command::new("cc")
        .args(["-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-Wall", "-o"])
        .arg(&so)
        .arg(faults_dir().join("fmi3_faults.c"))
        .args(flags)
        .arg("-lm")
        .status()
        .expect("the C compiler `cc` runs");
    assert!(status.success(), "cc failed on fmi3_faults.c with {flags:?}");
    let (binary, xml) = (std::fs::read(&so).unwrap(), std::fs::read(faults_dir().join("fmi3_faults.xml")).unwrap());
    let path = dir.join(format!("{name}.fmu"));
    write_zip(&path, &[ZipItem::File("modelDescription.xml", &xml), ZipItem::File("binaries/x86_64-linux/fmi3_faults.so", &binary)]);
    path
}

/// A careful FMI 3.0 FMU (every call checked against the standard's state machine) passes
/// every FMI 3.0 check of both interfaces; each fault injected into it is named, and only it.
/// A validator that flagged everything, or nothing, fails here.
#[test]
fn fmi3_a_correct_fmu_is_clean_and_each_fault_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let clean = fmi3_fmu(dir.path(), "clean", &[]);
    let v = validate(dir.path(), &[clean.to_str().unwrap()]);
    assert_eq!((v.code, v.troubles().len()), (0, 0), "{}", v.stdout);
    for (check, interface) in
        [("lifecycle.run", "Model Exchange"), ("state-machine.illegal", "Co-Simulation"), ("lifecycle.reset", "Model Exchange")]
    {
        assert!(v.has_passed(check, interface), "{check} {interface}: {}", v.stdout);
    }
    // The same Model Exchange integration as FMI 2.0's: x = exp(-t) crosses the threshold 0.5
    // once, at t = ln 2, and the bisection locates it within the RK4 error of h = 0.01 (below
    // 1e-10), not at the end of the step it happens in.
    let events = v.find("passed", "model-exchange.state-events", Some("Model Exchange"));
    let message = events["message"].as_str().unwrap();
    let t: f64 = message.split("at t = ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!(message.starts_with("1 state event(s)") && (t - 2f64.ln()).abs() < 1e-10, "the event at t = {t}, not ln 2: {message}");
    // It declares FMU state and serialization, has a String parameter and may be instantiated
    // many times: the capability probes run, and pass, on both interfaces.
    for interface in ["Co-Simulation", "Model Exchange"] {
        for check in [
            "capability.fmu-state",
            "capability.serialize",
            "arguments.null-instance",
            "arguments.null-arrays",
            "capability.threads",
            "variables.string",
        ] {
            assert!(v.has_passed(check, interface), "{check} {interface}: {}", v.stdout);
        }
    }
    // (interface, check, call, state, variable) of each expected error.
    type Expected<'a> = &'a [(&'a str, &'a str, &'a str, &'a str, &'a str)];
    let cases: [(&str, Expected); 6] = [
        ("NO_EXPORT", &[("", "binary.exports", "fmi3GetClock", "", "")]),
        (
            "SET_FIXED",
            &[
                ("Co-Simulation", "state-machine.illegal", "fmi3SetFloat64", "StepMode", "k"),
                ("Model Exchange", "state-machine.illegal", "fmi3SetFloat64", "EventMode", "k"),
                ("Model Exchange", "state-machine.illegal", "fmi3SetFloat64", "ContinuousTimeMode", "k"),
            ],
        ),
        // The second run differs: fmi3Reset named, in Terminated, with the variable that differs.
        (
            "RESET",
            &[
                ("Co-Simulation", "lifecycle.reset", "fmi3Reset", "Terminated", "crossings"),
                ("Model Exchange", "lifecycle.reset", "fmi3Reset", "Terminated", "crossings"),
            ],
        ),
        // NaN outputs and derivatives: the checks of finite values FMI 2.0 has too, and the
        // varying steps meet the NaN as well.
        (
            "NAN",
            &[
                ("Co-Simulation", "health.finite", "fmi3GetFloat64", "StepMode", "x"),
                ("Co-Simulation", "capability.variable-step", "", "", "x"),
                ("Model Exchange", "model-exchange.derivatives", "fmi3GetContinuousStateDerivatives", "ContinuousTimeMode", ""),
            ],
        ),
        ("SIZES", &[("Model Exchange", "lifecycle.run", "fmi3GetNumberOfContinuousStates", "EventMode", "")]),
        (
            "ILLEGAL",
            &[
                ("Co-Simulation", "state-machine.illegal", "fmi3UpdateDiscreteStates", "Instantiated", ""),
                ("Co-Simulation", "state-machine.illegal", "fmi3UpdateDiscreteStates", "InitializationMode", ""),
                ("Co-Simulation", "state-machine.illegal", "fmi3UpdateDiscreteStates", "StepMode", ""),
                ("Co-Simulation", "state-machine.illegal", "fmi3UpdateDiscreteStates", "Terminated", ""),
                ("Model Exchange", "state-machine.illegal", "fmi3UpdateDiscreteStates", "Instantiated", ""),
                ("Model Exchange", "state-machine.illegal", "fmi3UpdateDiscreteStates", "InitializationMode", ""),
                ("Model Exchange", "state-machine.illegal", "fmi3UpdateDiscreteStates", "ContinuousTimeMode", ""),
                ("Model Exchange", "state-machine.illegal", "fmi3UpdateDiscreteStates", "Terminated", ""),
            ],
        ),
    ];
    for (fault, expected) in cases {
        let fmu = fmi3_fmu(dir.path(), fault, &[&format!("-DFAULT_{fault}")]);
        let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
        assert_eq!(v.code, 1, "{fault}: {}", v.stdout);
        let expected: BTreeSet<_> = expected
            .iter()
            .map(|(i, c, call, s, var)| {
                ("error".to_owned(), i.to_string(), c.to_string(), call.to_string(), s.to_string(), var.to_string())
            })
            .collect();
        assert_eq!(v.troubles(), expected, "{fault}: {}", v.stdout);
    }
    let v = validate(dir.path(), &[dir.path().join("RESET.fmu").to_str().unwrap()]);
    let f = v.find("error", "lifecycle.reset", Some("Model Exchange"));
    assert!(f["message"].as_str().unwrap().contains("crossings at t = "), "the variable that differs is named: {f}");
}

/// The FMI 3.0 probes of FMU state, NULL arguments and String variables (which the correct C
/// FMU passes: see the test above): each fault injected into it is reported by the probe meant
/// for it, naming the function and the problem, and by no other probe. A probe that passed
/// everything, or failed everything, fails here.
#[test]
fn fmi3_the_capability_probes_name_each_fault() {
    let dir = tempfile::tempdir().unwrap();
    // (severity, interface, check, call, state, variable, words of the message) of each trouble.
    type Expected<'a> = &'a [(&'a str, &'a str, &'a str, &'a str, &'a str, &'a str, &'a str)];
    let cases: [(&str, Expected); 3] = [
        (
            // The restore brings back the start values: the outputs right after fmi3SetFMUState
            // are not those of the state saved (in the state the run was saved in).
            "STATE",
            &[
                (
                    "error",
                    "Co-Simulation",
                    "capability.fmu-state",
                    "fmi3SetFMUState",
                    "StepMode",
                    "x",
                    "did not restore the state saved at t = 1",
                ),
                (
                    "error",
                    "Co-Simulation",
                    "capability.serialize",
                    "fmi3SetFMUState",
                    "StepMode",
                    "x",
                    "did not restore the state saved at t = 1",
                ),
                (
                    "error",
                    "Model Exchange",
                    "capability.fmu-state",
                    "fmi3SetFMUState",
                    "ContinuousTimeMode",
                    "x",
                    "did not restore the state saved at t = 1",
                ),
                (
                    "error",
                    "Model Exchange",
                    "capability.serialize",
                    "fmi3SetFMUState",
                    "ContinuousTimeMode",
                    "x",
                    "did not restore the state saved at t = 1",
                ),
            ],
        ),
        (
            // fmi3GetFloat64 dereferences its NULL arrays: a crash in the call, a warning (NULL
            // arrays are the importer's error; a robust FMU refuses them), and the probe goes on.
            "NULL_VR",
            &[
                ("warning", "Co-Simulation", "arguments.null-arrays", "fmi3GetFloat64", "StepMode", "", "crashed"),
                ("warning", "Co-Simulation", "arguments.null-arrays", "fmi3GetFloat64", "StepMode", "time", "crashed"),
                ("warning", "Model Exchange", "arguments.null-arrays", "fmi3GetFloat64", "EventMode", "", "crashed"),
                ("warning", "Model Exchange", "arguments.null-arrays", "fmi3GetFloat64", "EventMode", "time", "crashed"),
            ],
        ),
        (
            // fmi3GetString says fmi3OK but hands out NULL: found at the first read, after
            // initialization.
            "STRING_NULL",
            &[
                ("error", "Co-Simulation", "variables.string", "fmi3GetString", "StepMode", "label", "NULL pointer"),
                ("error", "Model Exchange", "variables.string", "fmi3GetString", "EventMode", "label", "NULL pointer"),
            ],
        ),
    ];
    for (fault, expected) in cases {
        let fmu = fmi3_fmu(dir.path(), fault, &[&format!("-DFAULT_{fault}")]);
        let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
        let want: BTreeSet<_> = expected
            .iter()
            .map(|(sev, i, c, call, s, var, _)| {
                (sev.to_string(), i.to_string(), c.to_string(), call.to_string(), s.to_string(), var.to_string())
            })
            .collect();
        assert_eq!(v.troubles(), want, "{fault}: {}", v.stdout);
        for (severity, interface, check, call, .., words) in expected.iter() {
            let f = v.find(severity, check, Some(interface));
            let message = f["message"].as_str().unwrap();
            assert!(message.contains(words) && message.contains(call), "{fault}: {check} names {call} and says {words:?}: {f}");
        }
        // After the crash the rest of the arguments probe ran: the NULL instance cells passed.
        if fault == "NULL_VR" {
            assert!(v.has_passed("arguments.null-instance", "Model Exchange"), "{}", v.stdout);
        }
    }
}

/// The FMI 3.0 Reference FMUs are validated to the end, and their only errors are the
/// deviations from FMI 3.0.2 the README lists and explains (each confirmed in the sources they
/// ship: the state masks of fmi3Functions.c, setFloat64 in model.c).
#[test]
fn fmi3_the_reference_fmus_show_exactly_their_known_deviations() {
    let reference = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi3");
    assert!(reference.is_dir(), "the Reference FMUs are test data this test needs: {} is missing", reference.display());
    let dir = tempfile::tempdir().unwrap();
    type Trouble = (String, String, String, String, String, String);
    let error = |interface: &str, call: &str, state: &str, variable: &str| -> Trouble {
        ("error".into(), interface.into(), "state-machine.illegal".into(), call.into(), state.into(), variable.into())
    };
    // Every one of them: fmi3UpdateDiscreteStates in any state (MASK_fmi3NewDiscreteStates is
    // MASK_AnyState), fmi3EnterStepMode in Initialization Mode and, by Model Exchange
    // instances, in Event Mode (its mask ignores the interface), fmi3SetTime in Event Mode
    // (MASK_fmi3SetTime), the Model Exchange evaluations by Co-Simulation instances.
    let mut common: BTreeSet<Trouble> = BTreeSet::new();
    for state in ["Instantiated", "InitializationMode", "StepMode", "Terminated"] {
        common.insert(error("Co-Simulation", "fmi3UpdateDiscreteStates", state, ""));
    }
    for state in ["Instantiated", "InitializationMode", "ContinuousTimeMode", "Terminated"] {
        common.insert(error("Model Exchange", "fmi3UpdateDiscreteStates", state, ""));
    }
    for (interface, call, state) in [
        ("Co-Simulation", "fmi3EnterStepMode", "InitializationMode"),
        ("Co-Simulation", "fmi3GetContinuousStateDerivatives", "InitializationMode"),
        ("Co-Simulation", "fmi3GetContinuousStateDerivatives", "Terminated"),
        ("Model Exchange", "fmi3EnterStepMode", "InitializationMode"),
        ("Model Exchange", "fmi3EnterStepMode", "EventMode"),
        ("Model Exchange", "fmi3SetTime", "EventMode"),
    ] {
        common.insert(error(interface, call, state, ""));
    }
    // The arguments probe's warnings, every one of them: fmi3GetFMUState(instance, NULL),
    // fmi3GetNumberOfContinuousStates(instance, NULL) and fmi3GetNumberOfEventIndicators(instance,
    // NULL) crash (fmi3Functions.c passes the pointer on without the NULL check its other
    // functions make: getFMUState in cosimulation.c reallocates *FMUState, the size queries
    // write *nContinuousStates and *nEventIndicators). NULL is the importer's error, so these
    // are warnings; every NULL value array or value reference array, and every NULL instance,
    // is refused as it should be.
    let null_crash = |interface: &str, call: &str, state: &str| -> Trouble {
        ("warning".into(), interface.into(), "arguments.null-arrays".into(), call.into(), state.into(), String::new())
    };
    common.insert(null_crash("Model Exchange", "fmi3GetFMUState", "EventMode"));
    common.insert(null_crash("Model Exchange", "fmi3GetNumberOfContinuousStates", "ContinuousTimeMode"));
    common.insert(null_crash("Model Exchange", "fmi3GetNumberOfEventIndicators", "ContinuousTimeMode"));
    // With Event Mode (hasEventMode): the Model Exchange calls in a Co-Simulation Event Mode
    // (where the arguments probe calls, after initialization).
    let event_mode = [
        error("Co-Simulation", "fmi3EnterContinuousTimeMode", "EventMode", ""),
        error("Co-Simulation", "fmi3GetContinuousStateDerivatives", "EventMode", ""),
        error("Co-Simulation", "fmi3SetTime", "EventMode", ""),
        null_crash("Co-Simulation", "fmi3GetFMUState", "EventMode"),
    ];
    // Without it: fmi3EnterEventMode in Step Mode of an instance made with eventModeUsed false.
    let no_event_mode =
        [error("Co-Simulation", "fmi3EnterEventMode", "StepMode", ""), null_crash("Co-Simulation", "fmi3GetFMUState", "StepMode")];
    // A fixed parameter set after initialization: setFloat64 checks the state only for Model
    // Exchange (VanDerPol's mu: and lets Event Mode through).
    let fixed = |name: &str, states: &[&str]| states.iter().map(|s| error("Co-Simulation", "fmi3SetFloat64", s, name)).collect::<Vec<_>>();
    let expected: Vec<(&str, Vec<Trouble>)> = vec![
        ("BouncingBall", [event_mode.to_vec(), fixed("g", &["EventMode", "StepMode", "Terminated"])].concat()),
        ("Dahlquist", [no_event_mode.to_vec(), fixed("k", &["StepMode", "Terminated"])].concat()),
        (
            "Feedthrough",
            [
                event_mode.to_vec(),
                fixed("Float64_fixed_parameter", &["EventMode", "StepMode", "Terminated"]),
                // setString in model.c takes strlen of each value unchecked, as in its FMI 2.0
                // build: a NULL element crashes.
                ["Co-Simulation", "Model Exchange"]
                    .map(|i| {
                        let null = null_crash(i, "fmi3SetString", "InitializationMode");
                        (null.0, null.1, null.2, null.3, null.4, "String_input".to_owned())
                    })
                    .to_vec(),
            ]
            .concat(),
        ),
        ("Resource", no_event_mode.to_vec()),
        ("Stair", event_mode.to_vec()),
        ("StateSpace", event_mode.to_vec()),
        (
            "VanDerPol",
            [
                no_event_mode.to_vec(),
                fixed("mu", &["StepMode", "Terminated"]),
                vec![error("Model Exchange", "fmi3SetFloat64", "EventMode", "mu")],
            ]
            .concat(),
        ),
    ];
    for (name, own) in expected {
        let fmu = reference.join(format!("{name}.fmu"));
        let v = validate(dir.path(), &[fmu.to_str().unwrap()]);
        assert_eq!(v.code, 1, "{name}: {}", v.stdout);
        let want: BTreeSet<Trouble> = common.iter().cloned().chain(own).collect();
        assert_eq!(v.troubles(), want, "{name}: {}", v.stdout);
        // All of them declare canGetAndSetFMUState and canSerializeFMUState, and may be
        // instantiated many times: their FMU state round trips continue bit for bit (as fmpy
        // finds too: tests/fmpy/test_fmi3_fmu_state.py), their instances run alike on threads.
        for interface in ["Co-Simulation", "Model Exchange"] {
            for check in [
                "lifecycle.run",
                "lifecycle.reset",
                "state-machine.legal",
                "capability.fmu-state",
                "capability.serialize",
                "capability.threads",
                "arguments.null-instance",
            ] {
                assert!(v.has_passed(check, interface), "{name} {interface} {check}: {}", v.stdout);
            }
            // Feedthrough alone has String variables (a parameter and an input): read with their
            // start values, and the input set and read back.
            let strings = v.has_passed("variables.string", interface);
            assert_eq!(strings, name == "Feedthrough", "{name} {interface} variables.string: {}", v.stdout);
        }
    }
    // Clocks offers Scheduled Execution only: nothing to probe, and that is said.
    let v = validate(dir.path(), &[reference.join("Clocks.fmu").to_str().unwrap()]);
    assert_eq!((v.code, v.troubles().len()), (0, 0), "{}", v.stdout);
    assert!(v.stdout.contains("Scheduled Execution is declared but not probed"), "{}", v.stdout);
    // Roberts lists its extra/ entries twice with the same bytes: unpacked once, and a warning.
    let v = validate(dir.path(), &[reference.join("Roberts.fmu").to_str().unwrap()]);
    let warning = v.find("warning", "archive.zip", None)["message"].as_str().unwrap().to_owned();
    assert!(
        warning.contains("more than once with the same bytes") && warning.contains("extra/org.fmi-standard.fmi-ls-ref/Roberts_out.csv"),
        "{warning}"
    );
}

/// The shipped LS-REF result of the Reference FMU BouncingBall (FMI 3.0), as a file.
fn bouncing_ball_reference() -> (PathBuf, String) {
    let fmu = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi3/BouncingBall.fmu");
    let mut zip = zip::ZipArchive::new(std::fs::File::open(&fmu).unwrap()).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(&mut zip.by_name("extra/org.fmi-standard.fmi-ls-ref/BouncingBall_out.csv").unwrap(), &mut text).unwrap();
    (fmu, text)
}

/// `runner validate --reference-file` checks a run of the FMU (as `runner simulate` makes it)
/// against the file, as one more check of the report: BouncingBall passes its own shipped
/// result in the default tube (the same run `runner simulate --reference-file` passes,
/// tests/parity.rs), and fails it broken on purpose at one sample (h at t = 1 s, row 101,
/// raised by 1 cm: 10 times the default bound there, 1e-3·(|h| + max|h|) ≈ 1e-3 m), as an error
/// naming the column, time, values and bound in the text, JSON and JUnit reports.
#[test]
fn validate_checks_a_reference_file() {
    let dir = tempfile::tempdir().unwrap();
    let (fmu, text) = bouncing_ball_reference();
    std::fs::write(dir.path().join("good.csv"), &text).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    let cells: Vec<String> = lines[101].split(',').map(str::to_owned).collect();
    assert_eq!(cells[0], "1", "row 101 is t = 1 s");
    let h: f64 = cells[1].parse().unwrap();
    lines[101] = format!("1,{},{}", h + 0.01, cells[2]);
    std::fs::write(dir.path().join("broken.csv"), lines.join("\n")).unwrap();

    let v = validate(dir.path(), &[fmu.to_str().unwrap(), "--reference-file", "good.csv"]);
    let passed = v.find("passed", "reference-result", None);
    assert!(passed["message"].as_str().unwrap().starts_with("the run matches h, v at the 301 times of good.csv within"), "{}", v.stdout);
    assert!(v.stdout.contains("[reference-result] the run matches h, v at the 301 times of good.csv"), "{}", v.stdout);

    let junit = dir.path().join("junit.xml");
    let v = validate(dir.path(), &[fmu.to_str().unwrap(), "--reference-file", "broken.csv", "--junit", junit.to_str().unwrap()]);
    assert_eq!(v.code, 1, "an error: {}", v.stdout);
    let named = format!("broken.csv: h at t = 1 s (row 101 of the reference): the run has {h}, the reference {}", h + 0.01);
    let error = v.find("error", "reference-result", None);
    assert!(error["message"].as_str().unwrap().contains(&named), "{error}");
    assert_eq!(error["variable"], "h");
    assert!(error["value"].as_str().unwrap().starts_with(&format!("{h} at t = 1 s (reference {}, bound ", h + 0.01)), "{error}");
    assert!(v.stdout.contains(&named), "{}", v.stdout);
    let junit = std::fs::read_to_string(&junit).unwrap();
    let case = junit.split("<testcase").find(|c| c.contains("name=\"reference-result\"")).expect("a test case of the check");
    assert!(case.contains("<failure type=\"error\"") && case.contains(&named), "{case}");

    // --rtol and --atol belong to a reference; a missing file is named before any validation.
    let o = runner(dir.path(), &["validate", fmu.to_str().unwrap(), "--rtol", "1e-3"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("give it too"), "{}", stderr(&o));
    let o = runner(dir.path(), &["validate", fmu.to_str().unwrap(), "--reference-file", "missing.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read missing.csv"), "{}", stderr(&o));
}

/// Without --reference-file, an FMU's shipped LS-REF result is checked, a failure being a
/// warning (see `reference_finding` in commands/validate.rs): BouncingBall passes its own;
/// Roberts's manifest names BouncingBall's file, which Roberts does not hold, and the report
/// says so in a warning (not a crash, not an error); Clocks ships none and gets no such check.
#[test]
fn validate_checks_the_shipped_reference_result() {
    let dir = tempfile::tempdir().unwrap();
    let fmi3 = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi3");
    let v = validate(dir.path(), &[fmi3.join("BouncingBall.fmu").to_str().unwrap()]);
    let passed = v.find("passed", "reference-result", None);
    assert!(
        passed["message"].as_str().unwrap().contains("h, v at the 301 times of extra/org.fmi-standard.fmi-ls-ref/BouncingBall_out.csv"),
        "{passed}"
    );
    let v = validate(dir.path(), &[fmi3.join("Roberts.fmu").to_str().unwrap()]);
    let warning = v.find("warning", "reference-result", None);
    assert!(
        warning["message"].as_str().unwrap().contains(
            "names 'BouncingBall_out.csv' as its result, but the FMU has no extra/org.fmi-standard.fmi-ls-ref/BouncingBall_out.csv"
        ),
        "{warning}"
    );
    let v = validate(dir.path(), &[fmi3.join("Clocks.fmu").to_str().unwrap()]);
    assert!(v.findings.iter().all(|f| f["check"] != "reference-result"), "{}", v.stdout);
}

/// The reference check's run has no time limit of its own, so it is made only after the
/// validator's own runs through the DefaultExperiment went through: an FMU that hangs in
/// fmi2DoStep is reported by lifecycle.run (within --timeout) and its reference check is
/// skipped, not hung on.
#[test]
fn the_reference_check_is_skipped_after_a_failed_run() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faults_fmu(dir.path(), "hang", &["-DFAULT_HANG"], &[]);
    std::fs::write(dir.path().join("ref.csv"), "time,x\n0,1\n").unwrap();
    let v = validate(dir.path(), &[fmu.to_str().unwrap(), "--timeout", "0.5", "--reference-file", "ref.csv"]);
    assert_eq!(v.code, 1, "{}", v.stdout);
    v.find("error", "lifecycle.run", Some("Co-Simulation"));
    let skipped = v.find("skipped", "reference-result", None);
    assert!(skipped["message"].as_str().unwrap().contains("lifecycle.run"), "{skipped}");
}
