//! `runner linearize` against independent references: the Jacobians of the linear models equal
//! the matrices written from their derivations in their references.toml (the formulas crate
//! evaluates them), the pendulum's at any angle its analytic Jacobian, Reference VanDerPol.fmu's
//! (FMI 2.0 and 3.0) the analytic Jacobian of the Van der Pol equation, from its directional
//! derivatives and from differences alike; the quarter car's frequency response equals its
//! closed-form |H(i w)| and the Ex. 4 sweep's steady state; bad input is refused by name; states
//! moved through the importer are linearized where they were moved.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use common::*;
use formulas::References;
use serde_json::Value;

const MODELS: [&str; 4] = ["second_order", "mass_spring_damper", "quarter_car", "pendulum"];

/// The FMI 2.0 and FMI 3.0 FMUs of [`MODELS`], built once per test binary.
fn fmus() -> &'static Vec<PathBuf> {
    static BUILT: OnceLock<Vec<PathBuf>> = OnceLock::new();
    BUILT.get_or_init(|| {
        let here = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut args = vec!["build"];
        args.extend(MODELS);
        let out = ok(runner(here, &args));
        let paths: Vec<PathBuf> = out.lines().map(PathBuf::from).collect();
        assert_eq!(paths.len(), 2 * MODELS.len(), "runner build prints two paths per model: {out}");
        paths
    })
}

/// The model's FMI 2.0 and 3.0 FMUs.
fn both(model: &str) -> Vec<PathBuf> {
    fmus().iter().filter(|p| p.file_stem().is_some_and(|s| s == model)).cloned().collect()
}

fn references(model: &str) -> References {
    References::from_file(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models").join(model).join("references.toml")).unwrap()
}

fn reference_fmu(version: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus").join(version).join("VanDerPol.fmu")
}

/// `runner linearize FMU ARGS... --out DIR/j.json`: the JSON.
fn linearize(fmu: &Path, args: &[&str]) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("j.json");
    let mut all = vec!["linearize", fmu.to_str().unwrap(), "--out", json.to_str().unwrap()];
    all.extend(args);
    ok(runner(dir.path(), &all));
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

fn matrix(j: &Value, name: &str) -> Vec<Vec<f64>> {
    j[name].as_array().unwrap().iter().map(|row| row.as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect()).collect()
}

fn names(j: &Value, key: &str) -> Vec<String> {
    j[key].as_array().unwrap().iter().map(|v| v.as_str().unwrap().to_owned()).collect()
}

/// Element by element, |got - want| <= tol * (1 + |want|).
fn assert_close(what: &str, got: &[Vec<f64>], want: &[Vec<f64>], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: rows {got:?} against {want:?}");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert_eq!(g.len(), w.len(), "{what}: row {i}");
        for (k, (a, b)) in g.iter().zip(w).enumerate() {
            assert!((a - b).abs() <= tol * (1.0 + b.abs()), "{what}[{i}][{k}] = {a}, expected {b}\n{got:?}\n{want:?}");
        }
    }
}

/// Exact directional derivatives of linear equations are the coefficients up to rounding in
/// the products (a few ulp): 1e-13 relative.
const ROUNDING: f64 = 1e-13;

