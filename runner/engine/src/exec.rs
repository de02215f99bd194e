//! Where requests run: in this process (trusted FMUs: `--in-process`, the Python package's
//! threads), or in worker processes through the sandbox (the default of every command), with
//! the same results either way. A caller opens the FMU once ([`Held::open`]), then runs
//! [`RunRequest`]s one after another ([`Runs`]) or the points of a [`SweepRequest`] ([`sweep`]).

use std::ops::Range;

use fmi_importer::call_log::CallLogTarget;
use fmi_importer::{Description, Fmu, Interface, Reader, Unpacked};
use runner_sandbox::{run_batch, Config, Session, Workers};

use crate::isolated::{self, Engine, Job, Outcome as WorkerOutcome, Samples, Setup};
use crate::linear::Linear;
use crate::request::{FmuSource, LinearizeRequest, RunRequest, SweepRequest};
use crate::run::{Outcome, Texts};
use crate::sweep::{Plan, PointResult};

/// The FMU as a caller holds it: loaded for in-process runs, only unpacked and described when
/// workers run it (its binary's initializers then never run in the caller).
// One value for the whole command: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum Held {
    /// Loaded in this process: runs here.
    Loaded(Fmu),
    /// Unpacked and described only: runs in workers, which load this copy.
    Described(Unpacked),
}

impl Held {
    /// Opens the FMU of `source`: loaded here when `in_process`, else only described; returns it
    /// with the source its workers load (this copy).
    pub fn open(source: &FmuSource, in_process: bool) -> Result<(Held, FmuSource), String> {
        match in_process {
            true => Ok((Held::Loaded(source.load()?), source.clone())),
            false => source.open().map(|(unpacked, for_workers)| (Held::Described(unpacked), for_workers)),
        }
    }

    /// The FMU's description.
    pub fn description(&self) -> &Description {
        match self {
            Held::Loaded(f) => &f.description,
            Held::Described(u) => &u.description,
        }
    }

    /// The modelIdentifier of the interface it runs through.
    pub fn identifier(&self) -> &str {
        match self {
            Held::Loaded(f) => &f.identifier,
            Held::Described(u) => &u.identifier,
        }
    }

    /// The interface it runs through.
    pub fn interface(&self) -> Interface {
        match self {
            Held::Loaded(f) => f.interface,
            Held::Described(u) => u.interface,
        }
    }

    /// True if the FMU allows one instance per process only (canBeInstantiatedOnlyOncePerProcess).
    pub fn once_per_process(&self) -> bool {
        isolated::once_per_process(self.description(), self.interface())
    }
}

/// Runs requests one after another on a held FMU: in this process when it is loaded, else in a
/// worker process (replaced after a crash).
pub struct Runs<'a> {
    held: &'a Held,
    session: Option<Session<Engine>>,
}

