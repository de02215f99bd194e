//! `runner sweep`: the engine's sweep of a parameter space (one FMU instance per point, in
//! worker processes or, with `--in-process`, on threads), one CSV row per point streamed in
//! point order to `<out>.partial` as points finish, renamed to `<out>` when complete; a killed or
//! interrupted sweep continues with `--resume`. Then the peaks and a plot.
//!
//! The command resolves, runs, reports: its options are checked and merged with the model's
//! experiment once (`Settings`), bound to the FMU as the engine's [`SweepRequest`]
//! (`Settings::request`); the destination (`Destination`: standard output, or a durable
//! `.partial` file and the record `--resume` checks) takes the rows as the points finish; the
//! report prints the peaks and draws the plot.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use fmi_importer::Value;
use fmi_systems::System;
use runner_engine::exec::{self, Held, Points};
use runner_engine::input::InputTable;
use runner_engine::isolated::Engine;
use runner_engine::metrics::Metrics;
use runner_engine::request::{MetricSet, SweepRequest};
use runner_engine::run::Grid;
use runner_engine::sweep::{parse_range, Plan, PointResult, Space};
use runner_engine::variables;
use runner_sandbox::{Config, Workers};
use sha2::{Digest, Sha256};

use crate::commands::system;
use crate::experiment::{self, RunDefaults, Target};
use crate::integration::Integration;
use crate::interrupt;
use crate::report::partial::{self, PartialCsv, Record, SweepLock};
use crate::report::progress::Progress;
use crate::report::{self, output};
use crate::workers;
use plots::lines::{LinePlot, Mark, Series};

/// Options of `runner sweep`; empty lists and `None`s fall back to the model's experiment.toml.
#[derive(Default)]
pub struct Options {
    /// Model name or `.fmu` path.
    pub fmu: String,
    /// `NAME=START:STOP:STEP` or `NAME=V1,V2,...`.
    pub params: Vec<String>,
    /// `NAME=EXPR`.
    pub metrics: Vec<String>,
    /// Worker threads or processes (default: the number of cores).
    pub threads: Option<usize>,
    /// Grid and fixed assignments.
    pub run: RunDefaults,
    /// CSV destination.
    pub out: Option<PathBuf>,
    /// SVG destination.
    pub plot: Option<PathBuf>,
    /// The interface, and the runner's integrator for Model Exchange.
    pub integration: Integration,
    /// Run the points on threads of this process instead of worker processes.
    pub in_process: bool,
    /// A point running longer (seconds) is recorded as timed out and its worker replaced.
    pub point_timeout: Option<f64>,
    /// Memory limit of each worker in MiB (default: three quarters of the machine's, shared).
    pub worker_memory: Option<u64>,
    /// Continue the sweep whose finished rows are in `<out>.partial`.
    pub resume: bool,
    /// The command line as given, for the "continue with" message.
    pub command_line: Vec<String>,
    /// Inputs over time for every point (`--input-file`: fmpy's CSV convention).
    pub input_file: Option<PathBuf>,
    /// The master algorithm for a system (`--master`).
    pub master: Option<String>,
    /// How a system's connections pass Real values (`--coupling`).
    pub coupling: Option<String>,
}

