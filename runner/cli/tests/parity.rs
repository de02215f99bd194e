//! The flags `runner simulate` shares with fmusim and fmpy, on the Reference FMUs
//! (../shared/reference-fmus): `--start-time`, `--output-variable`, `--log-time-scale`.

mod common;

use std::path::PathBuf;

use common::{fails, ok, read_csv, runner};

fn reference(version: &str, model: &str) -> PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../../../shared/reference-fmus/{version}/{model}.fmu"))
}

/// `--output-variable` records exactly the variables named, in their order, a parameter (g)
/// included; `--start-time` starts the grid there. BouncingBall's ball is released at rest from
/// h = 1 m, so the first interval is free fall whatever the start time: v(t0 + k·0.01) is
/// -9.81·0.01·k (the FMU integrates v exactly with explicit Euler in time steps that are a
/// divisor of 0.01; compared to 1e-12).
#[test]
fn output_variables_and_start_time_choose_columns_and_grid() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference("fmi3", "BouncingBall");
    let csv = ok(runner(
        dir.path(),
        &[
            "simulate",
            fmu.to_str().unwrap(),
            "--output-variable",
            "v",
            "--output-variable",
            "g",
            "--start-time",
            "0.5",
            "--stop-time",
            "0.55",
        ],
    ));
    std::fs::write(dir.path().join("o.csv"), &csv).unwrap();
    let (header, rows) = read_csv(&dir.path().join("o.csv"));
    assert_eq!(header, ["time", "v", "g"], "exactly the variables named, in their order");
    assert_eq!(rows.len(), 6);
    for (k, row) in rows.iter().enumerate() {
        let t: f64 = row[0].parse().unwrap();
        assert!((t - (0.5 + 0.01 * k as f64)).abs() < 1e-12, "row {k} at t = {t}");
        let v: f64 = row[1].parse().unwrap();
        assert!((v + 9.81 * 0.01 * k as f64).abs() < 1e-12, "v = {v} at row {k}");
        assert_eq!(row[2], "-9.81", "the parameter g");
    }
    // fmpy's spelling takes several names at once.
    let csv = ok(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--stop-time", "0.01", "--output-variables", "h", "v"]));
    assert!(csv.starts_with("time,h,v\n"), "{csv}");
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--output-variable", "hh"]));
    assert!(err.contains("hh") && err.contains("'h'"), "an unknown name is refused with the close one: {err}");
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--output-variable", "h", "--output-variable", "h"]));
    assert!(err.contains("given twice"), "{err}");
}

/// `--log-time-scale` (fmusim's): the points are start·F^i with F the output interval, the last
/// one the stop time. Roberts (a stiff chemical kinetics problem, 1e-5 s to 1e8 s) integrated by
/// the runner's BDF gives one row per decade with F = 10; the three concentrations sum to 1 (the
/// reaction conserves mass; to the integrator's tolerance).
#[test]
fn a_logarithmic_time_scale_spans_decades() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference("fmi3", "Roberts");
    let args = [
        "simulate",
        fmu.to_str().unwrap(),
        "--interface",
        "model-exchange",
        "--solver",
        "bdf",
        "--log-time-scale",
        "--output-interval",
        "10",
    ];
    std::fs::write(dir.path().join("r.csv"), ok(runner(dir.path(), &args))).unwrap();
    let (header, rows) = read_csv(&dir.path().join("r.csv"));
    assert_eq!(header, ["time", "y1", "y2", "y3"]);
    assert_eq!(rows.len(), 14, "1e-5 s to 1e8 s: 13 decades, 14 points");
    for (i, row) in rows.iter().enumerate() {
        let t: f64 = row[0].parse().unwrap();
        let expected = 1e-5 * 10f64.powi(i as i32);
        assert!((t / expected - 1.0).abs() < 1e-12, "point {i}: {t}, not {expected}");
        let sum: f64 = row[1..].iter().map(|x| x.parse::<f64>().unwrap()).sum();
        assert!((sum - 1.0).abs() < 1e-3, "mass at t = {t}: {sum}");
    }
    let err = fails(runner(dir.path(), &["simulate", reference("fmi3", "BouncingBall").to_str().unwrap(), "--log-time-scale"]));
    assert!(err.contains("starts above 0"), "{err}");
    let mut factor_below_one = args;
    factor_below_one[8] = "0.5";
    let err = fails(runner(dir.path(), &factor_below_one));
    assert!(err.contains("a number above 1"), "{err}");
}

