//! `runner simulate SYSTEM` and `runner sweep SYSTEM`: an SSP system (`.ssp`, `.ssd`, or a
//! folder holding `SystemStructure.ssd`) run by the fixed-step master of `fmi-systems`.
//!
//! A system runs in worker processes through the sandbox, as a single FMU does, unless
//! `--in-process` says otherwise. One worker runs a whole run or sweep point: every component
//! and the master, so the components exchange values within the worker at no cost (a message
//! round trip per component and step would cost several times the step of a small FMU). A
//! component that crashes, hangs or leaks costs the worker, hence only its run or point; the
//! master tells the importer's call slot which component it drives
//! (`fmi_importer::trace::set_context`), and the worker keeps the components' names in the
//! memory it shares with its supervisor, so the report names the component, the FMI call and
//! the time. The supervisor opens the system once (unpacks it, and reads and checks it without
//! loading any component's binary); its workers load that copy ([`System::load_copy`]), so a
//! binary that crashes as it loads costs a worker, and leave nothing behind when they die.

use std::ops::Range;
use std::path::Path;
use std::sync::atomic::{AtomicU32, AtomicU8, Ordering};

use fmi_importer::trace::{self, Call, CallSlot};
use fmi_importer::Variable;
use fmi_systems::master::Assignment;
use fmi_systems::{Bound, Coupling, Master, Outcome as RunOutcome, System, SystemFiles};
use runner_engine::input::InputTable;
use runner_engine::isolated;
use runner_engine::metrics::Metrics;
use runner_engine::request::MetricSet;
use runner_engine::run::Grid;
use runner_engine::sweep::{self, PointResult, Space};
use runner_engine::variables;
use runner_sandbox::worker::{Incoming, Pacer, Serving};
use runner_sandbox::{run_batch, Config, Failure, Service, Session, SharedMemory, WorkerCommand, Workers};
use serde::{Deserialize, Serialize};

use crate::experiment::RunDefaults;
use crate::interrupt;
use crate::report::{self, output, partial};
use plots::outputs::{figure, Axis};
use plots::trace::Trace;

/// The hidden command a system's worker runs (`runner system-worker`).
pub const WORKER_COMMAND: &str = "system-worker";

/// The master named on the command line (`None`: Jacobi).
pub fn master(name: Option<&str>) -> Result<Master, String> {
    match name {
        None => Ok(Master::Jacobi),
        Some(n) => Master::from_name(n).ok_or_else(|| format!("--master '{n}': choose jacobi or gauss-seidel")),
    }
}

/// How the command line runs the system (`--master`, `--coupling`, `--input-file`), as it
/// travels to the workers.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Algorithm {
    pub master: Option<String>,
    pub coupling: Option<String>,
    /// The unconnected inputs over time, columns `COMPONENT.INPUT`.
    pub inputs: Option<InputTable>,
}

impl Algorithm {
    /// The algorithm the options name; `input_file` read as a table (checked against the
    /// system when it is bound).
    pub fn new(master: Option<String>, coupling: Option<String>, input_file: Option<&Path>) -> Result<Algorithm, String> {
        let inputs = match input_file {
            None => None,
            Some(path) => {
                let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read the input file {}: {e}", path.display()))?;
                Some(InputTable::from_csv(&text).map_err(|e| format!("{}: {e}", path.display()))?)
            }
        };
        Ok(Algorithm { master, coupling, inputs })
    }
}

/// The system bound for runs under the master and coupling named on the command line.
fn bind<'a>(system: &'a System, algorithm: &Algorithm) -> Result<Bound<'a>, String> {
    let coupling = match algorithm.coupling.as_deref() {
        None => None,
        Some(n) => Some(Coupling::from_name(n).ok_or_else(|| format!("--coupling '{n}': choose hold or polynomial"))?),
    };
    let mut bound = Bound::new(system, master(algorithm.master.as_deref())?)?;
    bound.set_coupling(coupling);
    if let Some(table) = &algorithm.inputs {
        bound.set_inputs(table).map_err(|e| format!("--input-file: {e}"))?;
    }
    Ok(bound)
}

