//! End-to-end tests of the importer on an FMU this project did not export: the Dahlquist
//! equation x' = -k x written directly in C (tests/c_fmu), compiled here with `cc` and zipped
//! into a temporary .fmu; plus the importer's refusals (bad archives, missing symbols, typos).

mod common;

use common::*;

/// The C FMU steps with the exact solution, so the only error is rounding: 300 products of
/// exp(-k h) lose at most a few hundred ulps, far below 1e-12 relative.
#[test]
fn simulate_matches_the_exact_solution_and_reads_all_types() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let out = dir.path().join("x.csv");
    ok(runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "k=0.7", "--set", "x0=2", "--out", "x.csv", "--plot", "x.svg"]));
    let (header, rows) = read_csv(&out);
    assert_eq!(header, ["time", "x", "steps", "ended"], "time first, then the outputs in ModelVariables order, like fmpy");
    // DefaultExperiment: stop 3 s, step 0.01 s: 301 rows.
    assert_eq!(rows.len(), 301);
    let (t, x, steps) = (column(&header, &rows, "time"), column(&header, &rows, "x"), column(&header, &rows, "steps"));
    for i in 0..rows.len() {
        let exact = 2.0 * (-0.7 * t[i]).exp();
        assert!((x[i] / exact - 1.0).abs() < 1e-12, "t = {}: x = {} but 2 exp(-0.7 t) = {exact}", t[i], x[i]);
        assert_eq!(steps[i], i as f64, "the Integer output counts fmi2DoStep calls");
    }
    assert!((t[300] - 3.0).abs() < 1e-12);
    let svg = std::fs::read_to_string(dir.path().join("x.svg")).unwrap();
    assert!(svg.contains("time (s)") && svg.contains("dahlquist: outputs"), "the plot has its axis label and title");
}

/// fmi2Discard + fmi2Terminated: the run stops, keeps its rows plus the state at the crossing
/// (fmi2LastSuccessfulTime = ln(x0 / x_min) / k exactly), and says why.
#[test]
fn a_model_that_ends_early_keeps_its_rows_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let o = runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--set", "x_min=0.2", "--out", "x.csv"]);
    let err = stderr(&o);
    assert!(o.status.success(), "an early end is not an error: {err}");
    assert!(
        err.contains("stopped before the stop time") && err.contains("x fell below x_min = 0.2"),
        "reason printed, formatted by the C logger shim: {err}"
    );
    assert!(err.contains("[dahlquist]"), "log lines carry the instance name: {err}");
    let (header, rows) = read_csv(&dir.path().join("x.csv"));
    let (t, x, ended) = (column(&header, &rows, "time"), column(&header, &rows, "x"), column(&header, &rows, "ended"));
    let crossing = 5f64.ln();
    assert!((t.last().unwrap() - crossing).abs() < 1e-12, "last row at ln 5, got {}", t.last().unwrap());
    assert_eq!(*x.last().unwrap(), 0.2);
    assert_eq!(*ended.last().unwrap(), 1.0, "the Boolean output is read as 1");
    // Rows before: every 0.01 s up to 1.60 < ln 5 = 1.6094.
    assert_eq!(rows.len(), 162);
}

/// Each point's final x must equal x0 exp(-3 k); the k = -1 point is refused by the model and
/// recorded with the model's own message, the other points still run, and the exit code says so.
#[test]
fn sweep_records_failures_and_is_independent_of_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let args = |threads: &'static str, out: &'static str| {
        vec![
            "sweep",
            f,
            "--param",
            "k=-1,0.5,1,2",
            "--param",
            "x0=1:2:0.5",
            "--metric",
            "end=final(x)",
            "--metric",
            "drop=(max(x) - min(x)) / max(x)",
            "--threads",
            threads,
            "--out",
            out,
        ]
    };
    let o = runner(dir.path(), &args("2", "two.csv"));
    let err = fails(o);
    assert!(err.contains("3 of 12 sweep point(s) failed"), "{err}");
    let (header, rows) = read_csv(&dir.path().join("two.csv"));
    assert_eq!(header, ["k", "x0", "end", "drop", "status"]);
    assert_eq!(rows.len(), 12, "4 x 3 points");
    for row in &rows {
        let (k, x0): (f64, f64) = (row[0].parse().unwrap(), row[1].parse().unwrap());
        if k < 0.0 {
            assert!(row[4].contains("k = -1 must not be negative"), "the FMU's logged reason is the status: {row:?}");
            assert_eq!(row[2], "", "no metric for a failed point");
        } else {
            assert_eq!(row[4], "ok");
            let end: f64 = row[2].parse().unwrap();
            assert!((end / (x0 * (-3.0 * k).exp()) - 1.0).abs() < 1e-12, "{row:?}");
            let drop: f64 = row[3].parse().unwrap();
            assert!((drop - (1.0 - (-3.0 * k).exp())).abs() < 1e-12, "{row:?}");
        }
    }
    // Points are in product order, the last --param fastest.
    assert_eq!((rows[0][0].as_str(), rows[0][1].as_str(), rows[1][1].as_str(), rows[3][0].as_str()), ("-1.0", "1.0", "1.5", "0.5"));
    let _ = runner(dir.path(), &args("1", "one.csv"));
    assert_eq!(
        std::fs::read(dir.path().join("one.csv")).unwrap(),
        std::fs::read(dir.path().join("two.csv")).unwrap(),
        "same CSV with 1 and 2 threads"
    );
}

