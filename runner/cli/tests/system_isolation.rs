//! Systems in worker processes: `runner sweep SYSTEM` and `runner simulate SYSTEM` run each point
//! (or the run) in a worker, so a component that crashes, hangs or leaks fails only its point,
//! named with the component, the signal (or exit code, or timeout), the FMI call and the time;
//! the other points equal an in-process run bit for bit (the same code runs the same point;
//! only the process differs). The systems here are built around tests/c_fmu/faulty.c, whose
//! `fault` parameter chooses the misbehaviour, from t = 0.31 (its 32nd step of 0.01 s).

mod common;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use common::*;

/// A system of two faulty.c components, `good` and `bad`, unconnected: `good` is stepped first
/// (index 0), so a crash named `bad` is not merely the last component stepped. `bad` gets the
/// parameter binding `binding` (SSV parameters inside <ssv:Parameters>).
fn faulty_system(dir: &Path, name: &str, binding: &str) -> PathBuf {
    faulty_system_compiled(dir, name, binding, &[])
}

/// [`faulty_system`], faulty.c compiled with `flags`.
fn faulty_system_compiled(dir: &Path, name: &str, binding: &str, flags: &[&str]) -> PathBuf {
    let fmu = faulty_fmu(dir, "faulty.fmu", false, flags);
    let parameters = |inner: &str| {
        format!(
            r#"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters>{inner}</ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"#
        )
    };
    let ssd = format!(
        r#"<ssd:System name="s"><ssd:Elements><ssd:Component name="good" source="resources/faulty.fmu"/><ssd:Component name="bad" source="resources/faulty.fmu">{}</ssd:Component></ssd:Elements></ssd:System>"#,
        parameters(binding)
    );
    system(dir, name, &ssd, &[("faulty.fmu", &fmu)], &[])
}

/// Rows of a CSV keyed by their first `key` columns.
fn rows_by_point(path: &Path, key: usize) -> Vec<(Vec<String>, Vec<String>)> {
    let (_, rows) = read_csv(path);
    rows.into_iter().map(|r| (r[..key].to_vec(), r[key..].to_vec())).collect()
}

fn sweep(dir: &Path, root: &Path, params: &[&str], out: &str, extra: &[&str]) -> std::process::Output {
    let mut args = vec!["sweep", root.to_str().unwrap()];
    for p in params {
        args.extend_from_slice(&["--param", p]);
    }
    args.extend_from_slice(&["--metric", "end=final(good.x)", "--metric", "mean=mean(bad.x)", "--threads", "2", "--out", out]);
    args.extend_from_slice(extra);
    // Temporary files go to a directory of the test's: crashed workers must leave none there.
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    std::process::Command::new(env!("CARGO_BIN_EXE_runner")).current_dir(dir).env("TMPDIR", &tmp).args(&args).output().unwrap()
}

