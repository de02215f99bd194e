//! `--log-fmi-calls [FILE]`: every FMI call with its arguments, status and duration, one line
//! per call, written as the calls happen. Checked on this project's FMU through FMI 2.0 and 3.0
//! and on the FMI 1.0 C test FMU, both interfaces, in a worker and in-process; on a Reference
//! FMU against the
//! calls fmpy makes on the same run; on a C FMU that crashes in fmi2DoStep, whose log must end
//! with that call; and for a file that cannot be written.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::*;

/// second_order built for FMI 2.0 and 3.0, once per test binary (concurrent builds would race
/// on the .fmu files).
fn second_order() -> &'static (PathBuf, PathBuf) {
    static BUILT: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    BUILT.get_or_init(|| {
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let out = ok(runner(here, &["build", "second_order"]));
        let paths: Vec<PathBuf> = out.lines().map(PathBuf::from).collect();
        assert_eq!(paths.len(), 2, "runner build prints the FMI 2.0 and the FMI 3.0 FMU: {out}");
        assert!(paths[1].ends_with("fmu3/second_order.fmu"), "{out}");
        (paths[0].clone(), paths[1].clone())
    })
}

fn reference_fmu(version: &str, model: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../../shared/reference-fmus/{version}/{model}.fmu"))
}

/// One line of the log: a call with its arguments, and (unless the call never returned) its
/// status, what it gave back and its duration.
#[derive(Debug)]
struct Call {
    name: String,
    arguments: String,
    status: Option<String>,
    results: String,
}

impl Call {
    /// The value of argument `name=` as written.
    fn argument(&self, name: &str) -> Option<&str> {
        let start = self.arguments.split(", ").find_map(|a| a.strip_prefix(&format!("{name}=")))?;
        Some(start)
    }
}

/// The calls of a log, in order; FMU messages (lines starting with `[`) are skipped. Every
/// finished line must end with a duration in microseconds; only the last may be unfinished.
fn parse(log: &str) -> Vec<Call> {
    let lines: Vec<&str> = log.lines().filter(|l| !l.starts_with('[')).collect();
    let mut calls = Vec::new();
    for (k, line) in lines.iter().enumerate() {
        let open = line.find('(').unwrap_or_else(|| panic!("no argument list in {line:?}"));
        let name = line[..open].to_owned();
        // FMI 1.0 names its functions fmiDoStep, ...; later versions fmi2DoStep, fmi3DoStep.
        let fmi1 = name.strip_prefix("fmi").is_some_and(|rest| rest.starts_with(|c: char| c.is_ascii_uppercase()));
        assert!(fmi1 || name.starts_with("fmi2") || name.starts_with("fmi3"), "{line:?} names no FMI function");
        let Some(arrow) = line.rfind(") -> ") else {
            assert_eq!(k + 1, lines.len(), "only the last line may lack its status: {line:?}");
            let arguments = line[open + 1..].strip_suffix(')').unwrap_or_else(|| panic!("{line:?}")).to_owned();
            calls.push(Call { name, arguments, status: None, results: String::new() });
            continue;
        };
        let rest = &line[arrow + 5..];
        let (returned, duration) = rest.rsplit_once(" [").unwrap_or_else(|| panic!("no duration in {line:?}"));
        let us: f64 = duration.strip_suffix(" us]").and_then(|d| d.parse().ok()).unwrap_or_else(|| panic!("bad duration in {line:?}"));
        assert!(us >= 0.0, "{line:?}");
        let (status, results) = returned.split_once(' ').unwrap_or((returned, ""));
        calls.push(Call {
            name,
            arguments: line[open + 1..arrow].to_owned(),
            status: Some(status.to_owned()),
            results: results.to_owned(),
        });
    }
    calls
}

/// The names of the calls that make an instance's life, in order (what both importers make the
/// same way; the reads and writes between them differ).
fn lifecycle(calls: &[Call]) -> Vec<&str> {
    const LIFE: [&str; 11] = [
        "Instantiate",
        "InstantiateCoSimulation",
        "InstantiateModelExchange",
        "SetupExperiment",
        "EnterInitializationMode",
        "ExitInitializationMode",
        "DoStep",
        "Terminate",
        "FreeInstance",
        "EnterContinuousTimeMode",
        "EnterStepMode",
    ];
    calls.iter().map(|c| c.name.as_str()).filter(|n| LIFE.contains(&&n[4..])).collect()
}

