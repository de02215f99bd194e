//! The models `runner serve` offers and what it runs on them: each FMU opened once (described
//! here, run in worker processes kept warm between requests), its variables with units and
//! ranges, and the runs of the API (simulate, scene, sweep) resolved exactly as `runner
//! simulate`, `runner animate` and `runner sweep` resolve theirs, so the numbers are the same.

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use fmi_importer::{Causality, Description, Kind, Solver, Value, Variable};
use plots::animation::Timing;
use plots::scene::Scene;
use plots::trace::{self, Trace};
use runner_engine::exec::{self, Held, Points, Runs};
use runner_engine::request::{FmuSource, MetricSet, RunRequest, SweepRequest};
use runner_engine::run::{Grid, GridSettings};
use runner_engine::sweep::{parse_range, PointResult};
use runner_engine::variables;
use runner_sandbox::Config;
use serde_json::{json, Value as Json};

use crate::experiment::{self, Experiment};
use crate::integration::Integration;
use crate::workers;

/// Most samples one run may return (a run of more is refused before it starts).
pub const MAX_SAMPLES: usize = 200_000;

/// A model as the server holds it: opened once, before the first request.
pub struct Model {
    /// The name the API knows it by (the model name, or the `.fmu` file's stem).
    pub id: String,
    /// The `.fmu` file (what the download sends).
    pub path: PathBuf,
    /// Its `experiment.toml` (empty for an FMU given by path).
    pub experiment: Experiment,
    held: Held,
    source: FmuSource,
    /// The `[animate]` scene, when the model has points to draw.
    scene: Option<Scene>,
    /// Declared `min` and `max` per variable name.
    ranges: HashMap<String, (Option<f64>, Option<f64>)>,
    solver: Solver,
}

impl Model {
    /// Opens the FMU `arg` names (a model of this workspace, built if missing, or a `.fmu` path).
    pub fn open(arg: &str) -> Result<Model, String> {
        let target = experiment::resolve(arg)?;
        let integration = Integration::default();
        let (held, source) = workers::open(&target.path, &integration, false)?;
        let ranges = match &held {
            Held::Described(unpacked) => declared_ranges(unpacked),
            Held::Loaded(_) => HashMap::new(),
        };
        // A model without points to draw simply has no animation; a broken `[animate]` section
        // is the model's error, said once at start.
        let scene = match Scene::new(held.description(), &target.experiment.animate) {
            Ok(scene) => Some(scene),
            Err(e) if has_animate_section(&target.experiment) => return Err(format!("{arg}: {e}")),
            Err(_) => None,
        };
        let id = match runner_workspace::locate(arg)? {
            runner_workspace::Located::Model { id, .. } => id,
            runner_workspace::Located::File(path) => path.file_stem().and_then(|s| s.to_str()).unwrap_or("fmu").to_owned(),
        };
        let solver = integration.solver()?;
        Ok(Model { id, path: target.path, experiment: target.experiment, held, source, scene, ranges, solver })
    }

    /// The FMU's description.
    pub fn description(&self) -> &Description {
        self.held.description()
    }

    /// The entry of the model list.
    pub fn summary(&self) -> Json {
        let md = self.description();
        json!({
            "id": self.id,
            "name": md.model_name,
            "description": md.description,
            "fmi_version": md.fmi_version_text,
            "interface": self.held.interface().to_string(),
            "animation": self.scene.is_some(),
        })
    }

    /// The model's page data: its variables, the default grid, the plotted outputs, the events
    /// and the sweep the experiment gives.
    pub fn details(&self) -> Result<Json, String> {
        let md = self.description();
        let grid = Grid::choose(md, &[self.experiment.simulate.grid()])?;
        let sweep = &self.experiment.sweep;
        let variables: Vec<Json> =
            md.variables.iter().filter(|v| v.causality != Causality::Independent).map(|v| self.variable(v)).collect();
        Ok(json!({
            "id": self.id,
            "name": md.model_name,
            "description": md.description,
            "fmi_version": md.fmi_version_text,
            "interface": self.held.interface().to_string(),
            "animation": self.scene.is_some(),
            "grid": { "start": grid.start, "stop": grid.stop, "interval": grid.interval, "tolerance": grid.tolerance },
            "set": self.experiment.simulate.set,
            "plotted": trace::continuous_outputs(md).iter().map(|v| &v.name).collect::<Vec<_>>(),
            "events": trace::event_variables(md).iter().map(|v| &v.name).collect::<Vec<_>>(),
            "sweep": { "param": sweep.param, "metric": sweep.metric, "set": sweep.set },
            "variables": variables,
        }))
    }

