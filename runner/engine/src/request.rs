//! Requests: what the engine runs, as data. A command (or the Python package, or a server)
//! checks its options once and resolves them into a request; the engine takes only requests,
//! and a request travels unchanged to a worker process (postcard) or a Dask worker (JSON), which
//! binds it to its own copy of the FMU and runs it exactly as the supervisor would have.
//!
//! - [`FmuSource`]: which FMU, through which interface, unpacked where.
//! - [`RunRequest`]: one simulation run (simulate, a run of a comparison, one step of a
//!   server), bound to an FMU's variables as a [`BoundRun`], run as a [`crate::run::Run`].
//! - [`SweepRequest`]: a parameter sweep, bound as a [`crate::sweep::Plan`].
//! - [`LinearizeRequest`]: a linearization of a Model Exchange FMU ([`crate::linear`]).

use std::path::{Path, PathBuf};

use fmi_importer::call_log::CallLogTarget;
use fmi_importer::exchange::JacobianSource;
use fmi_importer::state::{Identity, SavedState};
use fmi_importer::{Description, Fmu, Interface, Value, Variable};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::input::{InputTable, Inputs};
use crate::linear::Linear;
use crate::metrics::Metrics;
use crate::run::{Grid, Recording, Run};
use crate::sweep::Plan;

/// Where the FMU comes from and how it is loaded: the one place both a supervisor and its
/// workers load it, so an option of loading added here reaches the workers too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FmuSource {
    /// The `.fmu` file.
    pub path: PathBuf,
    /// Where the supervisor unpacked it, for its workers to load from (it deletes it).
    pub unpacked: Option<PathBuf>,
    /// The interface to drive it through (`None`: Co-Simulation when it offers that).
    pub interface: Option<Interface>,
}

impl FmuSource {
    /// The FMU at `path`, through `interface`.
    pub fn new(path: &Path, interface: Option<Interface>) -> FmuSource {
        FmuSource { path: path.to_path_buf(), unpacked: None, interface }
    }

    /// Loads the FMU (running its binary's initializers): from the supervisor's copy when there is
    /// one, else unpacking it.
    pub fn load(&self) -> Result<Fmu, String> {
        match &self.unpacked {
            Some(dir) => Fmu::load_unpacked(&self.path, dir, self.interface),
            None => Fmu::load_as(&self.path, self.interface),
        }
    }

    /// Unpacks the FMU and reads its description without loading its binary (what a supervisor
    /// needs, so an FMU's initializers never run in it); returns the source its workers load,
    /// from that copy.
    pub fn open(&self) -> Result<(fmi_importer::Unpacked, FmuSource), String> {
        let unpacked = fmi_importer::Unpacked::open_as(&self.path, self.interface)?;
        let for_workers = FmuSource { unpacked: Some(unpacked.dir.path().to_path_buf()), ..self.clone() };
        Ok((unpacked, for_workers))
    }
}

/// A value as a request carries it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum WireValue {
    Real(f64),
    Integer(i32),
    Int(i128),
    Boolean(bool),
    String(String),
    Binary(Vec<u8>),
    List(Vec<WireValue>),
}

impl From<&Value> for WireValue {
    fn from(v: &Value) -> WireValue {
        match v {
            Value::Real(x) => WireValue::Real(*x),
            Value::Integer(x) => WireValue::Integer(*x),
            Value::Int(x) => WireValue::Int(*x),
            Value::Boolean(x) => WireValue::Boolean(*x),
            Value::String(x) => WireValue::String(x.clone()),
            Value::Binary(x) => WireValue::Binary(x.clone()),
            Value::List(x) => WireValue::List(x.iter().map(WireValue::from).collect()),
        }
    }
}

impl From<WireValue> for Value {
    fn from(v: WireValue) -> Value {
        match v {
            WireValue::Real(x) => Value::Real(x),
            WireValue::Integer(x) => Value::Integer(x),
            WireValue::Int(x) => Value::Int(x),
            WireValue::Boolean(x) => Value::Boolean(x),
            WireValue::String(x) => Value::String(x),
            WireValue::Binary(x) => Value::Binary(x),
            WireValue::List(x) => Value::List(x.into_iter().map(Value::from).collect()),
        }
    }
}

/// Assignments by variable name, as requests carry them.
fn by_name(assignments: &[(&Variable, Value)]) -> Vec<(String, WireValue)> {
    assignments.iter().map(|(v, x)| (v.name.clone(), WireValue::from(x))).collect()
}

/// Assignments bound to the variables of `description`.
fn bind_assignments<'a>(description: &'a Description, assignments: &[(String, WireValue)]) -> Result<Vec<(&'a Variable, Value)>, String> {
    assignments.iter().map(|(n, v)| Ok((variable(description, n)?, Value::from(v.clone())))).collect()
}

fn variable<'a>(description: &'a Description, name: &str) -> Result<&'a Variable, String> {
    description.variable(name).ok_or_else(|| format!("the FMU has no variable '{name}'"))
}