/// Runs simulate with the call log in `calls.txt`; the log.
fn logged_run(dir: &Path, fmu: &Path, extra: &[&str]) -> String {
    let mut args = vec!["simulate", fmu.to_str().unwrap(), "--out", "x.csv", "--log-fmi-calls", "calls.txt"];
    args.extend_from_slice(extra);
    ok(runner(dir, &args));
    std::fs::read_to_string(dir.join("calls.txt")).unwrap()
}

/// The step calls of a Co-Simulation log as (currentCommunicationPoint, communicationStepSize).
fn steps(calls: &[Call], name: &str) -> Vec<(f64, f64)> {
    let number = |c: &Call, a: &str| -> f64 { c.argument(a).unwrap_or_else(|| panic!("{c:?} has no {a}")).parse().unwrap() };
    calls.iter().filter(|c| c.name == name).map(|c| (number(c, "currentCommunicationPoint"), number(c, "communicationStepSize"))).collect()
}

/// Through both versions and interfaces, in a worker and in this process: the log holds the
/// instance's life in the order the standard prescribes, each call OK; Co-Simulation steps
/// from each communication point (0, 0.05, ..., 0.15) to the next, both at most 1e-15 off
/// (the runner computes the points as start + k h and steps by their differences), and Model Exchange evaluates the derivatives. The
/// outputs each step reads are the CSV's values: the log shows what the FMU returned.
#[test]
fn our_fmu_in_both_versions_and_interfaces() {
    let (fmi2, fmi3) = second_order();
    let dir = tempfile::tempdir().unwrap();
    let grid = ["--stop-time", "0.2", "--output-interval", "0.05"];
    for (fmu, v) in [(fmi2, "fmi2"), (fmi3, "fmi3")] {
        for interface in ["co-simulation", "model-exchange"] {
            for mode in [&[][..], &["--in-process"][..]] {
                let what = format!("{v} {interface} {mode:?}");
                let log = logged_run(dir.path(), fmu, &[&grid[..], &["--interface", interface], mode].concat());
                let calls = parse(&log);
                for c in &calls {
                    let ok = format!("{v}OK");
                    // An instantiation returns the instance's address, fmi2FreeInstance nothing.
                    let fine = matches!(c.status.as_deref(), Some(s) if s == ok || s.starts_with("0x") || s == "(void)");
                    assert!(fine, "{what}: {c:?} did not return {ok}:\n{log}");
                }
                let life = lifecycle(&calls);
                let expected: Vec<String> = match (v, interface) {
                    ("fmi2", "co-simulation") => {
                        let mut e = vec!["Instantiate", "SetupExperiment", "EnterInitializationMode", "ExitInitializationMode"];
                        e.extend(["DoStep"; 4]);
                        e.extend(["Terminate", "FreeInstance"]);
                        e.iter().map(|n| format!("fmi2{n}")).collect()
                    }
                    ("fmi3", "co-simulation") => {
                        // The FMU has Event Mode: the runner enters Step Mode after initialization.
                        let mut e = vec!["InstantiateCoSimulation", "EnterInitializationMode", "ExitInitializationMode", "EnterStepMode"];
                        e.extend(["DoStep"; 4]);
                        e.extend(["Terminate", "FreeInstance"]);
                        e.iter().map(|n| format!("fmi3{n}")).collect()
                    }
                    ("fmi2", _) => ["Instantiate", "SetupExperiment", "EnterInitializationMode", "ExitInitializationMode"]
                        .iter()
                        .chain(&["EnterContinuousTimeMode", "Terminate", "FreeInstance"])
                        .map(|n| format!("fmi2{n}"))
                        .collect(),
                    _ => ["InstantiateModelExchange", "EnterInitializationMode", "ExitInitializationMode"]
                        .iter()
                        .chain(&["EnterContinuousTimeMode", "Terminate", "FreeInstance"])
                        .map(|n| format!("fmi3{n}"))
                        .collect(),
                };
                assert_eq!(life, expected, "{what}:\n{log}");
                if interface == "co-simulation" {
                    let steps = steps(&calls, &format!("{v}DoStep"));
                    for (k, (t, h)) in steps.iter().enumerate() {
                        assert!(
                            (t - 0.05 * k as f64).abs() <= 1e-15 && (h - 0.05).abs() <= 1e-15,
                            "{what}: step {k} is ({t}, {h}):\n{log}"
                        );
                    }
                } else {
                    let derivatives = if v == "fmi2" { "fmi2GetDerivatives" } else { "fmi3GetContinuousStateDerivatives" };
                    let evaluations = calls.iter().filter(|c| c.name == derivatives).count();
                    assert!(evaluations >= 4, "{what}: {evaluations} {derivatives} calls for 4 steps:\n{log}");
                    assert!(calls.iter().any(|c| c.name == derivatives && c.results.starts_with("derivatives=[")), "{what}:\n{log}");
                }
                // The last row of the CSV is what the last read before fmi2Terminate returned.
                let (header, rows) = read_csv(&dir.path().join("x.csv"));
                let q = column(&header, &rows, "q");
                let last_read = calls
                    .iter()
                    .rev()
                    .find(|c| c.name == format!("{v}GetReal") || c.name == "fmi3GetFloat64")
                    .unwrap_or_else(|| panic!("{what}: no read:\n{log}"));
                let shown = format!("{:?}", q.last().unwrap());
                assert!(last_read.results.contains(&shown), "{what}: the last read {last_read:?} does not hold q = {shown}");
            }
        }
    }
}