/// `runner sweep SYSTEM`: as a sweep of an FMU (worker processes or threads, rows streamed to
/// `<out>.partial`, `--resume`, the plot), each point an instance of the whole system.
fn run_system(options: &Options) -> Result<Summary, String> {
    let threads = thread_count(options)?;
    let sandbox = sandbox_limits(options, threads)?;
    let mut system = System::open(Path::new(&options.fmu))?;
    if sandbox.is_none() {
        system.load_binaries()?;
    }
    let algorithm = system::Algorithm::new(options.master.clone(), options.coupling.clone(), options.input_file.as_deref())?;
    let sweep = system::Sweep::new(&system, &options.run, &algorithm, &options.params, &options.metrics)?;
    let plan = sweep.plan();
    let n = plan.space.len;
    let isolation = match sandbox {
        Some((timeout, memory)) => Some(system::isolation(timeout, memory)?),
        None => None,
    };
    let workers = match &isolation {
        Some(config) => Some(Workers::start(config.clone(), threads.min(n))?),
        None => None,
    };
    if let Some(plot) = &options.plot {
        report::check_plot(plot)?;
    }
    let m = plan.metrics.metrics.len();
    let mut header: Vec<String> = plan.space.ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(plan.metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    let table = Table { header, m, space: &plan.space };
    let out = options.out.as_deref();
    if let Some(out) = out {
        output::check_destination(out)?;
    }
    let current = || system_record(&sweep, options.point_timeout);
    let destination = match Destination::open(out, options.resume, current, &table)? {
        Opened::Run(destination) => destination,
        Opened::Complete(summary) => return Ok(summary),
    };
    let clock = Instant::now();
    let finished = execute(n, destination, &table, |first, deliver| sweep.execute(workers, threads, first..n, deliver))?;
    let written = finish(finished, options, out, &table)?;
    report(&plan.space, &plan.metrics, threads, isolation.is_some(), &written, clock.elapsed().as_secs_f64());
    if let Some(path) = &options.plot {
        let x_unit = plan.swept().next().and_then(|v| v.unit.as_deref());
        let name = system.structure.name.as_str();
        plot_metrics(path, &plan.space, &plan.metrics, x_unit, sweep.spec().metrics.texts(), name, &written.kept)?;
    }
    Ok(Summary { points: n, failed: written.failed })
}

/// The record of a system sweep: what `--resume` compares. The system is identified by the
/// digest of what it is (see [`system_sha256`]), not by the path it was named by.
fn system_record(sweep: &system::Sweep, timeout: Option<f64>) -> Result<Record, String> {
    let system = sweep.system();
    let spec = sweep.spec();
    let mut entries: Vec<(String, String)> = Vec::new();
    let mut put = |k: &str, v: String| entries.push((k.to_owned(), v));
    put("system", system.path.display().to_string());
    put("system_sha256", system_sha256(system)?);
    put("points", sweep.plan().space.len.to_string());
    for (name, values) in &spec.ranges {
        put("param", range_text(name, values));
    }
    for text in spec.metrics.texts() {
        put("metric", text.clone());
    }
    // By value, as the FMU gets it: `0.05`, `5e-2` and `5 cm` are the same sweep.
    for (c, variable, value) in sweep.plan().sets() {
        put("set", format!("{}.{}={}", system.components[*c].name, variable.name, value_text(value)));
    }
    let grid = &spec.grid;
    put("start_time", format!("{:?}", grid.start));
    put("stop_time", format!("{:?}", grid.stop));
    put("output_interval", format!("{:?}", grid.interval));
    put("tolerance", grid.tolerance.map_or("the FMUs' defaults".to_owned(), |t| format!("{t:?}")));
    let algorithm = sweep.algorithm();
    put("master", algorithm.master.clone().unwrap_or_else(|| "jacobi".to_owned()));
    put("coupling", algorithm.coupling.clone().unwrap_or_else(|| "the best both ends allow".to_owned()));
    if let Some(inputs) = &algorithm.inputs {
        put("input_file", table_text(inputs));
    }
    put("point_timeout", timeout.map_or("none".to_owned(), |t| format!("{t:?} s")));
    Ok(Record { entries })
}

/// The sha256 of what a system is, the same however it is named (relative, absolute, through a
/// link, by its folder or its `.ssd`): an archive's bytes; for a folder (or the folder of an
/// `.ssd`), each structure, parameter, mapping and FMU file under it (not in linked folders), by
/// its name in the folder; then each component's FMU by its bytes and its parameter values,
/// which a folder's SSD may read from files anywhere. The FMUs extracted from an archive are not hashed again (their bytes are
/// the archive's, their paths a fresh temporary folder per run).
fn system_sha256(system: &System) -> Result<String, String> {
    let path = &system.path;
    let mut hash = Sha256::new();
    let mut put = |name: &str, digest: &str| {
        hash.update(name.as_bytes());
        hash.update([0]);
        hash.update(digest.as_bytes());
    };
    if path.extension().is_some_and(|e| e == "ssp") {
        put("", &file_sha256(path)?);
    } else {
        // `SystemStructure.ssd`'s parent is the empty path, which names no folder to read.
        let root =
            if path.is_dir() { path.as_path() } else { path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new(".")) };
        let mut files: Vec<PathBuf> = Vec::new();
        let mut folders = vec![root.to_path_buf()];
        while let Some(folder) = folders.pop() {
            // A folder below the root that cannot be listed (no permission, gone) holds nothing
            // the system read: it loaded, so what it uses is readable, and is hashed below.
            let entries = match std::fs::read_dir(&folder) {
                Ok(entries) => entries,
                Err(_) if folder != root => continue,
                Err(e) => return Err(format!("cannot read {}: {e}", folder.display())),
            };
            for entry in entries.flatten() {
                let p = entry.path();
                // A linked folder is not walked (links back up would walk without end); what
                // the system uses from it is hashed below, by component.
                if entry.file_type().is_ok_and(|t| t.is_dir()) {
                    folders.push(p);
                } else if p.extension().and_then(|e| e.to_str()).is_some_and(|e| matches!(e, "ssd" | "ssv" | "ssm" | "ssb" | "fmu")) {
                    files.push(p);
                }
            }
        }
        files.sort();
        for file in &files {
            // Only regular files (through links): reading a FIFO would wait for a writer. One
            // that cannot be opened (a dangling link, no permission) is no file the system read.
            if !std::fs::metadata(file).is_ok_and(|m| m.is_file()) || std::fs::File::open(file).is_err() {
                continue;
            }
            put(&file.strip_prefix(root).unwrap_or(file).display().to_string(), &file_sha256(file)?);
        }
    }
    for component in &system.structure.components {
        let in_archive = system.archive_root().is_some_and(|root| component.source.starts_with(root));
        let fmu_sha256 = if in_archive { String::new() } else { file_sha256(&component.source)? };
        put(&component.name, &fmu_sha256);
        for assignment in &component.parameters {
            put(&assignment.variable, &format!("{:?}", assignment.value));
        }
    }
    Ok(format!("{:x}", hash.finalize()))
}

