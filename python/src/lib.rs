//! `fmurunner._engine`: the runner's engine for Python. The Python side (`fmurunner/`) shapes
//! arguments and builds DataFrames; everything that runs an FMU is here and calls the engine
//! with its requests (a `SweepRequest` planned and run with `Plan::execute_range`, a
//! `RunRequest` bound and run), with the GIL released while Rust runs. Results cross as compact tables: little-endian `f64` bytes plus the
//! few strings (failed points' statuses, text columns) that numbers cannot carry.

mod stepping;
mod sweep_file;

use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

use fmi_importer::model::Dimension;
use fmi_importer::{Description, Fmu, Interface, Kind, Solver, Unpacked, Variable};
use formulas::References;
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use runner_engine::exec::{self, Held, Points as Where};
use runner_engine::input::InputTable;
use runner_engine::isolated;
use runner_engine::request::{FmuSource, MetricSet, RunRequest, SweepRequest};
use runner_engine::run::{Grid, GridSettings, Recording, Texts};
use runner_engine::sweep::PointResult;
use runner_engine::variables;
use runner_sandbox::WorkerCommand;
use runner_workspace::Located;

create_exception!(fmurunner, RunnerError, PyException, "An error of the runner: its message is the one the command line prints.");

/// The runner's message as a Python exception.
pub(crate) fn err(message: String) -> PyErr {
    RunnerError::new_err(message)
}

/// Points' results as Python receives them: row-major metric bytes, (point, status) of the
/// failed ones, seconds.
type Points<'py> = (Bound<'py, PyBytes>, Vec<(usize, String)>, f64);

/// A planned sweep as Python receives it: (the sweep as JSON, points, metric names, the name of
/// the interface it runs through).
type Plan = (String, usize, Vec<String>, &'static str);

/// A grid source as Python passes it: (stop_time, output_interval, tolerance).
type GridArgs = (Option<f64>, Option<f64>, Option<f64>);

fn grid_settings(args: &[GridArgs]) -> Vec<GridSettings> {
    args.iter()
        .map(|&(stop_time, output_interval, tolerance)| GridSettings { start_time: None, stop_time, output_interval, tolerance })
        .collect()
}

/// Resolves `fmu` as the command line does: an `.fmu` path, or a model of this workspace (whose
/// FMU `runner build` writes). Returns the file and, for a model, the `NAME=VALUE` sets and grid
/// of its experiment's `[simulate]` or `[sweep]` section (`command`).
#[pyfunction]
fn locate(fmu: &str, command: &str) -> PyResult<(String, Vec<String>, GridArgs)> {
    match runner_workspace::locate(fmu).map_err(err)? {
        Located::File(path) => Ok((path.display().to_string(), Vec::new(), (None, None, None))),
        Located::Model { id, fmu: path, experiment } => {
            if !path.is_file() {
                return Err(err(format!(
                    "{} is missing: build it first with `runner build {id}` (cargo run --release -p runner -- build {id})",
                    path.display()
                )));
            }
            let sections = runner_workspace::experiment::read(&experiment).map_err(err)?;
            let defaults = match command {
                "sweep" => sections.sweep.run(),
                _ => sections.simulate,
            };
            Ok((path.display().to_string(), defaults.set, (defaults.stop_time, defaults.output_interval, defaults.tolerance)))
        }
    }
}

fn variable_dict<'py>(py: Python<'py>, d: &Description, v: &Variable) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    out.set_item("name", &v.name)?;
    out.set_item("value_reference", v.value_reference)?;
    out.set_item("causality", v.causality.as_str())?;
    out.set_item("variability", v.variability.as_str())?;
    out.set_item("type", v.kind.name_in(d.fmi_version))?;
    out.set_item("unit", &v.unit)?;
    out.set_item("display_unit", &v.display_unit)?;
    out.set_item("start", v.start.as_ref().map(|s| s.to_string()))?;
    out.set_item("description", &v.description)?;
    let dimensions: Vec<String> = v
        .dimensions
        .iter()
        .map(|dim| match *dim {
            Dimension::Fixed(n) => n.to_string(),
            Dimension::Variable(vr) => d.variable_by_reference(vr).map_or(format!("vr {vr}"), |p| p.name.clone()),
        })
        .collect();
    out.set_item("dimensions", dimensions)?;
    Ok(out)
}

