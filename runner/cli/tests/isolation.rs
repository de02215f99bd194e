//! Worker processes: sweeps, simulate and compare on tests/c_fmu/faulty.c, an FMU that
//! segfaults, aborts, hangs, exits the process or leaks memory at chosen parameter values. Each
//! misbehaving point must be recorded with the signal (or exit code, or timeout) and the FMI call
//! and model time it happened at, while every other point equals an in-process run bit for bit
//! (the same code runs the same point; only the process differs).

mod common;

use std::collections::BTreeSet;

use common::*;

/// Rows of a CSV keyed by their first `key` columns.
fn rows_by_point(path: &std::path::Path, key: usize) -> Vec<(Vec<String>, Vec<String>)> {
    let (_, rows) = read_csv(path);
    rows.into_iter().map(|r| (r[..key].to_vec(), r[key..].to_vec())).collect()
}

/// The worker processes among the children of process `pid`.
fn worker_children(pid: u32) -> usize {
    let tasks = std::fs::read_dir(format!("/proc/{pid}/task")).map(|d| d.flatten().collect::<Vec<_>>()).unwrap_or_default();
    tasks
        .iter()
        .flat_map(|t| {
            std::fs::read_to_string(t.path().join("children")).unwrap_or_default().split_whitespace().map(str::to_owned).collect::<Vec<_>>()
        })
        .filter(|child| std::fs::read(format!("/proc/{child}/cmdline")).is_ok_and(|c| c.split(|&b| b == 0).nth(1) == Some(b"worker")))
        .count()
}

#[test]
fn crashing_and_hanging_points_are_recorded_and_the_rest_equal_an_in_process_run() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    // Temporary files go to a directory of the test's: crashed workers must leave none there.
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let sweep = |faults: &str, out: &str, extra: &[&str]| {
        let mut args = vec!["sweep", f, "--param", "k=0.5,1", "--param", faults, "--metric", "end=final(x)", "--metric", "mean=mean(x)"];
        args.extend_from_slice(&["--threads", "2", "--out", out]);
        args.extend_from_slice(extra);
        std::process::Command::new(env!("CARGO_BIN_EXE_runner")).current_dir(dir.path()).env("TMPDIR", &tmp).args(&args).output().unwrap()
    };
    // fault 0 runs normally; 1 SIGSEGV, 2 abort(), 3 a busy loop, 4 exit(3), all in fmi2DoStep
    // from t = 0.31 (the 32nd step of 0.01 s).
    let o = sweep("fault=0,1,2,3,4", "isolated.csv", &["--point-timeout", "1"]);
    assert_eq!(o.status.code(), Some(1), "failed points make the exit code 1: {}", stderr(&o));
    assert!(stderr(&o).contains("8 of 10 sweep point(s) failed"), "{}", stderr(&o));
    let isolated = rows_by_point(&dir.path().join("isolated.csv"), 2);
    let expected = [
        "ok",
        "crashed: SIGSEGV in fmi2DoStep at t = 0.31",
        "crashed: SIGABRT in fmi2DoStep at t = 0.31",
        "timed out after 1 s in fmi2DoStep at t = 0.31",
        "exited: the worker process ended with code 3 in fmi2DoStep at t = 0.31",
    ];
    assert_eq!(isolated.len(), 10);
    for (i, (point, values)) in isolated.iter().enumerate() {
        assert_eq!(values[2], expected[i % 5], "point {point:?}");
        if i % 5 != 0 {
            assert_eq!((values[0].as_str(), values[1].as_str()), ("", ""), "no metrics for a failed point");
        }
    }
    let left: Vec<_> = std::fs::read_dir(&tmp).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "workers load the supervisor's unpacked copy, so dead ones leave nothing: {left:?}");
    // The healthy points, in-process on threads (where a crash would take everything down).
    ok(sweep("fault=0", "in_process.csv", &["--in-process"]));
    let healthy: Vec<_> = isolated.iter().filter(|(_, v)| v[2] == "ok").cloned().collect();
    assert_eq!(healthy, rows_by_point(&dir.path().join("in_process.csv"), 2), "the same digits, so the same bits");
}