/// second_order at non-default coefficients: A from references.toml, the source directional
/// derivatives, and the eigenvalues those of a2 s^2 + a1 s + a0 (its handbook ODE; 2 s^2 + 10 s
/// + 12 has -3 and -2).
#[test]
fn second_order_is_its_handbook_ode() {
    for fmu in both("second_order") {
        for (a2, a1, a0) in [(2.0, 10.0, 12.0), (1.5, 7.0, 3.0)] {
            let sets = [format!("a2={a2}"), format!("a1={a1}"), format!("a0={a0}")];
            let j = linearize(&fmu, &["--set", &sets[0], "--set", &sets[1], "--set", &sets[2]]);
            assert_eq!(j["source"], "directional derivatives");
            assert_eq!(names(&j, "states"), ["q", "q_dot"]);
            let p = [("a2", a2), ("a1", a1), ("a0", a0)];
            let r = references("second_order");
            assert_close("A", &matrix(&j, "A"), &r.matrix("A", &p).unwrap(), ROUNDING);
            let eig = j["eigenvalues"].as_array().unwrap();
            let re: Vec<f64> = eig.iter().map(|e| e["re"].as_f64().unwrap()).collect();
            assert!(eig.iter().all(|e| e["im"].as_f64().unwrap() == 0.0), "real roots: {eig:?}");
            // Ordered by modulus: the slow root first.
            let want = [r.value("s_slow", &p).unwrap(), r.value("s_fast", &p).unwrap()];
            assert_close("eigenvalues", &[re], &[want.to_vec()], 1e-12);
        }
        let j = linearize(&fmu, &[]);
        let e: Vec<f64> = j["eigenvalues"].as_array().unwrap().iter().map(|e| e["re"].as_f64().unwrap()).collect();
        assert!((e[0] + 2.0).abs() < 1e-12 && (e[1] + 3.0).abs() < 1e-12, "the handbook's roots -2 and -3: {e:?}");
    }
}

/// mass_spring_damper: A, B, and the rows of C and D of its outputs a and F_total equal
/// references.toml's (App. B); the states' own outputs are unit rows.
#[test]
fn mass_spring_damper_matrices_are_its_derivation() {
    for fmu in both("mass_spring_damper") {
        let j = linearize(&fmu, &["--set", "m=3", "--set", "b=0.7", "--set", "k=40"]);
        assert_eq!(j["source"], "directional derivatives");
        assert_eq!(names(&j, "states"), ["x", "v"]);
        assert_eq!(names(&j, "inputs"), ["F"]);
        let p = [("m", 3.0), ("b", 0.7), ("k", 40.0)];
        let r = references("mass_spring_damper");
        assert_close("A", &matrix(&j, "A"), &r.matrix("A", &p).unwrap(), ROUNDING);
        assert_close("B", &matrix(&j, "B"), &r.matrix("B", &p).unwrap(), ROUNDING);
        let outputs = names(&j, "outputs");
        let (c, d) = (matrix(&j, "C"), matrix(&j, "D"));
        let rows = |m: &[Vec<f64>], of: &[&str]| -> Vec<Vec<f64>> {
            of.iter().map(|n| m[outputs.iter().position(|o| o == n).unwrap_or_else(|| panic!("no output {n}"))].clone()).collect()
        };
        assert_close("C", &rows(&c, &["a", "F_total"]), &r.matrix("C", &p).unwrap(), ROUNDING);
        assert_close("D", &rows(&d, &["a", "F_total"]), &r.matrix("D", &p).unwrap(), ROUNDING);
        assert_close("C of the states", &rows(&c, &["x", "v"]), &[vec![1.0, 0.0], vec![0.0, 1.0]], 0.0);
        // Differences of a linear model agree to their rounding, about eps / h ~ 4e-11.
        let fd = linearize(&fmu, &["--set", "m=3", "--set", "b=0.7", "--set", "k=40", "--finite-differences"]);
        assert_eq!(fd["source"], "finite differences");
        for name in ["A", "B", "C", "D"] {
            assert_close(name, &matrix(&fd, name), &matrix(&j, name), 1e-8);
        }
    }
}

/// quarter_car: A and B are the car's block of references.toml's road_system (its states
/// z_s, z_u, z_r, z_s', z_u' first; the constant external rate c there is the input
/// z_r_dot_ext here).
#[test]
fn quarter_car_matrices_are_its_derivation() {
    for fmu in both("quarter_car") {
        let j = linearize(&fmu, &["--set", "b_s=900", "--set", "k_t=150000"]);
        assert_eq!(j["source"], "directional derivatives");
        assert_eq!(names(&j, "states"), ["z_s", "z_u", "z_r", "z_s_dot", "z_u_dot"]);
        assert_eq!(names(&j, "inputs"), ["z_r_dot_ext"]);
        let p = [
            ("m_s", 200.0),
            ("m_u", 30.0),
            ("k_s", 18000.0),
            ("b_s", 900.0),
            ("k_t", 150000.0),
            ("b_t", 10.0),
            ("speed", 30.0),
            ("road_wavelength", 3.0),
        ];
        let road = references("quarter_car").matrix("road_system", &p).unwrap();
        let a: Vec<Vec<f64>> = road[..5].iter().map(|row| row[..5].to_vec()).collect();
        let b: Vec<Vec<f64>> = road[..5].iter().map(|row| vec![row[7]]).collect();
        assert_close("A", &matrix(&j, "A"), &a, ROUNDING);
        assert_close("B", &matrix(&j, "B"), &b, ROUNDING);
    }
}