/// Prints what the user should know of `bound` under `algorithm` (once, by the supervisor).
fn warn(bound: &Bound, algorithm: &Algorithm) {
    if let Some(w) = &bound.warning {
        eprintln!("warning: {w}");
    }
    if algorithm.coupling.as_deref() == Some("polynomial") && bound.polynomial_connections().is_empty() {
        eprintln!(
            "warning: --coupling polynomial: no connection of the system can pass a polynomial (that needs a Co-Simulation source with output derivatives and a continuous Real input of an FMI 2.0 FMU that interpolates inputs): every input holds"
        );
    }
}

/// The grid: the command line, then the SSD's DefaultExperiment and step annotation, then the
/// components' DefaultExperiments (the latest stop, the smallest step), then 500 intervals.
pub fn grid(system: &System, run: &RunDefaults) -> Result<Grid, String> {
    let e = system.structure.experiment;
    let defaults: Vec<_> = system.components.iter().filter_map(|c| c.fmu.description.default_experiment).collect();
    let start = e.start.unwrap_or(0.0);
    let stop = run.stop_time.or(e.stop).or_else(|| defaults.iter().filter_map(|d| d.stop_time).reduce(f64::max)).unwrap_or(start + 1.0);
    let interval = run
        .output_interval
        .or(e.step)
        .or_else(|| defaults.iter().filter_map(|d| d.step_size).reduce(f64::min))
        .unwrap_or((stop - start) / 500.0);
    Grid::checked(start, stop, interval, run.tolerance)
}

fn number(x: f64) -> String {
    format!("{x}")
}

/// The sandbox of systems run in worker processes of this binary: each run or point stopped
/// after `timeout`, each worker limited to `memory_mib` MiB, sharing a `Page` with its
/// supervisor.
pub fn isolation(timeout: Option<std::time::Duration>, memory_mib: u64) -> Result<Config, String> {
    let config = isolated::config(WorkerCommand::this_program(&[WORKER_COMMAND])?, timeout, memory_mib)?;
    Ok(Config { shared_bytes: std::mem::size_of::<Page>(), ..config })
}

/// The workers that run systems.
pub struct Systems;

/// What a system's worker is told before its jobs.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Setup {
    /// Load the system from the supervisor's copy and bind it under the algorithm (first,
    /// once per worker).
    Load { files: SystemFiles, algorithm: Box<Algorithm> },
    /// Plan this sweep, for the [`Job::Point`]s that follow.
    Sweep(Box<SweepSpec>),
}

/// A job of a system's worker.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Job {
    /// Run point `.0` of the sweep.
    Point(u64),
    /// Run the system on `grid` with the `COMPONENT.VARIABLE=VALUE` assignments `sets`,
    /// streaming its rows.
    Run { grid: Grid, sets: Vec<String> },
}

/// Rows of a running [`Job::Run`]: `t` then every column's value, row after row.
#[derive(Debug, Serialize, Deserialize)]
pub struct Rows(pub Vec<f64>);

/// How a job ended.
#[derive(Debug, Serialize, Deserialize)]
pub enum Outcome {
    /// A sweep point's metrics and status.
    Point(PointResult),
    /// A run: finished (`None`), ended early by a component (`Some(why)`), or failed.
    Run(Result<Option<String>, String>),
}

/// Bytes of the components' names kept in the shared memory.
const NAMES: usize = 16 * 1024 - 64;

/// The memory a system's worker shares with its supervisor: the importer's call slot (the
/// call, the time, and the component as the master set it) and the components' names,
/// NUL-separated, written once the system is loaded, read after the worker died.
#[repr(C)]
struct Page {
    slot: CallSlot,
    names_len: AtomicU32,
    names: [AtomicU8; NAMES],
}

