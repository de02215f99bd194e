//! End-to-end tests of simulate, sweep and info on this project's own FMUs (quarter_car and
//! second_order only, to keep the release builds few), built through `runner build` because
//! tests/run packs the FMUs only after `cargo test`.

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::*;

/// Builds the two FMUs once per test binary (concurrent builds would race on the .fmu files).
fn fmus() -> &'static (PathBuf, PathBuf) {
    static BUILT: OnceLock<(PathBuf, PathBuf)> = OnceLock::new();
    BUILT.get_or_init(|| {
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let out = ok(runner(here, &["build", "quarter_car", "second_order"]));
        let paths: Vec<PathBuf> = out.lines().map(PathBuf::from).collect();
        // The FMI 2.0 FMUs first, then the FMI 3.0 ones (target/fmu3).
        assert_eq!(paths.len(), 4, "runner build prints two paths per model: {out}");
        assert!(paths[2].ends_with("fmu3/quarter_car.fmu") && paths[3].ends_with("fmu3/second_order.fmu"), "{out}");
        (paths[0].clone(), paths[1].clone())
    })
}

/// |Z_s / Z_r|(i w) of the linear quarter car, from its two equations of motion in the Laplace
/// domain: (m_s s^2 + K_s) Z_s = K_s Z_u and (m_u s^2 + K_s + K_t) Z_u = K_s Z_s + K_t Z_r with
/// K_s = k_s + b_s s, K_t = k_t + b_t s (MODELS.md's default parameters).
fn transmissibility(speed: f64) -> f64 {
    let (m_s, m_u, k_s, b_s, k_t, b_t) = (200.0, 30.0, 18000.0, 1300.0, 125000.0, 10.0);
    let w = 2.0 * PI * speed / 3.0;
    // Complex numbers as (re, im).
    let mul = |a: (f64, f64), b: (f64, f64)| (a.0 * b.0 - a.1 * b.1, a.0 * b.1 + a.1 * b.0);
    let ks = (k_s, b_s * w);
    let kt = (k_t, b_t * w);
    let body = (k_s - m_s * w * w, b_s * w);
    let wheel = (k_s + k_t - m_u * w * w, (b_s + b_t) * w);
    let ks2 = mul(ks, ks);
    let den = mul(wheel, body);
    let den = (den.0 - ks2.0, den.1 - ks2.1);
    let num = mul(kt, ks);
    (num.0.hypot(num.1)) / den.0.hypot(den.1)
}