impl<'a> Runs<'a> {
    /// Runs on `held`: in this process when it is loaded, else in workers started as `config`
    /// says, loading `source`.
    pub fn new(held: &'a Held, config: &Config, source: &FmuSource) -> Runs<'a> {
        let session = match held {
            Held::Loaded(_) => None,
            Held::Described(_) => Some(Session::new(config.clone(), &[Setup::Load(source.clone())], held.once_per_process())),
        };
        Runs { held, session }
    }

    /// Runs `request`, calling `sample(t, values, texts)` at every sample. In a worker, a crash,
    /// a timeout, `stop()` or a failing `sample` end the run with an error naming the signal
    /// and the FMI call; in this process `stop()` ends it at its next sample ("interrupted"; an FMI
    /// call in progress cannot be stopped).
    pub fn run(
        &mut self,
        request: &RunRequest,
        stop: &dyn Fn() -> bool,
        mut sample: impl FnMut(f64, &[f64], &dyn Texts) -> Result<(), String>,
    ) -> Result<Outcome, String> {
        let session = match (self.held, self.session.as_mut()) {
            (Held::Loaded(fmu), _) => {
                let bound = request.bind(&fmu.description, fmu.interface, true)?;
                // `stop()` ends a run here at its next sample, as it ends one in a worker.
                let sample = |t: f64, values: &[f64], texts: &dyn Texts| {
                    if stop() {
                        return Err("interrupted".to_owned());
                    }
                    sample(t, values, texts)
                };
                return fmi_importer::call_log::logging(request.log_fmi_calls.as_ref(), || bound.run().execute(fmu, sample));
            }
            (Held::Described(_), Some(session)) => session,
            (Held::Described(_), None) => unreachable!("a session is made for a described FMU"),
        };
        // The worker's columns, laid out here as there: the texts it sends are of the columns
        // whose numbers do not give them.
        let description = self.held.description();
        let bound = request.bind(description, self.held.interface(), false)?;
        let recording = &bound.recording;
        let layout = Reader::with_sizes(description.fmi_version, &recording.variables, &recording.sizes)?;
        let lossy: Vec<usize> = (0..layout.len()).filter(|&c| layout.needs_text(c)).collect();
        let width = 1 + layout.len();
        let outcome = session.run(Job::Run(Box::new(request.clone())), stop, |Samples { values, texts }| {
            let samples = values.len() / width;
            if values.len() % width != 0 || texts.len() != samples * lossy.len() {
                return Err(format!("{}: the worker sent a sample of the wrong size", request.name));
            }
            for (k, chunk) in values.chunks_exact(width).enumerate() {
                let texts = Received { layout: &layout, lossy: &lossy, texts: &texts[k * lossy.len()..(k + 1) * lossy.len()] };
                sample(chunk[0], &chunk[1..], &texts)?;
            }
            Ok(())
        });
        let result = match outcome {
            Ok(WorkerOutcome::Run(result)) => {
                result.map(|end| Outcome { ended_early: end.ended_early, counters: end.counters, final_state: end.final_state })
            }
            Ok(_) => Err(format!("{}: the worker answered a run with something else", request.name)),
            Err(e) => Err(e),
        };
        end_call_line(&result, request.log_fmi_calls.as_ref());
        result
    }

    /// Linearizes as `request` says: in this process when the FMU is loaded here, else in a
    /// worker, where a crash or a timeout ends it with an error naming the signal and the FMI
    /// call (and `stop()` turning true, with "interrupted").
    pub fn linearize(&mut self, request: &LinearizeRequest, stop: &dyn Fn() -> bool) -> Result<Linear, String> {
        let session = match (self.held, self.session.as_mut()) {
            (Held::Loaded(fmu), _) => return request.run(fmu),
            (Held::Described(_), Some(session)) => session,
            (Held::Described(_), None) => unreachable!("a session is made for a described FMU"),
        };
        let name = &request.name;
        let outcome = session
            .run(Job::Linearize(Box::new(request.clone())), stop, |_| Err(format!("{name}: the worker sent samples while linearizing")));
        let result = match outcome {
            Ok(WorkerOutcome::Linear(result)) => result.map(|linear| *linear),
            Ok(_) => Err(format!("{name}: the worker answered a linearization with something else")),
            Err(e) => Err(e),
        };
        end_call_line(&result, request.log_fmi_calls.as_ref());
        result
    }
}

/// After a failed job of a worker logging its FMI calls to stderr, ends the line of the call the
/// worker may have died in, so the error does not run on from it (a blank line when the last
/// call had returned).
fn end_call_line<T>(outcome: &Result<T, String>, log: Option<&CallLogTarget>) {
    if outcome.is_err() && log == Some(&CallLogTarget::Stderr) {
        eprintln!();
    }
}

/// The texts of a sample a worker sent: its numbers printed by the layout's rules, and the
/// texts it sent for the columns numbers do not give.
struct Received<'a> {
    layout: &'a Reader,
    /// The columns that need text, ascending.
    lossy: &'a [usize],
    /// Their texts in this sample.
    texts: &'a [String],
}

impl Texts for Received<'_> {
    fn text(&self, c: usize, values: &[f64]) -> String {
        match self.lossy.binary_search(&c) {
            Ok(k) => self.texts[k].clone(),
            Err(_) => self.layout.text_of_number(c, values[c]),
        }
    }

    fn needs_text(&self, c: usize) -> bool {
        self.lossy.binary_search(&c).is_ok()
    }

    fn push_number_text(&self, c: usize, x: f64, out: &mut Vec<u8>) {
        self.layout.push_text_of_number(c, x, out)
    }
}

/// Where a sweep's points run.
// One value per sweep: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
pub enum Points {
    /// On this many threads of this process, the FMU loaded here.
    Threads(usize),
    /// In these worker processes (started ahead, told which FMU to load).
    Workers(Workers<Engine>),
}

/// Starts `count` workers for a sweep before the FMU is even unpacked (see
/// [`runner_sandbox::Workers`]); [`load`] tells them which FMU.
pub fn start_workers(config: Config, count: usize) -> Result<Workers<Engine>, String> {
    Workers::start(config, count)
}

/// Tells `workers` the FMU to load, and whether each point needs a process of its own.
pub fn load(workers: &mut Workers<Engine>, source: &FmuSource, once_per_process: bool) {
    workers.setup(&Setup::Load(source.clone()));
    workers.one_job_per_worker(once_per_process);
}

/// Runs the points `points` of `plan` (bound from `request`; the FMU loaded in `held` for
/// threads) where `on` says, and calls `deliver(i, result)` in point order as results arrive.
/// Stops early when `stop()` turns true (the points in progress are abandoned) or `deliver`
/// fails (its error is returned).
pub fn sweep(
    held: &Held,
    plan: &Plan,
    request: &SweepRequest,
    on: Points,
    points: Range<usize>,
    stop: &(dyn Fn() -> bool + Sync),
    mut deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
) -> Result<(), String> {
    let points = points.start..points.end.min(plan.space.len);
    match (held, on) {
        (Held::Loaded(fmu), Points::Threads(threads)) => plan.execute_range(fmu, points, threads, stop, deliver),
        (Held::Described(_), Points::Workers(workers)) => run_batch(
            workers,
            &Setup::Sweep(Box::new(request.clone())),
            points,
            |i| Job::Point(i as u64),
            stop,
            |i, outcome| match outcome {
                WorkerOutcome::Point(result) => deliver(i, result),
                _ => Err(format!("the worker answered point {i} with something other than its result")),
            },
        ),
        (Held::Loaded(_), Points::Workers(_)) => Err("the FMU is loaded in this process: sweep it on threads".to_owned()),
        (Held::Described(_), Points::Threads(_)) => Err("the FMU is not loaded in this process: sweep it in workers".to_owned()),
    }
}