/// The pendulum at 0, 50 and 170 degrees, with friction: its Jacobian is references.toml's
/// analytic one at that angle; without friction at rest its one mode is undamped at
/// sqrt(g/L).
#[test]
fn pendulum_jacobian_at_any_angle_and_its_small_angle_frequency() {
    for fmu in both("pendulum") {
        let r = references("pendulum");
        for degrees in [0.0f64, 50.0, 170.0] {
            let theta = degrees.to_radians();
            let sets = [format!("theta0={theta}"), "c=0.03".to_owned(), "L=1.2".to_owned()];
            let j = linearize(&fmu, &["--set", &sets[0], "--set", &sets[1], "--set", &sets[2]]);
            assert_eq!(names(&j, "states"), ["theta", "omega"]);
            let p = [("g", 9.81), ("L", 1.2), ("m", 0.5), ("c", 0.03), ("theta", theta)];
            assert_close(&format!("jacobian at {degrees} deg"), &matrix(&j, "A"), &r.matrix("jacobian", &p).unwrap(), ROUNDING);
        }
        let j = linearize(&fmu, &["--set", "theta0=0", "--set", "c=0"]);
        let modes = j["modes"].as_array().unwrap();
        assert_eq!(modes.len(), 1, "{modes:?}");
        let wn = r.value("omega_small_angle", &[("g", 9.81), ("L", 0.75)]).unwrap();
        assert!((modes[0]["natural_frequency"].as_f64().unwrap() / wn - 1.0).abs() < 1e-12, "{modes:?} against {wn}");
        assert!(modes[0]["damping_ratio"].as_f64().unwrap().abs() < 1e-12, "{modes:?}");
    }
}

/// d/dx of (x1, mu (1 - x0^2) x1 - x0): the Van der Pol equation's Jacobian, by hand.
fn van_der_pol_jacobian(mu: f64, x0: f64, x1: f64) -> Vec<Vec<f64>> {
    vec![vec![0.0, 1.0], vec![-2.0 * mu * x0 * x1 - 1.0, mu * (1.0 - x0 * x0)]]
}

