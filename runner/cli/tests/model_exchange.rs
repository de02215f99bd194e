//! End-to-end tests of the runner's Model Exchange driver on an FMU this project did not
//! export: tests/c_fmu/me_faults.c, the Dahlquist equation x' = -k x with a time event every
//! `period` seconds, compiled here with `cc`, and its faults (an fmi2Error or NaN from the
//! derivatives, an event iteration that never settles, NaN event indicators, an early end),
//! plus the choice of interface and the refusals around it.

mod common;

use common::*;

fn me_fmu(dir: &std::path::Path) -> std::path::PathBuf {
    me_faults_fmu(dir, "me_faults.fmu", str::to_owned)
}

/// Runs `runner simulate` on `fmu` with `args`; the CSV's header and rows, and stderr.
fn simulate(dir: &std::path::Path, fmu: &std::path::Path, args: &[&str]) -> (Vec<String>, Vec<Vec<String>>, String) {
    let mut all = vec!["simulate", fmu.to_str().unwrap(), "--out", "x.csv"];
    all.extend_from_slice(args);
    let o = runner(dir, &all);
    let err = stderr(&o);
    assert!(o.status.success(), "runner failed: {err}");
    let (header, rows) = read_csv(&dir.join("x.csv"));
    (header, rows, err)
}

/// An FMU offering only Model Exchange runs as such without --interface. The solution is the
/// exact exp(-k t) to the tolerance (rtol 1e-10, atol 1e-12 on values <= 1: 1e-9), and the
/// time events every 0.5 s (on the grid) and every 0.3 s (between grid points) are counted at
/// the right rows: the row at t = 0.5 already shows the event of t = 0.5.
#[test]
fn the_dahlquist_solution_and_its_time_events() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    for (period, solver) in [(0.5, "dopri5"), (0.3, "dopri5"), (0.5, "rk4")] {
        let p = format!("period={period}");
        let (header, rows, _) = simulate(
            dir.path(),
            &fmu,
            &["--set", "k=0.7", "--set", &p, "--tolerance", "1e-10", "--abs-tolerance", "1e-12", "--solver", solver],
        );
        assert_eq!(header, ["time", "x", "ticks"]);
        assert_eq!(rows.len(), 301);
        let (t, x, ticks) = (column(&header, &rows, "time"), column(&header, &rows, "x"), column(&header, &rows, "ticks"));
        for i in 0..rows.len() {
            // RK4 at the default 1 ms step: error ~ h^4 / 120 per unit time, far below 1e-9.
            assert!((x[i] - (-0.7 * t[i]).exp()).abs() < 1e-9, "{solver} t = {}: x = {}", t[i], x[i]);
            let expected = (t[i] / period + 1e-9).floor();
            assert_eq!(ticks[i], expected, "period {period}: ticks at t = {}", t[i]);
        }
    }
}

/// An fmi2Error from fmi2GetDerivatives stops the run with the call, the time and the FMU's
/// own reason; x.csv keeps the rows before the failure (every 0.01 s up to the end of the last step accepted before t = 1, a few points before it).
#[test]
fn an_error_from_the_derivatives_names_the_call_and_the_time() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "fault=1", "--out", "x.csv"]));
    assert!(err.contains("fmi2GetDerivatives at t = 1") && err.contains("returned fmi2Error"), "{err}");
    // DOPRI5 steps across communication points, so the first evaluation at or after t = 1 (where
    // the fault starts) is a stage of the step covering it, at some t in [1, 1.1).
    assert!(err.contains("the derivative cannot be evaluated at t = 1") && err.contains("(fault 1)"), "the FMU's reason: {err}");
    let (header, rows) = read_csv(&dir.path().join("x.csv"));
    let t = column(&header, &rows, "time");
    assert!(err.contains(&format!("x.csv keeps the {} row(s) before the failure", rows.len())), "{err}");
    assert!(*t.last().unwrap() <= 1.0 + 1e-12 && t.len() >= 90, "the rows up to the fault: {t:?}");
}

/// NaN derivatives with fmi2OK: each method stops (DOPRI5 after trying smaller steps) and the
/// message names the call, the time and the value.
#[test]
fn nan_derivatives_are_reported_with_the_time_and_the_call() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    for solver in ["dopri5", "rk4", "euler"] {
        let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "fault=2", "--solver", solver]));
        assert!(err.contains(&format!("the runner's {solver} integration from t = ")), "{err}");
        assert!(err.contains("became NaN or infinite at t = 1"), "{err}");
        assert!(err.contains("fmi2GetDerivatives at t = 1") && err.contains("returned derivatives[0] = NaN"), "{err}");
    }
}

/// Issue 37: k = 1e30 makes x' = -k x stiff beyond measure: DOPRI5 is stable only for steps
/// under 3.3e-30 s, so reaching the first communication point (0.01 s) would take some 3e27
/// steps (k = 1e300 overflows instead, a failure of its own). The runner's integrator gives up after MAX_STEPS_PER_CALL step attempts in one call
/// with an error naming the FMU, the time reached, the count and the hint, and x.csv keeps the
/// rows before the failure (the one at t = 0), as the other failures do. Before the bound the
/// run did not end.
#[test]
fn an_extreme_parameter_ends_the_run_at_the_step_bound() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let started = std::time::Instant::now();
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "k=1e30", "--solver", "dopri5", "--out", "x.csv"]));
    let took = started.elapsed();
    println!("{took:.2?}: {err}");
    let limit = format!("after {} step attempts in one call", solvers::MAX_STEPS_PER_CALL);
    assert!(err.contains("me_faults") && err.contains("the runner's dopri5 integration from t = 0 failed"), "{err}");
    assert!(err.contains("gave up at t = ") && err.contains(&limit) && err.contains("stiff"), "{err}");
    let (header, rows) = read_csv(&dir.path().join("x.csv"));
    assert!(err.contains(&format!("x.csv keeps the {} row(s) before the failure", rows.len())), "{err}");
    assert_eq!(column(&header, &rows, "time"), [0.0], "the row at the start");
    // A hang guard: a million steps through the FMU's C calls take a few seconds.
    assert!(took < std::time::Duration::from_secs(180), "{took:.2?}");
}