/// The sweep against the frequency response. `steady=max(z_s,5)/max(z_r,5)` looks only at the
/// last 5 s: the slowest mode decays like exp(-3.3 t), so the start-up transient is below 1e-7
/// there, and what remains is sampling: the max of a sinusoid sampled every h is low by at most
/// 1 - cos(w h / 2) ~ (w h)^2 / 8 = 4.9e-4 at 30 m/s (w = 62.8 rad/s, h = 1e-3 s), for z_s and
/// z_r independently, hence 1e-3 relative. The handbook's whole-run `max(z_s)/max(z_r)` equals
/// the steady state only near resonance (there the steady response dominates the transient):
/// at 4 m/s, within the same 1e-3.
#[test]
fn quarter_car_sweep_matches_the_frequency_response_and_ignores_thread_count() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let args = |threads: &'static str, out: &'static str| {
        vec![
            "sweep",
            q,
            "--param",
            "speed=2:30:4",
            "--metric",
            "transmissibility=max(z_s)/max(z_r)",
            "--metric",
            "steady=max(z_s, 5)/max(z_r, 5)",
            "--tolerance",
            "1e-9",
            "--output-interval",
            "1e-3",
            "--threads",
            threads,
            "--out",
            out,
            "--plot",
            "t.svg",
        ]
    };
    let stdout = ok(runner(dir.path(), &args("2", "two.csv")));
    let (header, rows) = read_csv(&dir.path().join("two.csv"));
    assert_eq!(header, ["speed", "transmissibility", "steady", "status"]);
    let (speed, whole, steady) =
        (column(&header, &rows, "speed"), column(&header, &rows, "transmissibility"), column(&header, &rows, "steady"));
    assert_eq!(speed, [2.0, 6.0, 10.0, 14.0, 18.0, 22.0, 26.0, 30.0]);
    for i in 0..speed.len() {
        let h = transmissibility(speed[i]);
        assert!((steady[i] / h - 1.0).abs() < 1e-3, "speed {}: steady-state ratio {} vs |H| = {h}", speed[i], steady[i]);
        assert!(whole[i] >= steady[i] * (1.0 - 1e-3), "the whole-run maximum includes the steady state");
    }
    assert!(stdout.contains("transmissibility: peak"), "{stdout}");
    let _ = ok(runner(dir.path(), &args("1", "one.csv")));
    assert_eq!(
        std::fs::read(dir.path().join("one.csv")).unwrap(),
        std::fs::read(dir.path().join("two.csv")).unwrap(),
        "identical CSV with 1 and 2 threads"
    );
    let svg = std::fs::read_to_string(dir.path().join("t.svg")).unwrap();
    assert!(svg.contains("speed (m/s)") && svg.contains("peak"), "axis label with unit and the peak label");

    let near_resonance = ok(runner(
        dir.path(),
        &[
            "sweep",
            q,
            "--param",
            "speed=4",
            "--metric",
            "t=max(z_s)/max(z_r)",
            "--tolerance",
            "1e-9",
            "--output-interval",
            "1e-3",
            "--threads",
            "2",
            "--out",
            "res.csv",
        ],
    ));
    let (header, rows) = read_csv(&dir.path().join("res.csv"));
    let t = column(&header, &rows, "t")[0];
    assert!((t / transmissibility(4.0) - 1.0).abs() < 1e-3, "at resonance {t} vs {}; {near_resonance}", transmissibility(4.0));
}

/// Ex. 1 against its closed form, written once in the model's experiment.toml (the forcing
/// e^{-3t} is at a root of 2 s^2 + 10 s + 12, hence a t e^{-3t} term). With relative tolerance
/// 1e-10 and the default abs_tol 1e-9, DOPRI5's global error stays orders below the 1e-6 allowed.
#[test]
fn second_order_simulation_matches_the_closed_form() {
    let (_, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    ok(runner(
        dir.path(),
        &[
            "simulate",
            second_order.to_str().unwrap(),
            "--tolerance",
            "1e-10",
            "--output-interval",
            "0.01",
            "--out",
            "q.csv",
            "--plot",
            "q.svg",
        ],
    ));
    let (header, rows) = read_csv(&dir.path().join("q.csv"));
    assert_eq!(&header[..2], ["time", "q"]);
    let (t, q) = (column(&header, &rows, "time"), column(&header, &rows, "q"));
    assert_eq!(rows.len(), 1001, "10 s every 0.01 s");
    let experiment: toml::Table = include_str!("../../../models/second_order/experiment.toml").parse().unwrap();
    let closed_form = formulas::Formula::parse(experiment["compare"]["reference"]["q"].as_str().unwrap()).unwrap();
    assert_eq!(closed_form.names, ["t"]);
    for (t, q) in t.iter().zip(&q) {
        let exact = closed_form.evaluate(&[*t]);
        assert!((q - exact).abs() < 1e-6, "t = {t}: q = {q}, exact {exact}");
    }
}

#[test]
fn info_and_typos_on_our_fmu() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let out = ok(runner(dir.path(), &["info", q]));
    let speed = out.lines().find(|l| l.starts_with("speed ")).expect("a line for speed");
    assert!(speed.contains("parameter") && speed.contains("m/s") && speed.contains("30"), "{speed}");
    let err = fails(runner(dir.path(), &["simulate", q, "--set", "sped=3"]));
    assert!(err.contains("did you mean 'speed'"), "{err}");
    // A value the model refuses is reported with the model's own message.
    let err = fails(runner(dir.path(), &["simulate", q, "--set", "k_s=0", "--stop-time", "0.1"]));
    assert!(err.contains("k_s"), "{err}");
}

