//! Stepping an FMU from outside, one call at a time: a controller, a reinforcement-learning
//! environment or a hardware-in-the-loop rig drives the simulation from its own loop
//! (`fmurunner.Simulation`; a server or the command line can do the same). A [`Stepper`] holds
//! one initialized instance of any FMU, whatever its version and interface (Model Exchange is
//! integrated by the runner's solvers between the calls, as in a run), and offers what such a
//! loop needs: a step or an advance to a time, reading and setting variables by name, the FMU's
//! state saved as bytes and restored, a reset that reuses the instance, and real-time pacing.
//!
//! It runs in this process. [`IsolatedStepper`] offers the same calls on an instance in a worker
//! process of the sandbox: one round trip per call, and a crashing or hanging FMU costs only its
//! worker.
//!
//! Misuse is refused with a message before any FMU call (a name that is not a variable, with the
//! nearest names; a value of the wrong type; a step after the end). A call the FMU refuses
//! leaves the instance failed, as the standard has it (after an Error only a reset is allowed):
//! every later call but [`Stepper::reset`] then says so.

use std::sync::mpsc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use fmi_importer::state::SavedState;
use fmi_importer::trace::{self, CallSlot};
use fmi_importer::{Causality, Description, FmiVersion, Fmu, Instance, Kind, Reader, Solver, Step, Value, Variability, Variable};
use runner_sandbox::worker::{Incoming, Serving};
use runner_sandbox::{Config, Failure, Service, Session, SharedMemory};
use serde::{Deserialize, Serialize};

use crate::isolated::place;
use crate::request::{FmuSource, WireValue};
use crate::run::Recording;
use crate::variables;

/// How a stepped simulation starts: what a [`Stepper`] is opened with (and a worker is told).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StepSettings {
    /// The instance name.
    pub name: String,
    /// The start time (`None`: the FMU's default experiment's, else 0).
    pub start_time: Option<f64>,
    /// The stop time, past which no step goes (`None`: none; the FMU is told none).
    pub stop_time: Option<f64>,
    /// The relative tolerance (`None`: the FMU's default experiment's, else the FMU's own).
    pub tolerance: Option<f64>,
    /// The runner's integrator, for Model Exchange.
    pub solver: Solver,
    /// Variables set before initialization, by name, in order.
    pub start_values: Vec<(String, WireValue)>,
    /// Turns the FMU's debug logging on.
    pub debug_logging: bool,
}

impl StepSettings {
    /// Settings of an instance called `name` with the FMU's defaults and nothing set.
    pub fn new(name: &str) -> StepSettings {
        StepSettings {
            name: name.to_owned(),
            start_time: None,
            stop_time: None,
            tolerance: None,
            solver: Solver::default(),
            start_values: Vec::new(),
            debug_logging: false,
        }
    }

    /// The start values bound to `description`'s variables, each checked settable.
    fn bind<'a>(&self, description: &'a Description) -> Result<Vec<(&'a Variable, Value)>, String> {
        self.start_values
            .iter()
            .map(|(name, value)| {
                let variable = variables::find(description, name)?;
                variables::check_settable(variable)?;
                Ok((variable, Value::from(value.clone())))
            })
            .collect()
    }
}

/// How far a step got.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Stepped {
    /// The time reached.
    pub time: f64,
    /// True when the step reached the end it was asked for; false when the FMU returned early
    /// (FMI 3.0) at an event, handled, at `time`.
    pub complete: bool,
    /// Events the FMU stopped the step at (handled, in Event Mode), the last at `time` when the
    /// step is not complete.
    pub events: u32,
}

/// A value given to [`Stepper::set`], before it is checked against the variable's type.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Given {
    /// A number (a Python float).
    Real(f64),
    /// A whole number (a Python int).
    Integer(i128),
    /// A truth value.
    Boolean(bool),
    /// Text: a String's value, or a number with a unit (`"120deg"`), or a Binary in hex.
    Text(String),
    /// Bytes of a Binary.
    Bytes(Vec<u8>),
    /// The elements of an array, row-major.
    List(Vec<Given>),
}

impl Given {
    fn what(&self) -> String {
        match self {
            Given::Real(x) => format!("the float {x:?}"),
            Given::Integer(i) => format!("the int {i}"),
            Given::Boolean(b) => format!("the bool {b}"),
            Given::Text(t) => format!("the text {t:?}"),
            Given::Bytes(b) => format!("{} bytes", b.len()),
            Given::List(items) => format!("a list of {} values", items.len()),
        }
    }
}

