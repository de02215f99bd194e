//! FMI 1.0 import end to end: the C FMI 1.0 test FMUs (tests/c_fmu/fmi1_linear.c, a damped
//! oscillator with a step input at a time event, and fmi1_bouncing.c, a bouncing ball with state
//! events), each compiled here as Co-Simulation and as Model Exchange, through `info`,
//! `simulate`, `sweep`, `compare` and `validate`, checked against their closed forms; and the
//! refusals of bad FMI 1.0 input. The comparison with fmpy's run of the same FMUs is
//! tests/fmpy/test_fmi1_import.py.

mod common;

use std::path::{Path, PathBuf};

use common::*;

const G: f64 = 9.81;

/// x1 of x1'' + c x1' + k x1 = u(t), x1(0) = 1, x1'(0) = 0, u stepping from 0 to 1 at t = 2 s
/// (the description's c = 0.4, t_switch = 2; underdamped for k > 0.04).
fn oscillator(t: f64, k: f64) -> f64 {
    let (a, wd) = (0.2, (k - 0.04).sqrt());
    let free = |s: f64| (-a * s).exp() * ((wd * s).cos() + a / wd * (wd * s).sin());
    free(t) + if t >= 2.0 { (1.0 - free(t - 2.0)) / k } else { 0.0 }
}

/// The ball dropped from 1 m with restitution `e`: (h, v, bounces so far) at `t`.
fn ball(t: f64, e: f64) -> (f64, f64, usize) {
    let (mut tb, mut vb, mut n) = ((2.0 / G).sqrt(), (2.0 * G).sqrt() * e, 0);
    if t < tb {
        return (1.0 - G / 2.0 * t * t, -G * t, 0);
    }
    // The bounces accumulate (Zeno) at 2.56 s for e = 0.7: the tests stop before.
    while tb + 2.0 * vb / G <= t {
        (tb, vb, n) = (tb + 2.0 * vb / G, vb * e, n + 1);
    }
    let s = t - tb;
    (vb * s - G / 2.0 * s * s, vb - G * s, n + 1)
}

fn build(dir: &Path, model: &str, co_simulation: bool) -> PathBuf {
    let file = format!("{model}_{}.fmu", if co_simulation { "cs" } else { "me" });
    fmi1_fmu(dir, &file, model, co_simulation, str::to_owned)
}

/// `info` reads the FMI 1.0 description: its one interface and the variables with FMI 1.0's
/// causality and variability in the words of the others (a `parameter` is a fixed parameter).
#[test]
fn info_describes_both_interfaces() {
    let dir = tempfile::tempdir().unwrap();
    let me = ok(runner(dir.path(), &["info", build(dir.path(), "bouncing", false).to_str().unwrap()]));
    assert!(me.contains("FMI version  1.0") && me.contains("Co-Simulation: not offered"), "{me}");
    assert!(me.contains("Model Exchange: modelIdentifier fmi1_bouncing (2 continuous states, 1 event indicators"), "{me}");
    let g = me.lines().find(|l| l.starts_with("g ")).unwrap();
    assert!(g.contains("parameter") && g.contains("fixed") && g.contains("9.81"), "{g}");
    let bounces = me.lines().find(|l| l.starts_with("bounces ")).unwrap();
    assert!(bounces.contains("output") && bounces.contains("discrete") && bounces.contains("Integer"), "{bounces}");
    let cs = ok(runner(dir.path(), &["info", build(dir.path(), "linear", true).to_str().unwrap()]));
    assert!(cs.contains("Co-Simulation: modelIdentifier fmi1_linear") && cs.contains("Model Exchange: not offered"), "{cs}");
}