impl Page {
    /// Records the components' names, in order (as many as fit).
    fn write_names<'n>(&self, names: impl IntoIterator<Item = &'n str>) {
        let mut at = 0;
        for name in names {
            let name = name.as_bytes();
            if at + name.len() + 1 > NAMES {
                break;
            }
            for (cell, &b) in self.names[at..].iter().zip(name.iter().chain(&[0])) {
                cell.store(b, Ordering::Relaxed);
            }
            at += name.len() + 1;
        }
        self.names_len.store(at as u32, Ordering::Release);
    }

    /// The name of component `c` (0-based), if recorded.
    fn name(&self, c: usize) -> Option<String> {
        let len = (self.names_len.load(Ordering::Acquire) as usize).min(NAMES);
        let bytes: Vec<u8> = self.names[..len].iter().map(|b| b.load(Ordering::Relaxed)).collect();
        // Each name ends with a NUL: without the last, the pieces are the names.
        let names = bytes.strip_suffix(&[0]).filter(|n| !n.is_empty())?;
        names.split(|&b| b == 0).nth(c).map(|n| String::from_utf8_lossy(n).into_owned())
    }

    /// Where the worker was: `in fmi2DoStep of component 'car' at t = 0.31`.
    fn place(&self) -> String {
        let (call, time) = self.slot.read();
        let component = match self.slot.context() {
            0 => String::new(),
            c => match self.name(c as usize - 1) {
                Some(name) => format!(" of component '{name}'"),
                None => format!(" of component {c}"),
            },
        };
        match (call, time) {
            (Call::None, _) => format!("before its first FMI call{component}"),
            (Call::Load, _) if component.is_empty() => "while loading the components' binaries".to_owned(),
            (Call::Load, _) => format!("while loading the binary{component}"),
            (call, Some(t)) => format!("in {}{component} at t = {t}", call.name()),
            (call, None) => format!("in {}{component}", call.name()),
        }
    }
}

impl Service for Systems {
    type Setup = Setup;
    type Job = Job;
    type Message = Rows;
    type Outcome = Outcome;

    fn failed(job: &Job, failure: &Failure, shared: &SharedMemory) -> Outcome {
        // SAFETY: the worker laid a `Page` (atomics only) over this memory, sized for it.
        let at = unsafe { shared.view::<Page>() }.place();
        match job {
            Job::Point(_) => Outcome::Point(PointResult { metrics: None, status: failure.describe(&at) }),
            Job::Run { .. } => Outcome::Run(Err(failure.describe(&at))),
        }
    }
}

/// A sweep of a system, as it travels to the workers: the grid, the assignments of every point,
/// the swept parameters' values and the metrics.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SweepSpec {
    pub grid: Grid,
    pub sets: Vec<String>,
    pub ranges: Vec<(String, Vec<f64>)>,
    pub metrics: MetricSet,
}

/// A sweep of a system checked against it: what every point runs.
pub struct SweepPlan<'a> {
    grid: Grid,
    sets: Vec<Assignment<'a>>,
    swept: Vec<(usize, &'a Variable)>,
    pub space: Space,
    pub metrics: Metrics,
    /// The columns the metrics read, in the order of their sources.
    sources: Vec<usize>,
}