/// What a finished sweep reports.
pub struct Summary {
    /// Number of points.
    pub points: usize,
    /// Points whose status is not `ok`.
    pub failed: usize,
}

/// Where the CSV and the plot go. The experiment's CSV and plot are one default: naming the CSV
/// on the command line drops the default plot too, rather than writing it beside the CSV's
/// default place.
fn output_paths(options: &Options, defaults: &experiment::SweepDefaults) -> (Option<PathBuf>, Option<PathBuf>) {
    let out = options.out.clone().or_else(|| defaults.out.clone());
    let plot = options.plot.clone().or_else(|| if options.out.is_none() { defaults.plot.clone() } else { None });
    (out, plot)
}

fn value_text(value: &Value) -> String {
    match value {
        Value::Real(x) => format!("{x:?}"),
        Value::Integer(i) => i.to_string(),
        Value::Int(i) => i.to_string(),
        Value::Boolean(b) => b.to_string(),
        Value::String(s) => format!("{s:?}"),
        Value::Binary(bytes) => bytes.iter().map(|b| format!("{b:02x}")).collect(),
        Value::List(items) => format!("[{}]", items.iter().map(value_text).collect::<Vec<_>>().join(" ")),
    }
}

/// The record of this sweep: what `--resume` compares (see [`partial`]).
fn record(
    path: &Path,
    fmu_sha256: &str,
    interface: fmi_importer::Interface,
    plan: &Plan,
    request: &SweepRequest,
    timeout: Option<f64>,
) -> Record {
    let mut entries: Vec<(String, String)> = Vec::new();
    let mut put = |k: &str, v: String| entries.push((k.to_owned(), v));
    put("fmu", path.display().to_string());
    put("fmu_sha256", fmu_sha256.to_owned());
    put("interface", interface.name().to_owned());
    put("points", plan.space.len.to_string());
    for (name, values) in &plan.space.ranges {
        put("param", range_text(name, values));
    }
    for text in request.metrics.texts() {
        put("metric", text.clone());
    }
    for (variable, value) in &plan.fixed {
        put("set", format!("{}={}", variable.name, value_text(value)));
    }
    let grid = &plan.grid;
    put("start_time", format!("{:?}", grid.start));
    put("stop_time", format!("{:?}", grid.stop));
    put("output_interval", format!("{:?}", grid.interval));
    put("tolerance", grid.tolerance.map_or("the FMU's default".to_owned(), |t| format!("{t:?}")));
    if interface == fmi_importer::Interface::ModelExchange {
        let s = &grid.solver;
        put("solver", format!("{} (fixed step {:?} s, abs_tol {:?})", s.method.name(), s.fixed_step, s.abs_tol));
    }
    put("point_timeout", timeout.map_or("none".to_owned(), |t| format!("{t:?} s")));
    if let Some(inputs) = &request.inputs {
        put("input_file", table_text(inputs));
    }
    Record { entries }
}

/// An input table as a record names it: the table itself, not the file's name (the same name
/// may hold other inputs later).
fn table_text(inputs: &InputTable) -> String {
    let mut hash = Sha256::new();
    for name in &inputs.names {
        hash.update(name.as_bytes());
        hash.update([0]);
    }
    for x in inputs.time.iter().chain(inputs.values.iter().flatten()) {
        hash.update(x.to_bits().to_le_bytes());
    }
    format!("{} columns, {} rows (sha256 {:x})", inputs.names.len(), inputs.time.len(), hash.finalize())
}

/// A swept parameter's values as a record names them: their count, ends and digest.
fn range_text(name: &str, values: &[f64]) -> String {
    let mut hash = Sha256::new();
    for x in values {
        hash.update(x.to_bits().to_le_bytes());
    }
    let digest = format!("{:x}", hash.finalize());
    let (first, last) = (values.first().copied().unwrap_or(f64::NAN), values.last().copied().unwrap_or(f64::NAN));
    format!("{name}: {} values from {first:?} to {last:?} (sha256 {})", values.len(), &digest[..16])
}