/// `given` as a value of `variable` (of `description`), or why it is not one: the type rules of
/// a setter that takes Python's values.
pub fn value_of(description: &Description, variable: &Variable, given: &Given) -> Result<Value, String> {
    if variable.is_array() {
        let Given::List(items) = given else {
            return Err(format!("'{}' is an array: give its elements as a list or a numpy array", variable.name));
        };
        if let Some(n) = fixed_size(variable) {
            if items.len() != n {
                return Err(format!("'{}' has {n} elements; {} were given", variable.name, items.len()));
            }
        }
        let element = Variable { dimensions: Vec::new(), ..variable.clone() };
        return items.iter().map(|item| value_of(description, &element, item)).collect::<Result<Vec<_>, _>>().map(Value::List);
    }
    let wrong = |expected: &str| format!("'{}' is {} ({expected}); {} is not one", variable.name, kind_name(variable.kind), given.what());
    match (variable.kind, given) {
        (_, Given::List(_)) => Err(format!("'{}' is a scalar; {} cannot set it", variable.name, given.what())),
        (_, Given::Text(text)) if variable.kind != Kind::String => variables::parse_quantity(description, variable, text),
        (Kind::Real | Kind::Float32, Given::Real(x)) if x.is_finite() => Ok(Value::Real(*x)),
        (Kind::Real | Kind::Float32, Given::Integer(i)) => Ok(Value::Real(*i as f64)),
        (Kind::Real | Kind::Float32, _) => Err(wrong("a finite number")),
        (Kind::Boolean, Given::Boolean(b)) => Ok(Value::Boolean(*b)),
        (Kind::Boolean, Given::Integer(i @ (0 | 1))) => Ok(Value::Boolean(*i == 1)),
        (Kind::Boolean, _) => Err(wrong("True or False")),
        (Kind::String, Given::Text(t)) => Ok(Value::String(t.clone())),
        (Kind::String, _) => Err(wrong("a str")),
        (Kind::Binary, Given::Bytes(b)) => Ok(Value::Binary(b.clone())),
        (Kind::Binary, _) => Err(wrong("bytes")),
        (Kind::Clock, _) => Err(format!("'{}' is a Clock; clocks cannot be set", variable.name)),
        (kind, given) => {
            let whole = match given {
                Given::Integer(i) => Some(*i),
                Given::Real(x) if x.fract() == 0.0 && x.abs() < 1e38 => Some(*x as i128),
                _ => None,
            };
            let Some(i) = whole else { return Err(wrong("a whole number")) };
            match kind {
                Kind::Integer | Kind::Enumeration if variable_is_fmi2_int(kind, description) => i32::try_from(i)
                    .map(Value::Integer)
                    .map_err(|_| format!("'{}' is an Integer (32 bits); {i} is out of its range", variable.name)),
                Kind::Integer => {
                    i32::try_from(i).map(Value::Integer).map_err(|_| format!("'{}' is an Int32; {i} is out of its range", variable.name))
                }
                _ => {
                    let (lo, hi) = kind.integer_range().unwrap_or((i128::MIN, i128::MAX));
                    if (lo..=hi).contains(&i) {
                        Ok(Value::Int(i))
                    } else {
                        Err(format!("'{}' is {}; {i} is out of its range {lo}..={hi}", variable.name, kind_name(kind)))
                    }
                }
            }
        }
    }
}

/// FMI 1.0 and 2.0 Integers and Enumerations are 32 bits (`Value::Integer`).
fn variable_is_fmi2_int(kind: Kind, description: &Description) -> bool {
    kind == Kind::Integer || matches!(description.fmi_version, FmiVersion::Fmi1 | FmiVersion::Fmi2)
}

fn kind_name(kind: Kind) -> String {
    let name = kind.as_str();
    let article = if name.starts_with(['A', 'E', 'I', 'U', 'a', 'e', 'i', 'u']) { "an" } else { "a" };
    format!("{article} {name}")
}

/// The number of elements of an array whose dimensions are all fixed.
fn fixed_size(variable: &Variable) -> Option<usize> {
    variable
        .dimensions
        .iter()
        .map(|d| match d {
            fmi_importer::model::Dimension::Fixed(n) => usize::try_from(*n).ok(),
            fmi_importer::model::Dimension::Variable(_) => None,
        })
        .product()
}

/// Checks that `variable` may be set between steps: an input, or a tunable parameter.
pub fn check_settable_between_steps(variable: &Variable) -> Result<(), String> {
    match (variable.causality, variable.variability) {
        (Causality::Input, _) => Ok(()),
        (Causality::Parameter, Variability::Tunable) => Ok(()),
        (Causality::Parameter | Causality::StructuralParameter, _) => Err(format!(
            "'{}' is a {} parameter: it is set before initialization only (give it in start_values, or to reset())",
            variable.name, variable.variability
        )),
        _ => Err(format!(
            "'{}' is {} ({}); only inputs and tunable parameters can be set while stepping",
            variable.name, variable.causality, variable.variability
        )),
    }
}

/// What a selection of variables reads: per column its number (Booleans as 0/1), and where a
/// number does not give it (64-bit integers, Strings, Binaries) its exact text.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Values {
    /// One number per column.
    pub numbers: Vec<f64>,
    /// `(column, text)` of the columns whose numbers do not give them.
    pub texts: Vec<(usize, String)>,
}

/// What a value is in Python: how a column's number and text become one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ValueKind {
    /// Real, Float32: a float.
    Float,
    /// The integer types and Enumerations: an int.
    Int,
    /// Boolean: a bool.
    Bool,
    /// String: a str.
    Text,
    /// Binary: bytes (read as hexadecimal text).
    Bytes,
}