#[test]
fn info_lists_variables_units_and_capabilities() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let out = ok(runner(dir.path(), &["info", fmu.to_str().unwrap()]));
    for expected in ["dahlquist", "Co-Simulation: modelIdentifier dahlquist", "get/set FMU state", "stop 3 s"] {
        assert!(out.contains(expected), "info lacks {expected:?}:\n{out}");
    }
    let k = out.lines().find(|l| l.starts_with("k ")).expect("a line for k");
    assert!(k.contains("parameter") && k.contains("1/s") && k.contains("Decay rate"), "{k}");
    let steps = out.lines().find(|l| l.starts_with("steps ")).expect("a line for steps");
    assert!(steps.contains("output") && steps.contains("Integer"), "{steps}");
}

#[test]
fn unknown_names_and_bad_ranges_are_explained() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let err = fails(runner(dir.path(), &["simulate", f, "--set", "x_mni=1"]));
    assert!(err.contains("no variable 'x_mni'") && err.contains("did you mean 'x_min'"), "{err}");
    let err = fails(runner(dir.path(), &["sweep", f, "--param", "k=1,2", "--metric", "m=max(xx)"]));
    assert!(err.contains("no variable 'xx'") && err.contains("'x'"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", f, "--set", "x=1"]));
    assert!(err.contains("only parameters and inputs can be set"), "{err}");
    for (range, expected) in [
        ("k=5:1:0.5", "below START"),
        ("k=1:5:0", "STEP must be positive"),
        ("k=1:five:1", "STOP 'five' is not a number"),
        ("k=a,b", "'a' is not a number"),
    ] {
        let err = fails(runner(dir.path(), &["sweep", f, "--param", range, "--metric", "m=final(x)"]));
        assert!(err.contains(expected), "{range}: {err}");
    }
    let err = fails(runner(dir.path(), &["sweep", f, "--param", "k=1", "--metric", "m=max(x"]));
    assert!(err.contains("expected ')'"), "{err}");
}

#[test]
fn missing_files_and_foreign_platforms_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let err = fails(runner(dir.path(), &["info", "no_such.fmu"]));
    assert!(err.contains("no_such.fmu does not exist"), "{err}");
    let win = c_fmu(dir.path(), "win.fmu", "win64", &[]);
    let err = fails(runner(dir.path(), &["info", win.to_str().unwrap()]));
    assert!(err.contains("binaries/linux64/dahlquist.so is missing") && err.contains("win64"), "{err}");
}

/// Names that would land outside the extraction directory, and links, are refused before
/// anything is written.
#[test]
fn zip_slip_and_links_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let xml = std::fs::read(c_fmu_dir().join("modelDescription.xml")).unwrap();
    let cases: [(&str, ZipItem, &str); 4] = [
        ("dotdot.fmu", ZipItem::File("../escaped.txt", b"x"), "a '..' component"),
        ("nested.fmu", ZipItem::File("resources/../../escaped.txt", b"x"), "a '..' component"),
        ("absolute.fmu", ZipItem::File("/tmp/escaped.txt", b"x"), "an absolute path"),
        ("link.fmu", ZipItem::Link("resources/passwd", "/etc/passwd"), "symbolic link"),
    ];
    for (file, bad, expected) in cases {
        let path = dir.path().join(file);
        write_zip(&path, &[ZipItem::File("modelDescription.xml", &xml), bad]);
        let err = fails(runner(dir.path(), &["info", path.to_str().unwrap()]));
        assert!(err.contains("refusing entry") && err.contains(expected), "{file}: {err}");
    }
    assert!(!dir.path().parent().unwrap().join("escaped.txt").exists());
}

#[test]
fn a_missing_function_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "nostep.fmu", "linux64", &["-DOMIT_DO_STEP"]);
    let err = fails(runner(dir.path(), &["simulate", fmu.to_str().unwrap()]));
    assert!(err.contains("does not export the function fmi2DoStep"), "{err}");
}