/// Reference VanDerPol.fmu (FMI 2.0 and 3.0) declares directional derivatives: at its start
/// (x = (2, 0)) and at t = 1.3 of a run with mu = 2.5, A from them equals the analytic
/// Jacobian at the states reached, and so does A from central differences, within their error
/// (eps^(2/3) ~ 4e-11 relative per element, times the curvature: 1e-8 covers it).
#[test]
fn reference_van_der_pol_from_directional_derivatives_and_differences() {
    for version in ["fmi2", "fmi3"] {
        let fmu = reference_fmu(version);
        for args in [vec![], vec!["--set", "mu=2.5", "--at", "1.3"]] {
            let mu = if args.is_empty() { 1.0 } else { 2.5 };
            let exact = linearize(&fmu, &args);
            assert_eq!(exact["source"], "directional derivatives", "{version}");
            let x: Vec<f64> = exact["x"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
            if args.is_empty() {
                assert_eq!(x, [2.0, 0.0]);
            } else {
                assert!(exact["time"].as_f64().unwrap() == 1.3 && x != [2.0, 0.0], "{exact}");
            }
            let analytic = van_der_pol_jacobian(mu, x[0], x[1]);
            assert_close(&format!("{version} A"), &matrix(&exact, "A"), &analytic, ROUNDING);
            let mut fd_args = args.clone();
            fd_args.push("--finite-differences");
            let fd = linearize(&fmu, &fd_args);
            assert_eq!(fd["source"], "finite differences");
            assert_close(&format!("{version} A by differences"), &matrix(&fd, "A"), &analytic, 1e-8);
            // The outputs x0 and x1 are the states.
            assert_close("C", &matrix(&exact, "C"), &[vec![1.0, 0.0], vec![0.0, 1.0]], 0.0);
        }
    }
}

/// Ex. 4: |Z_s/Z_r|(i w) from `--bode` at the sweep's speeds (w = 2 pi speed / 3: the
/// frequencies speed / 3 Hz), as the ratio of the responses to the road rate z_r_dot_ext of
/// z_s and of z_r (Z_s/Z_r = (Z_s/U)/(Z_r/U)). Against the closed form of references.toml to
/// rounding (1e-9), and against simulations: the `steady_state` column of the Ex. 4 sweep
/// (experiment.toml: the amplitudes of z_s and z_r at w fitted to the 1 ms samples of the last
/// 5 s of 10 s runs, rtol 1e-9) within 1e-6, as issue 34 asks. The fit is exact for a
/// sinusoid, so what is left is the start-up transient: its slowest mode, exp(-2.574 t), is
/// down to 2.6e-6 of its start at t = 5 (measured: 1.8e-7 at most, at 5 m/s, next to the
/// body's resonance). Run to 20 s and fitted from 10 s on, where that mode is at 7e-12, only
/// the integrator's error at rtol 1e-9 remains: within 2e-8 (measured 2.5e-9). The sampled
/// maxima the column had before, max(z_s, 5)/max(z_r, 5), are off by up to 6.5e-4 (at 50 m/s:
/// each is low by up to 1 - cos(w h / 2)), which 1e-6 would have needed samples every 30 us
/// to reach.
#[test]
fn quarter_car_bode_is_the_ex4_frequency_response() {
    let fmu = &both("quarter_car")[0];
    let dir = tempfile::tempdir().unwrap();
    let speeds: Vec<f64> = (0..99).map(|i| 1.0 + 0.5 * i as f64).collect();
    let hz: Vec<String> = speeds.iter().map(|s| format!("{:?}", s / 3.0)).collect();
    let hz = hz.join(",");
    let q = fmu.to_str().unwrap();
    let args = [
        "linearize",
        q,
        "--bode",
        "z_r_dot_ext:z_s",
        "--bode",
        "z_r_dot_ext:z_r",
        "--frequencies",
        &hz,
        "--bode-out",
        "bode.csv",
        "--plot",
        "bode.svg",
    ];
    ok(runner(dir.path(), &args));
    assert!(std::fs::read_to_string(dir.path().join("bode.svg")).unwrap().starts_with("<svg"));
    let bode = read_csv(&dir.path().join("bode.csv"));
    assert_eq!(
        bode.0,
        [
            "frequency_hz",
            "omega_rad_s",
            "magnitude(z_s/z_r_dot_ext)",
            "phase_deg(z_s/z_r_dot_ext)",
            "magnitude(z_r/z_r_dot_ext)",
            "phase_deg(z_r/z_r_dot_ext)"
        ]
    );
    // The Ex. 4 sweep's metric, as experiment.toml gives it, and the same from 10 s of 20.
    let steady = "steady_state=amplitude(z_s, 5, 2*pi*speed/road_wavelength)/amplitude(z_r, 5, 2*pi*speed/road_wavelength)";
    let experiment =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/quarter_car/experiment.toml")).unwrap();
    assert!(experiment.contains(&format!("\"{steady}\"")), "experiment.toml's steady_state is the one checked here");
    let settled = "settled=amplitude(z_s, 10, 2*pi*speed/road_wavelength)/amplitude(z_r, 10, 2*pi*speed/road_wavelength)";
    let sweep = |metric: &str, stop: &str, out: &str| {
        let args = ["sweep", q, "--param", "speed=1:50:0.5", "--metric", metric, "--tolerance", "1e-9", "--output-interval", "1e-3"];
        ok(runner(dir.path(), &[&args[..], &["--stop-time", stop, "--out", out]].concat()));
        read_csv(&dir.path().join(out))
    };
    let ex4 = sweep(steady, "10", "ex4.csv");
    let long = sweep(settled, "20", "long.csv");
    let r = references("quarter_car");
    let (mut worst_ex4, mut worst_long) = (0.0f64, 0.0f64);
    for (k, speed) in speeds.iter().enumerate() {
        let row = &bode.1[k];
        let h = row[2] / row[4];
        let p = [
            ("m_s", 200.0),
            ("m_u", 30.0),
            ("k_s", 18000.0),
            ("b_s", 1300.0),
            ("k_t", 125000.0),
            ("b_t", 10.0),
            ("speed", *speed),
            ("road_wavelength", 3.0),
        ];
        let closed = r.value("transmissibility", &p).unwrap();
        assert!((h / closed - 1.0).abs() < 1e-9, "speed {speed}: |H| {h} against the closed form {closed}");
        assert_eq!((ex4.1[k][0], long.1[k][0]), (*speed, *speed));
        let (e, l) = ((h / ex4.1[k][1] - 1.0).abs(), (h / long.1[k][1] - 1.0).abs());
        assert!(e < 1e-6, "speed {speed}: |H| {h} against the Ex. 4 sweep's steady state {} ({e:e} relative)", ex4.1[k][1]);
        assert!(l < 2e-8, "speed {speed}: |H| {h} against the 20 s runs' {} ({l:e} relative)", long.1[k][1]);
        (worst_ex4, worst_long) = (worst_ex4.max(e), worst_long.max(l));
    }
    eprintln!("|H| against the sweeps, largest relative difference: Ex. 4 {worst_ex4:e}, 20 s {worst_long:e}");
    // The frequency's names are checked before the first run, and its value at each point.
    let err = fails(runner(dir.path(), &["sweep", q, "--param", "speed=1", "--metric", "a=amplitude(z_s, 5, 2*pi*speed/wavelength)"]));
    assert!(err.contains("amplitude's frequency 2*pi*speed/wavelength") && err.contains("'wavelength'"), "{err}");
    let args = ["sweep", q, "--param", "speed=0,1", "--metric", "a=amplitude(z_s, 5, 2*pi*speed/road_wavelength)", "--stop-time", "6"];
    let err = fails(runner(dir.path(), &[&args[..], &["--out", "zero.csv"]].concat()));
    assert!(err.contains("1 of 2 sweep point(s) failed"), "{err}");
    let rows = std::fs::read_to_string(dir.path().join("zero.csv")).unwrap();
    assert!(rows.contains("amplitude's frequency 2*pi*speed/road_wavelength is 0 rad/s here; it must be a positive number"), "{rows}");
}

/// A sweep's metrics of modes: mass_spring_damper's damping ratio b / (2 sqrt(k m)) and natural
/// frequency sqrt(k/m) against b (the textbook second-order system), with its default k and m;
/// no simulation is needed, none is run. A mode number past the model's modes fails the point
/// saying so, and Co-Simulation is refused.
#[test]
fn sweeps_take_a_modes_damping_as_a_function_of_a_parameter() {
    let fmu = &both("mass_spring_damper")[1];
    let dir = tempfile::tempdir().unwrap();
    let q = fmu.to_str().unwrap();
    let metrics = ["--metric", "zeta=damping(1)", "--metric", "wn=natural_frequency(1)"];
    let mut args = vec!["sweep", q, "--param", "b=0:400:100", "--out", "s.csv"];
    args.extend(metrics);
    ok(runner(dir.path(), &args));
    let (header, rows) = read_csv(&dir.path().join("s.csv"));
    assert_eq!(header, ["b", "zeta", "wn", "status"]);
    let (k, m): (f64, f64) = (1751.2683524647637, 350.2536704929527);
    for row in &rows {
        let zeta = row[0] / (2.0 * (k * m).sqrt());
        assert!((row[1] - zeta).abs() < 1e-13, "b = {}: damping {} against {zeta}", row[0], row[1]);
        assert!((row[2] / (k / m).sqrt() - 1.0).abs() < 1e-13, "b = {}: wn {}", row[0], row[2]);
    }
    assert_eq!(rows.len(), 5);
    let err = fails(runner(dir.path(), &["sweep", q, "--param", "b=1,2", "--metric", "z=damping(2)", "--out", "t.csv"]));
    assert!(err.contains("2 of 2 sweep point(s) failed"), "{err}");
    let status = std::fs::read_to_string(dir.path().join("t.csv")).unwrap();
    assert!(status.contains("the metrics read mode 2, and the model linearized at its initial state has 1 mode(s)"), "{status}");
    let err = fails(runner(dir.path(), &["sweep", q, "--param", "b=1,2", "--metric", "z=damping(1)", "--interface", "co-simulation"]));
    assert!(err.contains("drop --interface co-simulation"), "{err}");
}

/// The header and the numeric rows of a CSV (a `status` column dropped).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().unwrap().split(',').map(str::to_owned).collect();
    let rows = lines.map(|l| l.split(',').filter_map(|v| v.parse::<f64>().ok()).collect()).collect();
    (header, rows)
}