/// An FMU that leaks 40 MB per instance: a worker whose memory passes half its limit is replaced
/// after its point, so all eight points succeed (in one process they would need 320 MB of a
/// 256 MB limit) and equal an in-process run; one that leaks 10 MB every step from t = 0.31
/// exhausts the limit within its run, its malloc returns NULL and it crashes, that point alone.
#[test]
fn leaking_points_get_fresh_workers_and_a_runaway_leak_fails_its_point_only() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let metrics = ["--metric", "end=final(x)", "--metric", "pid=final(pid)"];
    let mut args = vec!["sweep", f, "--param", "x0=1:8:1", "--param", "fault=6", "--threads", "1", "--out", "leak.csv"];
    args.extend_from_slice(&metrics);
    // While it runs, a replaced worker must be gone at once (with its memory), not wait for the
    // end of the sweep: at most the running worker and one exiting are alive.
    let mut child = spawn_runner(dir.path(), &[&args[..], &["--worker-memory", "256"]].concat());
    let mut most = 0;
    while child.try_wait().unwrap().is_none() {
        most = most.max(worker_children(child.id()));
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    assert!(child.wait().unwrap().success());
    assert!(most <= 2, "{most} workers alive at once on 1 thread");
    let leaky = rows_by_point(&dir.path().join("leak.csv"), 2);
    assert!(leaky.iter().all(|(_, v)| v[2] == "ok"), "{leaky:?}");
    let pids: BTreeSet<&str> = leaky.iter().map(|(_, v)| v[1].as_str()).collect();
    assert!(pids.len() >= 3, "40 MB per point, replaced past 128 MB: a new worker every few points, got {pids:?}");
    let out = args.iter().position(|a| *a == "leak.csv").unwrap();
    args[out] = "in_process.csv";
    ok(runner(dir.path(), &[&args[..], &["--in-process"]].concat()));
    let in_process = rows_by_point(&dir.path().join("in_process.csv"), 2);
    let end = |rows: &[(Vec<String>, Vec<String>)]| rows.iter().map(|(p, v)| (p.clone(), v[0].clone())).collect::<Vec<_>>();
    assert_eq!(end(&leaky), end(&in_process));

    let o = runner(
        dir.path(),
        &[
            "sweep",
            f,
            "--param",
            "fault=0,5",
            "--set",
            "leak_mb=10",
            "--metric",
            "end=final(x)",
            "--worker-memory",
            "256",
            "--out",
            "runaway.csv",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = rows_by_point(&dir.path().join("runaway.csv"), 1);
    assert_eq!(rows[0].1[1], "ok");
    assert!(rows[1].1[1].starts_with("crashed: SIGSEGV in fmi2DoStep at t = "), "{rows:?}");
}

/// After fmi2Fatal the standard trusts no instance of the FMU in that process: the point that
/// returned it fails with the FMU's reason, and the next point runs in a fresh worker (on one
/// thread it would otherwise reuse the first one, as the point before the fatal one did).
#[test]
fn a_worker_whose_fmu_returned_fatal_runs_no_more_points() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let args = ["sweep", f, "--param", "fault=0,0,8,0", "--metric", "pid=final(pid)", "--threads", "1", "--out", "fatal.csv"];
    let o = runner(dir.path(), &args);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let rows = rows_by_point(&dir.path().join("fatal.csv"), 1);
    let pid = |i: usize| rows[i].1[0].clone();
    assert_eq!(pid(0), pid(1), "one worker runs the points before the fatal one: {rows:?}");
    assert!(rows[2].1[1].contains("fmi2DoStep at t = 0.31 returned fmi2Fatal: fault 8: the model is corrupted"), "{rows:?}");
    assert_eq!(rows[3].1[1], "ok");
    assert_ne!(pid(3), pid(1), "a fresh worker after the fatal point: {rows:?}");
}

/// canBeInstantiatedOnlyOncePerProcess: every point gets a process of its own (the FMU refuses a
/// second instance in a process, so sharing one would fail points), and --in-process is refused.
/// The same binary with the flag left false shows that the check can fail.
#[test]
fn fmus_instantiable_once_per_process_get_a_process_per_point() {
    let dir = tempfile::tempdir().unwrap();
    let once = faulty_fmu(dir.path(), "once.fmu", true, &["-DONCE_PER_PROCESS"]);
    let args = |fmu: &std::path::Path, out: &str| {
        ["sweep", fmu.to_str().unwrap(), "--param", "k=0.5:2:0.5", "--metric", "pid=final(pid)", "--threads", "2", "--out", out]
            .map(String::from)
    };
    let run = |a: &[String], extra: &[&str]| {
        let mut all: Vec<&str> = a.iter().map(String::as_str).collect();
        all.extend_from_slice(extra);
        runner(dir.path(), &all)
    };
    ok(run(&args(&once, "once.csv"), &[]));
    let rows = rows_by_point(&dir.path().join("once.csv"), 1);
    assert!(rows.iter().all(|(_, v)| v[1] == "ok"), "{rows:?}");
    assert_eq!(rows.iter().map(|(_, v)| &v[0]).collect::<BTreeSet<_>>().len(), 4, "four points, four processes");
    let err = fails(run(&args(&once, "x.csv"), &["--in-process"]));
    assert!(err.contains("canBeInstantiatedOnlyOncePerProcess") && err.contains("drop --in-process"), "{err}");

    let undeclared = faulty_fmu(dir.path(), "undeclared.fmu", false, &["-DONCE_PER_PROCESS"]);
    let o = run(&args(&undeclared, "shared.csv"), &[]);
    assert_eq!(o.status.code(), Some(1));
    let rows = rows_by_point(&dir.path().join("shared.csv"), 1);
    assert!(rows.iter().any(|(_, v)| v[1].contains("only once per process")), "workers reused for undeclared FMUs: {rows:?}");
}

/// A point's time limit counts from when its worker is ready: an FMU whose binary takes a second
/// to load (its initializer sleeps) runs its points within a limit of half a second.
#[test]
fn the_time_limit_does_not_count_the_start_of_a_worker() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "slow.fmu", false, &["-DSLOW_LOAD"]);
    let f = fmu.to_str().unwrap();
    ok(runner(dir.path(), &["sweep", f, "--param", "k=0.5,1,1.5", "--metric", "end=final(x)", "--point-timeout", "0.5", "--out", "s.csv"]));
    let rows = rows_by_point(&dir.path().join("s.csv"), 1);
    assert!(rows.iter().all(|(_, v)| v[1] == "ok"), "{rows:?}");
    ok(runner(dir.path(), &["simulate", f, "--timeout", "0.5", "--out", "x.csv"]));
}