/// The sha256 of the file at `path` in hex, read in pieces (no copy of the whole file).
fn file_sha256(path: &Path) -> Result<String, String> {
    use std::io::Read;
    let cannot = |e: std::io::Error| format!("cannot read {}: {e}", path.display());
    let mut file = std::fs::File::open(path).map_err(cannot)?;
    let mut hash = Sha256::new();
    let mut buffer = vec![0u8; 1 << 16];
    loop {
        match file.read(&mut buffer) {
            Ok(0) => return Ok(format!("{:x}", hash.finalize())),
            Ok(n) => hash.update(&buffer[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(cannot(e)),
        }
    }
}

/// The options of a sweep, checked and merged with the model's experiment before the FMU is
/// opened: what is wrong with them costs nothing.
struct Settings {
    target: Target,
    /// The swept parameters and their values, in `--param` order.
    ranges: Vec<(String, Vec<f64>)>,
    /// The metrics, parsed once.
    metrics: MetricSet,
    threads: usize,
    /// `--point-timeout`, as given (the record names it).
    point_timeout: Option<f64>,
    /// The workers' sandbox; `None` with `--in-process`.
    isolation: Option<Config>,
    /// The runner's integrator for Model Exchange.
    solver: fmi_importer::Solver,
    out: Option<PathBuf>,
    plot: Option<PathBuf>,
}

impl Settings {
    /// Checks `options` and merges them with the model's experiment.
    fn resolve(options: &Options) -> Result<Settings, String> {
        let target = experiment::resolve(&options.fmu)?;
        let defaults = &target.experiment.sweep;
        let pick = |cli: &Vec<String>, file: &Vec<String>| if cli.is_empty() { file.clone() } else { cli.clone() };
        let param_texts = pick(&options.params, &defaults.param);
        let metric_texts = pick(&options.metrics, &defaults.metric);
        if param_texts.is_empty() {
            return Err("nothing to sweep: give --param NAME=START:STOP:STEP or NAME=V1,V2,...".to_owned());
        }
        if metric_texts.is_empty() {
            return Err("no metric: give --metric NAME=EXPR, e.g. --metric 'amplitude=max(x)'".to_owned());
        }
        let ranges = param_texts.iter().map(|p| parse_range(p)).collect::<Result<Vec<_>, _>>()?;
        let metrics = MetricSet::parse(&metric_texts)?;
        let threads = thread_count(options)?;
        let sandbox = sandbox_limits(options, threads)?;
        let solver = options.integration.solver()?;
        let (out, plot) = output_paths(options, defaults);
        let isolation = match sandbox {
            Some((timeout, memory)) => Some(workers::isolation(timeout, memory)?),
            None => None,
        };
        Ok(Settings { target, ranges, metrics, threads, point_timeout: options.point_timeout, isolation, solver, out, plot })
    }

    /// The number of points (saturating: the exact count is checked once the FMU is known).
    fn points(&self) -> usize {
        self.ranges.iter().fold(1usize, |n, (_, v)| n.saturating_mul(v.len()))
    }

    /// The sweep as the engine takes it, bound to the FMU `held`: the grid from the options, the
    /// experiment and the FMU's default experiment; the assignments common to every point (the
    /// experiment's, then the options'); the input file.
    fn request(&self, options: &Options, held: &Held) -> Result<SweepRequest, String> {
        let d = held.description();
        let defaults = &self.target.experiment.sweep;
        let mut grid = Grid::choose(d, &[options.run.grid(), defaults.run().grid()])?;
        grid.solver = self.solver;
        let mut set_texts = defaults.set.clone();
        set_texts.extend(options.run.set.iter().cloned());
        let inputs = workers::input_file(options.input_file.as_deref(), d, held.interface())?;
        let fixed = variables::parse_sets(d, &set_texts)?;
        Ok(SweepRequest::new(grid, &fixed, self.ranges.clone(), self.metrics.clone(), inputs))
    }
}

/// `--threads`, or one per core.
fn thread_count(options: &Options) -> Result<usize, String> {
    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".to_owned());
    }
    Ok(threads)
}

/// The workers' limits, `None` with `--in-process`: `--point-timeout`, and `--worker-memory`
/// in MiB (default: three quarters of the machine's memory, shared among `threads` workers).
fn sandbox_limits(options: &Options, threads: usize) -> Result<Option<(Option<Duration>, u64)>, String> {
    let timeout = runner_sandbox::timeout("--point-timeout", options.point_timeout)?;
    if options.in_process && timeout.is_some() {
        return Err("--point-timeout needs worker processes (a thread cannot be stopped): drop --in-process".to_owned());
    }
    if options.in_process && options.worker_memory.is_some() {
        return Err("--worker-memory limits worker processes: drop --in-process".to_owned());
    }
    Ok((!options.in_process).then(|| (timeout, options.worker_memory.unwrap_or_else(|| runner_sandbox::default_memory_mib(threads)))))
}

/// Where the rows go: standard output (or a device or pipe named by `--out`), or a durable file:
/// `<out>.partial`, extended as points finish and renamed to `<out>` when complete, with its
/// record beside it.
// One value per sweep: the variants' sizes do not matter.
#[allow(clippy::large_enum_variant)]
enum Destination {
    Stdout(csv::Writer<output::Output>),
    File {
        partial: PartialCsv,
        /// Held until the sweep ends: no other sweep writes this `--out` meanwhile.
        _lock: SweepLock,
        /// The first point still to run (a resumed sweep's), and the finished points' metric
        /// values and failures.
        first: usize,
        kept: Vec<f64>,
        failed: usize,
    },
}

/// What opening the destination found.
#[allow(clippy::large_enum_variant)]
enum Opened {
    /// Run the points from the destination's first on.
    Run(Destination),
    /// The file is complete already: every point is there.
    Complete(Summary),
}

/// The CSV of a sweep: its header, and the text of point `i`'s parameter values.
struct Table<'a> {
    header: Vec<String>,
    /// Metrics per row.
    m: usize,
    space: &'a Space,
}