/// Unknown names in --bode, an input given as output, an FMU without Model Exchange and a time
/// past the stop time are refused, each saying what is wrong.
#[test]
fn bad_input_is_refused_by_name() {
    let fmu = &both("mass_spring_damper")[0];
    let dir = tempfile::tempdir().unwrap();
    let q = fmu.to_str().unwrap();
    let err = fails(runner(dir.path(), &["linearize", q, "--bode", "G:a"]));
    assert!(err.contains("--bode G:a") && err.contains("'G'"), "{err}");
    let err = fails(runner(dir.path(), &["linearize", q, "--bode", "F:zz"]));
    assert!(err.contains("'zz'"), "{err}");
    let err = fails(runner(dir.path(), &["linearize", q, "--bode", "a:F"]));
    assert!(err.contains("'a' is not a continuous Real input"), "{err}");
    let err = fails(runner(dir.path(), &["linearize", q, "--bode", "F"]));
    assert!(err.contains("INPUT:OUTPUT"), "{err}");
    let err = fails(runner(dir.path(), &["linearize", q, "--at", "1e6"]));
    assert!(err.contains("--at 1000000: beyond the stop time"), "{err}");
    let err = fails(runner(dir.path(), &["linearize", q, "--plot", "x.svg"]));
    assert!(err.contains("give --bode INPUT:OUTPUT too"), "{err}");
    // The C test FMU offers Co-Simulation only.
    let cs = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let err = fails(runner(dir.path(), &["linearize", cs.to_str().unwrap()]));
    assert!(err.contains("runner linearize needs Model Exchange") && err.contains("Co-Simulation only"), "{err}");
}