    fn variable(&self, v: &Variable) -> Json {
        let md = self.description();
        let display = variables::display_unit_of(md, v);
        let (min, max) = self.ranges.get(&v.name).copied().unwrap_or((None, None));
        let settable = variables::check_settable(v).is_ok() && !v.is_array() && v.kind.is_numeric();
        json!({
            "name": v.name,
            "description": v.description,
            "causality": v.causality.to_string(),
            "variability": v.variability.to_string(),
            "kind": v.kind.to_string(),
            "unit": v.unit,
            "display": display.map(|d| json!({ "unit": d.name, "factor": d.factor, "offset": d.offset })),
            "start": if v.is_array() { None } else { v.start.as_ref().and_then(|s| s.as_number()) },
            "min": min,
            "max": max,
            "settable": settable,
            "array": v.is_array(),
        })
    }
}

/// True when the experiment has an `[animate]` section of its own (links, trails or points).
fn has_animate_section(experiment: &Experiment) -> bool {
    let a = &experiment.animate;
    !a.links.is_empty() || !a.trails.is_empty() || !a.points.is_empty()
}

/// The `min` and `max` the description declares for each variable (as written on the variable;
/// FMI 1.0 and 2.0 Integers and FMI 3.0 integers too).
fn declared_ranges(unpacked: &fmi_importer::Unpacked) -> HashMap<String, (Option<f64>, Option<f64>)> {
    let mut ranges = HashMap::new();
    if let Some(md) = &unpacked.fmi2 {
        use fmi_schema::fmi2::VariableType;
        for v in &md.model_variables {
            let range = match &v.var_type {
                VariableType::Real(r) => (r.attributes.min, r.attributes.max),
                VariableType::Integer(i) => (i.attributes.min.map(f64::from), i.attributes.max.map(f64::from)),
                _ => (None, None),
            };
            ranges.insert(v.name.clone(), range);
        }
    }
    if let Some(md) = &unpacked.fmi3 {
        use fmi_schema::fmi3::VariableKind;
        for v in &md.model_variables {
            let range = match &v.kind {
                VariableKind::Float { attributes, .. } => (attributes.min, attributes.max),
                VariableKind::Int { attributes, .. } => (attributes.min.map(|x| x as f64), attributes.max.map(|x| x as f64)),
                _ => (None, None),
            };
            ranges.insert(v.name.clone(), range);
        }
    }
    if let Some(md) = &unpacked.fmi1 {
        for v in &md.model_variables {
            ranges.insert(v.name.clone(), (v.min, v.max));
        }
    }
    ranges
}

/// What a run request may say: the grid, the values to set, the result's format.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunBody {
    /// Stop time (s).
    pub stop_time: Option<f64>,
    /// Communication interval (s).
    pub output_interval: Option<f64>,
    /// Relative tolerance.
    pub tolerance: Option<f64>,
    /// Values to set, by name: a number (SI) or text with a unit the FMU declares (`"120 deg"`).
    #[serde(default)]
    pub set: serde_json::Map<String, Json>,
    /// `"json"` (default) or `"csv"` (the CSV `runner simulate --out` writes).
    pub format: Option<String>,
    /// The recorded columns to answer with (default: all), so the page gets what it draws.
    pub variables: Option<Vec<String>>,
}

/// What a sweep request may say.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepBody {
    /// Swept parameters, `NAME=START:STOP:STEP` or `NAME=V1,V2,...`.
    pub param: Vec<String>,
    /// Metrics, `NAME=EXPR`.
    pub metric: Vec<String>,
    #[serde(flatten)]
    pub run: SweepRun,
}