/// `runner compare` on second_order: the work-precision table must show each method's order
/// (an independent property of the methods, not of our numbers): halving RK4's step divides its
/// error by 2^4 = 16, quartering Euler's divides it by 4; RK4 reaches 1e-6 with fewer
/// evaluations than Euler, and the reported counters follow from the settings.
#[test]
fn compare_shows_each_methods_order_and_the_cheapest_solver() {
    let (_, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let out =
        ok(runner(dir.path(), &["compare", second_order.to_str().unwrap(), "--target-error", "1e-6", "--out", "w.csv", "--plot", "w.svg"]));
    assert!(out.contains("rk4") && out.contains("dopri5"), "{out}");
    assert!(dir.path().join("w.svg").is_file());
    let (header, rows) = read_csv(&dir.path().join("w.csv"));
    let pick = |solver: &str, col: &str| -> Vec<f64> {
        let j = header.iter().position(|h| h == col).unwrap();
        rows.iter().filter(|r| r[0] == solver).map(|r| r[j].parse().unwrap()).collect()
    };
    let (rk4_err, rk4_rhs, rk4_steps) = (pick("rk4", "max_relative_error"), pick("rk4", "n_rhs"), pick("rk4", "n_steps"));
    // The first four halvings are in RK4's asymptotic range (errors 1e-8..1e-12, above roundoff).
    for k in 0..3 {
        let ratio = rk4_err[k] / rk4_err[k + 1];
        assert!((13.0..19.0).contains(&ratio), "RK4 error ratio {ratio} at halving {k}");
    }
    for (rhs, steps) in rk4_rhs.iter().zip(&rk4_steps) {
        assert_eq!(*rhs, 4.0 * steps, "RK4 evaluates f four times per step");
    }
    let euler_err = pick("euler", "max_relative_error");
    for k in 1..4 {
        let ratio = euler_err[k] / euler_err[k + 1];
        assert!((3.6..4.4).contains(&ratio), "Euler error ratio {ratio} at step/4 number {k}");
    }
    let cheapest = |solver: &str| {
        let (err, rhs) = (pick(solver, "max_relative_error"), pick(solver, "n_rhs"));
        err.iter().zip(&rhs).filter(|(e, _)| **e <= 1e-6).map(|(_, r)| *r).fold(f64::INFINITY, f64::min)
    };
    assert!(cheapest("rk4") < cheapest("euler"), "rk4 {} vs euler {}", cheapest("rk4"), cheapest("euler"));
    // A bad target error is refused with a message naming it.
    let msg = fails(runner(dir.path(), &["compare", second_order.to_str().unwrap(), "--target-error", "0"]));
    assert!(msg.contains("--target-error"), "{msg}");
}

/// With a model name, `compare` measures errors against the closed form in the model's
/// experiment.toml. The closed form is independent of every solver, so DOPRI5 at tight
/// tolerance must agree with it to about its tolerance (1e-9 bound: rtol 1e-10 plus the error
/// of the dense output between steps is well below that), and RK4 still shows order 4. With
/// --set the closed form no longer applies and the reference is DOP853.
#[test]
fn compare_uses_the_closed_form_reference_of_the_experiment_file() {
    fmus();
    let dir = tempfile::tempdir().unwrap();
    let out = ok(runner(dir.path(), &["compare", "second_order", "--out", "w.csv", "--plot", "w.svg"]));
    assert!(out.contains("max over q, q_dot, u of") && out.contains("y_ref from the closed-form solution of experiment.toml"), "{out}");
    let (header, rows) = read_csv(&dir.path().join("w.csv"));
    let j = header.iter().position(|h| h == "max_relative_error").unwrap();
    let error =
        |solver: &str, value: &str| rows.iter().find(|r| r[0] == solver && r[2] == value).map(|r| r[j].parse::<f64>().unwrap()).unwrap();
    let tight = error("dopri5", "0.0000000001");
    assert!(tight < 1e-9, "DOPRI5 at rtol 1e-10 against the closed form: {tight}");
    let ratio = error("rk4", "0.01") / error("rk4", "0.005");
    assert!((13.0..19.0).contains(&ratio), "RK4 halving ratio {ratio}");
    let o = runner(dir.path(), &["compare", "second_order", "--set", "q0=1", "--out", "w2.csv", "--plot", "w2.svg"]);
    assert!(o.status.success() && String::from_utf8_lossy(&o.stdout).contains("y_ref from DOP853 at rtol 1e-13"), "{}", stderr(&o));
    assert!(stderr(&o).contains("holds for its own parameter values"), "{}", stderr(&o));
}

/// `runner compare quarter_car second_order` (2 s of the quarter car, to keep it short): the
/// adaptive methods step across the 1 ms communication points, so their steps follow the
/// tolerance as each method's error estimate says they must, an independent property of the
/// methods: the step size goes as rtol^(1/q), q the local order of the estimate (5 for DOPRI5, 3
/// for BS23, 8 for DOP853), so each decade of tolerance costs 10^(1/q) times the steps: 1.58x,
/// 2.15x, 1.33x (within 10 %, in the asymptotic half of the tolerances). At rtol 1e-2 DOPRI5
/// takes far fewer steps than the 2,000 communication points. Then the Ex. 4 question: the step
/// counts of both models side by side and the Euler/DOPRI5 ratios, consistent with the tables.
#[test]
fn compare_two_models_shows_adaptive_steps_following_the_tolerance_and_the_step_ratios() {
    fmus();
    let dir = tempfile::tempdir().unwrap();
    let out = ok(runner(dir.path(), &["compare", "quarter_car", "second_order", "--stop-time", "2", "--target-error", "1e-4"]));
    let (header, rows) = read_csv(&dir.path().join("quarter_car_compare.csv"));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let steps = |solver: &str| -> Vec<f64> { rows.iter().filter(|r| r[0] == solver).map(|r| r[col("n_steps")].parse().unwrap()).collect() };
    for (solver, q) in [("dopri5", 5.0), ("bs23", 3.0), ("dop853", 8.0)] {
        let n = steps(solver);
        assert!(n.windows(2).all(|w| w[1] > w[0]), "{solver}: steps must grow as the tolerance falls: {n:?}");
        let expected = 10f64.powf(1.0 / q);
        for w in n[n.len() / 2..].windows(2) {
            let per_decade = w[1] / w[0];
            assert!((per_decade / expected - 1.0).abs() < 0.1, "{solver}: {per_decade} steps per decade, expected {expected}: {n:?}");
        }
    }
    assert!(steps("dopri5")[0] < 200.0, "DOPRI5 at rtol 1e-2 over 2,000 communication points: {:?}", steps("dopri5"));
    assert!(steps("rk4").iter().all(|&n| n >= 2000.0), "a fixed step lands on every communication point");
    assert!(dir.path().join("second_order_compare.csv").is_file() && dir.path().join("second_order_compare.svg").is_file());
    let summary = out.split("steps for an error of 1e-4").nth(1).unwrap_or_else(|| panic!("no step-count summary: {out}"));
    let line = |model: &str| summary.lines().find(|l| l.starts_with(model)).unwrap_or_else(|| panic!("no line for {model}: {summary}"));
    assert!(line("quarter_car").contains("(1.000x)") && line("second_order").contains("(1.000x)"), "{summary}");
    // "forward Euler needs 22372x the steps of DOPRI5 on quarter_car and 4039x on second_order: ..."
    let verdict = summary.lines().find(|l| l.starts_with("forward Euler needs")).unwrap_or_else(|| panic!("{summary}"));
    let number_before = |marker: &str| -> f64 {
        let token = verdict.split(marker).next().unwrap().split_whitespace().last().unwrap();
        token.trim_end_matches('x').parse().unwrap_or_else(|_| panic!("no number before '{marker}' in {verdict}"))
    };
    let (r_car, r_ode) = (number_before(" the steps of DOPRI5 on quarter_car"), number_before(" on second_order"));
    // Euler (order 1) against DOPRI5 at 1e-4: thousands of times the steps on both.
    assert!(r_car > 1000.0 && r_ode > 1000.0, "{verdict}");
    assert!(verdict.contains(&format!("{:.1}x as wide on quarter_car", r_car / r_ode)), "{verdict}");
    // --out names one model's file: refused for two, before any run.
    let err = fails(runner(dir.path(), &["compare", "quarter_car", "second_order", "--out", "x.csv"]));
    assert!(err.contains("--out and --plot name the files of one model, but 2 models were given"), "{err}");
}

/// After a call returns fmi2Error (parameters refused at initialization, a diverged step) the
/// standard allows only fmi2Reset and fmi2FreeInstance: the runner must not send fmi2Terminate,
/// which the FMU would answer with an "illegal call sequence" line that reads like a bug.
#[test]
fn after_an_error_the_runner_makes_no_illegal_call() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let refused = fails(runner(dir.path(), &["simulate", q, "--set", "speed=-3", "--out", "a.csv"]));
    assert!(refused.contains("speed = -3"), "{refused}");
    let diverged =
        fails(runner(dir.path(), &["simulate", q, "--set", "solver=0", "--set", "fixed_step=0.01", "--set", "k_t=1e9", "--out", "b.csv"]));
    assert!(diverged.contains("diverged"), "{diverged}");
    for err in [refused, diverged] {
        assert!(!err.contains("not allowed") && !err.contains("illegal call sequence"), "{err}");
    }
}