/// CSV in both directions for arrays: StateSpace's input vector u (3 elements) given as fmusim
/// writes an array (one column `u`, the elements separated by spaces) and as the runner writes
/// one (`u[1]`, `u[2]`, `u[3]`) drives the same run, to the bit; the runner's own CSV of that
/// run, read back as an input file, drives it once more identically. The recorded u is the
/// table's (a step from a repeated time on uses the value after it: 2 4 6 from 0.5 s on).
#[test]
fn array_inputs_read_fmusims_cells_and_the_runners_columns() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference("fmi3", "StateSpace");
    let fmusim = "time,u\n0,1 2 3\n0.5,1 2 3\n0.5,2 4 6\n1,2 4 6\n";
    let ours = "time,u[1],u[2],u[3]\n0,1,2,3\n0.5,1,2,3\n0.5,2,4,6\n1,2,4,6\n";
    let run = |table: &str, name: &str| {
        std::fs::write(dir.path().join(name), table).unwrap();
        let args = [
            "simulate",
            fmu.to_str().unwrap(),
            "--input-file",
            name,
            "--stop-time",
            "1",
            "--output-interval",
            "0.25",
            "--output-variable",
            "u",
            "--output-variable",
            "y",
        ];
        ok(runner(dir.path(), &args))
    };
    let from_fmusim = run(fmusim, "fmusim.csv");
    assert_eq!(run(ours, "ours.csv"), from_fmusim, "one column of cells or one column per element: the same run");
    std::fs::write(dir.path().join("out.csv"), &from_fmusim).unwrap();
    // The runner's CSV of u read back, as it wrote it and as fmusim's cells: the same run.
    let (header, rows) = read_csv(&dir.path().join("out.csv"));
    let written: Vec<String> = std::iter::once(header[..4].join(",")).chain(rows.iter().map(|r| r[..4].join(","))).collect();
    let cells: Vec<String> =
        std::iter::once("time,u".to_owned()).chain(rows.iter().map(|r| format!("{},{}", r[0], r[1..4].join(" ")))).collect();
    assert_eq!(run(&written.join("\n"), "written.csv"), run(&cells.join("\n"), "cells.csv"));
    let (header, rows) = read_csv(&dir.path().join("out.csv"));
    assert_eq!(&header[..4], ["time", "u[1]", "u[2]", "u[3]"]);
    assert_eq!(rows[1][1..4], ["1.0", "2.0", "3.0"]);
    assert_eq!(rows[3][1..4], ["2.0", "4.0", "6.0"], "the step from 0.5 s on takes the value after the discontinuity");

    std::fs::write(dir.path().join("short.csv"), "time,u\n0,1 2 3\n1,1 2\n").unwrap();
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--input-file", "short.csv"]));
    assert!(err.contains("line 3") && err.contains("2 values where other rows have 3"), "{err}");
    std::fs::write(dir.path().join("gap.csv"), "time,u[1],u[3]\n0,1,2\n").unwrap();
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--input-file", "gap.csv"]));
    assert!(err.contains("u[3]") && err.contains("in order"), "{err}");
}

/// `--reference-file` without a file checks the run against the results the FMU ships under
/// FMI-LS-REF: every Reference FMU that ships them passes, through Co-Simulation (the FMUs'
/// references are their own Co-Simulation results, which the runner reproduces), in the
/// default tube (rtol 1e-3, atol 1e-3 of each column's amplitude).
#[test]
fn the_reference_fmus_pass_their_shipped_references() {
    let dir = tempfile::tempdir().unwrap();
    let models = ["BouncingBall", "Dahlquist", "Feedthrough", "Resource", "Stair", "VanDerPol"];
    for (version, model) in models.iter().map(|m| ("fmi2", m)).chain(models.iter().chain(&["StateSpace"]).map(|m| ("fmi3", m))) {
        let fmu = reference(version, model);
        let o = runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--reference-file", "--out", "o.csv"]);
        let err = common::stderr(&o);
        assert!(o.status.success(), "{version} {model}: {err}");
        assert!(err.contains("reference check passed") && err.contains("(the FMU's LS-REF result)"), "{version} {model}: {err}");
    }
}