/// What `runner info` shows of the FMU at `path`, as a dict (the binary is not loaded).
#[pyfunction]
fn describe<'py>(py: Python<'py>, path: &str) -> PyResult<Bound<'py, PyDict>> {
    let unpacked = py.detach(|| Unpacked::open(Path::new(path))).map_err(err)?;
    let d = &unpacked.description;
    let out = PyDict::new(py);
    out.set_item("model_name", &d.model_name)?;
    out.set_item("description", &d.description)?;
    out.set_item("fmi_version", &d.fmi_version_text)?;
    out.set_item("guid", &d.instantiation_token)?;
    out.set_item("generation_tool", &d.generation_tool)?;
    for (key, interface) in [("co_simulation", Interface::CoSimulation), ("model_exchange", Interface::ModelExchange)] {
        let Some(c) = d.interface(interface) else {
            out.set_item(key, py.None())?;
            continue;
        };
        let caps = PyDict::new(py);
        caps.set_item("model_identifier", &c.model_identifier)?;
        caps.set_item("needs_execution_tool", c.needs_execution_tool)?;
        caps.set_item("can_be_instantiated_only_once_per_process", c.can_be_instantiated_only_once_per_process)?;
        caps.set_item("can_get_and_set_fmu_state", c.can_get_and_set_fmu_state)?;
        caps.set_item("can_serialize_fmu_state", c.can_serialize_fmu_state)?;
        caps.set_item("provides_directional_derivative", c.provides_directional_derivative)?;
        if interface == Interface::CoSimulation {
            caps.set_item("can_handle_variable_communication_step_size", c.can_handle_variable_communication_step_size)?;
            caps.set_item("can_interpolate_inputs", c.can_interpolate_inputs)?;
            caps.set_item("max_output_derivative_order", c.max_output_derivative_order)?;
        }
        out.set_item(key, caps)?;
    }
    out.set_item("number_of_continuous_states", d.number_of_continuous_states)?;
    out.set_item("number_of_event_indicators", d.number_of_event_indicators)?;
    match &d.default_experiment {
        Some(e) => {
            let de = PyDict::new(py);
            de.set_item("start_time", e.start_time)?;
            de.set_item("stop_time", e.stop_time)?;
            de.set_item("tolerance", e.tolerance)?;
            de.set_item("step_size", e.step_size)?;
            out.set_item("default_experiment", de)?;
        }
        None => out.set_item("default_experiment", py.None())?,
    }
    let list = PyList::empty(py);
    for v in &d.variables {
        list.append(variable_dict(py, d, v)?)?;
    }
    out.set_item("variables", list)?;
    Ok(out)
}

/// How a column's numbers become a pandas column.
fn column_kind(kind: Kind) -> &'static str {
    match kind {
        Kind::Real | Kind::Float32 => "float",
        Kind::Boolean => "bool",
        Kind::String | Kind::Binary | Kind::Clock => "text",
        _ => "int",
    }
}

/// A loaded FMU (unpacked, binary open) that runs simulations and sweep points in this process.
#[pyclass(frozen, module = "fmurunner._engine")]
struct Model {
    fmu: Fmu,
    /// A copy of an FMU received as bytes (a Dask worker's), deleted with the model.
    _copy: Option<tempfile::TempDir>,
}

/// Per column name (an array element `x[1]` by its variable `x`): the variable's unit and, when
/// the FMU declares one for it, its display unit as (name, factor, offset) with
/// `display = factor * SI + offset`. Columns that are not variables are left out.
fn units_of<'py>(py: Python<'py>, d: &Description, names: &[String]) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    for name in names {
        let base = name.split('[').next().unwrap_or(name);
        let Some(v) = d.variable(base) else { continue };
        let display = variables::display_unit_of(d, v).map(|c| (c.name, c.factor, c.offset));
        out.set_item(name, (v.unit.clone(), display))?;
    }
    Ok(out)
}