#[test]
fn simulate_reports_the_signal_and_the_call_and_takes_a_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", f, "--out", "worker.csv"]));
    ok(runner(dir.path(), &["simulate", f, "--out", "in_process.csv", "--in-process"]));
    assert_eq!(
        std::fs::read(dir.path().join("worker.csv")).unwrap().len(),
        std::fs::read(dir.path().join("in_process.csv")).unwrap().len(),
        "the same rows (only the pid column differs)"
    );
    let (header, a) = read_csv(&dir.path().join("worker.csv"));
    let (_, b) = read_csv(&dir.path().join("in_process.csv"));
    let x = header.iter().position(|h| h == "x").unwrap();
    assert_eq!(a.iter().map(|r| &r[x]).collect::<Vec<_>>(), b.iter().map(|r| &r[x]).collect::<Vec<_>>(), "x bit for bit");

    let o = runner(dir.path(), &["simulate", f, "--set", "fault=1", "--out", "crash.csv"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("faulty: crashed: SIGSEGV in fmi2DoStep at t = 0.31"), "{}", stderr(&o));
    // The rows the worker sent before it died are kept: a prefix of the clean run's, all
    // before the crash at the first step from t >= 0.31.
    let (_, kept) = read_csv(&dir.path().join("crash.csv"));
    assert!(kept.len() <= 32 && kept.iter().zip(&a).all(|(k, r)| k[x] == r[x]), "{kept:?}");
    let o = runner(dir.path(), &["simulate", f, "--set", "fault=3", "--timeout", "0.5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("faulty: timed out after 0.5 s in fmi2DoStep at t = 0.31"), "{}", stderr(&o));
    let err = fails(runner(dir.path(), &["simulate", f, "--timeout", "1", "--in-process"]));
    assert!(err.contains("--timeout needs a worker process"), "{err}");
}

/// `compare` runs in a worker: the Euler runs crash (fault_solver = 0), or the RK4 runs hang
/// (fault_solver = 1) past --point-timeout; each is recorded in its row and the other solver's
/// runs and the reference still run.
#[test]
fn compare_records_crashed_runs_and_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let o = runner(
        dir.path(),
        &["compare", f, "--solvers", "euler,rk4", "--set", "fault=1", "--set", "fault_solver=0", "--out", "c.csv", "--plot", "c.svg"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (header, rows) = read_csv(&dir.path().join("c.csv"));
    let status = header.iter().position(|h| h == "status").unwrap();
    for row in &rows {
        if row[0] == "euler" {
            assert_eq!(row[status], "compare: crashed: SIGSEGV in fmi2DoStep at t = 0.31", "{row:?}");
        } else {
            assert_eq!(row[status], "ok", "{row:?}");
        }
    }
    assert!(rows.iter().filter(|r| r[0] == "euler").count() >= 2, "a new worker after each crash");

    let o = runner(
        dir.path(),
        &[
            "compare",
            f,
            "--solvers",
            "euler,rk4",
            "--set",
            "fault=3",
            "--set",
            "fault_solver=1",
            "--point-timeout",
            "0.3",
            "--out",
            "h.csv",
            "--plot",
            "h.svg",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, rows) = read_csv(&dir.path().join("h.csv"));
    for row in &rows {
        let expected = if row[0] == "rk4" { "compare: timed out after 0.3 s in fmi2DoStep at t = 0.31" } else { "ok" };
        assert_eq!(row[status], expected, "{row:?}");
    }
}

/// Workers start before the FMU is unpacked: when it turns out unusable, the sweep fails with the
/// FMU's problem alone, the workers let go before they were told what to load (they would
/// complain on stderr if they took that for a broken request).
/// No process is left running either: the workers are found by a mark in their environment
/// (inherited from the runner), whoever their parent is by then.
#[test]
fn workers_started_ahead_of_an_unusable_fmu_leave_only_its_error() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.fmu"), "not a zip").unwrap();
    let mark = format!("RUNNER_TEST_MARK=unusable-fmu-{}", std::process::id());
    let sweep = |fmu: &str| {
        let args = ["sweep", fmu, "--param", "k=1,2", "--metric", "end=final(x)", "--threads", "2", "--out", "s.csv"];
        let (key, value) = mark.split_once('=').unwrap();
        std::process::Command::new(env!("CARGO_BIN_EXE_runner")).current_dir(dir.path()).env(key, value).args(args).output().unwrap()
    };
    let err = fails(sweep("bad.fmu"));
    assert_eq!(err.lines().count(), 1, "one line, the FMU's problem: {err}");
    assert!(err.contains("bad.fmu is not a zip archive"), "{err}");
    let err = fails(sweep("/nonexistent.fmu"));
    assert_eq!(err.trim_end(), "error: FMU file /nonexistent.fmu does not exist");
    // A released worker exits within moments; one still there after seconds was left behind.
    let marked = || -> Vec<String> {
        std::fs::read_dir("/proc")
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().bytes().all(|b| b.is_ascii_digit()))
            .filter(|e| std::fs::read(e.path().join("environ")).is_ok_and(|env| env.split(|&b| b == 0).any(|v| v == mark.as_bytes())))
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect()
    };
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(5);
    while !marked().is_empty() && std::time::Instant::now() < deadline {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert_eq!(marked(), Vec::<String>::new(), "processes of the failed sweeps still running");
    assert!(!dir.path().join("s.csv.sweep").exists() && !dir.path().join("s.csv.partial").exists(), "nothing written");
}

/// The `runner-fmu-*` directories in the temporary directories (and /dev/shm).
fn unpack_dirs() -> BTreeSet<std::path::PathBuf> {
    let parents = [std::env::temp_dir(), "/tmp".into(), "/dev/shm".into()];
    parents
        .iter()
        .filter_map(|p| std::fs::read_dir(p).ok())
        .flat_map(|d| d.flatten().collect::<Vec<_>>())
        .filter(|e| e.file_name().to_string_lossy().starts_with("runner-fmu-"))
        .map(|e| e.path())
        .collect()
}

/// Those of the FMUs unpacked from a modelDescription.xml holding `token`, other than `old` ones.
fn unpacked_copies(token: &str, old: &BTreeSet<std::path::PathBuf>) -> Vec<std::path::PathBuf> {
    unpack_dirs()
        .into_iter()
        .filter(|d| !old.contains(d))
        .filter(|d| std::fs::read_to_string(d.join("modelDescription.xml")).is_ok_and(|xml| xml.contains(token)))
        .collect()
}

/// A marked copy of the C test FMU (its description holds a token of this test run), so that
/// its unpacked copies can be told from every other runner's.
fn marked_fmu(dir: &std::path::Path) -> (std::path::PathBuf, String) {
    let so = dir.join("dahlquist.so");
    compile_c_fmu(&so, &[]);
    let token = format!(
        "unpack-test-{}-{}",
        std::process::id(),
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos()
    );
    let xml = std::fs::read_to_string(c_fmu_dir().join("modelDescription.xml")).unwrap().replace("Dahlquist test equation", &token);
    assert!(xml.contains(&token));
    let fmu = dir.join("marked.fmu");
    let binary = std::fs::read(&so).unwrap();
    write_zip(&fmu, &[ZipItem::File("modelDescription.xml", xml.as_bytes()), ZipItem::File("binaries/linux64/dahlquist.so", &binary)]);
    (fmu, token)
}

/// A runner SIGKILLed while its FMU is unpacked in memory (/dev/shm) cannot remove the copy;
/// the next runner that unpacks there does, as the copy's process is gone. Where this machine
/// unpacks on disk instead (TMPDIR unset and /tmp a tmpfs, or /dev/shm unusable) the test
/// says so and checks nothing more: copies on disk are left to the system's cleaning of /tmp.
#[test]
fn a_killed_runners_copy_in_memory_is_removed_by_the_next_runner() {
    let dir = tempfile::tempdir().unwrap();
    let (fmu, token) = marked_fmu(dir.path());
    let f = fmu.to_str().unwrap();
    let old = unpack_dirs();
    let args = ["sweep", f, "--param", "k=0.5:1.3:0.0001", "--metric", "end=final(x)", "--output-interval", "1e-4", "--out", "s.csv"];
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
        .current_dir(dir.path())
        .env_remove("TMPDIR")
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    let copy = loop {
        if let Some(copy) = unpacked_copies(&token, &old).pop() {
            break copy;
        }
        assert!(child.try_wait().unwrap().is_none(), "the sweep ended before its copy was seen");
        assert!(started.elapsed() < std::time::Duration::from_secs(20), "no unpacked copy seen");
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    child.kill().unwrap();
    child.wait().unwrap();
    if !copy.starts_with("/dev/shm") {
        println!("this machine unpacks on disk ({}): nothing to clean in memory", copy.display());
        return;
    }
    assert!(copy.exists(), "the killed runner's copy is left behind");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
        .current_dir(dir.path())
        .env_remove("TMPDIR")
        .args(["info", f])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!copy.exists(), "the next runner removed {}", copy.display());
}

/// A sweep unpacks its FMU once, into a directory of its own (in memory, /dev/shm, when TMPDIR
/// is unset and the temporary directory is on disk), and removes it before it exits, in worker
/// processes and in-process alike. The copy is looked for while the sweep runs, so the test
/// knows where it was and cannot pass by looking in the wrong place.
#[test]
fn a_sweeps_unpacked_copy_is_removed_before_it_exits_in_both_modes() {
    let dir = tempfile::tempdir().unwrap();
    let (fmu, token) = marked_fmu(dir.path());
    for mode in [&[][..], &["--in-process"][..]] {
        let mut args =
            vec!["sweep", fmu.to_str().unwrap(), "--param", "k=0.5:1.3:0.004", "--metric", "end=final(x)", "--output-interval", "1e-3"];
        args.extend_from_slice(&["--threads", "2", "--out", "s.csv"]);
        args.extend_from_slice(mode);
        let _ = std::fs::remove_file(dir.path().join("s.csv"));
        // Directories left by other (killed) runs are not looked into.
        let old = unpack_dirs();
        let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_runner"))
            .current_dir(dir.path())
            .env_remove("TMPDIR")
            .args(&args)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let mut seen = Vec::new();
        let status = loop {
            if seen.is_empty() {
                seen = unpacked_copies(&token, &old);
            }
            if let Some(status) = child.try_wait().unwrap() {
                break status;
            }
            std::thread::sleep(std::time::Duration::from_millis(2));
        };
        assert!(status.success(), "the sweep {mode:?} failed");
        assert_eq!(seen.len(), 1, "one unpacked copy while the sweep {mode:?} ran: {seen:?}");
        assert_eq!(unpacked_copies(&token, &old), Vec::<std::path::PathBuf>::new(), "the sweep {mode:?} left its copy behind");
    }
}

/// A worker that crashes (fault 1, SIGSEGV) or hangs (fault 3, stopped by `--timeout 1`) in the
/// step from t = 1, after rows that came slowly (5 ms a step: half a second for the 101 rows t = 0
/// to 1), leaves in the --out file all but the rows of its last tenth of a second: the worker
/// sends what it holds once a tenth of a second has passed, not only when 64 KiB are waiting
/// (before, every row was lost with the worker, and the message said the run failed before its
/// first row). At 5 ms a step a tenth of a second is 20 rows; at least 60 of the 101 are asked
/// for, which leaves room for a loaded machine's slower wake-ups. The rows kept are the first
/// rows of a clean run's, and the message counts them.
#[test]
fn a_worker_that_crashes_or_hangs_keeps_all_but_its_last_tenth_of_a_second_of_rows() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "slow.fmu", false, &["-DSLOW_STEP"]);
    let f = fmu.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", f, "--stop-time", "1", "--out", "clean.csv"]));
    let (header, clean) = read_csv(&dir.path().join("clean.csv"));
    assert_eq!(clean.len(), 101);
    let x = header.iter().position(|h| h == "x").unwrap();
    for (fault, failure) in [("1", "crashed: SIGSEGV in fmi2DoStep at t = 1"), ("3", "timed out after 1 s in fmi2DoStep at t = 1")] {
        let out = format!("fault{fault}.csv");
        let set_fault = format!("fault={fault}");
        let args = ["simulate", f, "--set", &set_fault, "--set", "fault_time=1", "--stop-time", "2", "--timeout", "1", "--out", &out];
        let err = fails(runner(dir.path(), &args));
        assert!(err.contains(failure), "{err}");
        let (h, kept) = read_csv(&dir.path().join(&out));
        assert_eq!(h, header);
        assert!(kept.len() >= 60, "fault {fault}: {} of the 101 rows before the failure kept: {err}", kept.len());
        assert!(err.contains(&format!("{out} keeps the {} row(s) before the failure", kept.len())), "{err}");
        assert!(kept.iter().zip(&clean).all(|(k, c)| k[x] == c[x]), "fault {fault}: the kept rows are the clean run's first");
    }
}

/// Ctrl-C (SIGINT) a second into a run whose rows come slowly (5 ms a step, 100 s of model time)
/// stops it with exit code 130 and keeps in --out the rows before it, as a failed run and a
/// system's interrupted run do (it once threw them away after saying "keeping what has
/// finished"), in a worker and in this process: they are the first rows of a clean run, and the
/// message counts them. SIGTERM (a job scheduler's, `kill`'s) does the same: it once killed the
/// runner, leaving the rows in a hidden temporary file and no --out.
#[test]
fn an_interrupted_run_keeps_its_rows_in_the_out_file() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "slow.fmu", false, &["-DSLOW_STEP"]);
    let f = fmu.to_str().unwrap();
    ok(runner(dir.path(), &["simulate", f, "--stop-time", "1", "--out", "clean.csv"]));
    let (header, clean) = read_csv(&dir.path().join("clean.csv"));
    let x = header.iter().position(|h| h == "x").unwrap();
    for (mode, signal) in
        [(&[][..], libc::SIGINT), (&["--in-process"][..], libc::SIGINT), (&[][..], libc::SIGTERM), (&["--in-process"][..], libc::SIGTERM)]
    {
        let mut args = vec!["simulate", f, "--stop-time", "100", "--out", "stopped.csv"];
        args.extend(mode);
        let child = spawn_runner(dir.path(), &args);
        std::thread::sleep(std::time::Duration::from_secs(1));
        // SAFETY: a signal to the child this test started.
        assert_eq!(unsafe { libc::kill(child.id() as libc::pid_t, signal) }, 0);
        let o = child.wait_with_output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(130), "{mode:?}: {err}");
        let (h, kept) = read_csv(&dir.path().join("stopped.csv"));
        assert_eq!(h, header);
        assert!(!kept.is_empty() && kept.len() < 10_001, "{mode:?}: {} rows", kept.len());
        assert!(err.contains(&format!("stopped.csv keeps the {} row(s) before the interruption", kept.len())), "{mode:?}: {err}");
        assert!(kept.iter().zip(&clean).all(|(k, c)| k[x] == c[x]), "{mode:?}: the kept rows are a clean run's first");
    }
}

