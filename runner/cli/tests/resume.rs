//! Durable sweeps: the finished rows are in `<out>.partial` as points finish, a sweep killed
//! with SIGKILL at any moment continues with `--resume` and ends with exactly the bytes of an
//! uninterrupted run, a partial file of another sweep is refused with the difference (a metric
//! typed another way is not one), and write
//! failures (a full disk, here a file size limit) leave the rows already written intact.

mod common;

use std::os::unix::process::CommandExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;

/// The sweep these tests run: 401 points of about 3 ms each (3,000 steps of the C FMU through
/// the debug-built runner), so about 0.6 s on 2 workers.
fn sweep_args<'a>(fmu: &'a str, out: &'a str) -> Vec<&'a str> {
    vec![
        "sweep",
        fmu,
        "--param",
        "k=0.5:1.3:0.002",
        "--metric",
        "end=final(x)",
        "--metric",
        "m=mean(x)",
        "--output-interval",
        "1e-3",
        "--threads",
        "2",
        "--out",
        out,
    ]
}

/// The reference: the same sweep uninterrupted, in-process.
fn reference(dir: &Path, fmu: &str) -> Vec<u8> {
    let mut args = sweep_args(fmu, "reference.csv");
    args.push("--in-process");
    ok(runner(dir, &args));
    std::fs::read(dir.join("reference.csv")).unwrap()
}

/// Worker processes of the runner whose parent is this test process: orphans, which a killed
/// runner must not leave (its workers die with it).
fn orphaned_workers() -> Vec<u32> {
    let me = std::process::id();
    let mut found = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        let stat = std::fs::read_to_string(entry.path().join("stat")).unwrap_or_default();
        let ppid = stat.rsplit(')').next().and_then(|rest| rest.split_whitespace().nth(1)).and_then(|p| p.parse::<u32>().ok());
        let cmdline = std::fs::read(entry.path().join("cmdline")).unwrap_or_default();
        if ppid == Some(me) && cmdline.split(|&b| b == 0).nth(1) == Some(b"worker") {
            found.push(pid);
        }
    }
    found
}

/// SIGKILL at pseudo-random moments (the seed is printed), up to five times, each followed by
/// `--resume`; then a last `--resume` that runs to the end must write the reference's bytes.
/// Orphaned workers would be reparented to this process (a child subreaper) and are looked for.
#[test]
fn a_sweep_killed_at_random_moments_resumes_to_exactly_the_uninterrupted_csv() {
    // SAFETY: prctl on this process.
    assert_eq!(unsafe { libc::prctl(libc::PR_SET_CHILD_SUBREAPER, 1) }, 0);
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let expected = reference(dir.path(), f);
    let mut seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos() as u64 | 1;
    println!("kill times from seed {seed}");
    let mut random = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut args = sweep_args(f, "killed.csv");
    let mut kills = 0;
    let started = Instant::now();
    while kills < 5 {
        let mut child = spawn_runner(dir.path(), &args);
        let delay = Duration::from_millis(40 + random() % 350);
        std::thread::sleep(delay);
        if child.try_wait().unwrap().is_some() {
            break; // it finished before the kill: the last run below checks the result
        }
        child.kill().unwrap();
        child.wait().unwrap();
        kills += 1;
        let partial = dir.path().join("killed.csv.partial");
        if partial.exists() {
            let bytes = std::fs::read(&partial).unwrap();
            assert!(
                expected.starts_with(&bytes[..bytes.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1)]),
                "after a kill at {delay:?}, the partial file's complete rows are the reference's first rows"
            );
        }
        if args.last() != Some(&"--resume") {
            args.push("--resume");
        }
        assert!(started.elapsed() < Duration::from_secs(60), "bounded");
    }
    println!("{kills} kills");
    if args.last() != Some(&"--resume") {
        args.push("--resume");
    }
    ok(runner(dir.path(), &args));
    assert_eq!(std::fs::read(dir.path().join("killed.csv")).unwrap(), expected, "exactly the uninterrupted run's CSV");
    assert!(!dir.path().join("killed.csv.partial").exists());
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(orphaned_workers(), Vec::<u32>::new(), "a killed runner's workers die with it");

    // Resuming the finished sweep says so and changes nothing.
    let before = std::fs::metadata(dir.path().join("killed.csv")).unwrap().modified().unwrap();
    let o = runner(dir.path(), &args);
    assert!(o.status.success());
    assert!(stderr(&o).contains("killed.csv is already complete: all 401 points of this sweep are there; nothing to do"), "{}", stderr(&o));
    assert_eq!(std::fs::metadata(dir.path().join("killed.csv")).unwrap().modified().unwrap(), before);
}

