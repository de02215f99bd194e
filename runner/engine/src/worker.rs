//! The worker side of [`crate::isolation`]: a process that loads the FMU once and runs the
//! points or runs its supervisor sends, one at a time. If the FMU crashes or hangs, only this
//! process is lost; the call it was in is in memory shared with the supervisor.

use std::fs::File;
use std::io::{BufReader, Write};
use std::os::fd::{FromRawFd, RawFd};
use std::sync::Mutex;

use fmi_importer::trace::{self, CallSlot};

use crate::protocol::{self, Reply, Request, RunEnd};
use crate::run;
use crate::sweep::Plan;

/// The file descriptor of the shared [`CallSlot`] in a worker.
pub(crate) const SLOT_FD: RawFd = 3;

/// Where replies go: the pipe the supervisor reads (not stdout, which the FMU may print to).
static REPLIES: Mutex<Option<File>> = Mutex::new(None);

/// Samples per [`Reply::Samples`] message, in f64s: 64 KiB frames.
const BATCH: usize = 8192;

fn reply(message: &Reply) -> Result<(), String> {
    let mut replies = REPLIES.lock().map_err(|_| "the reply pipe is poisoned".to_owned())?;
    let pipe = replies.as_mut().ok_or("the worker has no reply pipe")?;
    protocol::send(pipe, message).map_err(|e| format!("cannot reply to the runner: {e}"))
}

/// FMU log lines and notes go to the supervisor, which prints them where its own go.
fn forward_line(line: &str) {
    let _ = reply(&Reply::Log(line.to_owned()));
}

/// Resident memory of this process in bytes (0 if unknown), from `statm`, /proc/self/statm kept
/// open: one read per point rather than an open, a read and a close.
fn resident_bytes(statm: Option<&File>) -> u64 {
    use std::os::unix::fs::FileExt;
    let mut buffer = [0u8; 128];
    let text = match statm.map(|f| f.read_at(&mut buffer, 0)) {
        Some(Ok(n)) => String::from_utf8_lossy(&buffer[..n]).into_owned(),
        _ => std::fs::read_to_string("/proc/self/statm").unwrap_or_default(),
    };
    let pages: u64 = text.split_whitespace().nth(1).and_then(|p| p.parse().ok()).unwrap_or(0);
    // SAFETY: sysconf has no preconditions.
    pages * unsafe { libc::sysconf(libc::_SC_PAGESIZE) }.max(0) as u64
}

/// Takes the protocol's descriptors away from stdin and stdout, so an FMU that prints (or
/// reads) cannot corrupt the messages: its stdout goes to stderr, its stdin is empty.
fn protocol_pipes() -> Result<(File, File), String> {
    // SAFETY: plain descriptor calls on the process's own standard descriptors.
    unsafe {
        let requests = libc::fcntl(0, libc::F_DUPFD_CLOEXEC, 10);
        let replies = libc::fcntl(1, libc::F_DUPFD_CLOEXEC, 10);
        if requests < 0 || replies < 0 {
            return Err(format!("cannot set up the worker's pipes: {}", std::io::Error::last_os_error()));
        }
        let null = libc::open(c"/dev/null".as_ptr(), libc::O_RDONLY);
        if null < 0 || libc::dup2(null, 0) < 0 || libc::dup2(2, 1) < 0 {
            return Err(format!("cannot redirect the worker's standard streams: {}", std::io::Error::last_os_error()));
        }
        libc::close(null);
        Ok((File::from_raw_fd(requests), File::from_raw_fd(replies)))
    }
}

/// Maps the shared call slot the supervisor put at [`SLOT_FD`] and records FMI calls in it.
fn map_slot() -> Result<&'static CallSlot, String> {
    // SAFETY: maps the supervisor's memfd of at least one page; the mapping is never unmapped,
    // so the 'static reference stays valid.
    unsafe {
        let p = libc::mmap(std::ptr::null_mut(), 4096, libc::PROT_READ | libc::PROT_WRITE, libc::MAP_SHARED, SLOT_FD, 0);
        if p == libc::MAP_FAILED {
            return Err(format!("cannot map the call slot: {}", std::io::Error::last_os_error()));
        }
        libc::close(SLOT_FD);
        let slot = &*(p as *const CallSlot);
        slot.clear();
        trace::set_slot(slot);
        Ok(slot)
    }
}