/// The grid and the values of a sweep's every point.
#[derive(Debug, Default, serde::Deserialize)]
pub struct SweepRun {
    pub stop_time: Option<f64>,
    pub output_interval: Option<f64>,
    pub tolerance: Option<f64>,
    #[serde(default)]
    pub set: serde_json::Map<String, Json>,
}

/// `set` as `--set NAME=VALUE` texts: a number in its shortest form that reads back the same.
/// Strings and Binaries are refused: a String parameter may name a file on the server (the
/// road's `table`), and the client gives no paths.
fn set_texts(md: &Description, set: &serde_json::Map<String, Json>) -> Result<Vec<String>, String> {
    set.iter()
        .map(|(name, value)| {
            let variable = variables::find(md, name)?;
            if matches!(variable.kind, Kind::String | Kind::Binary) {
                return Err(format!(
                    "'{name}' is a {}: only numbers and Booleans are set from the page (a String may name a file on the server)",
                    variable.kind
                ));
            }
            Ok((name, value))
        })
        .map(|named| {
            named.and_then(|(name, value)| match value {
                Json::Number(n) => match (n.as_i64(), n.as_f64()) {
                    // A whole number stays one (an Integer parameter refuses `1.0`).
                    (Some(i), _) => Ok(format!("{name}={i}")),
                    (None, Some(x)) => Ok(format!("{name}={x:?}")),
                    (None, None) => Err(format!("set {name}: {n} is not a number")),
                },
                Json::String(s) => Ok(format!("{name}={s}")),
                Json::Bool(b) => Ok(format!("{name}={b}")),
                other => Err(format!("set {name}: give a number or a text such as \"120 deg\", not {other}")),
            })
        })
        .collect()
}

fn grid_settings(stop_time: Option<f64>, output_interval: Option<f64>, tolerance: Option<f64>) -> GridSettings {
    GridSettings { start_time: None, stop_time, output_interval, tolerance }
}

/// Refuses a grid of more samples than a response may carry.
fn check_samples(grid: &Grid) -> Result<(), String> {
    match grid.steps() {
        n if n >= MAX_SAMPLES => Err(format!(
            "{} s every {} s is {n} samples, more than the {MAX_SAMPLES} a run here may have: raise output_interval or lower stop_time",
            grid.stop - grid.start,
            grid.interval
        )),
        _ => Ok(()),
    }
}

/// A result: time, the recorded columns (SI), the events, and the CSV when asked.
pub struct Recorded {
    pub trace: Trace,
    pub csv: Option<Vec<u8>>,
    pub events: Vec<trace::Event>,
    pub outputs: usize,
    pub grid: Grid,
    pub run_ms: f64,
}

/// Where a model's runs go: its worker sessions, each kept (with its FMU loaded) for the next
/// request, so a slider's run starts in a warm worker.
pub struct Served<'a> {
    pub model: &'a Model,
    idle: Mutex<Vec<Runs<'a>>>,
    config: Config,
}