impl Table<'_> {
    fn spell(&self, i: usize) -> Vec<String> {
        let mut point = Vec::new();
        self.space.point(i, &mut point);
        point.iter().map(|x| format!("{x:?}")).collect()
    }
}

impl Destination {
    /// Opens the sweep's destination: to standard output, or (with `out`) a new partial file
    /// and record, or with `resume` the earlier sweep's, checked to be this sweep's.
    fn open(out: Option<&Path>, resume: bool, current: impl FnOnce() -> Result<Record, String>, table: &Table) -> Result<Opened, String> {
        let Some(out) = out else {
            if resume {
                return Err("--resume needs --out FILE.csv: a sweep to standard output keeps no partial file".to_owned());
            }
            let mut writer = output::csv_writer(None)?;
            writer.write_record(&table.header).map_err(|e| format!("cannot write CSV: {e}"))?;
            return Ok(Opened::Run(Destination::Stdout(writer)));
        };
        if output::is_stream(out) {
            // `<out>.partial` beside /dev/null would be a file in /dev, renamed over the device.
            if resume {
                return Err(format!("--resume needs a regular file: {} is a device or a pipe, which keeps no partial file", out.display()));
            }
            let mut writer = output::csv_writer(Some(out))?;
            writer.write_record(&table.header).map_err(|e| format!("cannot write CSV: {e}"))?;
            return Ok(Opened::Run(Destination::Stdout(writer)));
        }
        let n = table.space.len;
        let current = current()?;
        let (partial_path, record_path) = (partial::partial_path(out), partial::record_path(out));
        // Before anything is read: another sweep at this `--out` would change it under us.
        let mut lock = SweepLock::acquire(out, "--resume")?;
        let had_record = lock.had_record;
        let earlier = || -> Result<Record, String> {
            let cannot = |e: &dyn std::fmt::Display| {
                format!("cannot read {}, the record of the sweep that wrote {}: {e}", record_path.display(), partial_path.display())
            };
            let text = std::fs::read_to_string(&record_path).map_err(|e| cannot(&e))?;
            if !had_record {
                return Err(cannot(&"it is empty"));
            }
            let earlier = Record::parse(&text).map_err(|e| format!("{}: {e}", record_path.display()))?;
            match earlier.difference(&current) {
                None => Ok(earlier),
                Some(diff) => Err(format!(
                    "{} is not from this sweep, so it cannot be resumed:\n{diff}\nrun the earlier sweep's command with --resume, or delete {} to start this one",
                    partial_path.display(),
                    partial_path.display()
                )),
            }
        };
        let mut spell_some = |i: usize| (i < n).then(|| table.spell(i));
        if resume && partial_path.exists() {
            earlier()?;
            let finished = partial::read_finished(&partial_path, &table.header, table.m, &mut spell_some)?;
            eprintln!(
                "resuming: {} of {n} points are in {}; running the other {}",
                finished.rows,
                partial_path.display(),
                n - finished.rows
            );
            // A kill before the whole header reached the file leaves it empty or with part of the
            // header, and no row: start it again.
            let file = if finished.valid == 0 {
                PartialCsv::create(out, &table.header)?
            } else {
                PartialCsv::resume(out, finished.valid, finished.rows)?
            };
            Ok(Opened::Run(Destination::File {
                partial: file,
                _lock: lock,
                first: finished.rows,
                kept: finished.metrics,
                failed: finished.failed,
            }))
        } else if resume && out.exists() && had_record {
            earlier()?;
            let finished = partial::read_finished(out, &table.header, table.m, &mut spell_some)?;
            if finished.rows != n {
                return Err(format!(
                    "{} has {} of this sweep's {n} rows and no partial file to continue; run without --resume to start again",
                    out.display(),
                    finished.rows
                ));
            }
            eprintln!("{} is already complete: all {n} points of this sweep are there; nothing to do", out.display());
            Ok(Opened::Complete(Summary { points: n, failed: finished.failed }))
        } else {
            if resume {
                eprintln!("nothing to resume: there is no {}; starting from the first point", partial_path.display());
            } else if partial_path.exists() {
                return Err(format!(
                    "{} holds the finished points of an earlier sweep: continue it with --resume, or delete it to start again",
                    partial_path.display()
                ));
            }
            lock.write_record(&current.text())?;
            Ok(Opened::Run(Destination::File {
                partial: PartialCsv::create(out, &table.header)?,
                _lock: lock,
                first: 0,
                kept: Vec::new(),
                failed: 0,
            }))
        }
    }

