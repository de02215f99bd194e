//! Instances on threads, for ThreadSanitizer: each thread runs random call sequences (the
//! driver of `fmi_calls`, fed from its own random bytes) on its own instances of every model,
//! FMI 2.0 and 3.0, for a given time. FMI allows distinct instances of one FMU to be called
//! from distinct threads at once, so the FMUs must share no mutable state between instances:
//! TSan reports any data race.
//!
//! Usage: fmi_threads SECONDS [THREADS]   (prints the counters; a race aborts with TSan's report)

#![feature(c_variadic)]

#[path = "../src/driver.rs"]
mod driver;
#[path = "../src/fmus.rs"]
mod fmus;

use std::time::{Duration, Instant};

/// xorshift64*: the threads' bytes (no dependency, reproducible from the seed printed).
fn fill(state: &mut u64, bytes: &mut [u8]) {
    for chunk in bytes.chunks_mut(8) {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        let v = state.wrapping_mul(0x2545_f491_4f6c_dd1d).to_le_bytes();
        chunk.copy_from_slice(&v[..chunk.len()]);
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seconds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let threads: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(4);
    let seed = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64) | 1;
    eprintln!("fmi_threads: {threads} threads for {seconds}s, seed {seed}");
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let fmus = fmus::all();
    // The last guard against a call that never returns: every call's work is bounded (one
    // fmi2DoStep takes at most solvers::MAX_STEPS_PER_CALL step attempts, issue 37, where a
    // pendulum of length 1e-20 used to have it step for hours), but should a bound fail, the
    // run stops GRACE after its deadline whatever a thread is doing: a race is reported (and
    // aborts) when it happens, so nothing TSan saw is lost; the counters say how far the run got.
    const GRACE: Duration = Duration::from_secs(30);
    std::thread::spawn(move || {
        std::thread::sleep(deadline.saturating_duration_since(Instant::now()) + GRACE);
        println!("fmi_threads: {} (a call was still running {}s after the deadline: stopped there)", driver::summary(), GRACE.as_secs());
        // SAFETY: _exit ends the process without running destructors or atexit handlers,
        // which the threads still inside the FMUs could race with.
        unsafe { libc::_exit(0) }
    });
    std::thread::scope(|scope| {
        let mut handles = Vec::new();
        for k in 0..threads {
            let fmus = &fmus;
            handles.push(scope.spawn(move || {
                let mut state = seed.wrapping_add(0x9e37_79b9_7f4a_7c15u64.wrapping_mul(k as u64 + 1)) | 1;
                let mut bytes = vec![0u8; 4096];
                while Instant::now() < deadline {
                    fill(&mut state, &mut bytes);
                    driver::run(fmus, &bytes);
                }
            }));
        }
        // Joined explicitly (pthread_join, which TSan sees): the scope's own wait is std's
        // uninstrumented counter, after which the FMUs' tables are freed.
        for handle in handles {
            handle.join().expect("a fuzzing thread panicked");
        }
    });
    println!("fmi_threads: {}", driver::summary());
}