/// A run that fails (fmi2DoStep returns fmi2Error at the first step from t = 0.5) keeps in its
/// --out file every row before the failure, the same rows standard output gets (t = 0 to 0.5
/// every 0.01 s: 51 rows), in a worker and in this process; the error names the time, the call
/// and the FMU's reason, also when the FMU logged it as information (fault 9), and the exit code
/// is 1.
#[test]
fn a_failed_run_keeps_its_rows_in_the_out_file_and_says_when_and_why() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let f = fmu.to_str().unwrap();
    let to_stdout = runner(dir.path(), &["simulate", f, "--set", "fault=7", "--set", "fault_time=0.5"]);
    assert_eq!(to_stdout.status.code(), Some(1));
    std::fs::write(dir.path().join("stdout.csv"), &to_stdout.stdout).unwrap();
    let (header, streamed) = read_csv(&dir.path().join("stdout.csv"));
    assert_eq!(streamed.len(), 51, "t = 0 to 0.5 on standard output");
    let x = header.iter().position(|h| h == "x").unwrap();
    for (fault, reason) in [("7", "fault 7: this step is refused"), ("9", "fault 9: the step size is too large for the table")] {
        for mode in [&[][..], &["--in-process"][..]] {
            let out = format!("fault{fault}{}.csv", mode.len());
            let set_fault = format!("fault={fault}");
            let mut args = vec!["simulate", f, "--set", &set_fault, "--set", "fault_time=0.5", "--out", &out];
            args.extend(mode);
            let o = runner(dir.path(), &args);
            let err = stderr(&o);
            assert_eq!(o.status.code(), Some(1), "{err}");
            assert!(err.contains(&format!("fmi2DoStep at t = 0.5 returned fmi2Error: {reason}")), "{mode:?}: {err}");
            assert!(err.contains(&format!("{out} keeps the 51 row(s) before the failure, up to t = 0.5")), "{mode:?}: {err}");
            let (h, kept) = read_csv(&dir.path().join(&out));
            assert_eq!(h, header);
            assert_eq!(kept.iter().map(|r| &r[x]).collect::<Vec<_>>(), streamed.iter().map(|r| &r[x]).collect::<Vec<_>>(), "{mode:?}");
        }
    }
    // Fault 10 logs its reason only with debug logging on: without --log the error says so,
    // with --log it carries the reason.
    let args = ["simulate", f, "--set", "fault=10", "--set", "fault_time=0.5", "--out", "quiet.csv"];
    let err = fails(runner(dir.path(), &args));
    assert!(
        err.contains("fmi2DoStep at t = 0.5 returned fmi2Error (the FMU logged no reason; with debug logging on (the runner's --log)"),
        "{err}"
    );
    let err = fails(runner(dir.path(), &[&args[..], &["--log"]].concat()));
    assert!(err.contains("fmi2DoStep at t = 0.5 returned fmi2Error: fault 10: said with debug logging only"), "{err}");
}

/// An FMU that leaves code to run at process exit (-DEXIT_HANDLER: an exit handler registered
/// for the whole process, as a PythonFMU's libpython does) needs its binary loaded until the
/// process exits: unloaded earlier, the exit jumps into unmapped memory (SIGSEGV, exit code
/// 139 from a shell). Each command ends cleanly, in this process and in a worker.
#[test]
fn an_fmus_binary_stays_loaded_until_the_process_exits() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "atexit.fmu", false, &["-DEXIT_HANDLER"]);
    let f = fmu.to_str().unwrap();
    for args in [&["simulate", f, "--in-process", "--out", "a.csv"][..], &["simulate", f, "--out", "b.csv"], &["info", f]] {
        let o = runner(dir.path(), args);
        assert_eq!(o.status.code(), Some(0), "{args:?} ended by {:?}: {}", o.status, stderr(&o));
    }
    let (_, rows) = read_csv(&dir.path().join("a.csv"));
    assert_eq!(rows.len(), 101, "the run itself is unchanged");
}