    /// Appends a row.
    fn append(&mut self, row: &[String]) -> Result<(), String> {
        match self {
            Destination::File { partial, .. } => partial.append(row),
            Destination::Stdout(writer) => writer.write_record(row).map_err(|e| format!("cannot write CSV: {e}")),
        }
    }
}

/// Runs `runner sweep`. To a file the CSV is streamed in point order to `<out>.partial` and
/// renamed into place when complete; an interrupted or killed sweep keeps its finished rows
/// there for `--resume`.
pub fn run(options: &Options) -> Result<Summary, String> {
    if fmi_systems::is_system(Path::new(&options.fmu)) {
        return run_system(options);
    }
    let settings = Settings::resolve(options)?;
    // Metrics of modes linearize every point: through Model Exchange.
    let mut integration = options.integration.clone();
    if settings.metrics.metrics().highest_mode().is_some() {
        if integration.interface == Some(fmi_importer::Interface::CoSimulation) {
            return Err("the metrics read modes of the linearized model (natural_frequency, damping), which needs the FMU's Model Exchange interface: drop --interface co-simulation".to_owned());
        }
        integration.interface = Some(fmi_importer::Interface::ModelExchange);
    }
    let path = settings.target.path.clone();
    // The record identifies the FMU by its file's sha256, hashed while this thread starts the
    // workers and unpacks the FMU: off the path to the first point when a core is free.
    let hashing = settings.out.as_ref().map(|_| {
        let path = path.clone();
        std::thread::spawn(move || file_sha256(&path))
    });
    // Workers start now, while this process unpacks the FMU; then they load it (from this
    // process's copy) while this process checks the plan and opens its files.
    let mut workers: Option<Workers<Engine>> = match &settings.isolation {
        Some(config) => Some(exec::start_workers(config.clone(), settings.threads.min(settings.points()))?),
        None => None,
    };
    let in_process = workers.is_none();
    let (held, source) = workers::open(&path, &integration, in_process)?;
    let once = held.once_per_process();
    if let Some(workers) = &mut workers {
        exec::load(workers, &source, once);
    }
    let request = settings.request(options, &held)?;
    let plan = request.plan(held.description(), held.identifier(), held.interface())?;
    let n = plan.space.len;
    if in_process && once && n > 1 {
        return Err(format!(
            "{} declares canBeInstantiatedOnlyOncePerProcess, so its points cannot share a process: drop --in-process (each point then gets a worker process of its own)",
            held.description().model_name
        ));
    }
    if let Some(plot) = &settings.plot {
        report::check_plot(plot)?;
    }
    let metrics = plan.metrics.metrics.len();
    let mut header: Vec<String> = plan.space.ranges.iter().map(|(n, _)| n.clone()).collect();
    header.extend(plan.metrics.metrics.iter().map(|(n, _)| n.clone()));
    header.push("status".to_owned());
    let table = Table { header, m: metrics, space: &plan.space };
    let current = || -> Result<Record, String> {
        let digest = match hashing {
            Some(hashing) => hashing.join().map_err(|_| format!("hashing {} failed", path.display()))??,
            None => file_sha256(&path)?,
        };
        Ok(record(&path, &digest, held.interface(), &plan, &request, settings.point_timeout))
    };
    if let Some(out) = &settings.out {
        output::check_destination(out)?;
    }
    let destination = match Destination::open(settings.out.as_deref(), options.resume, current, &table)? {
        Opened::Run(destination) => destination,
        Opened::Complete(summary) => return Ok(summary),
    };
    let on = match workers {
        Some(workers) => Points::Workers(workers),
        None => Points::Threads(settings.threads),
    };
    let clock = Instant::now();
    let finished = execute(n, destination, &table, |first, deliver| {
        exec::sweep(&held, &plan, &request, on, first..n, &interrupt::requested, deliver)
    })?;
    let written = finish(finished, options, settings.out.as_deref(), &table)?;
    let elapsed = clock.elapsed().as_secs_f64();
    report(&plan.space, &plan.metrics, settings.threads, settings.isolation.is_some(), &written, elapsed);
    if let Some(path) = &settings.plot {
        let x_unit = plan.swept[0].unit.as_deref();
        let name = held.description().model_name.as_str();
        plot_metrics(path, &plan.space, &plan.metrics, x_unit, request.metrics.texts(), name, &written.kept)?;
    }
    Ok(Summary { points: n, failed: written.failed })
}