impl<'a> Served<'a> {
    pub fn new(model: &'a Model, config: Config) -> Served<'a> {
        Served { model, idle: Mutex::new(Vec::new()), config }
    }

    /// Runs `request` in an idle worker session (or a new one), which is kept afterwards.
    fn run(
        &self,
        request: &RunRequest,
        stop: &dyn Fn() -> bool,
        sample: impl FnMut(f64, &[f64], &dyn runner_engine::run::Texts) -> Result<(), String>,
    ) -> Result<runner_engine::run::Outcome, String> {
        let taken = self.idle.lock().map_err(|_| "a run failed badly before".to_owned())?.pop();
        let mut runs = taken.unwrap_or_else(|| Runs::new(&self.model.held, &self.config, &self.model.source));
        let outcome = runs.run(request, stop, sample);
        if let Ok(mut idle) = self.idle.lock() {
            idle.push(runs);
        }
        outcome
    }

    /// One run as `runner simulate MODEL --set ...` makes it: the grid of the request, then
    /// the experiment's `[simulate]`, then the FMU's default experiment; the experiment's
    /// values, then the request's. Records the outputs (the CSV's columns) and then every
    /// other numeric scalar that is not a parameter (for phase plots).
    pub fn simulate(&self, body: &RunBody, stop: &dyn Fn() -> bool) -> Result<Recorded, String> {
        let model = self.model;
        let md = model.description();
        let mut grid =
            Grid::choose(md, &[grid_settings(body.stop_time, body.output_interval, body.tolerance), model.experiment.simulate.grid()])?;
        grid.solver = model.solver;
        check_samples(&grid)?;
        let mut sets = model.experiment.simulate.set.clone();
        sets.extend(set_texts(md, &body.set)?);
        let assignments = variables::parse_sets(md, &sets)?;
        let csv = match body.format.as_deref() {
            None | Some("json") => false,
            Some("csv") => true,
            Some(other) => return Err(format!("format '{other}': give json or csv")),
        };
        let outputs: Vec<&Variable> = md.outputs().filter(|v| v.kind != Kind::Clock).collect();
        let mut recorded = outputs.clone();
        let parameter = |v: &Variable| {
            matches!(
                v.causality,
                Causality::Parameter | Causality::CalculatedParameter | Causality::StructuralParameter | Causality::Independent
            )
        };
        recorded.extend(
            md.variables
                .iter()
                .filter(|v| v.kind.is_numeric() && !v.is_array() && !parameter(v) && !outputs.iter().any(|o| o.name == v.name)),
        );
        let output_columns = runner_engine::run::Recording::new(md, &outputs, &assignments)?.names.len();
        let recording = Trace::recording(md, &recorded, &assignments, false)?;
        let request = RunRequest::new(self.model.held.identifier(), grid, &assignments, &recording, false);
        let mut trace = Trace::empty(&recording, &grid);
        let mut writer = csv.then(|| csv::Writer::from_writer(Vec::new()));
        if let Some(w) = &mut writer {
            let mut header = vec!["time".to_owned()];
            header.extend(recording.names[..output_columns].iter().cloned());
            w.write_record(&header).map_err(|e| format!("cannot write CSV: {e}"))?;
        }
        let mut row: Vec<String> = Vec::new();
        let clock = Instant::now();
        let outcome = self.run(&request, stop, |t, values, texts| {
            trace.push(t, values);
            if let Some(w) = &mut writer {
                row.clear();
                row.push(format!("{t:?}"));
                row.extend((0..output_columns).map(|c| texts.text(c, values)));
                w.write_record(&row).map_err(|e| format!("cannot write CSV: {e}"))?;
            }
            Ok(())
        })?;
        let run_ms = clock.elapsed().as_secs_f64() * 1e3;
        trace.ended_early = outcome.ended_early;
        let events = trace::events(&trace, &trace::event_variables(md));
        let csv = match writer {
            Some(w) => Some(w.into_inner().map_err(|e| format!("cannot write CSV: {e}"))?),
            None => None,
        };
        Ok(Recorded { trace, csv, events, outputs: output_columns, grid, run_ms })
    }

    /// The animation's geometry, resolved as `runner animate` resolves its run: the grid of the
    /// request, then `[animate]`'s, then `[simulate]`'s, sampled at the frame step; the values
    /// of `[simulate]`, `[animate]`, then the request.
    pub fn scene(&self, body: &RunBody, stop: &dyn Fn() -> bool) -> Result<Option<Json>, String> {
        let model = self.model;
        let Some(scene) = &model.scene else { return Ok(None) };
        let md = model.description();
        let config = &model.experiment.animate;
        let grid = Grid::choose(
            md,
            &[grid_settings(body.stop_time, body.output_interval, body.tolerance), config.run().grid(), model.experiment.simulate.grid()],
        )?;
        let timing = Timing::choose(grid.interval, config.speed, config.fps)?;
        let grid = Grid { interval: timing.interval, solver: model.solver, ..grid };
        check_samples(&grid)?;
        let mut sets = model.experiment.simulate.set.clone();
        sets.extend(config.set.iter().cloned());
        sets.extend(set_texts(md, &body.set)?);
        let assignments = variables::parse_sets(md, &sets)?;
        let mut recorded: Vec<&Variable> = scene.variables(md);
        for v in md.outputs().filter(|v| v.kind.is_numeric()) {
            if !recorded.iter().any(|r| r.name == v.name) {
                recorded.push(v);
            }
        }
        let recording = Trace::recording(md, &recorded, &assignments, false)?;
        let request = RunRequest::new(model.held.identifier(), grid, &assignments, &recording, false);
        let mut trace = Trace::empty(&recording, &grid);
        let outcome = self.run(&request, stop, |t, values, _| {
            trace.push(t, values);
            Ok(())
        })?;
        trace.ended_early = outcome.ended_early;
        if trace.time.is_empty() {
            return Err(format!("{} produced no samples to animate", md.model_name));
        }
        let motion = scene.motion(&trace)?;
        let g = motion.geometry();
        let frames = timing.frames(&trace.time);
        let points: Vec<Json> = g
            .positions
            .iter()
            .zip(&g.names)
            .zip(&g.fixed)
            .map(|((p, name), fixed)| {
                json!({ "name": name, "fixed": fixed, "x": p.iter().map(|q| q.0).collect::<Vec<_>>(), "y": p.iter().map(|q| q.1).collect::<Vec<_>>() })
            })
            .collect();
        Ok(Some(json!({
            "time": trace.time,
            "frames": frames,
            "fps": timing.fps,
            "frame_step": timing.frame_step,
            "points": points,
            "links": g.links.iter().map(|(ids, shown)| json!({ "points": ids, "shown": shown })).collect::<Vec<_>>(),
            "trails": g.trails.iter().map(|(p, shown)| json!({ "point": p, "shown": shown })).collect::<Vec<_>>(),
            "levels": g.levels,
            "views": g.views.iter().map(|(x, y)| [x.start, x.end, y.start, y.end]).collect::<Vec<_>>(),
            "stamps": g.stamps,
            "ended_early": trace.ended_early,
        })))
    }
}

/// A sweep the server runs in the background, polled for its progress.
pub struct SweepJob {
    pub model: String,
    pub total: usize,
    pub params: Vec<String>,
    pub metrics: Vec<String>,
    pub cancel: AtomicBool,
    pub state: Mutex<SweepState>,
    pub started: Instant,
}

/// What a sweep has finished so far.
#[derive(Default)]
pub struct SweepState {
    /// Per finished point (in point order): its parameter values, its metrics and its status.
    pub rows: Vec<(Vec<f64>, Option<Vec<f64>>, String)>,
    pub finished: bool,
    pub error: Option<String>,
    pub seconds: Option<f64>,
}

impl SweepJob {
    /// The job as the API reports it, with the rows from `from` on.
    pub fn report(&self, from: usize) -> Json {
        let state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let rows: Vec<Json> = state
            .rows
            .iter()
            .skip(from)
            .map(|(point, metrics, status)| json!({ "point": point, "metrics": metrics, "status": status }))
            .collect();
        json!({
            "model": self.model,
            "total": self.total,
            "done": state.rows.len(),
            "from": from.min(state.rows.len()),
            "finished": state.finished,
            "error": state.error,
            "seconds": state.seconds,
            "params": self.params,
            "metrics": self.metrics,
            "rows": rows,
        })
    }