impl ValueKind {
    /// The kind of a variable of type `kind`.
    pub fn of(kind: Kind) -> ValueKind {
        match kind {
            Kind::Real | Kind::Float32 => ValueKind::Float,
            Kind::Boolean => ValueKind::Bool,
            Kind::String => ValueKind::Text,
            Kind::Binary | Kind::Clock => ValueKind::Bytes,
            _ => ValueKind::Int,
        }
    }
}

/// Per variable read: its kind, and its element count when it is an array (`None` for a scalar).
pub type Shapes = Vec<(ValueKind, Option<usize>)>;

/// Variables chosen once by name, read as often as wanted ([`Stepper::read`]).
pub struct Selection {
    /// The names asked for.
    pub names: Vec<String>,
    /// Per name: its kind, and its element count when it is an array (`None` for a scalar).
    pub shapes: Shapes,
    reader: Option<Reader>,
    /// The values read last.
    pub values: Values,
}

impl Selection {
    /// The columns of the selection: one per scalar, one per element of an array.
    pub fn len(&self) -> usize {
        self.values.numbers.len()
    }

    /// True for a selection of nothing.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// True when every column is a number read exactly as an f64 (Reals, Float32s, Booleans
    /// and integers of up to 32 bits): the selection reads into a plain float array.
    pub fn numeric(&self) -> bool {
        self.shapes.iter().all(|(kind, _)| matches!(kind, ValueKind::Float | ValueKind::Int | ValueKind::Bool))
            && self.values.texts.is_empty()
    }
}

/// Where a stepped simulation is.
#[derive(Debug, Clone, PartialEq)]
enum Status {
    /// Stepping.
    Running,
    /// The FMU ended the simulation (its reason): its values can be read; a reset starts again.
    Ended(String),
    /// A call failed (its message): only a reset is allowed.
    Failed(String),
}

/// Real-time pacing: simulated time follows the wall clock at `factor` (1: real time, 2: twice
/// as fast), from the first step after the simulation started or jumped (reset, state set).
#[derive(Debug, Clone)]
pub struct Pacing {
    factor: f64,
    /// The wall-clock instant and simulated time that correspond.
    anchor: Option<(Instant, f64)>,
    /// Steps that ended later than the wall clock allowed.
    pub overruns: u64,
    /// The largest such lateness (s of wall-clock time).
    pub worst_lateness: f64,
}

impl Pacing {
    /// Pacing at `factor` times real time.
    pub fn new(factor: f64) -> Result<Pacing, String> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(format!("realtime={factor} must be a positive number (1.0 is real time)"));
        }
        Ok(Pacing { factor, anchor: None, overruns: 0, worst_lateness: 0.0 })
    }

    /// Before a step from simulated time `t`: the first one anchors the clocks.
    fn start(&mut self, t: f64) {
        if self.anchor.is_none() {
            self.anchor = Some((Instant::now(), t));
        }
    }

    /// After a step to simulated time `t`: sleeps until the wall clock reaches it, or counts an
    /// overrun when it is already past (the clocks are not moved: later steps catch up).
    fn finish(&mut self, t: f64) {
        let Some((wall, sim)) = self.anchor else { return };
        let due = (t - sim) / self.factor;
        let elapsed = wall.elapsed().as_secs_f64();
        if elapsed > due {
            self.overruns += 1;
            self.worst_lateness = self.worst_lateness.max(elapsed - due);
        } else {
            std::thread::sleep(Duration::from_secs_f64(due - elapsed));
        }
    }

    /// Forgets the anchor: simulated time jumped.
    fn restart(&mut self) {
        self.anchor = None;
    }
}

/// The instance of a stepper and the FMU it borrows (none between freeing an instance and
/// making its replacement, see [`Stepper::reset`]).
struct Live<'a> {
    instance: Option<Instance<'a>>,
}

self_cell::self_cell!(
    struct Held {
        owner: Arc<Fmu>,
        #[not_covariant]
        dependent: Live,
    }
);

/// One initialized instance of an FMU, stepped from outside, in this process.
pub struct Stepper {
    held: Held,
    settings: StepSettings,
    start: f64,
    /// The stop time, infinite when there is none.
    stop: f64,
    time: f64,
    status: Status,
    /// Real-time pacing, when asked for.
    pub pacing: Option<Pacing>,
}

// SAFETY: an FMU instance may be called from any thread, one call at a time (FMI does not tie
// an instance to the thread that made it); a Stepper is used through `&mut` only, so its calls
// never overlap. The raw pointers it holds are the FMU's instance and callbacks.
unsafe impl Send for Stepper {}