/// FMI 1.0 (the C test FMU of a linear oscillator) through both interfaces, in a worker and in
/// this process: the instance's life in the order FMI 1.0 prescribes (instantiate, the start
/// time set for Model Exchange, initialize, the steps, terminate, free), each call fmiOK, the
/// Booleans named fmiTrue/fmiFalse; Co-Simulation steps from each point of the grid as for
/// FMI 2.0 (1e-15: the runner's start + k h), Model Exchange evaluates the derivatives; the last
/// read returned the CSV's last value of y.
#[test]
fn fmi1_in_both_interfaces() {
    let dir = tempfile::tempdir().unwrap();
    let grid = ["--stop-time", "0.2", "--output-interval", "0.05"];
    for co_simulation in [true, false] {
        let fmu = fmi1_fmu(dir.path(), &format!("linear_{co_simulation}.fmu"), "linear", co_simulation, str::to_owned);
        for mode in [&[][..], &["--in-process"][..]] {
            let what = format!("co-simulation {co_simulation} {mode:?}");
            let log = logged_run(dir.path(), &fmu, &[&grid[..], mode].concat());
            let calls = parse(&log);
            for c in &calls {
                let fine = matches!(c.status.as_deref(), Some(s) if s == "fmiOK" || s.starts_with("0x") || s == "(void)");
                assert!(fine, "{what}: {c:?} did not return fmiOK:\n{log}");
            }
            const LIFE: [&str; 10] = [
                "fmiInstantiateSlave",
                "fmiInitializeSlave",
                "fmiDoStep",
                "fmiTerminateSlave",
                "fmiFreeSlaveInstance",
                "fmiInstantiateModel",
                "fmiSetTime",
                "fmiInitialize",
                "fmiTerminate",
                "fmiFreeModelInstance",
            ];
            // Model Exchange sets the time at every step: only the first, before fmiInitialize.
            let first_of_set_time = calls.iter().position(|c| c.name == "fmiSetTime");
            let life: Vec<&str> = calls
                .iter()
                .enumerate()
                .filter(|(k, c)| LIFE.contains(&c.name.as_str()) && (c.name != "fmiSetTime" || Some(*k) == first_of_set_time))
                .map(|(_, c)| c.name.as_str())
                .collect();
            let expected: Vec<&str> = if co_simulation {
                let mut e = vec!["fmiInstantiateSlave", "fmiInitializeSlave"];
                e.extend(["fmiDoStep"; 4]);
                e.extend(["fmiTerminateSlave", "fmiFreeSlaveInstance"]);
                e
            } else {
                vec!["fmiInstantiateModel", "fmiSetTime", "fmiInitialize", "fmiTerminate", "fmiFreeModelInstance"]
            };
            assert_eq!(life, expected, "{what}:\n{log}");
            let instantiate = &calls[0];
            assert_eq!(instantiate.argument("loggingOn"), Some("fmiFalse"), "{what}: {instantiate:?}");
            if co_simulation {
                let initialize = calls.iter().find(|c| c.name == "fmiInitializeSlave").unwrap();
                assert_eq!(initialize.arguments, "tStart=0.0, StopTimeDefined=fmiTrue, tStop=0.2", "{what}");
                for (k, (t, h)) in steps(&calls, "fmiDoStep").iter().enumerate() {
                    assert!((t - 0.05 * k as f64).abs() <= 1e-15 && (h - 0.05).abs() <= 1e-15, "{what}: step {k} is ({t}, {h}):\n{log}");
                }
                assert!(calls.iter().filter(|c| c.name == "fmiDoStep").all(|c| c.argument("newStep") == Some("fmiTrue")), "{what}");
            } else {
                assert_eq!(calls[1].arguments, "time=0.0", "{what}: the start time is set before fmiInitialize");
                let initialize = calls.iter().find(|c| c.name == "fmiInitialize").unwrap();
                assert!(initialize.results.starts_with("iterationConverged=fmiTrue"), "{what}: {initialize:?}");
                let evaluations = calls.iter().filter(|c| c.name == "fmiGetDerivatives").count();
                assert!(evaluations >= 4, "{what}: {evaluations} fmiGetDerivatives calls for 4 steps:\n{log}");
                assert!(calls.iter().any(|c| c.name == "fmiGetDerivatives" && c.results.starts_with("derivatives=[")), "{what}:\n{log}");
            }
            let (header, rows) = read_csv(&dir.path().join("x.csv"));
            let y = column(&header, &rows, "y");
            let last_read = calls.iter().rev().find(|c| c.name == "fmiGetReal").unwrap_or_else(|| panic!("{what}: no read:\n{log}"));
            let shown = format!("{:?}", y.last().unwrap());
            assert!(last_read.results.contains(&shown), "{what}: the last read {last_read:?} does not hold y = {shown}");
        }
    }
}