/// [`units_of`] for the FMU at `path` (its description only).
#[pyfunction]
fn column_units<'py>(py: Python<'py>, path: &str, names: Vec<String>) -> PyResult<Bound<'py, PyDict>> {
    let unpacked = py.detach(|| Unpacked::open(Path::new(path))).map_err(err)?;
    units_of(py, &unpacked.description, &names)
}

/// The little-endian bytes of `values`.
fn f64_bytes(values: &[f64]) -> Vec<u8> {
    let mut out = Vec::with_capacity(values.len() * 8);
    for x in values {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out
}

impl Model {
    fn grid(&self, sources: &[GridArgs]) -> Result<Grid, String> {
        Grid::choose(&self.fmu.description, &grid_settings(sources))
    }

    fn spec(&self, spec_json: &str) -> PyResult<SweepRequest> {
        serde_json::from_str(spec_json).map_err(|e| err(format!("not a sweep of this version of fmurunner: {e}")))
    }
}

/// Refuses a sweep of more than one point in one process for an FMU that allows only one instance.
fn check_once_per_process(d: &Description, interface: Interface, points: usize) -> Result<(), String> {
    if points > 1 && runner_engine::isolated::once_per_process(d, interface) {
        return Err(format!(
            "{} declares canBeInstantiatedOnlyOncePerProcess, so its points cannot share a process: sweep it with `runner sweep`, which gives each point a worker process of its own",
            d.model_name
        ));
    }
    Ok(())
}

/// The runner's integrator for Model Exchange as `simulate` and `sweep` take it: the options
/// checked, and whether any was given (they are refused for a Co-Simulation run).
struct Integrator {
    solver: Solver,
    given: bool,
}

impl Integrator {
    fn new(solver: Option<&str>, fixed_step: Option<f64>, abs_tolerance: Option<f64>) -> PyResult<Integrator> {
        let given = solver.is_some() || fixed_step.is_some() || abs_tolerance.is_some();
        Ok(Integrator { solver: stepping::solver_of(solver, fixed_step, abs_tolerance)?, given })
    }

    /// Refuses the options for an FMU that runs as Co-Simulation, where they would do nothing.
    fn check(&self, d: &Description, identifier: &str, interface: Interface) -> PyResult<()> {
        stepping::check_solver(d, identifier, interface, self.given).map_err(err)
    }
}

/// Checks a sweep of the FMU `d` run through `interface` and returns it as data (JSON) that any
/// process holding this FMU through that interface runs the same way: the grid from
/// `grid_sources` with the `integrator`, the common `sets`, the swept `ranges` (their cartesian
/// product, the last varying fastest) and the `NAME=EXPR` `metrics`. Also returns the number of
/// points, the metric names and the interface's name.
#[allow(clippy::too_many_arguments)]
fn plan(
    d: &Description,
    identifier: &str,
    interface: Interface,
    grid_sources: &[GridArgs],
    integrator: &Integrator,
    sets: Vec<String>,
    ranges: Vec<(String, Vec<f64>)>,
    metrics: Vec<String>,
) -> PyResult<Plan> {
    integrator.check(d, identifier, interface)?;
    let mut grid = Grid::choose(d, &grid_settings(grid_sources)).map_err(err)?;
    grid.solver = integrator.solver;
    if ranges.is_empty() {
        return Err(err("nothing to sweep: give params, a dict of parameter name to its values".to_owned()));
    }
    if metrics.is_empty() {
        return Err(err("no metric: give metrics, e.g. {'amplitude': 'max(x)'}".to_owned()));
    }
    if let Some((name, _)) = ranges.iter().find(|(_, values)| values.is_empty()) {
        return Err(err(format!("params['{name}'] has no values")));
    }
    let fixed = variables::parse_sets(d, &sets).map_err(err)?;
    // The spec, which the sweep's record holds, has the metrics in their one spelling: a resume
    // does not depend on how they were typed (`final(x)`, `final( x )`).
    let metrics = MetricSet::parse(&MetricSet::parse(&metrics).map_err(err)?.metrics().canonical()).map_err(err)?;
    let spec = SweepRequest::new(grid, &fixed, ranges, metrics, None);
    let plan = spec.plan(d, identifier, interface).map_err(err)?;
    check_once_per_process(d, interface, plan.space.len).map_err(err)?;
    let names = plan.metrics.metrics.iter().map(|(n, _)| n.clone()).collect();
    let json = serde_json::to_string(&spec).map_err(|e| err(format!("cannot encode the sweep: {e}")))?;
    Ok((json, plan.space.len, names, interface.name()))
}

/// [`plan`] for the FMU at `path` through `interface` (as [`Model::new`] takes it) with the
/// integrator `solver`, `fixed_step`, `abs_tolerance` (as [`Model::simulate`]), from its
/// description alone (its binary is not loaded: a Dask client plans a sweep that only the
/// workers run).
#[pyfunction]
#[pyo3(signature = (path, grid_sources, sets, ranges, metrics, interface=None, solver=None, fixed_step=None, abs_tolerance=None))]
#[allow(clippy::too_many_arguments)]
fn plan_sweep(
    py: Python<'_>,
    path: &str,
    grid_sources: Vec<GridArgs>,
    sets: Vec<String>,
    ranges: Vec<(String, Vec<f64>)>,
    metrics: Vec<String>,
    interface: Option<&str>,
    solver: Option<&str>,
    fixed_step: Option<f64>,
    abs_tolerance: Option<f64>,
) -> PyResult<Plan> {
    let interface = stepping::interface_of(interface)?;
    let integrator = Integrator::new(solver, fixed_step, abs_tolerance)?;
    let unpacked = py.detach(|| Unpacked::open_as(Path::new(path), interface)).map_err(err)?;
    plan(&unpacked.description, &unpacked.identifier, unpacked.interface, &grid_sources, &integrator, sets, ranges, metrics)
}

#[pymethods]
impl Model {
    /// Unpacks and loads the FMU at `path` through `interface` (`co-simulation` or
    /// `model-exchange`; by default Co-Simulation when it offers it, else Model Exchange).
    #[new]
    #[pyo3(signature = (path, interface=None))]
    fn new(py: Python<'_>, path: &str, interface: Option<&str>) -> PyResult<Model> {
        let interface = stepping::interface_of(interface)?;
        let fmu = py.detach(|| Fmu::load_as(Path::new(path), interface)).map_err(err)?;
        Ok(Model { fmu, _copy: None })
    }

    /// Loads an FMU from its bytes (as a Dask worker receives it) through `interface` (as
    /// [`Model::new`]); `name` is its file name.
    #[staticmethod]
    #[pyo3(signature = (data, name, interface=None))]
    fn from_bytes(py: Python<'_>, data: Vec<u8>, name: &str, interface: Option<&str>) -> PyResult<Model> {
        let interface = stepping::interface_of(interface)?;
        py.detach(|| {
            let dir = tempfile::Builder::new()
                .prefix("fmurunner-")
                .tempdir()
                .map_err(|e| format!("cannot create a directory for {name}: {e}"))?;
            let file_name = Path::new(name).file_name().map_or_else(|| PathBuf::from("model.fmu"), PathBuf::from);
            let path = dir.path().join(file_name);
            std::fs::write(&path, &data).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            let fmu = Fmu::load_as(&path, interface)?;
            // The FMU is unpacked elsewhere: its archive is no longer needed.
            let _ = std::fs::remove_file(&path);
            Ok(Model { fmu, _copy: Some(dir) })
        })
        .map_err(err)
    }

    /// The model's name and its modelIdentifier.
    #[getter]
    fn identifier(&self) -> &str {
        &self.fmu.identifier
    }

    /// One run: `sets` (`NAME=VALUE`) before initialization, the grid from the first of
    /// `grid_sources` that gives each entry (else the FMU's default experiment), `input` as
    /// (names, time, columns); a Model Exchange FMU integrated by `solver` (a method name), with
    /// `fixed_step` and `abs_tolerance` for the methods that use them. Returns (names, kinds,
    /// row-major f64 bytes of time and the outputs, rows, {column: texts} for columns numbers
    /// cannot give, why it ended early).
    #[allow(clippy::type_complexity, clippy::too_many_arguments)]
    #[pyo3(signature = (grid_sources, sets, input=None, solver=None, fixed_step=None, abs_tolerance=None))]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        grid_sources: Vec<GridArgs>,
        sets: Vec<String>,
        input: Option<(Vec<String>, Vec<f64>, Vec<Vec<f64>>)>,
        solver: Option<&str>,
        fixed_step: Option<f64>,
        abs_tolerance: Option<f64>,
    ) -> PyResult<(Vec<String>, Vec<&'static str>, Bound<'py, PyBytes>, usize, Bound<'py, PyDict>, Option<String>)> {
        let md = &self.fmu.description;
        let integrator = Integrator::new(solver, fixed_step, abs_tolerance)?;
        integrator.check(md, &self.fmu.identifier, self.fmu.interface)?;
        let (names, kinds, data, rows, texts, ended_early) = py
            .detach(|| -> Result<_, String> {
                let mut grid = self.grid(&grid_sources)?;
                grid.solver = integrator.solver;
                let assignments = variables::parse_sets(md, &sets)?;
                let inputs = match input {
                    Some((names, time, values)) => Some(InputTable::from_columns(names, time, values)?),
                    None => None,
                };
                // As `runner simulate` records them: Strings of either version as text, Binaries
                // in hexadecimal; clocks have no value.
                let recordable = |v: &&Variable| v.kind != Kind::Clock;
                let outputs: Vec<&Variable> = md.outputs().filter(recordable).collect();
                let recording = Recording::new(md, &outputs, &assignments)?;
                let request = RunRequest::new(&self.fmu.identifier, grid, &assignments, &recording, false).with_inputs(inputs);
                let bound = request.bind(md, self.fmu.interface, true)?;
                let recording = &bound.recording;
                let mut kinds = vec!["float"];
                for (v, &size) in recording.variables.iter().zip(&recording.sizes) {
                    kinds.extend(std::iter::repeat_n(column_kind(v.kind), size));
                }
                let columns = recording.names.len();
                let mut data: Vec<f64> = Vec::new();
                let mut texts: Vec<Option<Vec<String>>> = vec![None; columns];
                let mut rows = 0usize;
                let outcome = bound.run().execute(&self.fmu, |t: f64, values: &[f64], text: &dyn Texts| {
                    data.push(t);
                    data.extend_from_slice(&values[..columns]);
                    for (c, slot) in texts.iter_mut().enumerate() {
                        if text.needs_text(c) || kinds[c + 1] == "text" {
                            slot.get_or_insert_with(Vec::new).push(text.text(c, values));
                        }
                    }
                    rows += 1;
                    Ok(())
                })?;
                let mut names = vec!["time".to_owned()];
                names.extend(recording.names.iter().cloned());
                Ok((names, kinds, data, rows, texts, outcome.ended_early))
            })
            .map_err(err)?;
        let text_columns = PyDict::new(py);
        for (c, column) in texts.into_iter().enumerate() {
            if let Some(column) = column {
                text_columns.set_item(&names[c + 1], column)?;
            }
        }
        Ok((names, kinds, PyBytes::new(py, &f64_bytes(&data)), rows, text_columns, ended_early))
    }

    /// [`units_of`] for this FMU.
    fn units<'py>(&self, py: Python<'py>, names: Vec<String>) -> PyResult<Bound<'py, PyDict>> {
        units_of(py, &self.fmu.description, &names)
    }

    /// The model's name.
    #[getter]
    fn model_name(&self) -> &str {
        &self.fmu.description.model_name
    }

    /// [`plan_sweep`] for this FMU, through the interface it was loaded for.
    #[pyo3(signature = (grid_sources, sets, ranges, metrics, solver=None, fixed_step=None, abs_tolerance=None))]
    #[allow(clippy::too_many_arguments)]
    fn plan_sweep(
        &self,
        grid_sources: Vec<GridArgs>,
        sets: Vec<String>,
        ranges: Vec<(String, Vec<f64>)>,
        metrics: Vec<String>,
        solver: Option<&str>,
        fixed_step: Option<f64>,
        abs_tolerance: Option<f64>,
    ) -> PyResult<Plan> {
        let f = &self.fmu;
        let integrator = Integrator::new(solver, fixed_step, abs_tolerance)?;
        plan(&f.description, &f.identifier, f.interface, &grid_sources, &integrator, sets, ranges, metrics)
    }

    /// Runs the points `start..stop` of the sweep `spec_json` (from [`Model::plan_sweep`]) on
    /// `threads` threads. Returns the row-major f64 bytes of their metrics (NaN where a point
    /// did not run), the (point, status) of every point whose status is not `ok`, and the
    /// seconds it took.
    #[pyo3(signature = (spec_json, start, stop, threads, on_rows=None))]
    fn run_points<'py>(
        &self,
        py: Python<'py>,
        spec_json: &str,
        start: usize,
        stop: usize,
        threads: usize,
        on_rows: Option<Py<PyAny>>,
    ) -> PyResult<Points<'py>> {
        let spec = self.spec(spec_json)?;
        let interrupt = Interrupt::new();
        let outcome = py.detach(|| -> Result<_, String> {
            let clock = Instant::now();
            let plan = spec.plan(&self.fmu.description, &self.fmu.identifier, self.fmu.interface)?;
            if start > stop || stop > plan.space.len {
                return Err(format!("points {start}..{stop} are not within the sweep's {} points", plan.space.len));
            }
            check_once_per_process(&self.fmu.description, self.fmu.interface, plan.space.len)?;
            let m = plan.metrics.metrics.len();
            let mut collected = Collected::new(start, stop, m, on_rows);
            let stopper = || interrupt.requested();
            let outcome = plan.execute_range(&self.fmu, start..stop, threads, &stopper, |i, r: PointResult| collected.take(i, r));
            collected.finish(outcome, clock)
        });
        points_for_python(py, interrupt, outcome)
    }
}