/// Faults 1 (SIGSEGV), 2 (abort), 4 (exit(3)) and 5 (a leak of 40 MB per step, which exhausts
/// the 256 MiB worker limit within the run, so its malloc returns NULL and it crashes) in
/// component `bad`, at two values of `good.k`: each of those points fails alone, naming `bad`,
/// and the healthy points equal an in-process run of the same points to the digit. A fault in
/// `good` names `good`.
#[test]
fn a_crashing_component_fails_only_its_points_and_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "faulty", "");
    let o = sweep(dir.path(), &root, &["good.k=0.5,1", "bad.fault=0,1,2,4,5"], "isolated.csv", &["--worker-memory", "256"]);
    assert_eq!(o.status.code(), Some(1), "failed points make the exit code 1: {}", stderr(&o));
    assert!(stderr(&o).contains("8 of 10 sweep point(s) failed"), "{}", stderr(&o));
    let isolated = rows_by_point(&dir.path().join("isolated.csv"), 2);
    assert_eq!(isolated.len(), 10);
    let expected = [
        "ok",
        "crashed: SIGSEGV in fmi2DoStep of component 'bad' at t = 0.31",
        "crashed: SIGABRT in fmi2DoStep of component 'bad' at t = 0.31",
        "exited: the worker process ended with code 3 in fmi2DoStep of component 'bad' at t = 0.31",
    ];
    for (i, (point, values)) in isolated.iter().enumerate() {
        let status = &values[2];
        match expected.get(i % 5) {
            Some(e) => assert_eq!(status, e, "point {point:?}"),
            // The leak's crash comes a few steps after it starts, when the limit is reached.
            None => {
                assert!(status.starts_with("crashed: SIGSEGV in fmi2DoStep of component 'bad' at t = 0.3"), "point {point:?}: {status}")
            }
        }
        if i % 5 != 0 {
            assert_eq!((values[0].as_str(), values[1].as_str()), ("", ""), "no metrics for a failed point");
        }
    }
    let left: Vec<_> = std::fs::read_dir(dir.path().join("tmp")).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "workers load the supervisor's unpacked copy, so dead ones leave nothing: {left:?}");
    // The healthy points, in-process on threads (where a crash would take everything down).
    ok(sweep(dir.path(), &root, &["good.k=0.5,1", "bad.fault=0"], "in_process.csv", &["--in-process"]));
    let healthy: Vec<_> = isolated.iter().filter(|(_, v)| v[2] == "ok").cloned().collect();
    assert_eq!(healthy.len(), 2);
    assert_eq!(healthy, rows_by_point(&dir.path().join("in_process.csv"), 2), "the same digits, so the same bits");
    // The first component stepped is named when it is the one that crashes.
    let o = sweep(dir.path(), &root, &["good.fault=1"], "good.csv", &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let (_, rows) = read_csv(&dir.path().join("good.csv"));
    assert_eq!(rows[0][3], "crashed: SIGSEGV in fmi2DoStep of component 'good' at t = 0.31");
}