/// Runs the worker until the supervisor closes the request pipe. Only the supervisor starts
/// this (the hidden `runner worker` command), with the descriptors it set up.
pub fn serve() -> Result<(), String> {
    // A crashing FMU must not write core files of the worker, one per crash.
    let no_core = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
    // SAFETY: setrlimit with a valid struct.
    unsafe { libc::setrlimit(libc::RLIMIT_CORE, &no_core) };
    let (requests, replies) = protocol_pipes()?;
    *REPLIES.lock().map_err(|_| "poisoned")? = Some(replies);
    fmi_importer::set_log_printer(forward_line);
    let slot = map_slot()?;
    let mut requests = BufReader::new(requests);
    let next = |r: &mut BufReader<File>| protocol::receive::<Request>(r).map_err(|e| format!("cannot read the runner's request: {e}"));

    let source = match next(&mut requests)? {
        Some(Request::Load(source)) => source,
        // Let go before the FMU was known (started ahead, and the FMU turned out unusable).
        Some(Request::Release) => return reply(&Reply::Released),
        None => return Ok(()),
        Some(other) => return Err(format!("the first request must be Load, not {other:?}")),
    };
    let fmu = match source.load() {
        Ok(fmu) => fmu,
        Err(e) => return reply(&Reply::Failed(e)),
    };
    reply(&Reply::Ready)?;
    let statm = File::open("/proc/self/statm").ok();
    let resident = || resident_bytes(statm.as_ref());
    let mut plan: Option<Plan> = None;
    // Set once this worker's memory passed the sweep's limit: it runs no more points.
    let mut retire_above: Option<u64> = None;
    let mut retired = false;
    let mut point = Vec::new();
    let mut samples: Vec<f64> = Vec::with_capacity(BATCH + 64);
    let never = || false;
    while let Some(request) = next(&mut requests)? {
        slot.clear();
        match request {
            Request::Load(_) => return Err("the FMU is loaded once per worker".to_owned()),
            Request::Release => {
                // From now on the runner may exit first: the parent-death signal would kill this
                // process while it unloads the FMU (and removes its copy, if it unpacked one). An
                // alarm bounds an FMU that hangs in being unloaded.
                // SAFETY: prctl and alarm on this process.
                unsafe {
                    libc::prctl(libc::PR_SET_PDEATHSIG, 0);
                    libc::alarm(10);
                }
                reply(&Reply::Released)?;
                break;
            }
            Request::Sweep { spec, retire_above: limit } => match spec.plan(&fmu.description, &fmu.identifier, fmu.interface) {
                Ok(p) => {
                    plan = Some(p);
                    retire_above = limit;
                    reply(&Reply::Ready)?;
                }
                Err(e) => return reply(&Reply::Failed(e)),
            },
            Request::Point(i) => {
                let plan = plan.as_ref().ok_or("a Point request before the Sweep")?;
                let i = usize::try_from(i).map_err(|_| "point index out of range")?;
                if i >= plan.space.len {
                    return Err(format!("point {i} is not in the sweep of {} points", plan.space.len));
                }
                if retired {
                    reply(&Reply::Skipped(i as u64))?;
                    continue;
                }
                let result = plan.run_point(&fmu, i, &mut point, &never);
                let resident = resident();
                retired = retire_above.is_some_and(|limit| resident > limit);
                reply(&Reply::Point { index: i as u64, result, resident })?;
            }
            Request::Run(job) => {
                let result = job.resolve(&fmu.description).and_then(|(assignments, recording)| {
                    let inputs = job.inputs.as_ref().map(|table| table.bind(&fmu.description, fmu.interface)).transpose()?;
                    samples.clear();
                    let mut texts = Vec::new();
                    // The columns the supervisor cannot print from their numbers.
                    let mut lossy: Option<Vec<usize>> = None;
                    let flush = |samples: &mut Vec<f64>, texts: &mut Vec<String>| {
                        reply(&Reply::Samples { values: std::mem::take(samples), texts: std::mem::take(texts) })
                    };
                    let outcome = run::run_with_inputs(
                        &fmu,
                        &job.name,
                        &job.grid,
                        &assignments,
                        inputs.as_ref(),
                        &recording,
                        job.debug_logging,
                        |t, values, reader| {
                            samples.push(t);
                            samples.extend_from_slice(values);
                            let lossy = lossy.get_or_insert_with(|| (0..values.len()).filter(|&c| reader.needs_text(c)).collect());
                            texts.extend(lossy.iter().map(|&c| reader.text(c, values)));
                            if samples.len() >= BATCH || texts.len() >= BATCH {
                                flush(&mut samples, &mut texts)?;
                                samples.reserve(BATCH + 64);
                            }
                            Ok(())
                        },
                    );
                    if !samples.is_empty() {
                        flush(&mut samples, &mut texts)?;
                    }
                    outcome.map(|o| RunEnd { ended_early: o.ended_early, counters: o.counters })
                });
                reply(&Reply::RunDone { result, resident: resident() })?;
            }
        }
    }
    let _ = std::io::stderr().flush();
    Ok(())
}