/// A stop test for a long call with the GIL released: true once Python has a signal to raise
/// (Ctrl-C), looked at every 100 ms at most; the error is kept for the caller to raise.
struct Interrupt {
    last: Mutex<(Instant, Option<PyErr>)>,
}

impl Interrupt {
    fn new() -> Interrupt {
        Interrupt { last: Mutex::new((Instant::now(), None)) }
    }

    fn requested(&self) -> bool {
        let Ok(mut last) = self.last.try_lock() else { return false };
        if last.1.is_some() {
            return true;
        }
        if last.0.elapsed() < Duration::from_millis(100) {
            return false;
        }
        last.0 = Instant::now();
        if let Err(e) = Python::attach(|py| py.check_signals()) {
            last.1 = Some(e);
            return true;
        }
        false
    }

    /// The signal's exception, if one stopped the call.
    fn raised(self) -> Option<PyErr> {
        self.last.into_inner().ok().and_then(|(_, e)| e)
    }
}

/// Metrics of points as they arrive, in point order from `start`; with `on_rows`, handed to
/// Python as they come (every 100 ms at most, and at the end): `on_rows(first, metric bytes,
/// failures)` of the points since the last call, so a sweep to a file keeps its finished rows.
struct Collected {
    start: usize,
    m: usize,
    values: Vec<f64>,
    failures: Vec<(usize, String)>,
    delivered: usize,
    on_rows: Option<Py<PyAny>>,
    /// The first point not yet handed to `on_rows`, and when they last were.
    handed: usize,
    last_handed: Instant,
}