/// The FMI 1.0 bouncing ball through Model Exchange for 1 s (one bounce, at 0.45 s): the calls
/// of the event handling and of its Integer and Boolean outputs are logged too, each fmiOK,
/// and the bounce's fmiEventUpdate says the states changed (the velocity is reversed).
#[test]
fn fmi1_events_and_discrete_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = fmi1_fmu(dir.path(), "bouncing.fmu", "bouncing", false, str::to_owned);
    let log = logged_run(dir.path(), &fmu, &["--stop-time", "1", "--output-interval", "0.1"]);
    let calls = parse(&log);
    for name in [
        "fmiGetEventIndicators",
        "fmiCompletedIntegratorStep",
        "fmiEventUpdate",
        "fmiGetContinuousStates",
        "fmiGetInteger",
        "fmiGetBoolean",
    ] {
        let made: Vec<&Call> = calls.iter().filter(|c| c.name == name).collect();
        assert!(!made.is_empty(), "no {name} in the log:\n{log}");
        assert!(made.iter().all(|c| c.status.as_deref() == Some("fmiOK")), "{name}: {made:?}");
    }
    let bounce = calls.iter().find(|c| c.name == "fmiEventUpdate").unwrap();
    assert_eq!(bounce.arguments, "intermediateResults=fmiFalse");
    assert!(bounce.results.contains("stateValuesChanged=fmiTrue"), "{bounce:?}");
    let (header, rows) = read_csv(&dir.path().join("x.csv"));
    assert_eq!(column(&header, &rows, "bounces").last(), Some(&1.0), "one bounce in 1 s");
}

/// A Reference FMU (FMI 2.0 Co-Simulation) run by the runner and by fmpy with the same grid:
/// the instance's life is the same sequence of calls in both logs, and the steps have the same
/// points and sizes (to 1e-12: both compute start + k h, perhaps in a different order).
#[test]
fn a_reference_fmu_makes_the_calls_fmpy_makes() {
    let fmu = reference_fmu("fmi2", "BouncingBall");
    let dir = tempfile::tempdir().unwrap();
    let log = logged_run(dir.path(), &fmu, &["--stop-time", "0.5", "--output-interval", "0.1"]);
    let ours = parse(&log);
    let script = format!(
        r#"
import fmpy
calls = []
fmpy.simulate_fmu({fmu:?}, stop_time=0.5, output_interval=0.1, fmi_call_logger=calls.append)
print("\n".join(calls))
"#,
        fmu = fmu.to_str().unwrap()
    );
    let python = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv/bin/python");
    let o = std::process::Command::new(python).arg("-c").arg(script).current_dir(dir.path()).output().expect("the test venv's Python runs");
    assert!(o.status.success(), "fmpy failed: {}", String::from_utf8_lossy(&o.stderr));
    let theirs_text = String::from_utf8(o.stdout).unwrap();
    // fmpy's lines are `name(arguments) -> status`, as ours without the duration.
    let theirs: Vec<Call> = theirs_text
        .lines()
        .filter(|l| l.starts_with("fmi2"))
        .map(|l| {
            let open = l.find('(').unwrap();
            let close = l.rfind(')').unwrap();
            Call { name: l[..open].to_owned(), arguments: l[open + 1..close].to_owned(), status: None, results: String::new() }
        })
        .collect();
    assert_eq!(lifecycle(&ours), lifecycle(&theirs), "ours:\n{log}\nfmpy's:\n{theirs_text}");
    let (a, b) = (steps(&ours, "fmi2DoStep"), steps(&theirs, "fmi2DoStep"));
    assert_eq!(a.len(), 5, "{log}");
    assert_eq!(a.len(), b.len());
    for ((t, h), (u, g)) in a.iter().zip(&b) {
        assert!((t - u).abs() <= 1e-12 && (h - g).abs() <= 1e-12, "ours ({t}, {h}), fmpy's ({u}, {g})");
    }
}