/// A third-party FMU that crashes while it is linearized (tests/c_fmu/me_faults.c, fault 6: a
/// NULL dereference in fmi2GetDerivatives from t_fault on) costs only the worker process it
/// runs in: the runner fails naming the FMU, the signal and the FMI call, at the initial state
/// and in the simulation to --at alike. Without the fault it linearizes to x' = -k x, in a
/// worker and in this process (--in-process) to the same bits.
#[test]
fn a_crashing_fmu_fails_the_linearization_not_the_runner() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = me_faults_fmu(dir.path(), "me_faults.fmu", str::to_owned);
    let f = fmu.to_str().unwrap();
    let o = runner(dir.path(), &["linearize", f, "--set", "fault=6", "--set", "t_fault=0", "--out", "crash.json"]);
    assert_eq!(o.status.code(), Some(1), "an error, not a signal: {}", stderr(&o));
    assert!(stderr(&o).contains("me_faults: crashed: SIGSEGV in fmi2GetDerivatives at t = 0"), "{}", stderr(&o));
    assert!(!dir.path().join("crash.json").exists());
    let o = runner(dir.path(), &["linearize", f, "--set", "fault=6", "--at", "2"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("me_faults: crashed: SIGSEGV in fmi2GetDerivatives at t = 1"), "{}", stderr(&o));
    let worker = linearize(&fmu, &["--set", "k=2.5", "--at", "1.5"]);
    let in_process = linearize(&fmu, &["--set", "k=2.5", "--at", "1.5", "--in-process"]);
    assert_eq!(worker, in_process, "the same code on the same FMU: the same JSON");
    assert_eq!(worker["source"], "finite differences", "me_faults declares no directional derivatives");
    // Central differences of the linear -k x: exact but for rounding of the step.
    assert!((matrix(&worker, "A")[0][0] + 2.5).abs() < 1e-7, "{}", worker["A"]);
    let err = fails(runner(dir.path(), &["linearize", f, "--timeout", "1", "--in-process"]));
    assert!(err.contains("--timeout needs a worker process"), "{err}");
}