#[test]
fn resume_refuses_a_partial_file_of_another_sweep_and_names_the_difference() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let expected = reference(dir.path(), f);
    // A sweep killed after its first ten rows, as a kill leaves it: the record and a partial file.
    ok(runner(dir.path(), &sweep_args(f, "s.csv")));
    let ten_rows: usize = expected.split_inclusive(|&b| b == b'\n').take(11).map(<[u8]>::len).sum();
    std::fs::write(dir.path().join("s.csv.partial"), &expected[..ten_rows + 7]).unwrap(); // and a torn row
    std::fs::remove_file(dir.path().join("s.csv")).unwrap();
    let partial_before = std::fs::read(dir.path().join("s.csv.partial")).unwrap();

    let mut other_metric = sweep_args(f, "s.csv");
    other_metric[7] = "m=max(x)";
    other_metric.push("--resume");
    let err = fails(runner(dir.path(), &other_metric));
    assert!(
        err.contains("s.csv.partial is not from this sweep")
            && err.contains("metric: the partial file's sweep has end=final(x); m=mean(x), this one end=final(x); m=max(x)"),
        "{err}"
    );
    let rebuilt = c_fmu(dir.path(), "rebuilt.fmu", "linux64", &["-O0"]);
    let mut other_fmu = sweep_args(rebuilt.to_str().unwrap(), "s.csv");
    other_fmu.push("--resume");
    let err = fails(runner(dir.path(), &other_fmu));
    assert!(err.contains("fmu_sha256: the partial file's sweep has"), "{err}");
    let mut other_grid = sweep_args(f, "s.csv");
    other_grid[9] = "2e-3";
    other_grid.push("--resume");
    assert!(fails(runner(dir.path(), &other_grid)).contains("output_interval: the partial file's sweep has 0.001, this one 0.002"));
    let err = fails(runner(dir.path(), &sweep_args(f, "s.csv")));
    assert!(err.contains("s.csv.partial holds the finished points of an earlier sweep: continue it with --resume"), "{err}");
    assert_eq!(std::fs::read(dir.path().join("s.csv.partial")).unwrap(), partial_before, "refusals change nothing");

    // The same metric typed another way is the same sweep.
    let mut resume = sweep_args(f, "s.csv");
    resume[5] = "end = final( x )";
    resume.push("--resume");
    let o = runner(dir.path(), &resume);
    assert!(stderr(&o).contains("resuming: 10 of 401 points are in s.csv.partial; running the other 391"), "{}", stderr(&o));
    assert!(o.status.success());
    assert_eq!(std::fs::read(dir.path().join("s.csv")).unwrap(), expected);
    let err = fails(runner(dir.path(), &["sweep", f, "--param", "k=1,2", "--metric", "e=final(x)", "--resume"]));
    assert!(err.contains("--resume needs --out"), "{err}");
}

/// Two sweeps to the same `--out` at once would interleave their rows in one partial file: the
/// second is refused at once, naming the file, whether it starts afresh or with `--resume`, and
/// changes nothing. The lock dies with its process: after a SIGKILL of the first, `--resume`
/// continues and ends with exactly the uninterrupted run's bytes. Before the lock, the second
/// with `--resume` ran, both appending to one file (a fresh one is refused only because the
/// partial file is there already, so not before the first's header is written).
#[test]
fn a_second_sweep_to_the_same_out_is_refused_and_a_killed_ones_lock_does_not_block_resume() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    // Four times the other tests' points (about 2.5 s on 2 workers): the first sweep is still
    // running while the second starts and is refused, which is checked below.
    let mut args = sweep_args(f, "s.csv");
    args[3] = "k=0.5:1.3:0.0005";
    let mut reference_args = args.clone();
    reference_args[13] = "reference.csv";
    reference_args.push("--in-process");
    ok(runner(dir.path(), &reference_args));
    let expected = std::fs::read(dir.path().join("reference.csv")).unwrap();

    let mut first = spawn_runner(dir.path(), &args);
    let partial = dir.path().join("s.csv.partial");
    let started = Instant::now();
    while std::fs::read(&partial).map_or(0, |b| b.iter().filter(|&&c| c == b'\n').count()) < 20 {
        assert!(started.elapsed() < Duration::from_secs(60) && first.try_wait().unwrap().is_none(), "the first sweep writes rows");
        std::thread::sleep(Duration::from_millis(10));
    }
    let mut resumed = args.clone();
    resumed.push("--resume");
    for second in [&resumed, &args] {
        let err = fails(runner(dir.path(), second));
        assert!(err.contains("another sweep is writing s.csv (it holds s.csv.sweep locked)"), "{err}");
    }
    assert!(first.try_wait().unwrap().is_none(), "the first sweep was still running while the second was refused");
    first.kill().unwrap(); // SIGKILL: no chance to unlock
    first.wait().unwrap();
    let o = runner(dir.path(), &resumed);
    assert!(o.status.success() && stderr(&o).contains("resuming: "), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.path().join("s.csv")).unwrap(), expected, "exactly the uninterrupted run's CSV");
}