/// Fault 3 makes `bad` loop forever in fmi2DoStep from t = 0.31: under `--point-timeout 1` that
/// point is stopped after a second, named, and the other point is intact; `runner simulate
/// --timeout 1` of the same system fails naming it and keeps the rows its worker sent. A timeout cannot
/// stop a thread: with `--in-process` both are refused.
#[test]
fn a_hanging_component_times_out_its_point_only() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "hang", "");
    let started = Instant::now();
    let o = sweep(dir.path(), &root, &["bad.fault=0,3"], "hang.csv", &["--point-timeout", "1"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let (_, rows) = read_csv(&dir.path().join("hang.csv"));
    assert_eq!(rows[0][3], "ok");
    assert_eq!(rows[1][3], "timed out after 1 s in fmi2DoStep of component 'bad' at t = 0.31");
    assert!(started.elapsed() < Duration::from_secs(30), "the hung worker is killed, not waited for");
    let out = dir.path().join("sim.csv");
    let args = ["simulate", root.to_str().unwrap(), "--set", "bad.fault=3", "--timeout", "1", "--out", out.to_str().unwrap()];
    let err = fails(runner(dir.path(), &args));
    assert!(err.contains("timed out after 1 s in fmi2DoStep of component 'bad' at t = 0.31") && err.contains("rows before it"), "{err}");
    // The rows the worker sent before it was stopped are kept: a prefix of a clean run's, all
    // before the step that hung (the first from t >= 0.31).
    let clean = dir.path().join("clean.csv");
    ok(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--in-process", "--out", clean.to_str().unwrap()]));
    let (header, kept) = read_csv(&out);
    let (_, all) = read_csv(&clean);
    // All but the pid columns (the process each instance runs in).
    let same = |k: &Vec<String>, r: &Vec<String>| header.iter().zip(k.iter().zip(r)).all(|(h, (a, b))| h.ends_with(".pid") || a == b);
    assert!(kept.len() <= 32 && kept.iter().zip(&all).all(|(k, r)| same(k, r)), "{kept:?}");
    let err = fails(runner(
        dir.path(),
        &["sweep", root.to_str().unwrap(), "--param", "bad.fault=0", "--metric", "e=final(good.x)", "--in-process", "--point-timeout", "1"],
    ));
    assert!(err.contains("--point-timeout needs worker processes"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--in-process", "--timeout", "1"]));
    assert!(err.contains("--timeout needs a worker process"), "{err}");
}

/// A system's worker that crashes (component `bad`, SIGSEGV in the step from t = 1) after rows
/// that came slowly (each component 5 ms a step: a second for the 101 rows t = 0 to 1) leaves in
/// the --out file all but the rows of its last tenth of a second (10 rows at 10 ms a step), not
/// none as when the worker sent rows only 64 KiB at a time; at least 60 of the 101 are asked for,
/// room for a loaded machine's slower wake-ups. The rows kept are a clean run's first.
#[test]
fn a_system_worker_that_crashes_keeps_all_but_its_last_tenth_of_a_second_of_rows() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system_compiled(dir.path(), "slow", "", &["-DSLOW_STEP"]);
    let r = root.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", r, "--stop-time", "1", "--out", "clean.csv"]));
    let (header, clean) = read_csv(&dir.path().join("clean.csv"));
    assert_eq!(clean.len(), 101);
    let args = ["simulate", r, "--set", "bad.fault=1", "--set", "bad.fault_time=1", "--stop-time", "2", "--out", "crashed.csv"];
    let err = fails(runner(dir.path(), &args));
    assert!(err.contains("crashed: SIGSEGV in fmi2DoStep of component 'bad' at t = 1"), "{err}");
    let (h, kept) = read_csv(&dir.path().join("crashed.csv"));
    assert_eq!(h, header);
    assert!(kept.len() >= 60, "{} of the 101 rows before the crash kept", kept.len());
    let x: Vec<usize> = header.iter().enumerate().filter(|(_, h)| h.ends_with(".x")).map(|(c, _)| c).collect();
    assert!(kept.iter().zip(&clean).all(|(k, c)| x.iter().all(|&i| k[i] == c[i])), "the kept rows are the clean run's first");
}

/// Ctrl-C (SIGINT) a second into a system's run in this process whose rows come slowly stops it
/// with exit code 130, the rows before it kept in --out (the first rows of a clean run), as in a
/// worker; the run in this process once went on to its stop time and exited 0.
#[test]
fn an_interrupted_system_run_in_process_stops_and_keeps_its_rows() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system_compiled(dir.path(), "slow", "", &["-DSLOW_STEP"]);
    let r = root.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", r, "--in-process", "--stop-time", "1", "--out", "clean.csv"]));
    let (header, clean) = read_csv(&dir.path().join("clean.csv"));
    let child = spawn_runner(dir.path(), &["simulate", r, "--in-process", "--stop-time", "100", "--out", "stopped.csv"]);
    std::thread::sleep(Duration::from_secs(1));
    // SAFETY: a signal to the child this test started.
    assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) }, 0);
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(130), "{}", stderr(&o));
    assert!(stderr(&o).contains("interrupted (the rows before it are in stopped.csv)"), "{}", stderr(&o));
    let (h, kept) = read_csv(&dir.path().join("stopped.csv"));
    assert_eq!(h, header);
    assert!(!kept.is_empty() && kept.len() < 10_001, "{} rows", kept.len());
    let x: Vec<usize> = header.iter().enumerate().filter(|(_, h)| h.ends_with(".x")).map(|(c, _)| c).collect();
    assert!(kept.iter().zip(&clean).all(|(k, c)| x.iter().all(|&i| k[i] == c[i])), "the kept rows are a clean run's first");
}

