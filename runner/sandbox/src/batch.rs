//! Many independent jobs over a pool of workers (a sweep's points), delivered in job order as
//! they finish. A worker that crashes, hangs past the time limit or is left unusable costs the
//! job it was in, which is delivered as the service's [`Service::failed`] outcome; the jobs it
//! had been sent but not started run again on another worker.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::ops::Range;
use std::time::{Duration, Instant};

use crate::frame::{Reply, Request};
use crate::pool::{Config, Event, Pool, Worker};
use crate::{Failure, Service};

/// Worker processes started ahead of a batch, before its setup is known: they start while the
/// supervisor prepares (unpacks the FMU), and set up (load it) while the supervisor checks the
/// batch (a worker's start costs about as much as ten of the handbook's runs).
pub struct Workers<S: Service> {
    pool: Pool<S>,
    ready: Vec<Worker<S>>,
}

impl<S: Service> Workers<S> {
    /// Starts `count` workers (at least one); they wait for [`Workers::setup`].
    pub fn start(config: Config, count: usize) -> Result<Workers<S>, String> {
        let mut pool = Pool::new(config);
        let ready = (0..count.max(1)).map(|_| pool.spawn()).collect::<Result<Vec<_>, _>>()?;
        Ok(Workers { pool, ready })
    }

    /// Tells the workers `setup`, as will the workers that replace them.
    pub fn setup(&mut self, setup: &S::Setup) {
        let first = !self.pool.has_setup();
        self.pool.add_setup(setup, None);
        for worker in &mut self.ready {
            worker.setup(setup, None);
            if first {
                // The start counted as a setup to come (see `Pool::spawn`).
                worker.unready -= 1;
            }
        }
    }

    /// Gives every job a worker of its own (an FMU that declares
    /// canBeInstantiatedOnlyOncePerProcess): a worker is replaced after each job.
    pub fn one_job_per_worker(&mut self, one: bool) {
        self.pool.one_job_per_worker = one;
    }

    /// The configuration the workers started with.
    pub fn config(&self) -> &Config {
        self.pool.config()
    }
}

impl<S: Service> Drop for Workers<S> {
    fn drop(&mut self) {
        let mut released: Vec<u64> = self.ready.drain(..).map(Worker::release).collect();
        self.pool.await_released(&mut released);
    }
}

/// How long the supervisor waits for an event before it looks at the clock and `stop` again.
const TICK: Duration = Duration::from_millis(50);

/// Jobs a worker has been sent at most: the one it runs and the next, so that it never waits
/// for the supervisor between jobs (each wait is a wake-up of three threads: milliseconds on a
/// busy machine). One when each job needs a process of its own.
const DEPTH: usize = 2;

/// One worker and the jobs sent to it.
struct Lane<S: Service> {
    worker: Option<Worker<S>>,
    /// The jobs sent, in order: the first is running.
    sent: VecDeque<usize>,
    /// When the first of `sent` started: when it was sent, or when the one before it ended.
    started: Option<Instant>,
    /// The worker gets no more jobs: it retired or was told to release.
    closed: bool,
    /// Release was sent after its last job.
    releasing: bool,
}

impl<S: Service> Lane<S> {
    fn busy(&self) -> Option<(usize, Instant)> {
        self.sent.front().copied().zip(self.started)
    }
}