/// A time within rounding of `b`: the end of a step summed from its start and length.
fn reached(a: f64, b: f64) -> bool {
    a >= b || (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

impl Stepper {
    /// Instantiates `fmu` and initializes it as `settings` say: ready to step from its start time.
    pub fn open(fmu: Arc<Fmu>, settings: StepSettings) -> Result<Stepper, String> {
        let description = &fmu.description;
        let start = settings.start_time.or(description.default_experiment.and_then(|e| e.start_time)).unwrap_or(0.0);
        let stop = settings.stop_time.unwrap_or(f64::INFINITY);
        if !start.is_finite() {
            return Err(format!("start time {start} must be a finite number"));
        }
        if stop <= start || stop.is_nan() {
            return Err(format!("stop time {stop} must be after the start time {start}"));
        }
        if let Some(t) = settings.tolerance {
            if !(t.is_finite() && t > 0.0) {
                return Err(format!("tolerance {t} must be a positive number"));
            }
        }
        settings.bind(description)?;
        let name = settings.name.clone();
        let held =
            Held::try_new(fmu, |fmu| fmu.instantiate(&name, settings.debug_logging).map(|instance| Live { instance: Some(instance) }))?;
        let mut stepper = Stepper { held, settings, start, stop, time: start, status: Status::Running, pacing: None };
        stepper.initialize()?;
        Ok(stepper)
    }

    /// The FMU.
    pub fn fmu(&self) -> &Fmu {
        self.held.borrow_owner()
    }

    /// The FMU's description.
    pub fn description(&self) -> &Description {
        &self.fmu().description
    }

    /// The settings it was opened (or last reset) with.
    pub fn settings(&self) -> &StepSettings {
        &self.settings
    }

    /// The time reached.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Calls the instance; a failure leaves the simulation failed (only a reset is allowed).
    fn call<T>(&mut self, f: impl FnOnce(&mut Instance) -> Result<T, String>) -> Result<T, String> {
        let result = self.held.with_dependent_mut(|_, live| match &mut live.instance {
            Some(instance) => f(instance),
            None => Err("the FMU could not be instantiated again; open a new simulation".to_owned()),
        });
        if let Err(e) = &result {
            self.status = Status::Failed(e.clone());
        }
        result
    }

    /// Set up, the start values set, initialized: ready at the start time.
    fn initialize(&mut self) -> Result<(), String> {
        let (solver, tolerance, start, stop) = (self.settings.solver, self.tolerance(), self.start, self.stop);
        let fmu = Arc::clone(self.held.borrow_owner());
        let assignments = self.settings.bind(&fmu.description)?;
        self.call(|instance| {
            instance.set_solver(solver);
            instance.setup_experiment(tolerance, start, stop)?;
            for (variable, value) in &assignments {
                instance.set(variable, value)?;
            }
            instance.enter_initialization_mode()?;
            instance.exit_initialization_mode()
        })?;
        self.time = start;
        self.status = Status::Running;
        if let Some(pacing) = &mut self.pacing {
            pacing.restart();
        }
        Ok(())
    }

    fn tolerance(&self) -> Option<f64> {
        self.settings.tolerance.or(self.description().default_experiment.and_then(|e| e.tolerance))
    }

    /// Ok while stepping; else why not.
    fn running(&self) -> Result<(), String> {
        match &self.status {
            Status::Running => Ok(()),
            Status::Ended(reason) => Err(format!("the simulation has ended ({reason}); reset() starts it again")),
            Status::Failed(message) => Err(format!("the FMU failed earlier ({message}); only reset() is allowed now")),
        }
    }

    /// Ok unless a call failed (an ended simulation can still be read).
    fn readable(&self) -> Result<(), String> {
        match &self.status {
            Status::Failed(message) => Err(format!("the FMU failed earlier ({message}); only reset() is allowed now")),
            _ => Ok(()),
        }
    }

    /// One communication step of `dt` from the current time. An FMI 3.0 FMU may return early
    /// at an event: the step then ends there (handled), `complete` false. The FMU ending the
    /// simulation is an error with its reason (the values it reached can still be read).
    pub fn step(&mut self, dt: f64) -> Result<Stepped, String> {
        self.running()?;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(format!("step size {dt} must be a positive number (seconds)"));
        }
        let end = self.time + dt;
        if end > self.stop && !reached(self.stop, end) {
            return Err(format!("a step of {dt} s from t = {} passes the stop time {}", self.time, self.stop));
        }
        self.step_to(end)
    }

    /// Steps to `t`, through every event on the way (FMI 3.0 early returns included): one step
    /// unless the FMU stops at events.
    pub fn advance_to(&mut self, t: f64) -> Result<Stepped, String> {
        self.running()?;
        if !t.is_finite() {
            return Err(format!("time {t} must be a finite number"));
        }
        if t < self.time && !reached(t, self.time) {
            return Err(format!(
                "t = {t} is before the current time {}: a simulation goes forward (set_state() or reset() go back)",
                self.time
            ));
        }
        if t > self.stop && !reached(self.stop, t) {
            return Err(format!("t = {t} is after the stop time {}", self.stop));
        }
        let mut events = 0;
        loop {
            if reached(self.time, t) {
                return Ok(Stepped { time: self.time, complete: true, events });
            }
            let stepped = self.step_to(t)?;
            events += stepped.events;
            if stepped.complete {
                return Ok(Stepped { events, ..stepped });
            }
        }
    }

    /// One FMU step from the current time to `end`.
    fn step_to(&mut self, end: f64) -> Result<Stepped, String> {
        let t = self.time;
        if let Some(pacing) = &mut self.pacing {
            pacing.start(t);
        }
        let step = self.call(|instance| instance.do_step(t, end - t))?;
        let stepped = match step {
            Step::Done => {
                self.time = end;
                Stepped { time: end, complete: true, events: 0 }
            }
            Step::Event { time } => {
                if let Some(reason) = self.call(|instance| instance.handle_event(time))? {
                    self.time = time;
                    self.status = Status::Ended(reason.clone());
                    return Err(reason);
                }
                let complete = reached(time, end);
                self.time = if complete { end } else { time };
                Stepped { time: self.time, complete, events: 1 }
            }
            Step::Ended { reason, last_time } => {
                if let Some(last) = last_time.filter(|&last| last > t) {
                    self.time = last;
                }
                self.status = Status::Ended(reason.clone());
                return Err(reason);
            }
        };
        if let Some(pacing) = &mut self.pacing {
            pacing.finish(self.time);
        }
        Ok(stepped)
    }

    /// Chooses variables to read by name (an unknown name is refused with the nearest ones).
    pub fn select(&self, names: &[&str]) -> Result<Selection, String> {
        let description = self.description();
        let mut variables: Vec<&Variable> = Vec::with_capacity(names.len());
        for name in names {
            variables.push(variables::find(description, name)?);
        }
        let assignments = self.settings.bind(description)?;
        let recording = Recording::new(description, &variables, &assignments)?;
        let shapes: Shapes =
            variables.iter().zip(&recording.sizes).map(|(v, &n)| (ValueKind::of(v.kind), v.is_array().then_some(n))).collect();
        // One reader for every type, FMI 2.0 Strings included (fmi2GetString).
        let reader =
            if variables.is_empty() { None } else { Some(Reader::with_sizes(description.fmi_version, &variables, &recording.sizes)?) };
        let columns: usize = recording.sizes.iter().sum();
        Ok(Selection {
            names: names.iter().map(|n| (*n).to_owned()).collect(),
            shapes,
            reader,
            values: Values { numbers: vec![0.0; columns], texts: Vec::new() },
        })
    }

    /// Reads the variables of `selection` into its `values`.
    pub fn read(&mut self, selection: &mut Selection) -> Result<(), String> {
        self.readable()?;
        let Selection { reader, values, .. } = selection;
        let numbers = &mut values.numbers;
        values.texts.clear();
        if let Some(reader) = reader {
            self.call(|instance| instance.read(reader, numbers))?;
            for c in 0..reader.len() {
                if reader.needs_text(c) {
                    values.texts.push((c, reader.text(c, numbers)));
                }
            }
        }
        Ok(())
    }

    /// Sets an input or a tunable parameter by name, from `given` (a number in SI, or text with
    /// a unit the FMU declares for it: `"120deg"`).
    pub fn set(&mut self, name: &str, given: &Given) -> Result<(), String> {
        self.running()?;
        let fmu = Arc::clone(self.held.borrow_owner());
        let variable = variables::find(&fmu.description, name)?;
        check_settable_between_steps(variable)?;
        if let (true, Given::List(items)) = (variable.is_array(), given) {
            // Sized by structural parameters, as they were set at the start.
            let assignments = self.settings.bind(&fmu.description)?;
            let n = Recording::new(&fmu.description, &[variable], &assignments)?.sizes[0];
            if items.len() != n {
                return Err(format!("'{}' has {n} elements; {} were given", variable.name, items.len()));
            }
        }
        let value = value_of(&fmu.description, variable, given)?;
        self.call(|instance| instance.set_between_steps(variable, &value))
    }

    /// Refuses state calls to an FMU that does not declare it can serialize its state.
    fn check_state_capability(&self) -> Result<(), String> {
        let fmu = self.fmu();
        let capable = fmu.description.interface(fmu.interface).is_some_and(|c| c.can_get_and_set_fmu_state && c.can_serialize_fmu_state);
        if capable {
            Ok(())
        } else {
            Err(format!(
                "{} does not declare canGetAndSetFMUstate and canSerializeFMUstate for {}, so its state cannot be saved or restored",
                fmu.description.model_name, fmu.interface
            ))
        }
    }

    /// The simulation's state as bytes: the FMU's serialized state and the time reached (and,
    /// for Model Exchange, the next time event); [`Stepper::set_state`] goes back to it.
    pub fn get_state(&mut self) -> Result<Vec<u8>, String> {
        self.readable()?;
        self.check_state_capability()?;
        let time = self.time;
        let saved = self.call(|instance| instance.save_state(time))?;
        let fmu = self.fmu();
        Ok(saved.to_bytes(fmu.state_identity()))
    }

    /// Goes back to a state of [`Stepper::get_state`], taken from an instance of this FMU.
    pub fn set_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.readable()?;
        self.check_state_capability()?;
        let fmu = self.fmu();
        let saved = SavedState::from_bytes(bytes, fmu.state_identity())?;
        self.call(|instance| instance.restore_state(&saved))?;
        self.time = saved.time;
        self.status = Status::Running;
        if let Some(pacing) = &mut self.pacing {
            pacing.restart();
        }
        Ok(())
    }

    /// Back to the start with the same instance (fmi2Reset, fmi3Reset; a new instance when the FMU
    /// has no reset or refuses it), initialized again; with `start_values`, those replace the
    /// ones it was opened with.
    pub fn reset(&mut self, start_values: Option<Vec<(String, WireValue)>>) -> Result<(), String> {
        if trace::fatal_seen() {
            return Err("an FMU in this process returned fmiFatal, after which the standard trusts none of its instances: open a new simulation in a new process (isolated=True runs it in a worker process)".to_owned());
        }
        if let Some(values) = start_values {
            let settings = StepSettings { start_values: values, ..self.settings.clone() };
            settings.bind(self.description())?;
            self.settings = settings;
        }
        if self.call(|instance| instance.reset()).is_err() {
            // An FMU without fmi2Reset/fmi3Reset (optional in FMI 2.0), or one that refuses it
            // after a failure: a fresh instance instead, the old one freed first (an FMU may
            // allow only one instance per process).
            let (name, debug_logging) = (self.settings.name.clone(), self.settings.debug_logging);
            self.held.with_dependent_mut(|fmu, live| -> Result<(), String> {
                live.instance = None;
                live.instance = Some(fmu.instantiate(&name, debug_logging)?);
                Ok(())
            })?;
        }
        self.initialize()
    }
}