/// Ctrl-C during a long sweep, in worker processes and in-process: the sweep stops, the exit
/// code is 130, the previous result file is left untouched, and the finished points stay in the
/// visible `big.csv.partial` (header and complete rows, in point order), with a message that says
/// where they are and how to continue.
#[test]
fn an_interrupted_sweep_keeps_its_finished_points_and_says_how_to_continue() {
    for mode in ["--threads=2", "--in-process"] {
        let dir = tempfile::tempdir().unwrap();
        let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
        let out = dir.path().join("big.csv");
        std::fs::write(&out, "the previous, complete result\n").unwrap();
        // 500,001 points: minutes of work, so the interrupt lands mid-sweep.
        let child = std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
            .current_dir(dir.path())
            .args(["sweep", fmu.to_str().unwrap(), "--param", "k=0.5:1:0.000001", "--metric", "end=final(x)", mode, "--out", "big.csv"])
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let partial = dir.path().join("big.csv.partial");
        let started = std::time::Instant::now();
        while std::fs::metadata(&partial).map_or(0, |m| m.len()) < 200 {
            assert!(started.elapsed().as_secs() < 60, "the sweep never started writing");
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        // SAFETY: signalling our own child process.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(130), "{mode}: exit code of an interrupted command: {err}");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "the previous, complete result\n", "the old file is untouched");
        let (header, rows) = read_csv(&partial);
        assert_eq!(header, ["k", "end", "status"]);
        assert!(!rows.is_empty());
        for (i, row) in rows.iter().enumerate() {
            assert_eq!(row[0].parse::<f64>().unwrap(), 0.5 + i as f64 * 0.000001, "{mode}: rows in point order");
            assert_eq!(row[2], "ok");
        }
        let said =
            format!("interrupted after {} of 500001 points; the finished points are in big.csv.partial; continue with: ", rows.len());
        assert!(err.contains(&said) && err.contains(&format!("{mode} --out big.csv --resume")), "{mode}: {err}");
    }
}

/// Without --out the CSV streams to stdout, and nothing else goes there: the peak summary moves
/// to stderr so the output can be piped into another tool.
#[test]
fn a_sweep_to_stdout_is_pure_csv() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let o = runner(dir.path(), &["sweep", fmu.to_str().unwrap(), "--param", "k=0.5,1", "--metric", "end=final(x)", "--threads", "2"]);
    let err = stderr(&o);
    let stdout = ok(o);
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), 3, "a header and two rows, nothing else: {stdout}");
    assert_eq!(lines[0], "k,end,status");
    for (line, k) in lines[1..].iter().zip([0.5f64, 1.0]) {
        let fields: Vec<&str> = line.split(',').collect();
        assert_eq!((fields[0].parse::<f64>().unwrap(), fields[2]), (k, "ok"), "{line}");
        assert!(fields[1].parse::<f64>().unwrap() > 0.0, "{line}");
    }
    assert!(err.contains("end: peak"), "{err}");
}

/// A binary the loader cannot load says why and what to do: a dependency it cannot find is
/// named (a library linked in, then removed), and a libpython symbol left undefined (as
/// PythonFMU's binaries leave them) suggests preloading libpython. Both in a worker and in this
/// process, and from `info`.
#[test]
fn loading_errors_name_the_missing_library_or_suggest_libpython() {
    let dir = tempfile::tempdir().unwrap();
    let lib = dir.path().join("libgone_dependency.so");
    let status = std::process::Command::new("cc")
        .args(["-shared", "-fPIC", "-x", "c", "-", "-o"])
        .arg(&lib)
        .stdin(std::process::Stdio::piped())
        .spawn()
        .and_then(|mut c| {
            use std::io::Write;
            c.stdin.take().unwrap().write_all(b"int gone_dependency(void) { return 1; }\n")?;
            c.wait()
        });
    assert!(status.unwrap().success(), "cc builds the dependency");
    let lib_dir = format!("-L{}", dir.path().display());
    let gone = faulty_fmu(dir.path(), "gone.fmu", false, &["-Wl,--no-as-needed", &lib_dir, "-lgone_dependency"]);
    std::fs::remove_file(&lib).unwrap();
    let python = faulty_fmu(dir.path(), "python.fmu", false, &["-DNEEDS_PYTHON"]);
    for mode in [&[][..], &["--in-process"][..]] {
        let mut args = vec!["simulate", gone.to_str().unwrap()];
        args.extend(mode);
        let err = fails(runner(dir.path(), &args));
        assert!(err.contains("the binary needs the library libgone_dependency.so") && err.contains("LD_LIBRARY_PATH"), "{mode:?}: {err}");
        let mut args = vec!["simulate", python.to_str().unwrap()];
        args.extend(mode);
        let err = fails(runner(dir.path(), &args));
        assert!(err.contains("_Py_NoneStruct is Python's") && err.contains("LD_PRELOAD=") && err.contains("libpython3"), "{mode:?}: {err}");
    }
    let err = fails(runner(dir.path(), &["info", python.to_str().unwrap()]));
    assert!(err.contains("LD_PRELOAD="), "{err}");
}