/// What the check cannot read is named: Roberts's manifest points at a file its archive does not
/// hold, Clocks ships no manifest, and --rtol without a reference has nothing to apply to.
#[test]
fn missing_references_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let err = fails(runner(dir.path(), &["simulate", reference("fmi3", "Roberts").to_str().unwrap(), "--reference-file"]));
    assert!(
        err.contains(
            "names 'BouncingBall_out.csv' as its result, but the FMU has no extra/org.fmi-standard.fmi-ls-ref/BouncingBall_out.csv"
        ),
        "{err}"
    );
    let err = fails(runner(dir.path(), &["simulate", reference("fmi3", "Clocks").to_str().unwrap(), "--reference-file"]));
    assert!(err.contains("ships no reference results"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", reference("fmi3", "BouncingBall").to_str().unwrap(), "--rtol", "1e-3"]));
    assert!(err.contains("give it too"), "{err}");
}

/// A reference broken on purpose at one sample (BouncingBall's h at t = 1 s raised by 1 cm)
/// fails the command, naming the column, the time, the row and both values; the CSV of the run
/// is written whole all the same.
#[test]
fn a_reference_broken_at_one_sample_fails_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference("fmi3", "BouncingBall");
    let file = std::fs::File::open(&fmu).unwrap();
    let mut zip = zip::ZipArchive::new(file).unwrap();
    let mut text = String::new();
    std::io::Read::read_to_string(&mut zip.by_name("extra/org.fmi-standard.fmi-ls-ref/BouncingBall_out.csv").unwrap(), &mut text).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    // Line 0 is the header: row 101 is t = 1.
    let cells: Vec<&str> = lines[101].split(',').collect();
    assert_eq!(cells[0], "1");
    let h: f64 = cells[1].parse().unwrap();
    lines[101] = format!("1,{},{}", h + 0.01, cells[2]);
    std::fs::write(dir.path().join("ref.csv"), lines.join("\n")).unwrap();
    std::fs::write(dir.path().join("good.csv"), &text).unwrap();
    ok(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--reference-file", "good.csv", "--out", "o.csv"]));
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--reference-file", "ref.csv", "--out", "o.csv"]));
    assert!(
        err.contains(&format!("ref.csv: h at t = 1 s (row 101 of the reference): the run has {h}, the reference {}", h + 0.01)),
        "{err}"
    );
    assert!(err.contains("above the bound"), "{err}");
    assert_eq!(read_csv(&dir.path().join("o.csv")).1.len(), 301, "the run's CSV is whole");
}

/// Against an independent reference: Dahlquist (x' = -k x, x(0) = 1, k = 1) written from its
/// closed form e^-t. The runner's dopri5 through Model Exchange (rtol 1e-10) passes a tube of
/// 1e-6; the FMU's own Co-Simulation (explicit Euler, h = 0.1: x = 0.9^(t/0.1), 0.019 off
/// e^-1 at 1 s) fails it, at the first sample, t = 0.1 s, where it is 0.9 against 0.9048.
#[test]
fn a_closed_form_reference_tells_an_accurate_run_from_euler() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = reference("fmi3", "Dahlquist");
    let rows: Vec<String> = (0..=100).map(|i| format!("{},{:?}", i as f64 / 10.0, (-(i as f64) / 10.0).exp())).collect();
    std::fs::write(dir.path().join("exact.csv"), format!("time,x\n{}\n", rows.join("\n"))).unwrap();
    let tube = ["--reference-file", "exact.csv", "--rtol", "0", "--atol", "1e-6"];
    let accurate = [&["simulate", fmu.to_str().unwrap(), "--interface", "model-exchange", "--tolerance", "1e-10"][..], &tube[..]].concat();
    let err = common::stderr(&runner(dir.path(), &accurate));
    assert!(err.contains("reference check passed: x at the 101 times of exact.csv within |y - ref| <= 0e0*|ref| + 1e-6"), "{err}");
    let euler = [&["simulate", fmu.to_str().unwrap()][..], &tube[..]].concat();
    let err = fails(runner(dir.path(), &euler));
    assert!(err.contains("x at t = 0.1 s (row 2 of the reference): the run has 0.9,"), "{err}");
}