/// The calls of a stepped simulation, on an instance in a worker process.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Call {
    /// Answered with the time: the first call, which starts the worker.
    Time,
    Step(f64),
    AdvanceTo(f64),
    Get(Vec<String>),
    Set(String, Given),
    GetState,
    SetState(Vec<u8>),
    Reset(Option<Vec<(String, WireValue)>>),
}

/// What a call in a worker answers.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub enum Answer {
    /// The time, after a call that moves none.
    Time(f64),
    Stepped(Stepped),
    /// Values read, and the shapes of the variables asked for.
    Values(Values, Shapes),
    State(Vec<u8>),
}

/// The workers of isolated stepping.
pub struct Stepping;

/// What a stepping worker is told first.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Open {
    /// The FMU to load.
    pub source: FmuSource,
    /// How to start its instance.
    pub settings: StepSettings,
}

impl Service for Stepping {
    type Setup = Open;
    type Job = Call;
    type Message = ();
    type Outcome = Result<Answer, String>;

    fn failed(_: &Call, failure: &Failure, shared: &SharedMemory) -> Result<Answer, String> {
        // SAFETY: the worker laid its call slot (atomics only) over the start of this memory.
        let at = place(unsafe { shared.view::<CallSlot>() }.read());
        Err(format!("the FMU's worker process {}", failure.describe(&at)))
    }
}