impl<'a> SweepPlan<'a> {
    /// Checks `spec` against `bound`: every name, value and metric, before any point runs.
    pub fn new(bound: &Bound<'a>, spec: &SweepSpec) -> Result<SweepPlan<'a>, String> {
        let sets = bound.parse_sets(&spec.sets)?;
        let mut swept = Vec::new();
        for (name, values) in &spec.ranges {
            let (c, v) = bound.resolve(name)?;
            variables::check_settable(v).map_err(|e| format!("--param {name}: {e}"))?;
            for &x in values {
                variables::number_value(v, x).map_err(|e| format!("--param {name}: {e}"))?;
            }
            swept.push((c, v));
        }
        let space = Space::new(spec.ranges.clone())?;
        let metrics = spec.metrics.metrics().clone();
        if metrics.needs_frequencies() {
            return Err(
                "amplitude(...) reads its frequency from parameters of one FMU: it is for sweeps of an FMU, not of a system".to_owned()
            );
        }
        if metrics.highest_mode().is_some() {
            return Err("natural_frequency(N) and damping(N) linearize one FMU: they are for sweeps of an FMU, not of a system".to_owned());
        }
        let sources = metrics
            .sources
            .iter()
            .map(|s| {
                bound.column(&s.variable).ok_or_else(|| {
                    format!("metric variable '{}' is not a column of the system (COMPONENT.VARIABLE of an output)", s.variable)
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(SweepPlan { grid: spec.grid, sets, swept, space, metrics, sources })
    }

    /// The `--set` assignments, resolved: (component, variable, value in the FMU's unit).
    pub fn sets(&self) -> &[Assignment<'a>] {
        &self.sets
    }

    /// The swept variables, in the order of the space's ranges.
    pub fn swept(&self) -> impl Iterator<Item = &'a Variable> + '_ {
        self.swept.iter().map(|&(_, v)| v)
    }

    /// Runs point `i` in an instance of the system of its own: the same code in a worker and
    /// on a thread, so both give the same bits.
    pub fn run_point(&self, bound: &Bound, i: usize, point: &mut Vec<f64>) -> PointResult {
        self.space.point(i, point);
        let mut assignments = self.sets.clone();
        for (&(c, v), &x) in self.swept.iter().zip(point.iter()) {
            // Checked in `SweepPlan::new`, before any run.
            assignments.push((c, v, variables::number_value(v, x).expect("value checked before the sweep")));
        }
        let mut acc = self.metrics.accumulators();
        // Only the metrics' columns are read (and what feeds connections), as a single FMU's
        // sweep reads only its metrics' variables.
        let result = bound.run_recorded(&format!("point{i}"), &self.grid, &assignments, &self.sources, |t, values| {
            for (a, &x) in acc.iter_mut().zip(values) {
                a.add(t, x);
            }
            Ok(())
        });
        match result {
            Ok(RunOutcome::Finished) => PointResult { metrics: Some(self.metrics.evaluate(&acc)), status: "ok".to_owned() },
            Ok(RunOutcome::Ended(why)) => {
                PointResult { metrics: Some(self.metrics.evaluate(&acc)), status: format!("{}{why}", partial::ENDED_EARLY) }
            }
            Err(failure) => PointResult { metrics: None, status: format!("failed: {failure}") },
        }
    }
}

/// Rows per [`Rows`] message, in f64s: 64 KiB frames.
const BATCH: usize = 8192;

/// Runs a system's worker until its supervisor releases it or closes the pipe. Only a
/// supervisor starts this (the runner's hidden `system-worker` command).
pub fn serve() -> Result<(), String> {
    let mut serving = Serving::<Systems>::start()?;
    fmi_importer::set_log_printer(runner_sandbox::worker::log);
    // SAFETY: the page (atomics only) fits in the shared memory (`isolation` sizes it), which
    // lives for the rest of the process.
    let page: &'static Page = unsafe { serving.shared().view::<Page>() };
    page.slot.clear();
    trace::set_slot(&page.slot);
    let (files, algorithm) = match serving.receive()? {
        Some(Incoming::Setup(Setup::Load { files, algorithm })) => (files, algorithm),
        // Let go before the system was known.
        None => return Ok(()),
        Some(_) => return Err("the first request must be Load".to_owned()),
    };
    // Named before loading: a binary that crashes as it loads is reported by its component.
    page.write_names(files.components.iter().map(|c| c.name.as_str()));
    let system = match System::load_copy(&files) {
        Ok(system) => system,
        Err(e) => return serving.ready(Err(e)),
    };
    let bound = match bind(&system, &algorithm) {
        Ok(bound) => bound,
        Err(e) => return serving.ready(Err(e)),
    };
    serving.ready(Ok(()))?;
    let mut plan: Option<SweepPlan> = None;
    let mut point = Vec::new();
    while let Some(request) = serving.receive()? {
        page.slot.clear();
        match request {
            Incoming::Setup(Setup::Load { .. }) => return Err("the system is loaded once per worker".to_owned()),
            Incoming::Setup(Setup::Sweep(spec)) => match SweepPlan::new(&bound, &spec) {
                Ok(p) => {
                    plan = Some(p);
                    serving.ready(Ok(()))?;
                }
                Err(e) => return serving.ready(Err(e)),
            },
            Incoming::Job { id, job: Job::Point(i) } => {
                let plan = plan.as_ref().ok_or("a Point request before the Sweep")?;
                let i = plan.space.index(i)?;
                let result = plan.run_point(&bound, i, &mut point);
                serving.finish(id, Outcome::Point(result), trace::fatal_seen())?;
            }
            Incoming::Job { id, job: Job::Run { grid, sets } } => {
                let result = run_streamed(&serving, &bound, &grid, &sets);
                serving.finish(id, Outcome::Run(result), trace::fatal_seen())?;
            }
        }
    }
    runner_sandbox::worker::flush();
    Ok(())
}

/// Runs the system in a worker, sending its rows in batches ([`Pacer`]).
fn run_streamed(serving: &Serving<Systems>, bound: &Bound, grid: &Grid, sets: &[String]) -> Result<Option<String>, String> {
    let sets = bound.parse_sets(sets)?;
    let mut rows: Vec<f64> = Vec::with_capacity(BATCH + 64);
    let mut pacer = Pacer::new(BATCH);
    let result = bound.run("system", grid, &sets, |t, values| {
        rows.push(t);
        rows.extend_from_slice(values);
        if pacer.due(rows.len()) {
            serving.send(&Rows(std::mem::take(&mut rows)))?;
            rows.reserve(BATCH + 64);
        }
        Ok(())
    });
    if !rows.is_empty() {
        serving.send(&Rows(rows))?;
    }
    match result {
        Ok(RunOutcome::Finished) => Ok(None),
        Ok(RunOutcome::Ended(why)) => Ok(Some(why.to_string())),
        Err(failure) => Err(failure.to_string()),
    }
}

/// `runner simulate SYSTEM`: one run, CSV `time,COMPONENT.VARIABLE,...`; in a worker process
/// stopped after `timeout` (as `isolation` says), or with `None` in this process.
pub fn simulate(
    path: &Path,
    run: &RunDefaults,
    algorithm: &Algorithm,
    out: Option<&Path>,
    isolation: Option<Config>,
    plot: Option<Plot>,
) -> Result<(), String> {
    let mut system = System::open(path)?;
    if isolation.is_none() {
        system.load_binaries()?;
    }
    let bound = bind(&system, algorithm)?;
    warn(&bound, algorithm);
    let grid = grid(&system, run)?;
    // Checked here too, so a typo is refused before a worker starts.
    let sets = bound.parse_sets(&run.set)?;
    let axes = plot.as_ref().map(|p| p.axes(&bound)).transpose()?;
    let mut trace = Trace { names: bound.columns.clone(), columns: vec![Vec::new(); bound.columns.len()], ..Trace::default() };
    let mut writer = output::csv_writer(out)?;
    let mut header = vec!["time".to_owned()];
    header.extend(bound.columns.iter().cloned());
    writer.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
    let mut row = Vec::with_capacity(header.len());
    let mut write = |t: f64, values: &[f64]| {
        if axes.is_some() {
            trace.push(t, values);
        }
        row.clear();
        row.push(number(t));
        row.extend(values.iter().map(|&x| number(x)));
        writer.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))
    };
    let result = match isolation {
        // Ctrl-C ends a run here at its next row, as it ends one in a worker.
        None => bound
            .run(
                "system",
                &grid,
                &sets,
                |t: f64, values: &[f64]| if interrupt::requested() { Err("interrupted".to_owned()) } else { write(t, values) },
            )
            .map_err(|failure| failure.to_string())
            .map(|outcome| match outcome {
                RunOutcome::Finished => None,
                RunOutcome::Ended(why) => Some(why.to_string()),
            }),
        Some(config) => {
            let width = 1 + bound.columns.len();
            let setup = Setup::Load { files: system.files(), algorithm: Box::new(algorithm.clone()) };
            let mut session = Session::<Systems>::new(config, &[setup], false);
            let job = Job::Run { grid, sets: run.set.clone() };
            let outcome = session.run(job, &interrupt::requested, |Rows(values)| {
                if values.len() % width != 0 {
                    return Err("the worker sent a row of the wrong size".to_owned());
                }
                values.chunks_exact(width).try_for_each(|r| write(r[0], &r[1..]))
            });
            match outcome {
                Ok(Outcome::Run(result)) => result,
                Ok(Outcome::Point(_)) => Err("the worker answered a run with a sweep point".to_owned()),
                Err(e) => Err(e),
            }
        }
    };
    // The rows before a failure are kept, as for single FMUs.
    let kept = writer.get_ref().describe();
    output::finish_csv(writer)?;
    let ended = result.map_err(|failure| format!("{failure} (the rows before it are in {kept})"))?;
    if let Some(why) = ended {
        eprintln!("the simulation ended early: {why}");
    }
    if let (Some(plot), Some((ys, x))) = (plot, axes) {
        let mut title = format!("{}: outputs", system.structure.name);
        if let Some(x) = &x {
            title.push_str(&format!(" against {}", x.name));
        }
        report::write_plot(plot.path, &figure(title, &[(None, &trace, Vec::new())], &ys, x.as_ref())?)?;
        eprintln!("wrote {}", plot.path.display());
    }
    Ok(())
}

/// What `--plot` draws of a system's run: one panel per `vars` (`COMPONENT.VARIABLE` columns;
/// default every component's continuous Real outputs) against time or `x`.
pub struct Plot<'a> {
    pub path: &'a Path,
    pub vars: &'a [String],
    pub x: Option<&'a str>,
}

impl Plot<'_> {
    /// The y axes and the x axis, each a column of `bound` in its component's display unit.
    fn axes(&self, bound: &Bound) -> Result<(Vec<Axis>, Option<Axis>), String> {
        let axis = |name: &str| -> Result<Axis, String> {
            let name = name.trim();
            let (c, v) = bound.resolve(name)?;
            if bound.column(name).is_none() || !v.kind.is_numeric() {
                return Err(format!("{name}: a system's plot draws the columns of its CSV (COMPONENT.VARIABLE of a numeric output or of an output that feeds a connection)"));
            }
            let description = &bound.system.components[c].fmu.description;
            let own = Axis::of(description, v);
            let label = format!("{}.{}", bound.system.components[c].name, own.label);
            Ok(Axis { name: name.to_owned(), label, conversion: own.conversion })
        };
        let ys: Vec<Axis> = if self.vars.is_empty() {
            let mut ys = Vec::new();
            for component in &bound.system.components {
                for v in plots::trace::continuous_outputs(&component.fmu.description) {
                    ys.push(axis(&format!("{}.{}", component.name, v.name))?);
                }
            }
            ys
        } else {
            self.vars.iter().map(|n| axis(n)).collect::<Result<_, _>>()?
        };
        if ys.is_empty() {
            return Err("the system's components have no continuous Real outputs to plot: choose columns with --plot-vars".to_owned());
        }
        Ok((ys, self.x.map(axis).transpose()?))
    }
}

/// A system sweep's supervisor side: the system bound and the sweep checked.
pub struct Sweep<'a> {
    system: &'a System,
    bound: Bound<'a>,
    plan: SweepPlan<'a>,
    spec: SweepSpec,
    algorithm: Algorithm,
}