/// One simulation run: everything [`Run`] takes, by name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRequest {
    /// Instance name.
    pub name: String,
    /// The time grid, tolerance and (Model Exchange) solver.
    pub grid: Grid,
    /// Variables set before initialization, in order.
    pub assignments: Vec<(String, WireValue)>,
    /// Variables sampled at every communication point, in order (an array's elements each).
    pub recorded: Vec<String>,
    /// Also sample at each event a step stops at ([`Recording::events`]).
    pub events: bool,
    /// Turns the FMU's debug logging on.
    pub debug_logging: bool,
    /// Inputs set before every step (`--input-file`), checked against the FMU where it runs.
    #[serde(default)]
    pub inputs: Option<InputTable>,
    /// A saved state (bytes of [`SavedState::to_bytes`]) the run goes on from, restored after
    /// initialization (`--initial-fmu-state-file`).
    #[serde(default)]
    pub initial_state: Option<Vec<u8>>,
    /// Return the state reached at the stop time (`--final-fmu-state-file`).
    #[serde(default)]
    pub final_state: bool,
    /// Log every FMI call of the run there (`--log-fmi-calls`).
    #[serde(default)]
    pub log_fmi_calls: Option<CallLogTarget>,
}

/// A [`RunRequest`] bound to an FMU's variables: it owns what a [`Run`] borrows.
pub struct BoundRun<'a> {
    /// Instance name.
    pub name: String,
    /// The time grid, tolerance and (Model Exchange) solver.
    pub grid: Grid,
    /// Set before initialization, in order.
    pub assignments: Vec<(&'a Variable, Value)>,
    /// Set before every step (when bound with them).
    pub inputs: Option<Inputs<'a>>,
    /// The columns sampled.
    pub recording: Recording<'a>,
    /// Turns the FMU's debug logging on.
    pub debug_logging: bool,
    /// The state the run goes on from.
    pub initial_state: Option<SavedState>,
    /// Return the state reached at the stop time.
    pub final_state: bool,
}

impl BoundRun<'_> {
    /// The run to execute.
    pub fn run(&self) -> Run<'_, '_> {
        Run {
            name: &self.name,
            grid: &self.grid,
            assignments: &self.assignments,
            inputs: self.inputs.as_ref(),
            recording: &self.recording,
            debug_logging: self.debug_logging,
            initial_state: self.initial_state.as_ref(),
            final_state: self.final_state,
        }
    }
}

impl RunRequest {
    /// A request for `assignments` and `recording`, of variables of the FMU to run.
    pub fn new(name: &str, grid: Grid, assignments: &[(&Variable, Value)], recording: &Recording, debug_logging: bool) -> RunRequest {
        RunRequest {
            name: name.to_owned(),
            grid,
            assignments: by_name(assignments),
            recorded: recording.variables.iter().map(|v| v.name.clone()).collect(),
            events: recording.events,
            debug_logging,
            inputs: None,
            initial_state: None,
            final_state: false,
            log_fmi_calls: None,
        }
    }

    /// The request with `inputs` set before every step.
    pub fn with_inputs(self, inputs: Option<InputTable>) -> RunRequest {
        RunRequest { inputs, ..self }
    }

    /// The request's assignments and recording looked up in `description`, arrays sized alike on
    /// both sides of a pipe; its inputs bound for `interface` when `with_inputs`.
    pub fn bind<'a>(&self, description: &'a Description, interface: Interface, with_inputs: bool) -> Result<BoundRun<'a>, String> {
        let assignments = bind_assignments(description, &self.assignments)?;
        let recorded: Vec<&Variable> = self.recorded.iter().map(|n| variable(description, n)).collect::<Result<_, String>>()?;
        let mut recording = Recording::new(description, &recorded, &assignments)?;
        recording.events = self.events;
        let inputs = match (&self.inputs, with_inputs) {
            (Some(table), true) => Some(table.bind(description, interface)?),
            _ => None,
        };
        let initial_state =
            self.initial_state.as_deref().map(|bytes| SavedState::from_bytes(bytes, Identity::of(description, interface))).transpose()?;
        Ok(BoundRun {
            name: self.name.clone(),
            grid: self.grid,
            assignments,
            inputs,
            recording,
            debug_logging: self.debug_logging,
            initial_state,
            final_state: self.final_state,
        })
    }
}

/// A linearization ([`crate::linear::linearize`]) by name: where, after what, how.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearizeRequest {
    /// Instance name.
    pub name: String,
    /// Start and stop time, tolerance and the runner's integrator (for `at`).
    pub grid: Grid,
    /// Variables set before initialization, in order.
    pub assignments: Vec<(String, WireValue)>,
    /// Simulate to this time first (`None`: linearize at the initial state).
    pub at: Option<f64>,
    /// Directional derivatives when the FMU provides them, or central differences always.
    pub prefer: JacobianSource,
    /// Log every FMI call of the linearization there (`--log-fmi-calls`).
    #[serde(default)]
    pub log_fmi_calls: Option<CallLogTarget>,
}

impl LinearizeRequest {
    /// A request for `assignments` of variables of the FMU to linearize.
    pub fn new(name: &str, grid: Grid, assignments: &[(&Variable, Value)], at: Option<f64>, prefer: JacobianSource) -> LinearizeRequest {
        LinearizeRequest { name: name.to_owned(), grid, assignments: by_name(assignments), at, prefer, log_fmi_calls: None }
    }

