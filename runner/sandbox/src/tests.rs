//! The sandbox against a real worker process: this test binary started again in worker mode
//! ([`worker_entry`]), running jobs that square a number, stream, crash, exit, hang, leak or
//! report an fmiFatal. What is compared: each job's outcome (the squares, or the failure in
//! words with the step the worker recorded in its shared memory) and which process ran it.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::worker::{Incoming, Serving};
use crate::{run_batch, Config, Failure, Service, Session, SharedMemory, WorkerCommand, Workers};

/// The test service.
struct Test;

#[derive(Debug, Clone, Serialize, Deserialize)]
enum Job {
    Square(u64),
    /// Sends 0, 1, ... n - 1 as messages.
    Stream(u64),
    Crash,
    Exit(i32),
    Hang,
    /// Keeps this many more bytes, touched.
    Leak(usize),
    /// Squares, and reports the process tainted (as after an fmiFatal).
    Fatal(u64),
}

/// A job's value and the worker process that ran it, or its failure in words.
type Outcome = Result<(u64, u32), String>;

impl Service for Test {
    type Setup = String;
    type Job = Job;
    type Message = u64;
    type Outcome = Outcome;

    fn failed(_: &Job, failure: &Failure, shared: &SharedMemory) -> Outcome {
        // SAFETY: an atomic in a zeroed page.
        let step = unsafe { shared.view::<AtomicU64>() }.load(Ordering::Relaxed);
        Err(failure.describe(&format!("at step {step}")))
    }
}

const WORKER: &str = "RUNNER_SANDBOX_TEST_WORKER";

/// The worker's side; a test only when this binary is started by the tests below.
#[test]
fn worker_entry() {
    if std::env::var_os(WORKER).is_none() {
        return;
    }
    let code = match serve() {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("test worker: {e}");
            1
        }
    };
    std::process::exit(code);
}

fn serve() -> Result<(), String> {
    let mut serving = Serving::<Test>::start()?;
    // SAFETY: an atomic in a zeroed page.
    let step = unsafe { serving.shared().view::<AtomicU64>() };
    let mut kept: Vec<Vec<u8>> = Vec::new();
    while let Some(request) = serving.receive()? {
        match request {
            Incoming::Setup(setup) => serving.ready(if setup == "refuse" { Err("refused to set up".into()) } else { Ok(()) })?,
            Incoming::Job { id, job } => {
                step.store(id, Ordering::Relaxed);
                let pid = std::process::id();
                let (outcome, tainted) = match job {
                    Job::Square(x) => (Ok((x * x, pid)), false),
                    Job::Fatal(x) => (Ok((x * x, pid)), true),
                    Job::Stream(n) => {
                        for k in 0..n {
                            serving.send(&k)?;
                        }
                        (Ok((n, pid)), false)
                    }
                    Job::Crash => {
                        // SAFETY: the default action of SIGSEGV ends this process, as a crash does
                        // (Rust's own handler would let a raised signal return).
                        unsafe {
                            libc::signal(libc::SIGSEGV, libc::SIG_DFL);
                            libc::raise(libc::SIGSEGV);
                        }
                        unreachable!("SIGSEGV ends the process")
                    }
                    Job::Exit(code) => std::process::exit(code),
                    Job::Hang => loop {
                        std::thread::sleep(Duration::from_secs(1));
                    },
                    Job::Leak(bytes) => {
                        kept.push(vec![1u8; bytes]);
                        (Ok((kept.len() as u64, pid)), false)
                    }
                };
                serving.finish(id, outcome, tainted)?;
            }
        }
    }
    Ok(())
}

/// Workers of this test binary; what they print (the test harness's own lines) goes to a file
/// in the directory returned, removed when it is dropped.
fn config() -> (Config, tempfile::TempDir) {
    let logs = tempfile::tempdir().unwrap();
    let program = std::env::current_exe().unwrap();
    let args = ["--exact", "tests::worker_entry", "--nocapture", "--test-threads", "1", "-q"].map(Into::into).to_vec();
    let command = WorkerCommand { program, args, env: vec![(WORKER.into(), "1".into())] };
    (Config { log_file: Some(logs.path().join("workers.log")), ..Config::new(command) }, logs)
}

/// Runs `jobs` on `threads` workers; the outcomes in the order delivered.
fn batch(config: Config, threads: usize, jobs: &[Job], setup: &str) -> Result<Vec<(usize, Outcome)>, String> {
    let mut workers = Workers::<Test>::start(config, threads)?;
    workers.setup(&"load".to_owned());
    let mut delivered = Vec::new();
    run_batch(
        workers,
        &setup.to_owned(),
        0..jobs.len(),
        |i| jobs[i].clone(),
        &|| false,
        |i, outcome| {
            delivered.push((i, outcome));
            Ok(())
        },
    )?;
    Ok(delivered)
}

/// A crash and an exit cost their own job only, named with the step the worker recorded; every
/// other job runs, and results arrive in job order.
#[test]
fn a_batch_charges_a_crash_to_its_job_only_and_delivers_in_order() {
    let jobs: Vec<Job> = (0..12u64)
        .map(|i| match i {
            3 => Job::Crash,
            7 => Job::Exit(3),
            _ => Job::Square(i),
        })
        .collect();
    let (config, _logs) = config();
    let delivered = batch(config, 2, &jobs, "sweep").unwrap();
    assert_eq!(delivered.iter().map(|(i, _)| *i).collect::<Vec<_>>(), (0..12).collect::<Vec<_>>());
    for (i, outcome) in &delivered {
        match i {
            3 => assert_eq!(outcome.as_ref().unwrap_err(), "crashed: SIGSEGV at step 3"),
            7 => assert_eq!(outcome.as_ref().unwrap_err(), "exited: the worker process ended with code 3 at step 7"),
            _ => assert_eq!(outcome.as_ref().unwrap().0, (*i as u64).pow(2)),
        }
    }
}