/// A negative number after an option is that option's value, refused with the reason, not an
/// unknown option with a tip about `--`.
#[test]
fn negative_numbers_reach_the_checks_that_explain_them() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let err = fails(runner(dir.path(), &["simulate", q, "--tolerance", "-1", "--out", "a.csv"]));
    assert!(err.contains("tolerance -1 must be a positive number"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", q, "--stop-time", "-5", "--out", "a.csv"]));
    assert!(err.contains("stop time -5 must be a number after the start time 0"), "{err}");
}

/// The same parameter in two --param options is refused before the first run (it would be
/// swept as two parameters, the later value silently winning).
#[test]
fn a_parameter_swept_twice_is_refused_before_running() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let err =
        fails(runner(dir.path(), &["sweep", q, "--param", "speed=1,2", "--param", "speed=3", "--metric", "m=max(z_s)", "--out", "b.csv"]));
    assert!(err.contains("--param speed is given twice"), "{err}");
    assert!(!dir.path().join("b.csv").exists());
}

/// A plot (or a comparison's table) is written after the runs: a destination directory that
/// does not exist is refused before them, not after the work, and no other file is written.
#[test]
fn a_destination_in_a_missing_directory_is_refused_before_running() {
    let (quarter_car, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let (q, s) = (quarter_car.to_str().unwrap(), second_order.to_str().unwrap());
    let cases: [&[&str]; 3] = [
        &["simulate", q, "--plot", "nodir/p.svg", "--out", "a.csv"],
        &["sweep", q, "--param", "speed=1,2", "--metric", "m=max(z_s)", "--plot", "nodir/p.svg", "--out", "a.csv"],
        &["compare", s, "--plot", "nodir/p.svg", "--out", "a.csv"],
    ];
    for args in cases {
        let err = fails(runner(dir.path(), args));
        assert!(err.contains("cannot write nodir/p.svg: the directory nodir does not exist"), "{args:?}: {err}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{args:?}: nothing written");
    }
}

/// Width and height of a PNG file, from its IHDR chunk (bytes 16..24, big-endian).
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is a PNG", path.display());
    let be = |b: &[u8]| u32::from_be_bytes([b[0], b[1], b[2], b[3]]);
    (be(&bytes[16..20]), be(&bytes[20..24]))
}