impl Collected {
    fn new(start: usize, stop: usize, m: usize, on_rows: Option<Py<PyAny>>) -> Collected {
        Collected {
            start,
            m,
            values: Vec::with_capacity((stop - start) * m),
            failures: Vec::new(),
            delivered: 0,
            on_rows,
            handed: start,
            last_handed: Instant::now(),
        }
    }

    fn take(&mut self, i: usize, r: PointResult) -> Result<(), String> {
        match r.metrics {
            Some(v) => self.values.extend_from_slice(&v),
            None => self.values.extend(std::iter::repeat_n(f64::NAN, self.m)),
        }
        if r.status != "ok" {
            self.failures.push((i, r.status));
        }
        self.delivered += 1;
        if self.last_handed.elapsed() >= Duration::from_millis(100) {
            self.hand()?;
        }
        Ok(())
    }

    /// After the points ran (`outcome`), the last rows handed over; itself and the seconds since
    /// `clock`, or the error that stopped the points.
    fn finish(mut self, outcome: Result<(), String>, clock: Instant) -> Result<(Collected, f64), String> {
        self.hand()?;
        outcome?;
        Ok((self, clock.elapsed().as_secs_f64()))
    }

    /// Hands the points not handed yet to `on_rows`. When it fails (Ctrl-C while it writes,
    /// a full disk) it is not called again: it may have written some of those rows already, and
    /// handing them again would write them twice, each later row in the place of another.
    fn hand(&mut self) -> Result<(), String> {
        let Some(on_rows) = &self.on_rows else { return Ok(()) };
        let end = self.start + self.delivered;
        if end == self.handed {
            return Ok(());
        }
        let rows = &self.values[(self.handed - self.start) * self.m..(end - self.start) * self.m];
        let failures: Vec<(usize, String)> = self.failures.iter().filter(|(i, _)| *i >= self.handed).cloned().collect();
        let first = self.handed;
        if let Err(e) = Python::attach(|py| on_rows.call1(py, (first, PyBytes::new(py, &f64_bytes(rows)), failures)).map(|_| ())) {
            // Let go of it while attached.
            Python::attach(|_| drop(self.on_rows.take()));
            return Err(format!("writing the finished rows failed: {e}"));
        }
        self.handed = end;
        self.last_handed = Instant::now();
        Ok(())
    }
}