    /// Linearizes `fmu` (loaded for Model Exchange) as requested, its FMI calls logged when asked.
    pub fn run(&self, fmu: &Fmu) -> Result<Linear, String> {
        let assignments = bind_assignments(&fmu.description, &self.assignments)?;
        let request =
            crate::linear::Request { name: &self.name, grid: &self.grid, assignments: &assignments, at: self.at, prefer: self.prefer };
        fmi_importer::call_log::logging(self.log_fmi_calls.as_ref(), || crate::linear::linearize(fmu, &request))
    }
}

/// Metrics parsed once from their `NAME=EXPR` texts, which is what travels: a worker parses the
/// texts it receives once, as it deserializes them.
#[derive(Debug, Clone)]
pub struct MetricSet {
    texts: Vec<String>,
    parsed: Metrics,
}

impl MetricSet {
    /// Parses `NAME=EXPR` definitions.
    pub fn parse(texts: &[String]) -> Result<MetricSet, String> {
        Ok(MetricSet { parsed: Metrics::parse(texts)?, texts: texts.to_vec() })
    }

    /// The definitions as given.
    pub fn texts(&self) -> &[String] {
        &self.texts
    }

    /// The parsed metrics.
    pub fn metrics(&self) -> &Metrics {
        &self.parsed
    }
}

impl PartialEq for MetricSet {
    fn eq(&self, other: &MetricSet) -> bool {
        self.texts == other.texts
    }
}

impl Serialize for MetricSet {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.texts.serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for MetricSet {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<MetricSet, D::Error> {
        let texts = Vec::<String>::deserialize(deserializer)?;
        MetricSet::parse(&texts).map_err(serde::de::Error::custom)
    }
}

/// A parameter sweep, resolved: every point a run of the same grid and fixed assignments with
/// the swept parameters set, summarized by the metrics. A process holding the FMU plans it
/// ([`SweepRequest::plan`]) and runs any of its points identically.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRequest {
    /// The grid of every run.
    pub grid: Grid,
    /// Assignments common to every point, in order (a later one wins).
    pub fixed: Vec<(String, WireValue)>,
    /// Each swept parameter's name and values, in `--param` order (the last varies fastest).
    pub ranges: Vec<(String, Vec<f64>)>,
    /// `NAME=EXPR` metrics.
    pub metrics: MetricSet,
    /// Inputs set before every step of every point (`--input-file`).
    #[serde(default)]
    pub inputs: Option<InputTable>,
}

impl SweepRequest {
    /// A sweep with `fixed` assignments, of variables of the FMU to sweep.
    pub fn new(
        grid: Grid,
        fixed: &[(&Variable, Value)],
        ranges: Vec<(String, Vec<f64>)>,
        metrics: MetricSet,
        inputs: Option<InputTable>,
    ) -> SweepRequest {
        SweepRequest { grid, fixed: by_name(fixed), ranges, metrics, inputs }
    }

    /// The checked plan of this sweep over the FMU `description` (modelIdentifier `identifier`),
    /// run through `interface`.
    pub fn plan<'a>(&self, description: &'a Description, identifier: &'a str, interface: Interface) -> Result<Plan<'a>, String> {
        let fixed = bind_assignments(description, &self.fixed)?;
        let metrics = self.metrics.clone().parsed;
        let mut plan = Plan::new(description, identifier, self.grid, fixed, self.ranges.clone(), metrics)?;
        plan.inputs = self.inputs.as_ref().map(|table| table.bind(description, interface)).transpose()?;
        Ok(plan)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::Grid;

    /// A sweep travels as postcard to a worker and as JSON to a Dask worker; both give it back
    /// equal, its metrics parsed again from their texts.
    #[test]
    fn a_sweep_request_travels_and_comes_back_equal() {
        let request = SweepRequest {
            grid: Grid::checked(0.0, 1.0, 0.01, Some(1e-9)).unwrap(),
            fixed: vec![("k".into(), WireValue::Real(0.1 + 0.2)), ("n".into(), WireValue::Int(-3))],
            ranges: vec![("speed".into(), vec![1.0, 1.5])],
            metrics: MetricSet::parse(&["t=max(z_s)/max(z_r, 5)".to_owned()]).unwrap(),
            inputs: None,
        };
        let wire: SweepRequest = postcard::from_bytes(&postcard::to_stdvec(&request).unwrap()).unwrap();
        assert_eq!(wire, request);
        assert_eq!(wire.metrics.metrics().sources.len(), 2, "parsed again on arrival");
        let json: SweepRequest = serde_json::from_str(&serde_json::to_string(&request).unwrap()).unwrap();
        assert_eq!(json, request);
        assert_eq!(json.metrics.texts(), ["t=max(z_s)/max(z_r, 5)"]);
        let bad = postcard::to_stdvec(&vec!["t=max(".to_owned()]).unwrap();
        assert!(postcard::from_bytes::<MetricSet>(&bad).is_err(), "texts that do not parse are refused on arrival");
    }
}