/// The text elements of an SVG file, trimmed.
fn svg_texts(path: &Path) -> Vec<String> {
    let svg = std::fs::read_to_string(path).unwrap();
    svg.split("<text").skip(1).filter_map(|t| Some(t.split_once('>')?.1.split_once("</text>")?.0.trim().to_owned())).collect()
}

/// `--plot` with `--plot-vars` draws one panel per chosen variable (a PNG as tall as the
/// panels say), `--plot-x` plots against a variable, and the plot options are checked before
/// any run: an unknown variable is named, a plot format we cannot write is refused.
#[test]
fn plots_show_the_chosen_variables_against_time_or_a_variable() {
    let (_, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let s = second_order.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", s, "--out", "a.csv", "--plot", "two.png", "--plot-vars", "q,u"]));
    // Two panels of 210 px under a 40 px title, 900 px wide (one column).
    assert_eq!(png_size(&dir.path().join("two.png")), (900, 2 * 210 + 40));
    ok(runner(dir.path(), &["simulate", s, "--out", "a.csv", "--plot", "phase.svg", "--plot-vars", "q_dot", "--plot-x", "q"]));
    let texts = svg_texts(&dir.path().join("phase.svg"));
    let has = |texts: &[String], t: &str| texts.iter().any(|x| x == t);
    assert!(has(&texts, "q") && has(&texts, "q_dot") && !has(&texts, "time (s)"), "q_dot against q, not time: {texts:?}");
    ok(runner(dir.path(), &["simulate", s, "--out", "a.csv", "--plot", "all.svg"]));
    let texts = svg_texts(&dir.path().join("all.svg"));
    assert!(has(&texts, "q") && has(&texts, "q_dot") && has(&texts, "u"), "every continuous output: {texts:?}");
    assert!(!texts.iter().any(|t| t.contains("n_steps") || t.contains("n_rhs")), "not the solver counters");
    let err = fails(runner(dir.path(), &["simulate", s, "--out", "b.csv", "--plot", "p.svg", "--plot-vars", "qq"]));
    assert!(err.contains("no variable 'qq'") && err.contains("did you mean 'q'"), "{err}");
    assert!(!dir.path().join("b.csv").exists(), "refused before the run");
    let err = fails(runner(dir.path(), &["simulate", s, "--out", "b.csv", "--plot", "p.pdf"]));
    assert!(err.contains(".svg or .png"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", s, "--out", "b.csv", "--plot-x", "q"]));
    assert!(err.contains("give --plot too"), "{err}");
}

/// `--overlay` runs once per value, the CSV gaining the overlaid parameter as a first column;
/// the runs differ as the closed form says (q0 enters linearly, q(0) = q0 exactly).
#[test]
fn overlays_run_once_per_value() {
    let (_, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let s = second_order.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", s, "--overlay", "q0=1,3", "--output-interval", "0.1", "--out", "o.csv", "--plot", "o.svg"]));
    let (header, rows) = read_csv(&dir.path().join("o.csv"));
    assert_eq!(&header[..3], ["q0", "time", "q"]);
    let (q0, time, q) = (column(&header, &rows, "q0"), column(&header, &rows, "time"), column(&header, &rows, "q"));
    assert_eq!(rows.len(), 2 * 101);
    assert_eq!((q0[0], q0[101]), (1.0, 3.0));
    assert_eq!((time[0], q[0], time[101], q[101]), (0.0, 1.0, 0.0, 3.0));
    let texts = svg_texts(&dir.path().join("o.svg"));
    assert!(texts.iter().any(|t| t == "q0 = 1") && texts.iter().any(|t| t == "q0 = 3"), "a legend entry per run: {texts:?}");
    let err = fails(runner(dir.path(), &["simulate", s, "--overlay", "q0=1", "--out", "p.csv"]));
    assert!(err.contains("at least two values"), "{err}");
}

/// A value given in a display unit the FMU declares is converted to SI (1 in/s = 0.0254 m/s
/// exactly, so 3937.007874 in/s is 100 m/s to 1e-9); an undeclared one is refused with the
/// units the variable can be given in.
#[test]
fn set_accepts_declared_display_units_and_refuses_others() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let run = |speed: &str, out: &str| ok(runner(dir.path(), &["simulate", q, "--set", speed, "--stop-time", "0.2", "--out", out]));
    run("speed=25", "si.csv");
    run("speed=984.2519685039370in/s", "in.csv");
    let (h, a) = read_csv(&dir.path().join("si.csv"));
    let (_, b) = read_csv(&dir.path().join("in.csv"));
    let (za, zb) = (column(&h, &a, "z_r"), column(&h, &b, "z_r"));
    for (x, y) in za.iter().zip(&zb) {
        assert!((x - y).abs() <= 1e-12, "the same road at 25 m/s either way: {x} vs {y}");
    }
    let err = fails(runner(dir.path(), &["simulate", q, "--set", "speed=30rpm", "--out", "c.csv"]));
    assert!(err.contains("'speed' cannot be given in 'rpm'") && err.contains("m/s, mm/s, in/s"), "{err}");
}

/// The Ex. 4 sweep through the Model Exchange interface: the runner's DOPRI5 on the FMU's
/// derivatives does the same arithmetic as the FMU's own DOPRI5 under Co-Simulation, at the
/// same tolerances and on the same grid, so the transmissibility is the same number to the bit.
#[test]
fn the_sweep_through_model_exchange_gives_the_co_simulation_numbers() {
    let (quarter_car, _) = fmus();
    let dir = tempfile::tempdir().unwrap();
    let q = quarter_car.to_str().unwrap();
    let args = |out: &'static str| {
        vec![
            "sweep",
            q,
            "--param",
            "speed=2:30:7",
            "--metric",
            "t=max(z_s)/max(z_r)",
            "--tolerance",
            "1e-9",
            "--threads",
            "2",
            "--out",
            out,
        ]
    };
    ok(runner(dir.path(), &args("cs.csv")));
    let mut me = args("me.csv");
    me.extend(["--interface", "model-exchange"]);
    ok(runner(dir.path(), &me));
    assert_eq!(std::fs::read(dir.path().join("me.csv")).unwrap(), std::fs::read(dir.path().join("cs.csv")).unwrap());
}

/// `compare --interface model-exchange` on second_order: the runner's own methods against the
/// closed form of experiment.toml; RK4 keeps its order 4 and its four evaluations per step,
/// counted by the runner's integrator.
#[test]
fn compare_through_model_exchange_uses_the_runners_solvers() {
    fmus();
    let dir = tempfile::tempdir().unwrap();
    let out = ok(runner(dir.path(), &["compare", "second_order", "--interface", "model-exchange", "--out", "w.csv", "--plot", "w.svg"]));
    assert!(out.contains("y_ref from the closed-form solution of experiment.toml"), "{out}");
    let (header, rows) = read_csv(&dir.path().join("w.csv"));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let rk4: Vec<&Vec<String>> = rows.iter().filter(|r| r[0] == "rk4").collect();
    let value = |r: &Vec<String>, name: &str| r[col(name)].parse::<f64>().unwrap();
    let ratio = value(rk4[0], "max_relative_error") / value(rk4[1], "max_relative_error");
    assert!((13.0..19.0).contains(&ratio), "RK4 halving ratio {ratio}");
    for r in &rk4 {
        assert_eq!(value(r, "n_rhs"), 4.0 * value(r, "n_steps"), "{r:?}");
    }
}

/// The FMI 3.0 FMU `runner build` packed next to the FMI 2.0 one at `fmu2` (target/fmu3).
fn fmi3_of(fmu2: &Path) -> PathBuf {
    fmu2.parent().unwrap().parent().unwrap().join("fmu3").join(fmu2.file_name().unwrap())
}

/// An entry of an FMU archive as text.
fn entry(fmu: &Path, name: &str) -> String {
    let mut zip = zip::ZipArchive::new(std::fs::File::open(fmu).unwrap()).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(&mut zip.by_name(name).unwrap_or_else(|e| panic!("{}: {name}: {e}", fmu.display())), &mut text).unwrap();
    text
}

/// Our FMI 3.0 FMUs ship LS-REF: a manifest of the Reference FMUs' shape naming the result of
/// the default experiment, which `runner simulate --reference-file` and `runner validate` (its
/// shipped-result check) pass in the default tube (rtol 1e-3): quarter_car's from DOP853 at
/// rtol 1e-12, second_order's outputs q, q_dot and u from their closed forms (the solver's
/// counters, also outputs, are left out: they count the reference run's own work). Those columns equal the
/// closed form written here in plain Rust (not through the formulas crate that wrote them) to
/// 1e-14: the CSV holds each f64 exactly (shortest round-trip text), so what remains is the
/// rounding of exp and of the three terms' sum, a few ulps of values of order 1.
#[test]
fn our_fmi3_fmus_ship_their_reference_results() {
    let (quarter_car, second_order) = fmus();
    let dir = tempfile::tempdir().unwrap();
    for fmu in [fmi3_of(quarter_car), fmi3_of(second_order)] {
        let manifest = entry(&fmu, "extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml");
        let id = fmu.file_stem().unwrap().to_str().unwrap();
        assert!(manifest.contains(&format!("<Related type=\"text/csv\" source=\"{id}_out.csv\" role=\"result\"")), "{manifest}");
        assert!(manifest.contains("fmi-ls:fmi-ls-name=\"org.fmi-standard.fmi-ls-ref\""), "{manifest}");
        let err = stderr(&runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--reference-file", "--out", "o.csv"]));
        assert!(err.contains("reference check passed") && err.contains("(the FMU's LS-REF result)"), "{id}: {err}");
        let report = dir.path().join("v.json");
        let o = runner(dir.path(), &["validate", fmu.to_str().unwrap(), "--strict", "--report", report.to_str().unwrap()]);
        let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let findings = json["reports"][0]["findings"].as_array().unwrap();
        assert!(
            findings.iter().any(|f| f["check"] == "reference-result" && f["severity"] == "passed"),
            "{id}: {}",
            String::from_utf8_lossy(&o.stdout)
        );
        assert!(o.status.success(), "{id}: {}", String::from_utf8_lossy(&o.stdout));
    }
    let manifest = entry(&fmi3_of(quarter_car), "extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml");
    assert!(manifest.contains("from DOP853 at rtol 1e-12"), "{manifest}");
    let fmu = fmi3_of(second_order);
    let manifest = entry(&fmu, "extra/org.fmi-standard.fmi-ls-ref/fmi-ls-manifest.xml");
    assert!(manifest.contains("Output of the default experiment, from its closed-form solution"), "{manifest}");
    std::fs::write(dir.path().join("ref.csv"), entry(&fmu, "extra/org.fmi-standard.fmi-ls-ref/second_order_out.csv")).unwrap();
    let (header, rows) = read_csv(&dir.path().join("ref.csv"));
    assert_eq!(header, ["time", "q", "q_dot", "u"], "the outputs, not the solver's counters n_steps and n_rhs");
    let (t, q, q_dot) = (column(&header, &rows, "time"), column(&header, &rows, "q"), column(&header, &rows, "q_dot"));
    assert!(t.len() > 100 && t[0] == 0.0 && *t.last().unwrap() == 10.0, "the default experiment, 0 to 10 s: {} rows", t.len());
    for (k, &t) in t.iter().enumerate() {
        let (e2, e3) = ((-2.0 * t).exp(), (-3.0 * t).exp());
        assert!((q[k] - (7.5 * e2 - 5.5 * e3 - 0.5 * t * e3)).abs() <= 1e-14, "q at t = {t}: {}", q[k]);
        assert!((q_dot[k] - (-15.0 * e2 + 16.0 * e3 + 1.5 * t * e3)).abs() <= 1e-14, "q_dot at t = {t}: {}", q_dot[k]);
    }
}