impl<'a> Sweep<'a> {
    /// Binds `system` under `algorithm` and checks the sweep of `params` with `metric_texts`
    /// on the grid of `run`.
    pub fn new(
        system: &'a System,
        run: &RunDefaults,
        algorithm: &Algorithm,
        params: &[String],
        metric_texts: &[String],
    ) -> Result<Sweep<'a>, String> {
        if params.is_empty() {
            return Err("nothing to sweep: give --param COMPONENT.PARAM=START:STOP:STEP or COMPONENT.PARAM=V1,V2,...".to_owned());
        }
        if metric_texts.is_empty() {
            return Err("no metric: give --metric NAME=EXPR, e.g. --metric 'amplitude=max(car.z_s)'".to_owned());
        }
        let bound = bind(system, algorithm)?;
        warn(&bound, algorithm);
        let ranges = params.iter().map(|p| sweep::parse_range(p)).collect::<Result<Vec<_>, _>>()?;
        let spec = SweepSpec { grid: grid(system, run)?, sets: run.set.clone(), ranges, metrics: MetricSet::parse(metric_texts)? };
        let plan = SweepPlan::new(&bound, &spec)?;
        Ok(Sweep { system, bound, plan, spec, algorithm: algorithm.clone() })
    }

    pub fn plan(&self) -> &SweepPlan<'a> {
        &self.plan
    }

    pub fn spec(&self) -> &SweepSpec {
        &self.spec
    }

    pub fn system(&self) -> &'a System {
        self.system
    }

    pub fn algorithm(&self) -> &Algorithm {
        &self.algorithm
    }

    /// Runs the points `points`, in `workers` or (`None`) on `threads` threads here, and calls
    /// `deliver(i, result)` in point order as they finish; stops when interrupted.
    pub fn execute(
        &self,
        workers: Option<Workers<Systems>>,
        threads: usize,
        points: Range<usize>,
        deliver: impl FnMut(usize, PointResult) -> Result<(), String>,
    ) -> Result<(), String> {
        match workers {
            None => {
                sweep::on_threads(points, threads, &interrupt::requested, |i, point| self.plan.run_point(&self.bound, i, point), deliver)
            }
            Some(mut workers) => {
                workers.setup(&Setup::Load { files: self.system.files(), algorithm: Box::new(self.algorithm.clone()) });
                // A component that allows one instance per process gets a process per point.
                let components = &self.system.components;
                workers.one_job_per_worker(components.iter().any(|c| isolated::once_per_process(&c.fmu.description, c.fmu.interface)));
                let mut deliver = deliver;
                run_batch(
                    workers,
                    &Setup::Sweep(Box::new(self.spec.clone())),
                    points,
                    |i| Job::Point(i as u64),
                    &interrupt::requested,
                    |i, outcome| match outcome {
                        Outcome::Point(result) => deliver(i, result),
                        Outcome::Run(_) => Err(format!("the worker answered point {i} with a run")),
                    },
                )
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What a supervisor reads after a worker died: the call and time of the importer's slot
    /// and the component the master set, by the name the worker recorded (by number when the
    /// names did not fit).
    #[test]
    fn a_dead_workers_place_names_the_component() {
        let memory = SharedMemory::new(std::mem::size_of::<Page>()).unwrap();
        // SAFETY: a fresh region sized for the page, zeroed.
        let page = unsafe { memory.view::<Page>() };
        page.slot.clear();
        page.write_names(["road", "car"]);
        page.slot.call.store(Call::DoStep as u32, Ordering::Relaxed);
        page.slot.time.store(0.31f64.to_bits(), Ordering::Relaxed);
        page.slot.context.store(2, Ordering::Relaxed);
        assert_eq!(page.place(), "in fmi2DoStep of component 'car' at t = 0.31");
        page.slot.context.store(1, Ordering::Relaxed);
        assert_eq!(page.place(), "in fmi2DoStep of component 'road' at t = 0.31");
        page.slot.context.store(3, Ordering::Relaxed);
        assert_eq!(page.place(), "in fmi2DoStep of component 3 at t = 0.31");
        page.slot.context.store(0, Ordering::Relaxed);
        assert_eq!(page.place(), "in fmi2DoStep at t = 0.31");
        page.slot.call.store(Call::Load as u32, Ordering::Relaxed);
        assert_eq!(page.place(), "while loading the components' binaries");
        page.slot.context.store(1, Ordering::Relaxed);
        assert_eq!(page.place(), "while loading the binary of component 'road'");
        page.slot.context.store(0, Ordering::Relaxed);
        // Names that do not fit are left out, not cut.
        let long = "x".repeat(NAMES);
        page.write_names(["road", long.as_str()]);
        page.slot.call.store(Call::Instantiate as u32, Ordering::Relaxed);
        page.slot.time.store(f64::NAN.to_bits(), Ordering::Relaxed);
        page.slot.context.store(2, Ordering::Relaxed);
        assert_eq!(page.place(), "in fmi2Instantiate of component 2");
    }
}