/// Runs the points `start..stop` of the sweep `spec_json` (from [`plan_sweep`]) of the FMU at
/// `path`, through `interface` (the one it was planned for), in `workers` worker processes of the sandbox, started by `worker` (program,
/// arguments): a point that crashes its worker, hangs past `point_timeout` seconds or grows past
/// `worker_memory` MiB is a row whose status says so, and the other points go on. The FMU's
/// binary is never loaded in this process. Returns what [`Model::run_points`] returns, and how
/// many points were delivered (fewer when Ctrl-C stopped the sweep: its exception is raised).
#[pyfunction]
#[pyo3(signature = (path, spec_json, start, stop, workers, worker, point_timeout=None, worker_memory=None, on_rows=None, interface=None))]
#[allow(clippy::too_many_arguments)]
fn run_points_isolated<'py>(
    py: Python<'py>,
    path: &str,
    spec_json: &str,
    start: usize,
    stop: usize,
    workers: usize,
    worker: (String, Vec<String>),
    point_timeout: Option<f64>,
    worker_memory: Option<u64>,
    on_rows: Option<Py<PyAny>>,
    interface: Option<&str>,
) -> PyResult<Points<'py>> {
    let interface = stepping::interface_of(interface)?;
    let spec: SweepRequest = serde_json::from_str(spec_json).map_err(|e| err(format!("not a sweep of this version of fmurunner: {e}")))?;
    if workers == 0 {
        return Err(err("workers must be at least 1".to_owned()));
    }
    let timeout = runner_sandbox::timeout("point_timeout", point_timeout).map_err(err)?;
    let memory = worker_memory.unwrap_or_else(|| runner_sandbox::default_memory_mib(workers));
    let command = WorkerCommand { program: worker.0.into(), args: worker.1.into_iter().map(Into::into).collect(), env: Vec::new() };
    let config = isolated::config(command, timeout, memory).map_err(err)?;
    let interrupt = Interrupt::new();
    let outcome = py.detach(|| -> Result<_, String> {
        let clock = Instant::now();
        let count = workers.min(stop.saturating_sub(start)).max(1);
        // Workers start while the FMU is unpacked here, then load this copy.
        let mut pool = exec::start_workers(config, count)?;
        let (held, source) = Held::open(&FmuSource::new(Path::new(path), interface), false)?;
        exec::load(&mut pool, &source, held.once_per_process());
        let plan = spec.plan(held.description(), held.identifier(), held.interface())?;
        if start > stop || stop > plan.space.len {
            return Err(format!("points {start}..{stop} are not within the sweep's {} points", plan.space.len));
        }
        let m = plan.metrics.metrics.len();
        let mut collected = Collected::new(start, stop, m, on_rows);
        let stopper = || interrupt.requested();
        let outcome = exec::sweep(&held, &plan, &spec, Where::Workers(pool), start..stop, &stopper, |i, r| collected.take(i, r));
        collected.finish(outcome, clock)
    });
    points_for_python(py, interrupt, outcome)
}