/// The record names the FMU by its content: the same path holding another build is refused on
/// `--resume` with the digests side by side, and accepted again once the first build is back.
#[test]
fn resume_refuses_a_changed_fmu_at_the_same_path() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "m.fmu", "linux64", &[]);
    let original = std::fs::read(&fmu).unwrap();
    let other = std::fs::read(c_fmu(dir.path(), "other.fmu", "linux64", &["-O0"])).unwrap();
    assert_ne!(original, other);
    let f = fmu.to_str().unwrap();
    let mut args = vec!["sweep", f, "--param", "k=0.5:1.3:0.1", "--metric", "end=final(x)", "--out", "s.csv"];
    ok(runner(dir.path(), &args));
    let complete = std::fs::read(dir.path().join("s.csv")).unwrap();
    // As a kill leaves it: the header and three rows in the partial file.
    let rows: usize = complete.split_inclusive(|&b| b == b'\n').take(4).map(<[u8]>::len).sum();
    std::fs::write(dir.path().join("s.csv.partial"), &complete[..rows]).unwrap();
    std::fs::remove_file(dir.path().join("s.csv")).unwrap();
    args.push("--resume");
    std::fs::write(&fmu, &other).unwrap();
    let err = fails(runner(dir.path(), &args));
    assert!(err.contains("s.csv.partial is not from this sweep") && err.contains("fmu_sha256: the partial file's sweep has"), "{err}");
    std::fs::write(&fmu, &original).unwrap();
    let o = runner(dir.path(), &args);
    assert!(o.status.success() && stderr(&o).contains("resuming: 3 of 9 points"), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.path().join("s.csv")).unwrap(), complete);
}

/// A write that fails (here past a file size limit, EFBIG, as a full disk fails with ENOSPC) stops
/// the sweep with a message naming the file and the cause; the partial file keeps exactly its
/// complete rows, and `--resume` once it can be written finishes it to the reference's bytes.
#[test]
fn a_failing_write_keeps_the_rows_already_written_and_the_sweep_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    // 1,601 short points, 80 kB of CSV; the limit lets the 16 kB binary be unpacked.
    let args =
        |out: &'static str| ["sweep", f, "--param", "k=0.5:1.3:0.0005", "--metric", "end=final(x)", "--metric", "m=mean(x)", "--out", out];
    ok(runner(dir.path(), &args("reference.csv")));
    let expected = std::fs::read(dir.path().join("reference.csv")).unwrap();
    let limit = 40_000;
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_runner"));
    cmd.current_dir(dir.path()).args(args("s.csv")).stdout(Stdio::null()).stderr(Stdio::piped());
    // SAFETY: setrlimit and signal between fork and exec, both async-signal-safe.
    unsafe {
        cmd.pre_exec(move || {
            let rlimit = libc::rlimit { rlim_cur: limit, rlim_max: limit };
            libc::setrlimit(libc::RLIMIT_FSIZE, &rlimit);
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            Ok(())
        });
    }
    let o = cmd.output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot write s.csv.partial: File too large") && err.contains("--resume"), "{err}");
    let partial = std::fs::read(dir.path().join("s.csv.partial")).unwrap();
    assert!(partial.len() as u64 <= limit && partial.len() > 100 && partial.ends_with(b"\n"), "{} bytes", partial.len());
    assert!(expected.starts_with(&partial), "complete rows only, each the reference's");
    assert!(!dir.path().join("s.csv").exists());
    ok(runner(dir.path(), &[&args("s.csv")[..], &["--resume"]].concat()));
    assert_eq!(std::fs::read(dir.path().join("s.csv")).unwrap(), expected);
}

#[test]
fn an_unwritable_destination_is_refused_before_any_point_runs() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let err = fails(runner(dir.path(), &sweep_args(f, "/proc/s.csv")));
    assert!(err.contains("cannot") && err.contains("/proc/s.csv"), "{err}");
    assert!(!err.contains("points in"), "nothing ran: {err}");
    let err = fails(runner(dir.path(), &sweep_args(f, "no/such/dir/s.csv")));
    assert!(err.contains("the directory no/such/dir does not exist"), "{err}");
}