/// `runner linearize ... | head -1`: the files are written before the summary is printed, and
/// a reader that has closed stdout before the runner writes to it (here: before it starts) is
/// not an error and costs no file.
#[test]
fn a_closed_stdout_costs_no_file() {
    let fmu = &both("quarter_car")[0];
    let dir = tempfile::tempdir().unwrap();
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
        .current_dir(dir.path())
        .args(["linearize", fmu.to_str().unwrap(), "--out", "q.json", "--bode", "z_r_dot_ext:z_s", "--plot", "q.svg"])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .unwrap();
    assert!(o.status.success(), "{:?}: {}", o.status, stderr(&o));
    assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    let json: Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("q.json")).unwrap()).unwrap();
    assert_eq!(names(&json, "states").len(), 5);
    assert!(std::fs::read_to_string(dir.path().join("quarter_car_bode.csv")).unwrap().starts_with("frequency_hz,omega_rad_s,"));
    assert!(std::fs::read_to_string(dir.path().join("q.svg")).unwrap().starts_with("<svg"));
}

/// The importer's `move_states`: the next linearization is at the moved states (a new point,
/// as an implicit solver moves them), so the FMU's directional derivatives there agree with
/// central differences there (both through the FMU; the differences err by about 1e-10
/// relative, the tolerance is 1e-7) and differ from those at the start (the pendulum's
/// d omega'/d theta is -g/L cos theta, which a radian moves by more than 0.1); a wrong number
/// of values is refused by name.
#[test]
fn moved_states_are_linearized_where_they_were_moved() {
    use fmi_importer::exchange::{JacobianSource, Ports};
    for path in both("pendulum") {
        let fmu = fmi_importer::Fmu::load_as(&path, Some(fmi_importer::Interface::ModelExchange)).unwrap();
        let mut instance = fmu.instantiate("moved", false).unwrap();
        instance.setup_experiment(None, 0.0, 1.0).unwrap();
        instance.enter_initialization_mode().unwrap();
        instance.exit_initialization_mode().unwrap();
        let mut reader = fmi_importer::Reader::new(fmu.description.fmi_version, &[]).unwrap();
        let mut jacobian = |instance: &mut fmi_importer::Instance, source| {
            let ports = Ports { inputs: &[], input_values: &[], outputs: &[], reader: &mut reader };
            instance.linearize(ports, source).unwrap()
        };
        let start = jacobian(&mut instance, JacobianSource::DirectionalDerivatives);
        let moved: Vec<f64> = start.x.iter().map(|x| x + 1.0).collect();
        instance.move_states(&moved).unwrap();
        let exact = jacobian(&mut instance, JacobianSource::DirectionalDerivatives);
        let differences = jacobian(&mut instance, JacobianSource::FiniteDifferences);
        assert_eq!((exact.x.as_slice(), differences.x.as_slice()), (moved.as_slice(), moved.as_slice()), "{path:?}");
        for (e, d) in exact.a.to_rows().iter().flatten().zip(differences.a.to_rows().iter().flatten()) {
            assert!((e - d).abs() <= 1e-7 * (1.0 + e.abs()), "{path:?}: {:?} against differences {:?}", exact.a, differences.a);
        }
        assert!((exact.a[1][0] - start.a[1][0]).abs() > 0.1, "{path:?}: {:?} at the start, {:?} moved", start.a, exact.a);
        let err = instance.move_states(&[1.0]).unwrap_err();
        assert!(err.contains("1 state values for 2 continuous states"), "{err}");
    }
}