/// `--final-fmu-state-file` then `--initial-fmu-state-file` continue a run: BouncingBall (both
/// FMI versions, Co-Simulation, in a worker and in this process) to 1.5 s, then from the saved
/// state to 3 s, gives the values of one run to 3 s bit for bit (the FMU steps the same fixed
/// steps; the times are printed from 1.5 + k·0.01 rather than k·0.01, so they are compared as
/// numbers to 1e-12). Through Model Exchange the runner's integrator restarts at 1.5 s, so the
/// continuation agrees to its tolerance (1e-6 here). A state is refused by another FMU and
/// through the other interface, naming both.
#[test]
fn a_saved_state_continues_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let numbers =
        |text: &str| -> Vec<Vec<f64>> { text.lines().skip(1).map(|l| l.split(',').map(|x| x.parse().unwrap()).collect()).collect() };
    for (version, interface, mode) in [
        ("fmi2", "co-simulation", None),
        ("fmi3", "co-simulation", None),
        ("fmi3", "co-simulation", Some("--in-process")),
        ("fmi3", "model-exchange", None),
    ] {
        let fmu = reference(version, "BouncingBall");
        let fmu = fmu.to_str().unwrap();
        let base = ["simulate", fmu, "--interface", interface];
        let with = |extra: &[&str]| -> Vec<Vec<f64>> {
            let args: Vec<&str> = base.iter().chain(extra).chain(mode.iter()).copied().collect();
            numbers(&ok(runner(dir.path(), &args)))
        };
        let full = with(&["--stop-time", "3"]);
        let first = with(&["--stop-time", "1.5", "--final-fmu-state-file", "s.bin"]);
        let second = with(&["--stop-time", "3", "--initial-fmu-state-file", "s.bin"]);
        assert_eq!(first.len(), 151);
        assert_eq!(second.len(), 151, "1.5 s to 3 s");
        assert_eq!(second[0], first[150], "{version} {interface}: the continuation starts where the first run ended");
        let tolerance = if interface == "co-simulation" { 0.0 } else { 1e-6 };
        for (k, (a, b)) in full[150..].iter().zip(&second).enumerate() {
            assert!((a[0] - b[0]).abs() < 1e-12, "time {} and {}", a[0], b[0]);
            for c in 1..3 {
                assert!((a[c] - b[c]).abs() <= tolerance, "{version} {interface} {mode:?}, row {k}: {a:?} against {b:?}");
            }
        }
    }
    let err =
        fails(runner(dir.path(), &["simulate", reference("fmi3", "BouncingBall").to_str().unwrap(), "--initial-fmu-state-file", "s.bin"]));
    assert!(err.contains("saved from this FMU run as Model Exchange, not as Co-Simulation"), "{err}");
    let err =
        fails(runner(dir.path(), &["simulate", reference("fmi3", "Dahlquist").to_str().unwrap(), "--initial-fmu-state-file", "s.bin"]));
    assert!(err.contains("saved from another FMU: model \"BouncingBall\"") && err.contains("not model \"Dahlquist\""), "{err}");
    let err = fails(runner(
        dir.path(),
        &[
            "simulate",
            reference("fmi3", "BouncingBall").to_str().unwrap(),
            "--interface",
            "model-exchange",
            "--initial-fmu-state-file",
            "s.bin",
            "--start-time",
            "1",
        ],
    ));
    assert!(err.contains("holds the state at t = 1.5 s"), "{err}");
    std::fs::write(dir.path().join("junk.bin"), b"not a state").unwrap();
    let err = fails(runner(
        dir.path(),
        &["simulate", reference("fmi3", "BouncingBall").to_str().unwrap(), "--initial-fmu-state-file", "junk.bin"],
    ));
    assert!(err.contains("junk.bin: not a saved state"), "{err}");
}