    /// The CSV `runner sweep --out` writes: parameters, metrics, status per point.
    pub fn csv(&self) -> Result<Vec<u8>, String> {
        let state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let mut w = csv::Writer::from_writer(Vec::new());
        let cannot = |e: csv::Error| format!("cannot write CSV: {e}");
        let mut header = self.params.clone();
        header.extend(self.metrics.iter().cloned());
        header.push("status".to_owned());
        w.write_record(&header).map_err(cannot)?;
        for (point, metrics, status) in &state.rows {
            let mut row: Vec<String> = point.iter().map(|x| format!("{x:?}")).collect();
            match metrics {
                Some(values) => row.extend(values.iter().map(|x| format!("{x:?}"))),
                None => row.extend(std::iter::repeat_n(String::new(), self.metrics.len())),
            }
            row.push(status.clone());
            w.write_record(&row).map_err(cannot)?;
        }
        w.into_inner().map_err(|e| format!("cannot write CSV: {e}"))
    }
}

/// A sweep checked against the model and ready to run: what `runner sweep MODEL --param ...
/// --metric ...` would run.
pub struct PreparedSweep<'m> {
    request: SweepRequest,
    model: &'m Model,
}

/// Checks a sweep request: its ranges, metrics, values and grid, and its number of points
/// against `max_points`.
pub fn prepare_sweep<'m>(model: &'m Model, body: &SweepBody, max_points: usize) -> Result<(PreparedSweep<'m>, SweepJob), String> {
    let md = model.description();
    if body.param.is_empty() {
        return Err("nothing to sweep: give param, e.g. [\"speed=5:30:5\"]".to_owned());
    }
    if body.metric.is_empty() {
        return Err("no metric: give metric, e.g. [\"amplitude=max(x)\"]".to_owned());
    }
    let ranges = body.param.iter().map(|p| parse_range(p)).collect::<Result<Vec<_>, _>>()?;
    let points = ranges.iter().fold(1usize, |n, (_, v)| n.saturating_mul(v.len()));
    if points > max_points {
        return Err(format!("{points} points is more than the {max_points} a sweep here may have (runner serve --max-points)"));
    }
    let metrics = MetricSet::parse(&body.metric)?;
    if metrics.metrics().highest_mode().is_some() {
        return Err("the metrics read modes of the linearized model (natural_frequency, damping), which `runner sweep` computes through Model Exchange; the page runs Co-Simulation: use runner sweep".to_owned());
    }
    let defaults = &model.experiment.sweep;
    let run = &body.run;
    let mut grid = Grid::choose(md, &[grid_settings(run.stop_time, run.output_interval, run.tolerance), defaults.run().grid()])?;
    grid.solver = model.solver;
    let mut sets = defaults.set.clone();
    sets.extend(set_texts(md, &run.set)?);
    let fixed: Vec<(&Variable, Value)> = variables::parse_sets(md, &sets)?;
    let request = SweepRequest::new(grid, &fixed, ranges, metrics, None);
    let plan = request.plan(md, model.held.identifier(), model.held.interface())?;
    let job = SweepJob {
        model: model.id.clone(),
        total: plan.space.len,
        params: plan.space.ranges.iter().map(|(n, _)| n.clone()).collect(),
        metrics: plan.metrics.metrics.iter().map(|(n, _)| n.clone()).collect(),
        cancel: AtomicBool::new(false),
        state: Mutex::new(SweepState::default()),
        started: Instant::now(),
    };
    Ok((PreparedSweep { request, model }, job))
}