/// A component whose binary crashes as it loads (an initializer raising SIGSEGV, as a broken
/// static constructor does): the supervisor reads and checks the system without loading any
/// binary, so it survives; every point of a sweep fails alone, and `runner simulate` of the
/// system fails with an exit code of 1, not a signal, both naming the component.
#[test]
fn a_binary_that_crashes_as_it_loads_costs_only_the_worker() {
    let dir = tempfile::tempdir().unwrap();
    let good = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let bad = faulty_fmu(dir.path(), "crashing.fmu", false, &["-DCRASH_ON_LOAD"]);
    let ssd = r#"<ssd:System name="s"><ssd:Elements><ssd:Component name="good" source="resources/faulty.fmu"/><ssd:Component name="bad" source="resources/crashing.fmu"/></ssd:Elements></ssd:System>"#;
    let root = system(dir.path(), "crash_on_load", ssd, &[("faulty.fmu", &good), ("crashing.fmu", &bad)], &[]);
    let o = sweep(dir.path(), &root, &["good.k=0.5,1"], "points.csv", &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let (_, rows) = read_csv(&dir.path().join("points.csv"));
    assert_eq!(rows.len(), 2);
    for row in &rows {
        assert_eq!(row[3], "crashed: SIGSEGV while loading the binary of component 'bad'", "{row:?}");
    }
    let o = runner(dir.path(), &["simulate", root.to_str().unwrap(), "--stop-time", "0.1"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("crashed: SIGSEGV while loading the binary of component 'bad'"), "{}", stderr(&o));
}

/// System worker processes whose parent is this test process: orphans, which a killed runner
/// must not leave (its workers die with it).
fn orphaned_system_workers() -> Vec<u32> {
    let me = std::process::id();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        let stat = std::fs::read_to_string(entry.path().join("stat")).unwrap_or_default();
        let ppid = stat.rsplit(')').next().and_then(|rest| rest.split_whitespace().nth(1)).and_then(|p| p.parse::<u32>().ok());
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        if ppid == Some(me) && cmdline.split(|&b| b == 0).nth(1) == Some(b"system-worker") {
            found.push(pid);
        }
    }
    found
}

/// A system sweep streams its rows to `<out>.partial`: killed (SIGKILL) once rows are there, it
/// leaves no worker behind, continues with `--resume` and ends with exactly the bytes of an
/// uninterrupted in-process run.
/// A partial file of the system before a change of its parameters is refused.
#[test]
fn a_killed_system_sweep_resumes_to_the_uninterrupted_csv() {
    // Orphaned workers would be reparented to this process (a child subreaper): looked for below.
    // SAFETY: prctl on this process.
    assert_eq!(unsafe { libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1) }, 0);
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "resume", "");
    let r = root.to_str().unwrap();
    // 401 points of 1,000 steps of two components each.
    let args = |out: &'static str| -> Vec<&str> {
        vec![
            "sweep",
            r,
            "--param",
            "good.k=0.5:1.3:0.002",
            "--metric",
            "end=final(good.x)",
            "--metric",
            "m=mean(bad.x)",
            "--output-interval",
            "1e-3",
            "--threads",
            "2",
            "--out",
            out,
        ]
    };
    let mut reference = args("reference.csv");
    reference.push("--in-process");
    ok(runner(dir.path(), &reference));
    let expected = std::fs::read(dir.path().join("reference.csv")).unwrap();
    let mut child = spawn_runner(dir.path(), &args("killed.csv"));
    let partial = dir.path().join("killed.csv.partial");
    let started = Instant::now();
    // Killed once a few rows are in the partial file.
    while std::fs::read(&partial).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count()) < 4 {
        assert!(child.try_wait().unwrap().is_none(), "the sweep ended before it could be killed");
        assert!(started.elapsed() < Duration::from_secs(60), "no rows within a minute");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(orphaned_system_workers(), Vec::<u32>::new(), "a killed runner's workers die with it");
    let bytes = std::fs::read(&partial).unwrap();
    let complete = &bytes[..bytes.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1)];
    assert!(expected.starts_with(complete), "the partial file's complete rows are the reference's first rows");
    let mut resume = args("killed.csv");
    resume.push("--resume");
    let o = runner(dir.path(), &resume);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resuming: "), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.path().join("killed.csv")).unwrap(), expected, "exactly the uninterrupted run's CSV");
    assert!(!partial.exists());
    // A partial file of the system before its parameters changed is not continued.
    let mut child = spawn_runner(dir.path(), &args("changed.csv"));
    let partial = dir.path().join("changed.csv.partial");
    while !std::fs::read(&partial).is_ok_and(|b| b.contains(&b'\n')) {
        assert!(child.try_wait().unwrap().is_none(), "the sweep ended before it could be killed");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    faulty_system(dir.path(), "resume", r#"<ssv:Parameter name="x0"><ssv:Real value="2"/></ssv:Parameter>"#);
    let mut resume = args("changed.csv");
    resume.push("--resume");
    let err = fails(runner(dir.path(), &resume));
    assert!(err.contains("is not from this sweep") && err.contains("system_sha256"), "{err}");
}

/// A system sweep's `--set` is recorded by the value the FMU gets, not as typed: `0.5` and `5e-1`
/// resume each other's sweep (they once refused each other as "not from this sweep"), while
/// another value is refused, naming the assignment.
#[test]
fn a_system_sweep_resumes_with_the_same_set_written_another_way() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    faulty_system(d, "faulty", "");
    let params = ["good.k=0.5,0.75,1"];
    ok(sweep(d, Path::new("faulty"), &params, "a.csv", &["--set", "good.x0=0.5"]));
    let complete = keep_first_row(d, "a.csv");
    let o = sweep(d, Path::new("faulty"), &params, "a.csv", &["--set", "good.x0=5e-1", "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resuming: 1 of 3 points"), "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("a.csv")).unwrap(), complete);
    keep_first_row(d, "a.csv");
    let err = fails(sweep(d, Path::new("faulty"), &params, "a.csv", &["--set", "good.x0=0.6", "--resume"]));
    assert!(err.contains("set: the partial file's sweep has good.x0=0.5, this one good.x0=0.6"), "{err}");
}

/// A sweep of an `.ssp` archive resumes: its record names the system by the archive's bytes, not
/// by the paths its FMUs were extracted to (a fresh temporary folder per run, which once made
/// every resume of an archive refused as "not from this sweep"). The first row of a finished
/// sweep is kept as the partial file; `--resume` runs the other points and ends with the same
/// bytes.
#[test]
fn a_sweep_of_an_ssp_archive_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "folder", "");
    let ssd = std::fs::read(root.join("SystemStructure.ssd")).unwrap();
    let fmu = std::fs::read(root.join("resources").join("faulty.fmu")).unwrap();
    let ssp = dir.path().join("faulty.ssp");
    write_zip(&ssp, &[ZipItem::File("SystemStructure.ssd", &ssd), ZipItem::File("resources/faulty.fmu", &fmu)]);
    let o = sweep(dir.path(), &ssp, &["good.k=0.5,0.75,1"], "a.csv", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let complete = std::fs::read(dir.path().join("a.csv")).unwrap();
    let first_row = complete.iter().enumerate().filter(|(_, &b)| b == b'\n').nth(1).unwrap().0 + 1;
    std::fs::write(dir.path().join("a.csv.partial"), &complete[..first_row]).unwrap();
    std::fs::remove_file(dir.path().join("a.csv")).unwrap();
    let o = sweep(dir.path(), &ssp, &["good.k=0.5,0.75,1"], "a.csv", &["--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("resuming: 1 of 3 points"), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.path().join("a.csv")).unwrap(), complete);
}

/// Cuts the finished sweep `out` (in `dir`) back to its header and first row, as `<out>.partial`:
/// a sweep killed after its first point.
fn keep_first_row(dir: &Path, out: &str) -> Vec<u8> {
    let complete = std::fs::read(dir.join(out)).unwrap();
    let first_row = complete.iter().enumerate().filter(|(_, &b)| b == b'\n').nth(1).unwrap().0 + 1;
    std::fs::write(dir.join(format!("{out}.partial")), &complete[..first_row]).unwrap();
    std::fs::remove_file(dir.join(out)).unwrap();
    complete
}

/// The same system named another way resumes the sweep: a folder given relatively, with a
/// trailing slash, absolutely, by its `.ssd`, or by the bare `SystemStructure.ssd` from inside
/// it; an `.ssp` relatively, absolutely or through a symbolic link. Each resume runs the two
/// points missing and ends with the bytes of the uninterrupted sweep. (The record once held the
/// path as given, and hashed every file with its path, so each of these was refused as "not from
/// this sweep"; the bare `SystemStructure.ssd` failed with "cannot read : No such file".)
#[test]
fn a_system_sweep_resumes_however_the_system_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let root = faulty_system(d, "faulty", "");
    let params = ["good.k=0.5,0.75,1"];
    ok(sweep(d, Path::new("faulty"), &params, "a.csv", &[]));
    let absolute = root.display().to_string();
    for name in ["./faulty/", absolute.as_str(), "faulty/SystemStructure.ssd"] {
        let complete = keep_first_row(d, "a.csv");
        let o = sweep(d, Path::new(name), &params, "a.csv", &["--resume"]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains("resuming: 1 of 3 points"), "{name}: {}", stderr(&o));
        assert_eq!(std::fs::read(d.join("a.csv")).unwrap(), complete, "{name}");
    }
    let complete = keep_first_row(d, "a.csv");
    let o = sweep(&root, Path::new("SystemStructure.ssd"), &params, "../a.csv", &["--resume"]);
    assert!(o.status.success(), "SystemStructure.ssd from inside the folder: {}", stderr(&o));
    assert_eq!(std::fs::read(d.join("a.csv")).unwrap(), complete, "SystemStructure.ssd from inside the folder");

    let ssd = std::fs::read(root.join("SystemStructure.ssd")).unwrap();
    let fmu = std::fs::read(root.join("resources").join("faulty.fmu")).unwrap();
    write_zip(&d.join("faulty.ssp"), &[ZipItem::File("SystemStructure.ssd", &ssd), ZipItem::File("resources/faulty.fmu", &fmu)]);
    std::os::unix::fs::symlink("faulty.ssp", d.join("link.ssp")).unwrap();
    ok(sweep(d, Path::new("faulty.ssp"), &params, "p.csv", &[]));
    let absolute = d.join("faulty.ssp").display().to_string();
    for name in [absolute.as_str(), "link.ssp"] {
        let complete = keep_first_row(d, "p.csv");
        let o = sweep(d, Path::new(name), &params, "p.csv", &["--resume"]);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        assert_eq!(std::fs::read(d.join("p.csv")).unwrap(), complete, "{name}");
    }
}

/// A folder's SSD may bind a parameter file outside the folder: changing that file changes the
/// system, so a partial file from before is refused (it was once resumed, its first row from the
/// old parameter values and the others from the new).
#[test]
fn a_changed_parameter_file_outside_the_system_folder_refuses_resume() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fmu = faulty_fmu(d, "faulty.fmu", false, &[]);
    let ssd = r#"<ssd:System name="s"><ssd:Elements><ssd:Component name="good" source="resources/faulty.fmu"><ssd:ParameterBindings><ssd:ParameterBinding source="../outside.ssv"/></ssd:ParameterBindings></ssd:Component><ssd:Component name="bad" source="resources/faulty.fmu"/></ssd:Elements></ssd:System>"#;
    let root = system(d, "outside", ssd, &[("faulty.fmu", &fmu)], &[]);
    let ssv = |x0: &str| {
        format!(
            r#"<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="x0"><ssv:Real value="{x0}"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>"#
        )
    };
    std::fs::write(d.join("outside.ssv"), ssv("1")).unwrap();
    ok(sweep(d, &root, &["bad.k=0.5,0.75,1"], "a.csv", &[]));
    keep_first_row(d, "a.csv");
    std::fs::write(d.join("outside.ssv"), ssv("2")).unwrap();
    let err = fails(sweep(d, &root, &["bad.k=0.5,0.75,1"], "a.csv", &["--resume"]));
    assert!(err.contains("is not from this sweep") && err.contains("system_sha256"), "{err}");
}