/// Serves a stepping worker until its supervisor lets it go. Only a supervisor starts this.
pub fn serve() -> Result<(), String> {
    let mut serving = Serving::<Stepping>::start()?;
    fmi_importer::set_log_printer(runner_sandbox::worker::log);
    // SAFETY: the call slot (atomics only) fits in the shared page, which lives for the rest of
    // the process.
    let slot: &'static CallSlot = unsafe { serving.shared().view::<CallSlot>() };
    slot.clear();
    trace::set_slot(slot);
    let Open { source, settings } = match serving.receive()? {
        Some(Incoming::Setup(open)) => open,
        None => return Ok(()),
        Some(Incoming::Job { .. }) => return Err("the first request must say which FMU to open".to_owned()),
    };
    let mut stepper = match source.load().and_then(|fmu| Stepper::open(Arc::new(fmu), settings)) {
        Ok(stepper) => stepper,
        Err(e) => return serving.ready(Err(e)),
    };
    serving.ready(Ok(()))?;
    while let Some(request) = serving.receive()? {
        match request {
            Incoming::Setup(_) => return Err("a stepping worker opens one FMU".to_owned()),
            Incoming::Job { id, job } => {
                let answer = answer(&mut stepper, job);
                serving.finish(id, answer, trace::fatal_seen())?;
            }
        }
    }
    runner_sandbox::worker::flush();
    Ok(())
}

/// Runs one call on `stepper`.
fn answer(stepper: &mut Stepper, call: Call) -> Result<Answer, String> {
    match call {
        Call::Time => Ok(Answer::Time(stepper.time())),
        Call::Step(dt) => stepper.step(dt).map(Answer::Stepped),
        Call::AdvanceTo(t) => stepper.advance_to(t).map(Answer::Stepped),
        Call::Get(names) => {
            let names: Vec<&str> = names.iter().map(String::as_str).collect();
            let mut selection = stepper.select(&names)?;
            stepper.read(&mut selection)?;
            Ok(Answer::Values(selection.values, selection.shapes))
        }
        Call::Set(name, given) => stepper.set(&name, &given).map(|()| Answer::Time(stepper.time())),
        Call::GetState => stepper.get_state().map(Answer::State),
        Call::SetState(bytes) => stepper.set_state(&bytes).map(|()| Answer::Time(stepper.time())),
        Call::Reset(values) => stepper.reset(values).map(|()| Answer::Time(stepper.time())),
    }
}

/// A call for the supervisor thread, with where its answer goes.
type Request = (Call, mpsc::Sender<Result<Answer, String>>);