/// Runs the jobs `jobs` (`job(i)` is job `i`) on `workers`, as many at once as were started,
/// after telling each the batch's `setup`, and calls `deliver(i, outcome)` in job order. Stops
/// when `stop()` turns true (the jobs in progress are abandoned and their workers killed) or
/// `deliver` fails (its error is returned); a setup that fails ends the batch with its error.
///
/// Each worker is sent its next job while it runs one (`DEPTH`), except for the last few jobs
/// of the batch, which go one at a time to whichever worker is free, so that the batch ends as
/// evenly as on threads; after the last job a worker is sent Release at once. A job sent to a
/// worker that crashed, timed out or retired before starting it runs again on another worker:
/// only the job a worker was in is charged with its end.
pub fn run_batch<S: Service>(
    mut workers: Workers<S>,
    setup: &S::Setup,
    jobs: Range<usize>,
    job: impl Fn(usize) -> S::Job,
    stop: &dyn Fn() -> bool,
    mut deliver: impl FnMut(usize, S::Outcome) -> Result<(), String>,
) -> Result<(), String> {
    if !workers.pool.has_setup() {
        return Err("the workers were told nothing to prepare before the batch".to_owned());
    }
    let end = jobs.end;
    let lane_count = workers.ready.len().min(end.saturating_sub(jobs.start)).max(1);
    let depth = if workers.pool.one_job_per_worker { 1 } else { DEPTH };
    // The worker itself stops at the memory the supervisor would replace it at, since the next
    // job is already on its way when the supervisor hears of its memory.
    let retire_above = workers.pool.retire_above();
    workers.pool.add_setup(setup, retire_above);
    let timeout = workers.pool.config.timeout;
    let mut lanes: Vec<Lane<S>> = Vec::new();
    for mut worker in workers.ready.drain(..lane_count) {
        worker.setup(setup, retire_above);
        lanes.push(Lane { worker: Some(worker), sent: VecDeque::new(), started: None, closed: false, releasing: false });
    }
    let pool = &mut workers.pool;
    let mut released: Vec<u64> = Vec::new();
    let mut next = jobs.start;
    // Jobs to run again: sent to a worker that ended before it started them.
    let mut again: BTreeSet<usize> = BTreeSet::new();
    let mut row = jobs.start;
    let mut waiting: BTreeMap<usize, S::Outcome> = BTreeMap::new();
    let outcome = (|| -> Result<(), String> {
        loop {
            if stop() {
                return Ok(());
            }
            for lane in lanes.iter_mut() {
                loop {
                    let left = again.len() + end.saturating_sub(next);
                    // The last jobs go one at a time, to whichever worker is free first.
                    let room = if left >= lane_count { depth } else { 1 };
                    if left == 0 || lane.sent.len() >= room || (lane.closed && lane.worker.is_some()) {
                        break;
                    }
                    if lane.worker.is_none() {
                        lane.worker = Some(pool.spawn()?);
                        lane.closed = false;
                        lane.releasing = false;
                    }
                    let i = again.pop_first().unwrap_or_else(|| {
                        next += 1;
                        next - 1
                    });
                    lane.worker.as_mut().expect("started above").send(&Request::Job { id: i as u64, job: job(i) });
                    if lane.sent.is_empty() {
                        lane.started = Some(Instant::now());
                    }
                    lane.sent.push_back(i);
                }
            }
            let nothing_left = again.is_empty() && next >= end;
            for lane in lanes.iter_mut() {
                // Done with a worker: let it go now, after the jobs it has, so that it
                // acknowledges right after its last one instead of a round trip later.
                if nothing_left || lane.closed {
                    if let Some(worker) = lane.worker.as_mut() {
                        if !lane.releasing {
                            worker.send(&Request::Release);
                            lane.releasing = true;
                            lane.closed = true;
                        }
                    }
                }
                if lane.closed && lane.sent.is_empty() {
                    if let Some(worker) = lane.worker.take() {
                        released.push(worker.detach());
                    }
                }
            }
            if lanes.iter().all(|l| l.sent.is_empty()) && nothing_left {
                return Ok(());
            }
            // Wake for the first deadline, or a tick to look at `stop`.
            let now = Instant::now();
            let wait = lanes
                .iter()
                .filter_map(|l| {
                    let worker = l.worker.as_ref()?;
                    l.busy().zip(timeout).map(|((_, started), limit)| (started + worker.limit(limit)).saturating_duration_since(now))
                })
                .fold(TICK, Duration::min);
            if let Some((id, event)) = pool.next(wait) {
                let lane = lanes.iter_mut().find(|l| l.worker.as_ref().is_some_and(|w| w.id == id));
                match (lane, event) {
                    (Some(_), Event::Reply(Reply::Failed(e))) => return Err(e),
                    (Some(lane), Event::Reply(Reply::Ready)) => {
                        let worker = lane.worker.as_mut().expect("matched by id");
                        worker.unready = worker.unready.saturating_sub(1);
                        if worker.unready == 0 && !lane.sent.is_empty() {
                            lane.started = Some(Instant::now());
                        }
                    }
                    (Some(lane), Event::Reply(Reply::Done { id: index, outcome, resident, tainted })) => {
                        if lane.sent.front().map(|&i| i as u64) == Some(index) {
                            waiting.insert(index as usize, outcome);
                            lane.sent.pop_front();
                            // The next job started as this one ended.
                            lane.started = Some(Instant::now());
                            if pool.worn_out(resident, tainted) {
                                // It runs no more jobs and exits, returning its memory.
                                lane.closed = true;
                            }
                        }
                    }
                    (Some(lane), Event::Reply(Reply::Skipped(index))) => {
                        if let Some(k) = lane.sent.iter().position(|&i| i as u64 == index) {
                            again.insert(lane.sent.remove(k).expect("found"));
                            lane.closed = true;
                        }
                    }
                    (Some(lane), Event::Gone) => {
                        let worker = lane.worker.take().expect("matched by id");
                        let (status, shared) = worker.kill();
                        // The job it was in is charged; those it had not started run again.
                        // An idle worker that ended is replaced at its next job.
                        if let Some(i) = lane.sent.pop_front() {
                            waiting.insert(i, S::failed(&job(i), &Failure::Ended(status), &shared));
                        }
                        again.extend(lane.sent.drain(..));
                        lane.started = None;
                    }
                    (None, Event::Gone | Event::Reply(Reply::Released)) => released.retain(|&i| i != id),
                    // Released, a message, or a late word from a worker already replaced.
                    (_, Event::Reply(_)) => {}
                }
            }
            if let Some(limit) = timeout {
                for lane in lanes.iter_mut() {
                    let (Some((i, started)), Some(worker)) = (lane.busy(), lane.worker.as_ref()) else { continue };
                    let limit = worker.limit(limit);
                    if started.elapsed() >= limit {
                        let (_, shared) = lane.worker.take().expect("a busy lane has a worker").kill();
                        lane.sent.pop_front();
                        again.extend(lane.sent.drain(..));
                        lane.started = None;
                        waiting.insert(i, S::failed(&job(i), &Failure::TimedOut(limit), &shared));
                    }
                }
            }
            while let Some(result) = waiting.remove(&row) {
                deliver(row, result)?;
                row += 1;
            }
        }
    })();
    for lane in lanes {
        if let Some(worker) = lane.worker {
            if !lane.sent.is_empty() {
                worker.kill();
            } else if lane.releasing {
                released.push(worker.detach());
            } else {
                released.push(worker.release());
            }
        }
    }
    pool.await_released(&mut released);
    outcome
}