/// An event iteration that never settles (newDiscreteStatesNeeded stays true) is cut off.
#[test]
fn an_event_iteration_that_never_settles_is_cut_off() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "fault=3"]));
    assert!(err.contains("the event iteration at t = 1 did not converge"), "{err}");
    assert!(err.contains("newDiscreteStatesNeeded") && err.contains("after 1000 calls"), "{err}");
}

/// An event indicator that is NaN would hide its events: the run stops at once, naming it.
#[test]
fn nan_event_indicators_stop_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "fault=4"]));
    assert!(err.contains("fmi2GetEventIndicators at t = 1") && err.contains("eventIndicators[0] = NaN"), "{err}");
}

/// terminateSimulation from an event ends the run early: the rows up to there are kept and the
/// reason the FMU logged (as information) is printed.
#[test]
fn terminate_simulation_ends_the_run_early_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let (header, rows, err) = simulate(dir.path(), &fmu, &["--set", "fault=5"]);
    assert!(err.contains("stopped before the stop time") && err.contains("the run is over at t = 1: the fault ends it"), "{err}");
    let t = column(&header, &rows, "time");
    assert_eq!((rows.len(), *t.last().unwrap()), (101, 1.0), "the rows up to the event at t = 1");
}

/// A sweep integrates every point with the runner's solver: final x = exp(-3 k).
#[test]
fn a_sweep_runs_model_exchange_points() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let args = ["sweep", fmu.to_str().unwrap(), "--param", "k=0.5,1,2", "--metric", "end=final(x)", "--tolerance", "1e-10"];
    let args: Vec<&str> = args.iter().copied().chain(["--abs-tolerance", "1e-12", "--threads", "2", "--out", "s.csv"]).collect();
    ok(runner(dir.path(), &args));
    let (header, rows) = read_csv(&dir.path().join("s.csv"));
    let (k, end) = (column(&header, &rows, "k"), column(&header, &rows, "end"));
    for i in 0..3 {
        assert!((end[i] - (-3.0 * k[i]).exp()).abs() < 1e-9, "k = {}: {}", k[i], end[i]);
    }
}

/// `compare` on a Model Exchange FMU without solver controls: the runner's own methods and
/// counters, against its DOPRI5 at rtol 1e-12. Each method reaches 1e-6 on x' = -x (Euler needs
/// h ~ 1e-6 / (t e^-t / 2) ~ 5e-6 s, the smallest step tried is 0.01 / 4^7 = 6e-7 s; the
/// implicit methods' tolerances go down to 1e-10).
#[test]
fn compare_uses_the_runners_solvers_and_counters() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let out = ok(runner(dir.path(), &["compare", fmu.to_str().unwrap(), "--interface", "model-exchange", "--target-error", "1e-6"]));
    for solver in ["euler", "rk4", "dopri5", "bdf", "esdirk"] {
        let line = out.lines().find(|l| l.starts_with(solver)).unwrap_or_else(|| panic!("{out}"));
        assert!(!line.contains("not reached"), "{line}");
    }
    let (header, rows) = read_csv(&dir.path().join("me_faults_compare.csv"));
    let rhs = column(&header, &rows, "n_rhs");
    assert!(rhs.iter().all(|&n| n > 0.0), "the runner's integrator counts its evaluations: {rhs:?}");
}

/// The interface options: one the FMU lacks is refused naming what it offers; an FMU that
/// needs an external tool is refused; the integrator's options are refused for Co-Simulation.
#[test]
fn interface_choices_are_checked() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_fmu(dir.path());
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--interface", "co-simulation"]));
    assert!(err.contains("does not support Co-Simulation: it offers Model Exchange only (--interface model-exchange)"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--interface", "me"]));
    assert!(err.contains("'me' is not an interface: use model-exchange or co-simulation"), "{err}");
    let tool = me_faults_fmu(dir.path(), "tool.fmu", |xml| xml.replace("needsExecutionTool=\"false\"", "needsExecutionTool=\"true\""));
    let err = fails(runner(dir.path(), &["simulate", tool.to_str().unwrap()]));
    assert!(err.contains("needs an external simulation tool (needsExecutionTool=\"true\")"), "{err}");
    let cs = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let err = fails(runner(dir.path(), &["simulate", cs.to_str().unwrap(), "--solver", "rk4"]));
    assert!(
        err.contains("--solver, --fixed-step and --abs-tolerance set the runner's integrator, which only Model Exchange uses"),
        "{err}"
    );
    assert!(err.contains("it offers no Model Exchange interface"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", cs.to_str().unwrap(), "--interface", "model-exchange"]));
    assert!(err.contains("does not support Model Exchange: it offers Co-Simulation only (--interface co-simulation)"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--fixed-step", "0"]));
    assert!(err.contains("--fixed-step 0 must be a positive number"), "{err}");
}