/// A system folder holding links to itself (two: each level of the walk doubles) sweeps to a
/// file: the record's digest does not follow linked folders (which once walked 2^40 paths, a
/// sweep that never started). Given a minute, which the sweep takes well under a second of.
#[test]
fn a_system_folder_that_links_to_itself_sweeps_to_a_file() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "linked", "");
    std::os::unix::fs::symlink(".", root.join("here")).unwrap();
    std::os::unix::fs::symlink("..", root.join("resources").join("up")).unwrap();
    let args = ["sweep", "linked", "--param", "good.k=0.5,1", "--metric", "end=final(good.x)", "--out", "a.csv"];
    let mut child = spawn_runner(dir.path(), &args);
    let started = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > Duration::from_secs(60) {
            child.kill().unwrap();
            panic!("the sweep of a folder that links to itself did not end within a minute");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(child.wait().unwrap().success());
    assert_eq!(read_csv(&dir.path().join("a.csv")).1.len(), 2);
}

/// An `.ssd` named directly: the record's digest walks its folder, where entries the system does
/// not use may not be readable. A dangling link `old.fmu`, a FIFO `notes.ssv` (reading it would
/// wait for a writer) and, unless the test runs as root (which reads through any mode), a folder
/// of mode 000 are passed over: the sweep runs and resumes. Before, the link failed the sweep
/// ("cannot read .../old.fmu") and the FIFO hung it.
#[test]
fn entries_the_system_does_not_use_and_cannot_be_read_do_not_fail_its_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let root = faulty_system(dir.path(), "cluttered", "");
    std::os::unix::fs::symlink("gone.fmu", root.join("old.fmu")).unwrap();
    let fifo = std::ffi::CString::new(root.join("notes.ssv").into_os_string().into_encoded_bytes()).unwrap();
    // SAFETY: mkfifo on a path this test owns.
    assert_eq!(unsafe { libc::mkfifo(fifo.as_ptr(), 0o644) }, 0);
    let private = root.join("private");
    std::fs::create_dir(&private).unwrap();
    std::fs::write(private.join("other.ssd"), "<not read/>").unwrap();
    // SAFETY: geteuid has no preconditions.
    let as_root = unsafe { libc::geteuid() } == 0;
    if as_root {
        println!("running as root, which reads a folder of mode 000: only the link and the FIFO are tried");
    } else {
        std::fs::set_permissions(&private, std::os::unix::fs::PermissionsExt::from_mode(0o000)).unwrap();
    }
    let args = ["sweep", "cluttered/SystemStructure.ssd", "--param", "good.k=0.5,1", "--metric", "end=final(good.x)", "--out", "a.csv"];
    let run = |args: &[&str]| {
        let mut child = spawn_runner(dir.path(), args);
        let started = Instant::now();
        while child.try_wait().unwrap().is_none() {
            if started.elapsed() > Duration::from_secs(60) {
                child.kill().unwrap();
                panic!("the sweep did not end within a minute (reading the FIFO?)");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        child.wait_with_output().unwrap()
    };
    let o = run(&args);
    let resumed = run(&[&args[..], &["--resume"]].concat());
    if !as_root {
        // The temporary folder must be removable.
        std::fs::set_permissions(&private, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    }
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(read_csv(&dir.path().join("a.csv")).1.len(), 2);
    // The same digest again: resuming the finished sweep finds it complete.
    let o = resumed;
    assert!(o.status.success() && stderr(&o).contains("already complete"), "{}", stderr(&o));
}

/// systems/quarter_car_road (built by `runner build`): the Ex. 4 sweep and a run in worker
/// processes write exactly the bytes of the same in-process; `--plot` draws both.
#[test]
fn quarter_car_road_in_workers_equals_in_process_to_the_bit() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let built = ok(runner(here, &["build", "quarter_car_road"]));
    let ssp = PathBuf::from(built.lines().last().expect("runner build prints the system's path"));
    assert!(ssp.ends_with("ssp/quarter_car_road.ssp"), "{built}");
    let dir = tempfile::tempdir().unwrap();
    let s = ssp.to_str().unwrap();
    let sweep = |out: &str, extra: &[&str]| {
        let mut args = vec!["sweep", s, "--param", "road.speed=5,10,20,30,50", "--metric", "t=max(car.z_s)/max(car.z_r)"];
        args.extend_from_slice(&["--metric", "a=rms(car.z_s_ddot)", "--stop-time", "2", "--threads", "2", "--out", out]);
        args.extend_from_slice(extra);
        ok(runner(dir.path(), &args));
        std::fs::read(dir.path().join(out)).unwrap()
    };
    assert_eq!(sweep("workers.csv", &["--plot", "sweep.svg"]), sweep("threads.csv", &["--in-process"]));
    // --plot draws a system's sweep as a single FMU's: each metric against the first parameter.
    let svg = std::fs::read_to_string(dir.path().join("sweep.svg")).unwrap();
    assert!(svg.contains("quarter_car_road: t, a against road.speed") && svg.contains("road.speed (m/s)"), "the title and axis");
    let simulate = |out: &str, extra: &[&str]| {
        let mut args = vec!["simulate", s, "--stop-time", "0.5", "--master", "gauss-seidel", "--out", out];
        args.extend_from_slice(extra);
        ok(runner(dir.path(), &args));
        std::fs::read(dir.path().join(out)).unwrap()
    };
    let worker = simulate("worker.csv", &["--plot", "run.svg", "--plot-vars", "car.z_s,road.z_r"]);
    // --plot draws the columns named, labelled with their component, in their units.
    let svg = std::fs::read_to_string(dir.path().join("run.svg")).unwrap();
    assert!(svg.contains("quarter_car_road: outputs") && svg.contains("car.z_s (m)") && svg.contains("road.z_r (m)"), "panels");
    assert!(worker.iter().filter(|&&b| b == b'\n').count() > 100, "rows are there");
    assert_eq!(worker, simulate("in_process.csv", &["--in-process"]));
}