/// Unmounts a file system mounted by a test, whatever happens.
struct Mounted(std::path::PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(&self.0).status();
    }
}

/// A really full disk (ENOSPC): a 64 kB tmpfs mounted for the test. The message names the file,
/// the cause and how many rows it kept, which are exactly the rows on file, each the reference's;
/// after the file system grows, `--resume` finishes the sweep to the reference's bytes. Mounting
/// needs root (as the test command runs here); elsewhere the test says it did not run, and the
/// file size limit test above covers the same code.
#[test]
fn a_full_disk_is_reported_and_the_rows_on_it_stay_intact() {
    let dir = tempfile::tempdir().unwrap();
    let small = dir.path().join("small");
    std::fs::create_dir(&small).unwrap();
    let mounted = Command::new("mount").args(["-t", "tmpfs", "-o", "size=64k", "tmpfs"]).arg(&small).status();
    if !mounted.is_ok_and(|s| s.success()) {
        eprintln!("not run: cannot mount a small tmpfs here (it needs root)");
        return;
    }
    let _unmount = Mounted(small.clone());
    let fmu = c_fmu(dir.path(), "dahlquist.fmu", "linux64", &[]);
    let f = fmu.to_str().unwrap();
    let args = |out: &str| {
        ["sweep", f, "--param", "k=0.5:1.5:0.0002", "--metric", "end=final(x)", "--metric", "m=mean(x)", "--out", out].map(String::from)
    };
    let run = |a: &[String], extra: &[&str]| {
        let mut all: Vec<&str> = a.iter().map(String::as_str).collect();
        all.extend_from_slice(extra);
        runner(dir.path(), &all)
    };
    ok(run(&args("reference.csv"), &["--in-process"]));
    let expected = std::fs::read(dir.path().join("reference.csv")).unwrap();
    assert!(expected.len() > 200_000, "the CSV does not fit on 64 kB");
    let out = small.join("t.csv");
    let o = run(&args(out.to_str().unwrap()), &[]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("t.csv.partial: No space left on device"), "{err}");
    let partial = std::fs::read(small.join("t.csv.partial")).unwrap();
    assert!(expected.starts_with(&partial) && partial.ends_with(b"\n"), "complete rows only, each the reference's");
    let rows = partial.iter().filter(|&&b| b == b'\n').count() - 1;
    assert!(err.contains(&format!("the {rows} points finished before are kept in")), "the count is of the rows on file: {err}");
    let grown = Command::new("mount").args(["-o", "remount,size=1m"]).arg(&small).status().unwrap();
    assert!(grown.success());
    ok(run(&args(out.to_str().unwrap()), &["--resume"]));
    assert_eq!(std::fs::read(&out).unwrap(), expected);
}

/// A destination that is a stream (`--out /dev/null`, `/dev/stdout`, a FIFO) is written directly:
/// the atomic temp-file-and-rename of result files, and a sweep's `<out>.partial`, would replace
/// the device with a regular file (as root, `--out /dev/null` did replace /dev/null). A FIFO
/// stands in for the device here: after `simulate` and `sweep`, it is still a FIFO, its reader got
/// the whole CSV, and nothing was created beside it. `--resume` to a stream is refused.
#[test]
fn a_device_or_pipe_destination_is_written_not_replaced() {
    use std::os::unix::fs::FileTypeExt;
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("rows");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let fifo_arg = fifo.to_str().unwrap();
    for args in [
        vec!["simulate", "second_order", "--stop-time", "1", "--out", fifo_arg],
        vec!["sweep", "second_order", "--param", "a0=10:12:1", "--metric", "peak=max(q)", "--out", fifo_arg],
    ] {
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
        };
        ok(runner(dir.path(), &args));
        let text = reader.join().unwrap();
        assert!(std::fs::metadata(&fifo).unwrap().file_type().is_fifo(), "{args:?}: the FIFO was replaced");
        let lines: Vec<&str> = text.lines().collect();
        match args[0] {
            "simulate" => assert!(lines[0].starts_with("time,") && lines.len() > 10, "{args:?}: {text}"),
            _ => assert_eq!(lines.len(), 4, "{args:?}: the header and 3 points: {text}"),
        }
        let beside: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(beside, [std::ffi::OsString::from("rows")], "{args:?}: nothing created beside the FIFO");
    }
    let o =
        runner(dir.path(), &["sweep", "second_order", "--param", "a0=10:12:1", "--metric", "peak=max(q)", "--out", fifo_arg, "--resume"]);
    assert!(!o.status.success() && stderr(&o).contains("--resume needs a regular file"), "{}", stderr(&o));
}