/// One CSV convention for both FMI versions: the Reference FMU Feedthrough (FMI 2.0 and 3.0,
/// outputs copied from inputs) writes its shared outputs as the same text in both, integers,
/// enumerations and Booleans as integers, String outputs included; in a worker and in this
/// process. (tests/fmpy/test_csv_convention.py checks the same columns against fmpy's CSV.)
#[test]
fn both_fmi_versions_write_one_csv_convention() {
    let reference = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus");
    let dir = tempfile::tempdir().unwrap();
    let sets = ["Int32_input=-7", "Boolean_input=true", "String_input=hello, world", "Enumeration_input=2", "Float64_continuous_input=1.5"];
    let mut tables = Vec::new();
    for (version, mode) in [("fmi2", None), ("fmi2", Some("--in-process")), ("fmi3", None)] {
        let fmu = reference.join(version).join("Feedthrough.fmu");
        let mut args = vec!["simulate", fmu.to_str().unwrap(), "--stop-time", "0.02", "--output-interval", "0.01", "--out", "f.csv"];
        for set in &sets {
            args.extend(["--set", set]);
        }
        args.extend(mode);
        ok(runner(dir.path(), &args));
        tables.push(read_csv(&dir.path().join("f.csv")));
    }
    let shared = ["time", "Float64_continuous_output", "Int32_output", "Boolean_output", "String_output", "Enumeration_output"];
    let pick = |(header, rows): &(Vec<String>, Vec<Vec<String>>)| -> Vec<Vec<String>> {
        let at: Vec<usize> =
            shared.iter().map(|n| header.iter().position(|h| h == n).unwrap_or_else(|| panic!("no {n} in {header:?}"))).collect();
        rows.iter().map(|r| at.iter().map(|&i| r[i].clone()).collect()).collect()
    };
    let fmi2 = pick(&tables[0]);
    assert_eq!(fmi2[0], ["0.0", "1.5", "-7", "1", "hello, world", "2"], "integers as integers, the String as it is");
    assert_eq!(fmi2.len(), 3);
    assert_eq!(pick(&tables[1]), fmi2, "in this process as in a worker");
    assert_eq!(pick(&tables[2]), fmi2, "FMI 3.0 as FMI 2.0");
}

/// `simulate` runs a description that breaks the standard (faulty.xml with `pid` left out of
/// ModelStructure/Outputs, which fmpy and `runner validate` refuse) but says so in one line
/// pointing at `runner validate`; the same FMU with its description intact gets no warning.
#[test]
fn simulate_warns_in_one_line_when_the_description_breaks_the_standard() {
    let dir = tempfile::tempdir().unwrap();
    let clean = faulty_fmu(dir.path(), "clean.fmu", false, &[]);
    let o = runner(dir.path(), &["simulate", clean.to_str().unwrap(), "--out", "clean.csv"]);
    assert!(o.status.success() && !stderr(&o).contains("breaks the FMI standard"), "{}", stderr(&o));
    let xml = std::fs::read_to_string(c_fmu_dir().join("faulty.xml")).unwrap();
    let broken =
        xml.replacen("<Outputs>\n      <Unknown index=\"1\"/>\n      <Unknown index=\"7\"/>", "<Outputs>\n      <Unknown index=\"1\"/>", 1);
    assert_ne!(broken, xml, "the edit applies");
    let binary = std::fs::read(dir.path().join("clean.fmu.so")).unwrap();
    let fmu = dir.path().join("broken.fmu");
    write_zip(&fmu, &[ZipItem::File("modelDescription.xml", broken.as_bytes()), ZipItem::File("binaries/linux64/faulty.so", &binary)]);
    let o = runner(dir.path(), &["simulate", fmu.to_str().unwrap(), "--out", "broken.csv"]);
    let err = stderr(&o);
    assert!(o.status.success(), "the run still runs: {err}");
    let warnings: Vec<&str> = err.lines().filter(|l| l.contains("breaks the FMI standard")).collect();
    assert_eq!(warnings.len(), 1, "one line: {err}");
    assert!(warnings[0].contains("ModelStructure/Outputs is missing pid") && warnings[0].contains("runner validate"), "{err}");
    let (h1, a) = read_csv(&dir.path().join("clean.csv"));
    let (h2, b) = read_csv(&dir.path().join("broken.csv"));
    assert_eq!(column(&h1, &a, "x"), column(&h2, &b, "x"), "the same run");
}