/// Both interfaces of both models against the closed forms, on the 0.01 s grid. Co-Simulation:
/// the FMU's own RK4 (sub-steps of 5e-4 s) with bisection for the bounces to 1e-12 s, measured
/// within 1e-10 of the closed forms: 1e-9 allowed. Model Exchange: the runner's DOPRI5 at the
/// description's rtol 1e-6, measured 6.7e-7 off on the oscillator (1e-5 allowed); the ball's
/// parabolas are exact for DOPRI5 and only the located bounces move it (4.4e-9 measured, 1e-6
/// allowed). The Integer and Boolean outputs (fmiGetInteger, fmiGetBoolean of a C char) count
/// exactly; the time event at 2 s must be taken (missed, y(5) would be -0.34, not -0.21).
#[test]
fn simulate_matches_the_closed_forms() {
    let dir = tempfile::tempdir().unwrap();
    for co_simulation in [true, false] {
        let bound = if co_simulation { 1e-9 } else { 1e-5 };
        let fmu = build(dir.path(), "linear", co_simulation);
        ok(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--output-interval", "0.01", "--out", "linear.csv"]));
        let (header, rows) = read_csv(&dir.path().join("linear.csv"));
        assert_eq!(header, ["time", "y"]);
        assert_eq!(rows.len(), 501);
        let (t, y) = (column(&header, &rows, "time"), column(&header, &rows, "y"));
        for (t, y) in t.iter().zip(&y) {
            assert!((y - oscillator(*t, 4.0)).abs() < bound, "co-simulation {co_simulation}: y({t}) = {y}, exact {}", oscillator(*t, 4.0));
        }

        let bound = if co_simulation { 1e-9 } else { 1e-6 };
        let fmu = build(dir.path(), "bouncing", co_simulation);
        ok(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--output-interval", "0.01", "--out", "ball.csv"]));
        let (header, rows) = read_csv(&dir.path().join("ball.csv"));
        assert_eq!(header, ["time", "h", "v", "bounces", "bounced"]);
        let numbers: Vec<Vec<f64>> = rows.iter().map(|row| row.iter().map(|x| x.parse().unwrap()).collect()).collect();
        for row in &numbers {
            let (t, h, v, n, bounced) = (row[0], row[1], row[2], row[3], row[4]);
            let (he, ve, ne) = ball(t, 0.7);
            assert!(
                (h - he).abs() < bound && (v - ve).abs() < bound,
                "co-simulation {co_simulation}: t = {t}: h {h} v {v}, exact {he} {ve}"
            );
            assert_eq!((n, bounced), (ne as f64, (ne > 0) as u8 as f64), "t = {t}");
        }
        assert_eq!(numbers.last().unwrap()[3], 4.0, "four bounces in 2 s");
    }
}

/// A sweep runs FMI 1.0 FMUs in its worker processes: the bounces in 2 s for three
/// restitutions (the closed form's counts, 4, 3 and 3: e = 0.9's third bounce is at 1.996 s),
/// through both interfaces, and the oscillator's end value for two stiffnesses (Co-Simulation,
/// its RK4 within 1e-9).
#[test]
fn sweep_counts_the_bounces_and_moves_the_oscillator() {
    let dir = tempfile::tempdir().unwrap();
    let expected: Vec<f64> = [0.7, 0.8, 0.9].iter().map(|&e| ball(2.0, e).2 as f64).collect();
    assert_eq!(expected, [4.0, 3.0, 3.0]);
    for co_simulation in [true, false] {
        let fmu = build(dir.path(), "bouncing", co_simulation);
        let args = ["sweep", fmu.to_str().unwrap(), "--param", "e=0.7,0.8,0.9", "--metric", "n=final(bounces)", "--out", "sweep.csv"];
        ok(runner(dir.path(), &args));
        let (header, rows) = read_csv(&dir.path().join("sweep.csv"));
        assert_eq!(column(&header, &rows, "n"), expected, "co-simulation {co_simulation}");
    }
    let fmu = build(dir.path(), "linear", true);
    ok(runner(dir.path(), &["sweep", fmu.to_str().unwrap(), "--param", "k=1,4", "--metric", "end=final(y)", "--out", "k.csv"]));
    let (header, rows) = read_csv(&dir.path().join("k.csv"));
    for (k, end) in column(&header, &rows, "k").iter().zip(column(&header, &rows, "end")) {
        assert!((end - oscillator(5.0, *k)).abs() < 1e-9, "k = {k}: y(5) = {end}, exact {}", oscillator(5.0, *k));
    }
}

/// `compare` integrates an FMI 1.0 Model Exchange FMU with the runner's methods: RK4 at a
/// 0.01 s step is within 1e-6 of the DOP853 reference on the oscillator (RK4's error at that
/// step is of order h^4 = 1e-8).
#[test]
fn compare_runs_the_methods_on_fmi1_model_exchange() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = build(dir.path(), "linear", false);
    let args = ["compare", fmu.to_str().unwrap(), "--interface", "model-exchange", "--solvers", "rk4,dopri5", "--target-error", "1e-6"];
    let out = ok(runner(dir.path(), &args));
    let rk4 = out.lines().find(|l| l.starts_with("rk4 ")).unwrap_or_else(|| panic!("{out}"));
    let error: f64 = rk4.split_whitespace().last().unwrap().parse().unwrap();
    assert!(error < 1e-6, "{rk4}");
}

/// FMI 1.0 components in an SSP system: the oscillator (Co-Simulation) feeding the Reference
/// FMU Feedthrough (FMI 2.0), beside the ball (Model Exchange). Each FMI 1.0 component gives the
/// same bits as its run alone, and under the default Jacobi master Feedthrough's output is the
/// oscillator's output of the step before.
#[test]
fn fmi1_components_run_in_systems() {
    let feedthrough = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi2/Feedthrough.fmu");
    if !feedthrough.is_file() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (linear, bouncing) = (build(d, "linear", true), build(d, "bouncing", false));
    let root = d.join("system");
    std::fs::create_dir_all(root.join("resources")).unwrap();
    for (file, from) in [("lin.fmu", &linear), ("ball.fmu", &bouncing), ("ft.fmu", &feedthrough)] {
        std::fs::copy(from, root.join("resources").join(file)).unwrap();
    }
    let connector = |name: &str, kind: &str| format!(r#"<ssd:Connector name="{name}" kind="{kind}"><ssc:Real/></ssd:Connector>"#);
    let component = |name: &str, connectors: String| {
        format!(
            r#"<ssd:Component name="{name}" source="resources/{name}.fmu"><ssd:Connectors>{connectors}</ssd:Connectors></ssd:Component>"#
        )
    };
    let ssd = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<ssd:SystemStructureDescription xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription"
    xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0" name="fmi1">
<ssd:System name="s"><ssd:Elements>{}{}{}</ssd:Elements><ssd:Connections>
<ssd:Connection startElement="lin" startConnector="y" endElement="ft" endConnector="Float64_continuous_input"/>
</ssd:Connections></ssd:System>
</ssd:SystemStructureDescription>"#,
        component("lin", connector("y", "output")),
        component("ball", connector("h", "output")),
        component("ft", connector("Float64_continuous_input", "input") + &connector("Float64_continuous_output", "output")),
    );
    std::fs::write(root.join("SystemStructure.ssd"), ssd).unwrap();
    let grid = ["--stop-time", "2", "--output-interval", "0.01"];
    let run = |path: &Path, out: &str| {
        let mut args = vec!["simulate", path.to_str().unwrap(), "--out", out];
        args.extend(grid);
        ok(runner(d, &args));
        read_csv(&d.join(out))
    };
    let (header, rows) = run(&root, "system.csv");
    let (lin_header, lin_rows) = run(&linear, "lin.csv");
    let (ball_header, ball_rows) = run(&bouncing, "ball.csv");
    assert_eq!(column(&header, &rows, "lin.y"), column(&lin_header, &lin_rows, "y"));
    assert_eq!(column(&header, &rows, "ball.h"), column(&ball_header, &ball_rows, "h"));
    let (y, fed) = (column(&header, &rows, "lin.y"), column(&header, &rows, "ft.Float64_continuous_output"));
    assert_eq!(fed[1..], y[..y.len() - 1]);
}

/// Bad FMI 1.0 input is refused with a message naming the problem.
#[test]
fn bad_fmi1_input_gets_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let simulate = |fmu: &Path, extra: &[&str]| {
        let mut args = vec!["simulate", fmu.to_str().unwrap(), "--out", "x.csv"];
        args.extend(extra);
        fails(runner(d, &args))
    };
    // A description read with errors: the variable and the attribute named.
    let fmu = fmi1_fmu(d, "causality.fmu", "bouncing", false, |x| x.replacen(r#"causality="output""#, r#"causality="sideways""#, 1));
    let err = simulate(&fmu, &[]);
    assert!(err.contains("variable 'h'") && err.contains("'sideways' is not a valid FMI 1.0 causality"), "{err}");
    // The binary's functions carry another prefix than the modelIdentifier.
    fmi1_fmu(d, "prefix.fmu", "linear", false, str::to_owned);
    let binary = std::fs::read(d.join("prefix.fmu.so")).unwrap();
    let xml = std::fs::read_to_string(c_fmu_dir().join("fmi1_linear.xml"))
        .unwrap()
        .replace(r#"modelIdentifier="fmi1_linear""#, r#"modelIdentifier="other""#);
    let fmu = d.join("other.fmu");
    write_zip(&fmu, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/other.so", &binary)]);
    let err = simulate(&fmu, &[]);
    assert!(err.contains("does not export the function other_fmiGetVersion (FMI 1.0 requires it of a Model Exchange FMU)"), "{err}");
    // The FMU refuses a GUID not its own; the reason it logs (through the FMI 1.0 logger, with
    // no instance yet) is in the error.
    let fmu = fmi1_fmu(d, "guid.fmu", "linear", false, |x| x.replace("fmi1linear01", "fmi1linear99"));
    let err = simulate(&fmu, &[]);
    assert!(err.contains("fmiInstantiateModel returned NULL: wrong GUID"), "{err}");
    // A slave that wraps a tool, and an interface the FMU does not offer.
    let fmu = fmi1_fmu(d, "tool.fmu", "linear", true, |x| x.replace("CoSimulation_StandAlone", "CoSimulation_Tool"));
    assert!(simulate(&fmu, &[]).contains("wraps a simulation tool (CoSimulation_Tool)"));
    let fmu = build(d, "linear", false);
    let err = simulate(&fmu, &["--interface", "co-simulation"]);
    assert!(err.contains("does not support Co-Simulation"), "{err}");
    // FMI 1.0 has no FMU state to save.
    let err = simulate(&fmu, &["--final-fmu-state-file", "state.bin"]);
    assert!(err.contains("its state cannot be saved"), "{err}");
}

/// `runner validate` on FMI 1.0: the clean test FMUs pass the description rules, the binary's
/// exports and version, and the lifecycle run of each interface; a broken description and a
/// binary without the identifier's functions are errors naming what is wrong.
#[test]
fn validate_checks_fmi1_descriptions_binaries_and_the_lifecycle() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for co_simulation in [true, false] {
        let fmu = build(d, "bouncing", co_simulation);
        let out = ok(runner(d, &["validate", fmu.to_str().unwrap()]));
        for passed in ["[description.rules]", "[binary.exports]", "[binary.version]", "[lifecycle.run]"] {
            assert!(out.contains(passed), "{passed} missing: {out}");
        }
        assert!(out.contains("Result: 0 error(s), 0 warning(s)") && out.contains("10 steps to t = 2"), "{out}");
    }
    let fmu = fmi1_fmu(d, "twice.fmu", "linear", false, |x| x.replace(r#"name="x2""#, r#"name="x1""#));
    let err = String::from_utf8(runner(d, &["validate", fmu.to_str().unwrap()]).stdout).unwrap();
    assert!(err.contains("variable 'x1' (line 17): the name is used by another variable"), "{err}");
    let fmu = fmi1_fmu(d, "exports.fmu", "linear", true, |x| x.replace("fmi1_linear", "other"));
    std::fs::rename(d.join("exports.fmu.so"), d.join("other.so")).unwrap();
    let binary = std::fs::read(d.join("other.so")).unwrap();
    let xml = std::fs::read_to_string(c_fmu_dir().join("fmi1_linear.xml"))
        .unwrap()
        .replace("fmi1_linear", "other")
        .replace("</fmiModelDescription>", FMI1_IMPLEMENTATION);
    write_zip(&fmu, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/other.so", &binary)]);
    let o = runner(d, &["validate", fmu.to_str().unwrap()]);
    let out = String::from_utf8(o.stdout).unwrap();
    assert_eq!(o.status.code(), Some(1), "{out}");
    assert!(out.contains("does not export other_fmiDoStep (FMI 1.0 requires it of a Co-Simulation FMU)"), "{out}");
    assert!(out.contains("[lifecycle.run]") && out.contains("not run: the binary lacks functions"), "{out}");
}