/// What running the points left: the destination, the metric values of every point delivered
/// (NaN for a failed one) and the failures, and how the run ended.
struct Finished {
    destination: Destination,
    kept: Vec<f64>,
    failed: usize,
    outcome: Result<(), String>,
}

/// Runs the `n` points from the destination's first on, by `run(first, deliver)`, each row
/// appended as it is delivered.
fn execute(
    n: usize,
    mut destination: Destination,
    table: &Table,
    run: impl FnOnce(usize, &mut dyn FnMut(usize, PointResult) -> Result<(), String>) -> Result<(), String>,
) -> Result<Finished, String> {
    let m = table.m;
    // Only the metric values are kept, for the peaks and the plot.
    let (first, mut kept, mut failed) = match &mut destination {
        Destination::File { first, kept, failed, .. } => (*first, std::mem::take(kept), *failed),
        Destination::Stdout(_) => (0, Vec::new(), 0),
    };
    let progress = Progress::start(n as u64, "points");
    kept.reserve(n.saturating_sub(first) * m);
    progress.inc(first as u64);
    let mut point = Vec::new();
    let mut row: Vec<String> = Vec::with_capacity(table.header.len());
    let mut deliver = |i: usize, r: PointResult| -> Result<(), String> {
        table.space.point(i, &mut point);
        row.clear();
        row.extend(point.iter().map(|x| format!("{x:?}")));
        match &r.metrics {
            Some(values) => {
                row.extend(values.iter().map(|x| format!("{x:?}")));
                kept.extend(values);
            }
            None => {
                row.extend(std::iter::repeat_n(String::new(), m));
                kept.extend(std::iter::repeat_n(f64::NAN, m));
            }
        }
        failed += usize::from(partial::failed(&r.status));
        row.push(r.status);
        destination.append(&row)?;
        progress.inc(1);
        Ok(())
    };
    let outcome = run(first, &mut deliver);
    drop(progress);
    Ok(Finished { destination, kept, failed, outcome })
}

/// What a sweep wrote.
struct Written {
    /// Metric values of every point, row-major.
    kept: Vec<f64>,
    failed: usize,
    /// Where the CSV went, for the summary line.
    destination: String,
    csv_on_stdout: bool,
}

/// Commits the destination, or on a failure or an interrupt keeps the finished rows and says
/// how to continue.
fn finish(finished: Finished, options: &Options, out: Option<&Path>, table: &Table) -> Result<Written, String> {
    let Finished { destination, kept, failed, outcome } = finished;
    let n = table.space.len;
    let delivered = kept.len() / table.m.max(1);
    let continue_with = || {
        let mut args = options.command_line.clone();
        if !args.iter().any(|a| a == "--resume") {
            args.push("--resume".to_owned());
        }
        workers::shell_line(&args)
    };
    if let Err(e) = outcome {
        return Err(match destination {
            Destination::File { partial, .. } => {
                let path = partial.path().to_path_buf();
                let _ = partial.close();
                // What reached the file, read back: rows a failed write did not reach are gone.
                let kept =
                    partial::read_finished(&path, &table.header, table.m, &mut |i| (i < n).then(|| table.spell(i))).map_or(0, |f| f.rows);
                format!(
                    "{e}\nthe {kept} points finished before are kept in {}; once it can be written, continue with: {}",
                    path.display(),
                    continue_with()
                )
            }
            Destination::Stdout(_) => e,
        });
    }
    if interrupt::requested() {
        return Err(match destination {
            Destination::File { partial, .. } => {
                let path = partial.path().to_path_buf();
                let done = partial.close()?;
                format!(
                    "interrupted after {done} of {n} points; the finished points are in {}; continue with: {}",
                    path.display(),
                    continue_with()
                )
            }
            Destination::Stdout(_) => format!("interrupted after {delivered} of {n} points"),
        });
    }
    let (destination_name, csv_on_stdout) = match out {
        Some(out) => (out.display().to_string(), false),
        None => ("standard output".to_owned(), true),
    };
    match destination {
        Destination::File { partial, .. } => partial.finish()?,
        Destination::Stdout(writer) => output::finish_csv(writer)?,
    }
    Ok(Written { kept, failed, destination: destination_name, csv_on_stdout })
}

/// The summary line and each metric's peak.
fn report(space: &Space, metrics: &Metrics, threads: usize, isolated: bool, written: &Written, elapsed: f64) {
    let n = space.len;
    let m = metrics.metrics.len();
    let mode = if isolated { "worker process(es)" } else { "thread(s), in-process" };
    eprintln!("{n} points in {elapsed:.2} s on {threads} {mode}; {} failed; wrote {}", written.failed, written.destination);
    let metric_of = |i: usize, k: usize| written.kept[i * m + k];
    let mut point = Vec::new();
    for (k, (name, _)) in metrics.metrics.iter().enumerate() {
        let best = (0..n).filter(|&i| metric_of(i, k).is_finite()).max_by(|&a, &b| metric_of(a, k).total_cmp(&metric_of(b, k)));
        if let Some(i) = best {
            space.point(i, &mut point);
            let at: Vec<String> = space.ranges.iter().zip(&point).map(|((n, _), x)| format!("{n} = {x}")).collect();
            let line = format!("{name}: peak {:?} at {}", metric_of(i, k), at.join(", "));
            // Keep a CSV on stdout clean: the summary goes to stderr then.
            if written.csv_on_stdout {
                eprintln!("{line}");
            } else {
                println!("{line}");
            }
        }
    }
}