impl PreparedSweep<'_> {
    /// Runs the points in `threads` worker processes started with `config`, recording each
    /// point in `job` as it finishes; stops when the job is cancelled or `stop()`.
    pub fn run(&self, job: &SweepJob, config: &Config, threads: usize, stop: &(dyn Fn() -> bool + Sync)) {
        let model = self.model;
        let held = &model.held;
        let outcome = (|| -> Result<(), String> {
            let plan = self.request.plan(held.description(), held.identifier(), held.interface())?;
            let n = plan.space.len;
            let mut workers = exec::start_workers(config.clone(), threads.min(n).max(1))?;
            exec::load(&mut workers, &model.source, held.once_per_process());
            let halted = || stop() || job.cancel.load(Ordering::Relaxed);
            let mut point = Vec::new();
            exec::sweep(held, &plan, &self.request, Points::Workers(workers), 0..n, &halted, |i, r: PointResult| {
                plan.space.point(i, &mut point);
                let mut state = job.state.lock().map_err(|_| "the sweep's record broke".to_owned())?;
                state.rows.push((point.clone(), r.metrics, r.status));
                Ok(())
            })?;
            if job.cancel.load(Ordering::Relaxed) {
                return Err("cancelled".to_owned());
            }
            Ok(())
        })();
        let mut state = job.state.lock().unwrap_or_else(|e| e.into_inner());
        state.finished = true;
        state.error = outcome.err();
        state.seconds = Some(job.started.elapsed().as_secs_f64());
    }
}