/// The points' metrics and statuses for Python; or the signal (Ctrl-C) that stopped them, or
/// the runner's error.
fn points_for_python<'py>(py: Python<'py>, interrupt: Interrupt, outcome: Result<(Collected, f64), String>) -> PyResult<Points<'py>> {
    if let Some(e) = interrupt.raised() {
        return Err(e);
    }
    let (collected, seconds) = outcome.map_err(err)?;
    Ok((PyBytes::new(py, &f64_bytes(&collected.values)), collected.failures, seconds))
}

/// Every entry of the references.toml at `path` (with the files it includes) as the engine
/// evaluates it at `values`: scalars as floats, matrices as lists of rows. Not public API: the
/// tests compare it with the Python evaluator of the same files (tests/fmpy/closed_form.py).
#[pyfunction]
fn reference_values<'py>(py: Python<'py>, path: &str, values: Vec<(String, f64)>) -> PyResult<Bound<'py, PyDict>> {
    let references = References::from_file(Path::new(path)).map_err(err)?;
    let values: Vec<(&str, f64)> = values.iter().map(|(name, value)| (name.as_str(), *value)).collect();
    let out = PyDict::new(py);
    for name in references.names() {
        out.set_item(name, references.value(name, &values).map_err(err)?)?;
    }
    for name in references.matrix_names() {
        out.set_item(name, references.matrix(name, &values).map_err(err)?)?;
    }
    Ok(out)
}

/// The runner's engine for Python (see the `fmurunner` package).
#[pymodule]
fn _engine(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("RunnerError", m.py().get_type::<RunnerError>())?;
    m.add_function(wrap_pyfunction!(locate, m)?)?;
    m.add_function(wrap_pyfunction!(describe, m)?)?;
    m.add_function(wrap_pyfunction!(plan_sweep, m)?)?;
    m.add_function(wrap_pyfunction!(reference_values, m)?)?;
    m.add_function(wrap_pyfunction!(run_points_isolated, m)?)?;
    m.add_function(wrap_pyfunction!(column_units, m)?)?;
    m.add_function(wrap_pyfunction!(stepping::serve_worker, m)?)?;
    m.add_class::<Model>()?;
    m.add_class::<stepping::Stepper>()?;
    m.add_class::<stepping::StepResult>()?;
    m.add_function(wrap_pyfunction!(sweep_file::csv_line, m)?)?;
    m.add_function(wrap_pyfunction!(sweep_file::read_finished, m)?)?;
    m.add_class::<sweep_file::SweepLock>()?;
    // The points a sweep may have, as the command line allows.
    m.add("MAX_POINTS", runner_engine::sweep::MAX_POINTS)?;
    Ok(())
}