/// Plots each metric against the first parameter (whose unit is `x_unit`) into `path`, peaks
/// marked: one line per combination of the other parameters; the title names `model`.
fn plot_metrics(
    path: &Path,
    space: &Space,
    metrics: &Metrics,
    x_unit: Option<&str>,
    metric_texts: &[String],
    model: &str,
    kept: &[f64],
) -> Result<(), String> {
    let n = space.len;
    let m = metrics.metrics.len();
    let metric_of = |i: usize, k: usize| kept[i * m + k];
    let mut point = Vec::new();
    let x_name = &space.ranges[0].0;
    let x_unit_text = x_unit.map_or(String::new(), |u| format!(" {u}"));
    let mut series = Vec::new();
    let mut marks = Vec::new();
    for (k, (metric, _)) in metrics.metrics.iter().enumerate() {
        // One line per combination of the other parameters, in point order.
        let mut lines: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
        for i in 0..n {
            space.point(i, &mut point);
            let others: Vec<String> = space.ranges.iter().zip(&point).skip(1).map(|((n, _), x)| format!("{n}={x}")).collect();
            let label = if others.is_empty() { metric.clone() } else { format!("{metric} ({})", others.join(", ")) };
            match lines.iter_mut().find(|(l, _)| *l == label) {
                Some((_, pts)) => pts.push((point[0], metric_of(i, k))),
                None => lines.push((label, vec![(point[0], metric_of(i, k))])),
            }
        }
        for (label, points) in lines {
            if let Some(&(x, y)) = points.iter().filter(|p| p.1.is_finite()).max_by(|a, b| a.1.total_cmp(&b.1)) {
                marks.push((label.clone(), Mark { at: (x, y), text: format!("peak {y:.4} at {x_name} = {x}{x_unit_text}") }));
            }
            series.push(Series { label, points });
        }
    }
    let x_label = match x_unit {
        Some(u) => format!("{x_name} ({u})"),
        None => x_name.clone(),
    };
    let y_label = if metrics.metrics.len() == 1 { metric_texts[0].replace('=', " = ") } else { "metric".to_owned() };
    let title = format!("{model}: {} against {x_name}", metrics.metrics.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>().join(", "));
    // With several lines, each peak says whose it is.
    let several = series.len() > 1;
    let marks: Vec<Mark> =
        marks.into_iter().map(|(label, m)| if several { Mark { text: format!("{label}: {}", m.text), ..m } } else { m }).collect();
    report::write_plot(path, &LinePlot { title: &title, x_label: &x_label, y_label: &y_label, series: &series, marks: &marks })?;
    eprintln!("wrote {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fmu_is_hashed_in_pieces_to_the_digest_of_its_bytes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.fmu");
        std::fs::write(&path, b"abc").unwrap();
        // FIPS 180-2's example: sha256("abc").
        assert_eq!(file_sha256(&path).unwrap(), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
        // Many pieces, the last one short: the same digest as of the whole in memory.
        let bytes: Vec<u8> = (0..200_003u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(file_sha256(&path).unwrap(), format!("{:x}", Sha256::digest(&bytes)));
        let missing = file_sha256(&dir.path().join("gone.fmu")).unwrap_err();
        assert!(missing.starts_with("cannot read ") && missing.contains("gone.fmu"), "{missing}");
    }

    #[test]
    fn naming_the_csv_drops_the_experiments_default_plot() {
        let defaults = experiment::SweepDefaults { out: Some("e.csv".into()), plot: Some("e.svg".into()), ..Default::default() };
        let paths = |out: Option<&str>, plot: Option<&str>| {
            let options = Options { out: out.map(PathBuf::from), plot: plot.map(PathBuf::from), ..Default::default() };
            let (o, p) = output_paths(&options, &defaults);
            (o.map(|p| p.display().to_string()), p.map(|p| p.display().to_string()))
        };
        let s = |x: &str| Some(x.to_owned());
        assert_eq!(paths(None, None), (s("e.csv"), s("e.svg")));
        assert_eq!(paths(Some("x.csv"), None), (s("x.csv"), None));
        assert_eq!(paths(None, Some("x.svg")), (s("e.csv"), s("x.svg")));
        assert_eq!(paths(Some("x.csv"), Some("x.svg")), (s("x.csv"), s("x.svg")));
    }
}