/// fault=1 makes the C FMU's fmi2DoStep crash with SIGSEGV at t = 0.31. In the worker the log,
/// written call by call, ends with that call, unfinished, and the runner's error names it too;
/// in this process, which the crash kills, the log ends the same. Without a file the log goes
/// to stderr.
#[test]
fn the_last_line_names_the_call_that_crashed() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let args = ["simulate", f, "--set", "fault=1", "--stop-time", "1", "--output-interval", "0.01", "--out", "x.csv"];
    let error = fails(runner(dir.path(), &[&args[..], &["--log-fmi-calls", "calls.txt"]].concat()));
    assert!(error.contains("in fmi2DoStep at t = 0.31"), "{error}");
    let log = std::fs::read_to_string(dir.path().join("calls.txt")).unwrap();
    let calls = parse(&log);
    let last = calls.last().unwrap();
    assert_eq!(last.name, "fmi2DoStep", "{log}");
    assert_eq!(last.status, None, "the crashed call never returned: {log}");
    assert_eq!(last.argument("currentCommunicationPoint"), Some("0.31"), "{log}");
    assert!(calls[..calls.len() - 1].iter().all(|c| c.status.as_deref().is_some_and(|s| s == "fmi2OK" || s.starts_with("0x"))), "{log}");

    // In this process the crash ends the runner, and the log still ends with the call.
    let o = runner(dir.path(), &[&args[..], &["--log-fmi-calls", "in-process.txt", "--in-process"]].concat());
    assert_eq!(o.status.code(), None, "killed by the FMU's SIGSEGV: {}", stderr(&o));
    let log = std::fs::read_to_string(dir.path().join("in-process.txt")).unwrap();
    let calls = parse(&log);
    let last = calls.last().unwrap();
    assert_eq!((last.name.as_str(), last.status.as_deref()), ("fmi2DoStep", None), "{log}");
    assert_eq!(last.argument("currentCommunicationPoint"), Some("0.31"), "{log}");

    // To stderr: the same lines among the runner's own.
    let o = runner(dir.path(), &[&args[..], &["--log-fmi-calls"]].concat());
    let error = fails(o);
    assert!(error.lines().any(|l| l.starts_with("fmi2Instantiate(instanceName=\"faulty\"") && l.ends_with(" us]")), "{error}");
    let crashed = error.lines().find(|l| l.starts_with("fmi2DoStep(currentCommunicationPoint=0.31, ")).unwrap_or_else(|| panic!("{error}"));
    assert!(crashed.ends_with("noSetFMUStatePriorToCurrentPoint=fmi2True)"), "the runner's error starts a line of its own: {error}");
}

/// A log file that cannot be written stops the command before the FMU runs, naming the file.
#[test]
fn an_unwritable_log_is_refused_before_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let error = fails(runner(dir.path(), &["simulate", f, "--out", "x.csv", "--log-fmi-calls", "no/such/dir/calls.txt"]));
    assert!(error.contains("cannot write the FMI call log no/such/dir/calls.txt"), "{error}");
    assert!(!dir.path().join("x.csv").exists(), "no run, no CSV");
}

/// `runner linearize` logs too: the Reference FMU VanDerPol (FMI 3.0) through Model Exchange,
/// its Jacobian from fmi3GetDirectionalDerivative, which it provides; every call OK.
#[test]
fn linearize_logs_its_calls() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference_fmu("fmi3", "VanDerPol");
    ok(runner(dir.path(), &["linearize", fmu.to_str().unwrap(), "--log-fmi-calls", "calls.txt"]));
    let log = std::fs::read_to_string(dir.path().join("calls.txt")).unwrap();
    let calls = parse(&log);
    assert_eq!(calls.first().map(|c| c.name.as_str()), Some("fmi3InstantiateModelExchange"), "{log}");
    assert!(calls.iter().any(|c| c.name == "fmi3GetDirectionalDerivative" && c.results.starts_with("sensitivity=[")), "{log}");
    assert_eq!(calls.last().map(|c| c.name.as_str()), Some("fmi3FreeInstance"), "{log}");
    assert!(calls.iter().all(|c| c.status.as_deref().is_some_and(|s| s == "fmi3OK" || s.starts_with("0x") || s == "(void)")), "{log}");
}