/// A job past the time limit is killed and charged; the batch goes on.
#[test]
fn a_hanging_job_times_out() {
    let (config, _logs) = config();
    let config = Config { timeout: Some(Duration::from_millis(300)), ..config };
    let jobs = [Job::Square(2), Job::Hang, Job::Square(4)];
    let delivered = batch(config, 1, &jobs, "sweep").unwrap();
    assert_eq!(delivered[1].1, Err("timed out after 0.3 s at step 1".to_owned()));
    assert_eq!((delivered[0].1.clone().unwrap().0, delivered[2].1.clone().unwrap().0), (4, 16));
}

/// A setup the worker refuses ends the batch with the worker's reason.
#[test]
fn a_refused_setup_ends_the_batch_with_its_reason() {
    let (config, _logs) = config();
    assert_eq!(batch(config, 2, &[Job::Square(1), Job::Square(2)], "refuse").unwrap_err(), "refused to set up");
}

/// After an fmiFatal the worker is not trusted with another job; a worker past half its memory
/// limit is replaced too.
#[test]
fn tainted_and_worn_out_workers_are_replaced() {
    let pids = |delivered: &[(usize, Outcome)]| delivered.iter().map(|(_, o)| o.as_ref().unwrap().1).collect::<Vec<_>>();
    let (config, _logs) = config();
    let delivered = batch(config.clone(), 1, &[Job::Square(1), Job::Fatal(2), Job::Square(3), Job::Square(4)], "sweep").unwrap();
    let p = pids(&delivered);
    assert_eq!(p[0], p[1], "the same worker until the fatal job");
    assert_ne!(p[1], p[2], "a fresh worker after it");
    assert_eq!(delivered[2].1.as_ref().unwrap().0, 9);
    // 256 MiB of address space, replaced past 128 MiB of resident memory: 40 MiB per job.
    let config = Config { memory_limit: Some(256 << 20), ..config };
    let leaks = vec![Job::Leak(40 << 20); 8];
    let p = pids(&batch(config, 1, &leaks, "sweep").unwrap());
    let mut jobs_per_worker = std::collections::BTreeMap::<u32, usize>::new();
    for pid in &p {
        *jobs_per_worker.entry(*pid).or_default() += 1;
    }
    assert!(jobs_per_worker.len() >= 2 && jobs_per_worker.values().all(|&n| n <= 4), "a new worker every 4 jobs at most: {p:?}");
}

/// A session streams a job's messages, survives a crash with a fresh worker, and stops when
/// asked.
#[test]
fn a_session_streams_and_replaces_a_crashed_worker() {
    let (config, _logs) = config();
    let mut session = Session::<Test>::new(config, &["load".to_owned()], false);
    let mut seen = Vec::new();
    let outcome = session.run(Job::Stream(5), &|| false, |k| {
        seen.push(k);
        Ok(())
    });
    assert_eq!(seen, [0, 1, 2, 3, 4]);
    let first = outcome.unwrap().unwrap().1;
    assert_eq!(session.run(Job::Crash, &|| false, |_| Ok(())).unwrap(), Err("crashed: SIGSEGV at step 0".to_owned()));
    let after = session.run(Job::Square(3), &|| false, |_| Ok(())).unwrap().unwrap();
    assert_eq!(after.0, 9);
    assert_ne!(after.1, first, "a fresh worker after the crash");
    assert_eq!(session.run(Job::Hang, &|| true, |_| Ok(())).unwrap_err(), "interrupted");
    // A watchdog of the client's: the job's step (written by the worker) tells it overran.
    let mut watch = |shared: &SharedMemory| {
        // SAFETY: an atomic in a zeroed page.
        (unsafe { shared.view::<AtomicU64>() }.load(Ordering::Relaxed) == 0).then_some(Duration::from_millis(7))
    };
    let watched = session.run_watched(Job::Hang, &|| false, &mut watch, |_| Ok(())).unwrap();
    assert_eq!(watched, Err("timed out after 0.007 s at step 0".to_owned()));
    let refused = session.run(Job::Stream(3), &|| false, |_| Err("no room".to_owned()));
    assert_eq!(refused.unwrap_err(), "no room", "a failing consumer stops the job");
}

#[test]
fn failures_name_the_signal_and_the_place() {
    use std::os::unix::process::ExitStatusExt;
    let segv = std::process::ExitStatus::from_raw(libc::SIGSEGV);
    assert_eq!(Failure::Ended(segv).describe("in fmi2DoStep at t = 0.31"), "crashed: SIGSEGV in fmi2DoStep at t = 0.31");
    assert_eq!(
        Failure::Ended(std::process::ExitStatus::from_raw(3 << 8)).describe("in fmi2DoStep at t = 1"),
        "exited: the worker process ended with code 3 in fmi2DoStep at t = 1"
    );
    assert_eq!(
        Failure::TimedOut(Duration::from_millis(500)).describe("in fmi2DoStep at t = 2.5"),
        "timed out after 0.5 s in fmi2DoStep at t = 2.5"
    );
    assert_eq!(crate::signal_name(64), "signal 64");
}

#[test]
fn timeouts_must_be_positive() {
    assert_eq!(crate::timeout("--timeout", Some(0.5)).unwrap(), Some(Duration::from_millis(500)));
    assert!(crate::timeout("--timeout", Some(0.0)).unwrap_err().contains("--timeout 0 must be a positive"));
    assert!(crate::timeout("--timeout", Some(f64::NAN)).is_err());
}