/// A stepped simulation whose instance lives in a worker process: each call is a round trip,
/// and a crash, a hang past the time limit or an fmiFatal of the FMU costs its worker only (an
/// error here; a reset starts a fresh worker). The worker is supervised from a thread of its own,
/// which lives as long as this value: a worker dies with the thread that started it.
pub struct IsolatedStepper {
    requests: Option<mpsc::Sender<Request>>,
    supervisor: Option<std::thread::JoinHandle<()>>,
    time: f64,
    /// The worker crashed or was killed (the message): every call but a reset is refused.
    lost: Option<String>,
    /// Real-time pacing, done here (the round trip is part of the step).
    pub pacing: Option<Pacing>,
}

impl IsolatedStepper {
    /// Starts a worker as `config` says, which loads `source` and opens its instance as
    /// `settings` say; fails as [`Stepper::open`] would.
    pub fn open(config: Config, source: FmuSource, settings: StepSettings) -> Result<IsolatedStepper, String> {
        let (requests, incoming) = mpsc::channel::<Request>();
        let supervisor = std::thread::Builder::new()
            .name("fmurunner-stepping".to_owned())
            .spawn(move || {
                let mut session = Session::<Stepping>::new(config, &[Open { source, settings }], false);
                let never = || false;
                for (call, answer) in incoming {
                    let outcome = session.run(call, &never, |()| Ok(())).and_then(|outcome| outcome);
                    if answer.send(outcome).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| format!("cannot start the thread that supervises the worker: {e}"))?;
        let mut stepper =
            IsolatedStepper { requests: Some(requests), supervisor: Some(supervisor), time: f64::NAN, lost: None, pacing: None };
        stepper.time = match stepper.ask(Call::Time)? {
            Answer::Time(t) => t,
            other => return Err(format!("the worker answered {other:?} to a first call")),
        };
        Ok(stepper)
    }

    /// The time reached.
    pub fn time(&self) -> f64 {
        self.time
    }

    fn ask(&mut self, call: Call) -> Result<Answer, String> {
        let (answer, receive) = mpsc::channel();
        let requests = self.requests.as_ref().ok_or("the simulation is closed")?;
        requests.send((call, answer)).map_err(|_| "the thread supervising the worker is gone".to_owned())?;
        let outcome = receive.recv().map_err(|_| "the thread supervising the worker is gone".to_owned())?;
        if let Err(e) = &outcome {
            if e.starts_with("the FMU's worker process") {
                self.lost = Some(e.clone());
            }
        }
        outcome
    }

    fn alive(&self) -> Result<(), String> {
        match &self.lost {
            Some(e) => Err(format!("{e}; reset() starts a new worker")),
            None => Ok(()),
        }
    }

    fn stepped(&mut self, call: Call) -> Result<Stepped, String> {
        self.alive()?;
        if let Some(pacing) = &mut self.pacing {
            pacing.start(self.time);
        }
        match self.ask(call)? {
            Answer::Stepped(stepped) => {
                self.time = stepped.time;
                if let Some(pacing) = &mut self.pacing {
                    pacing.finish(stepped.time);
                }
                Ok(stepped)
            }
            other => Err(format!("the worker answered {other:?} to a step")),
        }
    }

    /// [`Stepper::step`] in the worker.
    pub fn step(&mut self, dt: f64) -> Result<Stepped, String> {
        self.stepped(Call::Step(dt))
    }

    /// [`Stepper::advance_to`] in the worker.
    pub fn advance_to(&mut self, t: f64) -> Result<Stepped, String> {
        self.stepped(Call::AdvanceTo(t))
    }

    /// Reads `names` in the worker: their values and shapes.
    pub fn get(&mut self, names: Vec<String>) -> Result<(Values, Shapes), String> {
        self.alive()?;
        match self.ask(Call::Get(names))? {
            Answer::Values(values, shapes) => Ok((values, shapes)),
            other => Err(format!("the worker answered {other:?} to a read")),
        }
    }

    fn timed(&mut self, call: Call) -> Result<(), String> {
        match self.ask(call)? {
            Answer::Time(t) => {
                self.time = t;
                Ok(())
            }
            other => Err(format!("the worker answered {other:?}")),
        }
    }

    /// [`Stepper::set`] in the worker.
    pub fn set(&mut self, name: &str, given: Given) -> Result<(), String> {
        self.alive()?;
        self.timed(Call::Set(name.to_owned(), given))
    }

    /// [`Stepper::get_state`] in the worker.
    pub fn get_state(&mut self) -> Result<Vec<u8>, String> {
        self.alive()?;
        match self.ask(Call::GetState)? {
            Answer::State(bytes) => Ok(bytes),
            other => Err(format!("the worker answered {other:?} to get_state")),
        }
    }

    /// [`Stepper::set_state`] in the worker.
    pub fn set_state(&mut self, bytes: Vec<u8>) -> Result<(), String> {
        self.alive()?;
        self.timed(Call::SetState(bytes))?;
        if let Some(pacing) = &mut self.pacing {
            pacing.restart();
        }
        Ok(())
    }

    /// [`Stepper::reset`] in the worker; after a lost worker, a fresh worker's new instance.
    pub fn reset(&mut self, start_values: Option<Vec<(String, WireValue)>>) -> Result<(), String> {
        if self.lost.take().is_some() && start_values.is_none() {
            // The session starts a fresh worker, opened as at the start.
            self.timed(Call::Time)?;
        } else {
            self.timed(Call::Reset(start_values))?;
        }
        if let Some(pacing) = &mut self.pacing {
            pacing.restart();
        }
        Ok(())
    }
}

impl Drop for IsolatedStepper {
    fn drop(&mut self) {
        // Closing the channel ends the supervisor's loop; the session lets its worker go.
        self.requests = None;
        if let Some(supervisor) = self.supervisor.take() {
            let _ = supervisor.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::Dimension;

    fn variable(name: &str, kind: Kind, causality: Causality, variability: Variability) -> Variable {
        Variable {
            name: name.into(),
            value_reference: 0,
            description: None,
            kind,
            causality,
            variability,
            unit: None,
            display_unit: None,
            start: None,
            dimensions: Vec::new(),
        }
    }

    fn description() -> Description {
        Description {
            fmi_version: FmiVersion::Fmi3,
            fmi_version_text: "3.0".into(),
            model_name: "m".into(),
            description: None,
            instantiation_token: "g".into(),
            generation_tool: None,
            co_simulation: None,
            model_exchange: None,
            default_experiment: None,
            units: vec![],
            variables: vec![],
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        }
    }

    /// Values are checked against the variable's type before the FMU sees them: what Python
    /// passes (float, int, bool, str, bytes, lists) and the message for each wrong one.
    #[test]
    fn given_values_are_checked_against_the_type() {
        let d = description();
        let real = variable("x", Kind::Real, Causality::Input, Variability::Continuous);
        assert_eq!(value_of(&d, &real, &Given::Real(1.5)).unwrap(), Value::Real(1.5));
        assert_eq!(value_of(&d, &real, &Given::Integer(2)).unwrap(), Value::Real(2.0));
        assert_eq!(value_of(&d, &real, &Given::Text("2.5".into())).unwrap(), Value::Real(2.5));
        let e = value_of(&d, &real, &Given::Boolean(true)).unwrap_err();
        assert!(e.contains("'x' is a Real") && e.contains("the bool true"), "{e}");
        assert!(value_of(&d, &real, &Given::Real(f64::NAN)).unwrap_err().contains("finite"));
        let int = variable("n", Kind::Integer, Causality::Input, Variability::Discrete);
        assert_eq!(value_of(&d, &int, &Given::Integer(3)).unwrap(), Value::Integer(3));
        assert_eq!(value_of(&d, &int, &Given::Real(3.0)).unwrap(), Value::Integer(3));
        assert!(value_of(&d, &int, &Given::Real(2.5)).unwrap_err().contains("a whole number"));
        assert!(value_of(&d, &int, &Given::Integer(1 << 40)).unwrap_err().contains("out of its range"));
        let flag = variable("b", Kind::Boolean, Causality::Input, Variability::Discrete);
        assert_eq!(value_of(&d, &flag, &Given::Boolean(true)).unwrap(), Value::Boolean(true));
        assert!(value_of(&d, &flag, &Given::Real(1.0)).unwrap_err().contains("True or False"));
        let text = variable("s", Kind::String, Causality::Input, Variability::Discrete);
        assert!(value_of(&d, &text, &Given::Real(1.0)).unwrap_err().contains("a str"));
        let array = Variable { dimensions: vec![Dimension::Fixed(2)], ..real.clone() };
        assert_eq!(
            value_of(&d, &array, &Given::List(vec![Given::Real(1.0), Given::Integer(2)])).unwrap(),
            Value::List(vec![Value::Real(1.0), Value::Real(2.0)])
        );
        assert!(value_of(&d, &array, &Given::Real(1.0)).unwrap_err().contains("is an array"));
        assert!(value_of(&d, &array, &Given::List(vec![Given::Real(1.0)])).unwrap_err().contains("has 2 elements; 1 were given"));
    }

    #[test]
    fn only_inputs_and_tunable_parameters_are_set_while_stepping() {
        assert!(check_settable_between_steps(&variable("u", Kind::Real, Causality::Input, Variability::Continuous)).is_ok());
        assert!(check_settable_between_steps(&variable("k", Kind::Real, Causality::Parameter, Variability::Tunable)).is_ok());
        let fixed = check_settable_between_steps(&variable("m", Kind::Real, Causality::Parameter, Variability::Fixed)).unwrap_err();
        assert!(fixed.contains("before initialization only") && fixed.contains("start_values"), "{fixed}");
        let output = check_settable_between_steps(&variable("y", Kind::Real, Causality::Output, Variability::Continuous)).unwrap_err();
        assert!(output.contains("only inputs and tunable parameters"), "{output}");
    }

    #[test]
    fn pacing_refuses_a_factor_that_is_not_positive() {
        assert!(Pacing::new(0.0).is_err() && Pacing::new(f64::NAN).is_err() && Pacing::new(2.0).is_ok());
    }
}
