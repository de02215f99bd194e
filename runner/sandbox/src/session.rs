//! One job after another in a worker process, each streaming its messages as it runs (a
//! simulation's samples, the runs of a comparison), the worker replaced after a crash or when
//! worn out.

use std::time::{Duration, Instant};

use crate::frame::{Reply, Request};
use crate::pool::{Config, Event, Pool, Worker};
use crate::{Failure, Service};

/// How long the supervisor waits for an event before it looks at the clock and `stop` again.
const TICK: Duration = Duration::from_millis(50);

/// Runs jobs one at a time in a worker, replacing the worker after a crash.
pub struct Session<S: Service> {
    pool: Pool<S>,
    worker: Option<Worker<S>>,
    /// Workers let go, until they acknowledge.
    released: Vec<u64>,
}

impl<S: Service> Session<S> {
    /// A session whose workers are told `setups` (in order) before their first job; no worker
    /// starts before the first job. `one_job_per_worker`: a fresh worker for every job.
    pub fn new(config: Config, setups: &[S::Setup], one_job_per_worker: bool) -> Session<S> {
        let mut pool = Pool::new(config);
        for setup in setups {
            pool.add_setup(setup, None);
        }
        pool.one_job_per_worker = one_job_per_worker;
        Session { pool, worker: None, released: Vec::new() }
    }

    /// Runs `job` in a worker, handing each message it sends to `on_message`, and returns its
    /// outcome: the service's [`Service::failed`] one when the worker crashed or ran past the
    /// time limit. `Err` when the job could not run or was stopped: a setup that failed, a
    /// worker that could not start, `stop()` turning true or `on_message` failing (the worker
    /// is then killed).
    pub fn run(
        &mut self,
        job: S::Job,
        stop: &dyn Fn() -> bool,
        on_message: impl FnMut(S::Message) -> Result<(), String>,
    ) -> Result<S::Outcome, String> {
        self.run_watched(job, stop, &mut |_| None, on_message)
    }

    /// [`Session::run`] with a watchdog of the client's: `watch(shared)` is asked at every
    /// tick while the job runs and returns `Some(limit)` when the worker overran a time limit
    /// of its own accounting (a deadline the worker wrote into its shared memory before an FMI
    /// call, as a validator's probe does per call); the worker is then killed and the job's
    /// outcome is the service's [`Service::failed`] one for [`Failure::TimedOut`]`(limit)`.
    pub fn run_watched(
        &mut self,
        job: S::Job,
        stop: &dyn Fn() -> bool,
        watch: &mut dyn FnMut(&crate::SharedMemory) -> Option<Duration>,
        mut on_message: impl FnMut(S::Message) -> Result<(), String>,
    ) -> Result<S::Outcome, String> {
        let mut worker = match self.worker.take() {
            Some(w) => w,
            None => self.pool.spawn()?,
        };
        worker.send(&Request::Job { id: 0, job: job.clone() });
        let mut started = Instant::now();
        let timeout = self.pool.config.timeout;
        loop {
            if stop() {
                worker.kill();
                return Err("interrupted".to_owned());
            }
            let limit = timeout.map(|limit| worker.limit(limit));
            let overran = match limit {
                Some(limit) if started.elapsed() >= limit => Some(limit),
                _ => watch(&worker.shared),
            };
            if let Some(limit) = overran {
                let (_, shared) = worker.kill();
                return Ok(S::failed(&job, &Failure::TimedOut(limit), &shared));
            }
            let wait = limit.map_or(TICK, |limit| (started + limit).saturating_duration_since(Instant::now()).min(TICK));
            let Some((id, event)) = self.pool.next(wait) else { continue };
            if id != worker.id {
                continue; // an earlier worker's last words
            }
            match event {
                // The worker is set up: the job's time starts now.
                Event::Reply(Reply::Ready) => {
                    worker.unready = worker.unready.saturating_sub(1);
                    if worker.unready == 0 {
                        started = Instant::now();
                    }
                }
                Event::Reply(Reply::Failed(e)) => {
                    worker.kill();
                    return Err(e);
                }
                Event::Reply(Reply::Message(message)) => {
                    if let Err(e) = on_message(message) {
                        worker.kill();
                        return Err(e);
                    }
                }
                Event::Reply(Reply::Done { outcome, resident, tainted, .. }) => {
                    if self.pool.worn_out(resident, tainted) {
                        self.released.push(worker.release());
                    } else {
                        self.worker = Some(worker);
                    }
                    return Ok(outcome);
                }
                Event::Reply(_) => {}
                Event::Gone => {
                    let (status, shared) = worker.kill();
                    return Ok(S::failed(&job, &Failure::Ended(status), &shared));
                }
            }
        }
    }
}

impl<S: Service> Drop for Session<S> {
    fn drop(&mut self) {
        if let Some(worker) = self.worker.take() {
            self.released.push(worker.release());
        }
        self.pool.await_released(&mut self.released);
    }
}
