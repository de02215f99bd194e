//! The model core: one instance of a model in safe Rust, independent of the FMI version and
//! interface. It owns time, the state vector, the solver, events, the variable-access rules
//! (fixed, tunable, input) and FMU-state capture. Each front end (`fmi2`, later `fmi3`) keeps
//! its own state machine, decides which call is legal when, and translates its C calls into
//! the operations below; a [`Failure`] says whether the instance is still usable.
//!
//! Co-Simulation steps with the toolkit's solver ([`Core::do_step`]); Model Exchange leaves
//! the integration to the importer, who sets time and states and asks for derivatives and
//! event indicators, and the core finds which indicators crossed at an event, runs the model's
//! event handling and its constraint projection (`exchange.rs`).

pub mod derivatives;
mod exchange;
mod interpolation;

pub mod snapshot;
#[cfg(test)]
mod tests;

use ref_cast::RefCast;
use serde::{Deserialize, Serialize};

use crate::logging::{Logger, Status, LOG_EVENTS};
use crate::model::{refresh, Access, BaseType, Causality, EventOutcome, Model, Variability};
use crate::table::{Slot, Table, DIRECT_TIME};

pub use exchange::{EventUpdate, StepCompleted};
pub use interpolation::MAX_ORDER;
use solvers::controls::{Control, Controls};
use solvers::{Advance, Integrator, OdeSystem, SolverError};

/// The value references and orders of the last valid request of one kind (the output
/// derivatives read, the input derivatives set): an importer repeats the same request at every
/// communication step, so its value references and orders, which depend on the variable table
/// alone, are checked once; a request that differs is checked afresh, and one refused is not
/// kept.
#[derive(Default)]
pub(crate) struct Request {
    vrs: Vec<u32>,
    orders: Vec<i32>,
    /// The kept request is one variable's derivatives of orders 1 to k in turn, k up to
    /// [`MAX_ORDER`] (a polynomial coupling's, at every step: Jacobi's extrapolation asks for
    /// three, Gauss-Seidel's interpolation reads one): that variable, whose request is then
    /// compared and served as fixed-size arrays, without a loop per value.
    run: Option<u32>,
}

impl Request {
    /// True when `vrs` and `orders` are the kept request's. Compared element by element: a
    /// request is a few entries, and memcmp's two calls cost more than the comparison.
    #[inline]
    fn is(&self, vrs: &[u32], orders: &[i32]) -> bool {
        // One pass over both.
        self.vrs.len() == vrs.len()
            && self.orders.len() == orders.len()
            && self.vrs.iter().zip(&self.orders).zip(vrs.iter().zip(orders)).all(|((a, o), (b, p))| a == b && o == p)
    }

    /// Keeps `vrs` and `orders`, just checked.
    fn keep(&mut self, vrs: &[u32], orders: &[i32]) {
        self.vrs.clear();
        self.vrs.extend_from_slice(vrs);
        self.orders.clear();
        self.orders.extend_from_slice(orders);
        self.run = match vrs {
            [vr, ..] if RUN_ORDERS.get(..vrs.len()) == Some(orders) && vrs.iter().all(|v| v == vr) => Some(*vr),
            _ => None,
        };
    }

    /// Forgets the kept request (one being checked that may be refused).
    fn forget(&mut self) {
        self.vrs.clear();
        self.orders.clear();
        self.run = None;
    }

    /// The variable of the kept request when it is a [`Request::run`] of `K` orders and `vrs`
    /// and `orders` are that request again (the kept request's, as [`Request::is`] finds, in a
    /// few comparisons).
    #[inline(always)]
    fn run_of<const K: usize>(&self, vrs: &[u32], orders: &[i32]) -> Option<u32> {
        let vr = self.run?;
        let (vrs, orders) = (<&[u32; K]>::try_from(vrs).ok()?, <&[i32; K]>::try_from(orders).ok()?);
        (self.vrs.len() == K && *vrs == [vr; K] && orders[..] == RUN_ORDERS[..K]).then_some(vr)
    }
}

/// The orders of a [`Request::run`]: 1 to k.
const RUN_ORDERS: [i32; MAX_ORDER] = [1, 2, 3];

/// Why an operation failed: the status to return, the message to log, and whether the
/// instance is now broken (the front end then enters its Error state).
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    pub status: Status,
    pub message: String,
    /// The instance can no longer continue (a diverged step, a failed event): only reset or
    /// free are meaningful now. False for refused calls, which change nothing.
    pub broken: bool,
}

impl Failure {
    /// A refused call (`Error`, instance unchanged) with `message`.
    pub fn error(message: impl Into<String>) -> Failure {
        Failure { status: Status::Error, message: message.into(), broken: false }
    }

    /// A failure after which the instance cannot go on.
    pub fn broken(message: impl Into<String>) -> Failure {
        Failure { status: Status::Error, message: message.into(), broken: true }
    }
}

/// Result of a core operation.
pub type CallResult<T = ()> = Result<T, Failure>;

/// The names of the front end's calls that core messages refer to.
#[derive(Debug, Clone, Copy)]
pub struct Names {
    /// The call that sets tolerance, start and stop time (`fmi2SetupExperiment`).
    pub setup: &'static str,
    /// The call that ends initialization (`fmi2ExitInitializationMode`).
    pub exit_initialization: &'static str,
    /// The standard's names of the Real and Integer types (`Real`, `Integer`; FMI 3.0's
    /// `Float64`, `Int32`), for messages.
    pub real: &'static str,
    pub integer: &'static str,
}

impl Names {
    /// The name of `base_type` in this FMI version.
    fn type_name(&self, base_type: BaseType) -> &'static str {
        match base_type {
            BaseType::Real => self.real,
            BaseType::Integer => self.integer,
            BaseType::Boolean => "Boolean",
            BaseType::String => "String",
        }
    }
}

/// More events than this in one communication step means the model is chattering.
const MAX_EVENTS_PER_STEP: usize = 10_000;

/// What to try when a solution diverges, for the messages that say so.
const DIVERGED_ADVICE: &str =
    "the model may be unstable, or the step too large: with euler or rk4 reduce fixed_step, with the adaptive methods reduce tolerance/abs_tol or set max_step";

/// Everything an FMU state captures: enough to continue bit for bit from where it was taken.
#[derive(Clone, Serialize, Deserialize)]
#[serde(bound = "M: Model")]
pub struct State<M> {
    pub(crate) model: M,
    pub(crate) x: Vec<f64>,
    pub(crate) t: f64,
    pub(crate) start_time: f64,
    pub(crate) stop_time: Option<f64>,
    pub(crate) tolerance: Option<f64>,
    pub(crate) controls: Controls,
    pub(crate) integrator: Option<Integrator>,
    /// `x` holds the initial state computed from the current parameters.
    pub(crate) initial_state_ready: bool,
    pub(crate) outputs_dirty: bool,
    /// The model ended the experiment.
    pub(crate) terminated: bool,
    pub(crate) last_successful_time: f64,
    /// The status of the last step (`Ok`, `Discard` or `Error`).
    pub(crate) last_step_status: Status,
    /// Model Exchange: the event indicators' reference values, against which an event finds
    /// the indicators that changed sign (see `exchange.rs`).
    pub(crate) z_ref: Vec<f64>,
    /// Model Exchange: completed integrator steps and derivative evaluations the importer
    /// asked for, reported as `n_steps` and `n_rhs` (the importer's solver does the work).
    pub(crate) exchange_steps: u64,
    pub(crate) exchange_rhs: u64,
    /// Co-Simulation: the inputs that follow polynomials in time over steps, with their
    /// derivatives (`interpolation.rs`); empty while every input is held.
    pub(crate) drives: Vec<interpolation::Drive>,
}

impl<M: Model> State<M> {
    /// Brings the values `Model::outputs` computes up to date with (t, x).
    #[inline]
    fn refresh_outputs(&mut self) {
        if self.outputs_dirty {
            self.model.outputs(self.t, &self.x);
            self.outputs_dirty = false;
        }
    }

    fn new() -> State<M> {
        let mut model = M::default();
        refresh(&mut model);
        State {
            model,
            x: vec![0.0; M::N_STATES],
            t: 0.0,
            start_time: 0.0,
            stop_time: None,
            tolerance: None,
            controls: Controls::default(),
            integrator: None,
            initial_state_ready: false,
            outputs_dirty: true,
            terminated: false,
            last_successful_time: 0.0,
            last_step_status: Status::Ok,
            z_ref: vec![0.0; M::N_EVENT_INDICATORS],
            exchange_steps: 0,
            exchange_rhs: 0,
            drives: Vec::new(),
        }
    }
}

/// A model seen as the solver's ODE system. A transparent wrapper: the solver holds what is
/// in memory a `&M` (made from one by [`System::of`]), so the compiler still knows the stage
/// buffers it writes cannot alias the model's parameters, and can share work between stages.
#[derive(RefCast)]
#[repr(transparent)]
pub struct System<M>(pub M);

impl<M: Model> System<M> {
    /// The model `m` as an ODE system, without a copy. Its `#[derived]` fields must be those of
    /// its parameters ([`crate::Lift::refresh`]); debug builds check it.
    #[inline(always)]
    pub fn of(m: &M) -> &System<M> {
        debug_assert!(
            M::lifting().is_none_or(|l| (l.derived_current)(m)),
            "a parameter changed without Lift::refresh: the derived constants are stale"
        );
        System::ref_cast(m)
    }
}

impl<M: Model> OdeSystem for System<M> {
    #[inline]
    fn dim(&self) -> usize {
        M::N_STATES
    }
    // Always inlined into the solver's stages, to keep values in registers across them.
    #[inline(always)]
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        self.0.derivatives(t, x, dx)
    }
    fn n_event_indicators(&self) -> usize {
        M::N_EVENT_INDICATORS
    }
    fn event_indicators(&self, t: f64, x: &[f64], z: &mut [f64]) {
        Model::event_indicators(&self.0, t, x, z)
    }
}

/// How a communication step ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StepEnd {
    /// The step reached its end.
    Completed,
    /// The model ended the experiment inside the step (a landing, a limit position): time is
    /// where it ended, and the reason was logged with `Discard`.
    EndedEarly,
}

/// How a step that stops at events ended ([`Core::step_to_event`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StepStop {
    /// The step reached its end, or the model ended the experiment inside it.
    Ended(StepEnd),
    /// An event was located at the current time and waits for the model to handle it;
    /// `fired[i]` marks each indicator that changed sign.
    Event { fired: Vec<bool> },
}

/// Where the importer is in the lifecycle, as far as the variable rules care.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Phase {
    /// Before initialization ends: every parameter may be set.
    Initializing,
    /// After initialization (Co-Simulation between steps): only inputs and tunable parameters.
    /// A value that is not finite when read means the FMU's own solution diverged.
    Running,
    /// Model Exchange event mode: as `Running`, but the states are the importer's.
    Event,
    /// Model Exchange continuous-time mode: only continuous-time inputs may be set.
    ContinuousTime,
}

/// A live instance of model `M`.
pub struct Core<M: Model> {
    pub name: String,
    pub logger: Logger,
    names: Names,
    table: Table<M>,
    state: State<M>,
    /// Scratch copy of the state at the start of a step, to restore after a solver failure.
    x_start: Vec<f64>,
    /// The model as its resources made it (`Model::resources`), which a reset returns to.
    fresh: Option<Box<M>>,
    /// Moves on whenever the model's parameters, inputs or discrete state may have changed (a
    /// set, an event, a reset, a restored state): with the time and the states it says when
    /// the cached Jacobian blocks (`jacobians`) are those of the current point.
    version: u64,
    jacobians: derivatives::Jacobians,
    /// The output derivatives' buffers and lifted model, kept from call to call.
    trajectory: derivatives::Trajectory,
    /// The driven inputs as a driven step's stages evaluate them, when there are two or more
    /// (rebuilt at every such step, kept for its buffer; one is built on the stack).
    stages: Vec<interpolation::Stage<M>>,
    /// The last valid `set_input_derivatives` request (its value references and orders).
    input_request: Request,
}

impl<M: Model> Core<M> {
    /// A new instance with the table's start values.
    pub fn new(name: &str, logger: Logger, names: Names) -> Core<M> {
        Core {
            name: name.to_owned(),
            logger,
            names,
            table: Table::new(),
            state: State::new(),
            x_start: vec![0.0; M::N_STATES],
            fresh: None,
            version: 0,
            jacobians: Default::default(),
            trajectory: Default::default(),
            stages: Vec::new(),
            input_request: Request::default(),
        }
    }

    /// Lets the model read its resources from `dir` (at instantiation).
    pub fn load_resources(&mut self, dir: &std::path::Path) -> Result<(), crate::model::ModelError> {
        self.state.model.resources(dir)?;
        self.version += 1;
        self.fresh = Some(Box::new(self.state.model.clone()));
        Ok(())
    }

    /// The instance's variable table.
    pub fn table(&self) -> &Table<M> {
        &self.table
    }

    /// The model's current time.
    pub fn time(&self) -> f64 {
        self.state.t
    }

    /// Back to the start values (logging settings are kept).
    pub fn reset(&mut self) {
        self.version += 1;
        self.state = State::new();
        if let Some(fresh) = &self.fresh {
            self.state.model = (**fresh).clone();
        }
    }

    /// Tolerance, start and stop time of the experiment.
    pub fn setup(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        if !start_time.is_finite() {
            return Err(Failure::error(format!("startTime = {start_time} must be finite")));
        }
        if let Some(tol) = tolerance {
            if !(tol.is_finite() && tol > 0.0) {
                return Err(Failure::error(format!("tolerance = {tol} must be a finite number greater than zero")));
            }
        }
        if let Some(stop) = stop_time {
            if !(stop.is_finite() && stop >= start_time) {
                return Err(Failure::error(format!("stopTime = {stop} must be finite and not before startTime = {start_time}")));
            }
        }
        let s = &mut self.state;
        s.start_time = start_time;
        s.t = start_time;
        s.stop_time = stop_time;
        s.tolerance = tolerance;
        self.anchor_inputs(start_time);
        Ok(())
    }

    /// Computes the initial state from the current parameters (once per parameter change).
    fn ensure_initial_state(&mut self) -> CallResult {
        if !self.state.initial_state_ready {
            let mut x = vec![0.0; M::N_STATES];
            // The declared ranges first, then what only the model can check.
            let model = &mut self.state.model;
            refresh(model);
            crate::model::check_ranges(model)
                .and_then(|()| model.initial_state(&mut x))
                .map_err(|e| Failure::error(format!("the parameters were refused: {e}")))?;
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(Failure::error(format!("the initial state {i} is {}: check the parameters", x[i])));
            }
            self.state.x = x;
            self.state.initial_state_ready = true;
            self.version += 1;
            self.state.outputs_dirty = true;
        }
        Ok(())
    }

    /// Ends initialization: checks parameters and solver controls, starts the solver.
    pub fn start(&mut self) -> CallResult {
        self.ensure_initial_state()?;
        let rtol = self.state.tolerance.unwrap_or(M::info().tolerance);
        let settings = self.state.controls.settings(rtol).map_err(Failure::error)?;
        self.state.t = self.state.start_time;
        if let Some(bad) = self.first_non_finite() {
            return Err(Failure::error(format!("the parameters give {bad} at the start, which is not finite: check the parameters")));
        }
        let mut integrator = Integrator::new(settings, M::N_STATES, M::N_EVENT_INDICATORS);
        // No step beyond the experiment's end: the right-hand side is not evaluated past it.
        integrator.set_stop_time(self.state.stop_time);
        self.state.integrator = Some(integrator);
        self.state.last_successful_time = self.state.t;
        Ok(())
    }

    /// Before a read during initialization the state is first computed from the parameters.
    /// The reads then run `Model::outputs` at the first variable it computes, at most once per
    /// step, so reading states, parameters or inputs (what a sweep's metrics mostly read)
    /// costs no model evaluation.
    fn prepare_read(&mut self, phase: Phase) -> CallResult {
        if phase == Phase::Initializing {
            self.ensure_initial_state()?;
        }
        Ok(())
    }

    /// Refuses `vr` for a call on `kind` variables, naming the variable when `vr` is one of
    /// another type (the usual mistake: a value reference from the wrong list).
    fn unknown(&self, vr: u32, kind: BaseType, settable: bool) -> Failure {
        let wanted = self.names.type_name(kind);
        let wanted = match (settable, wanted.starts_with('I')) {
            (true, _) => format!("a settable {wanted}"),
            (false, true) => format!("an {wanted}"),
            (false, false) => format!("a {wanted}"),
        };
        match self.table.row(vr) {
            Some(row) => Failure::error(format!(
                "value reference {vr} is '{}' of type {}, not {wanted} variable",
                row.name,
                self.names.type_name(row.base_type)
            )),
            None => Failure::error(format!("value reference {vr} is not {wanted} variable of this FMU")),
        }
    }

    fn control_value(&self, c: Control) -> f64 {
        let s = &self.state;
        let counters = s.integrator.as_ref().map_or((s.exchange_steps, s.exchange_rhs), |i| (i.n_steps(), i.n_rhs()));
        match c {
            Control::NSteps => counters.0 as f64,
            Control::NRhs => counters.1 as f64,
            settable => self.state.controls.get(settable).expect("a settable control has a value"),
        }
    }

    /// The read a sweep makes at every communication point, when it names states and the time
    /// only: writes the values and gives true when every reference is one of those and every
    /// value is finite; else false, and the caller takes [`Core::get_real`], which writes every
    /// value again and names the problem. Nothing here can panic, so the front ends call it
    /// before their unwinding guard: with no guard and a small frame, reading two states costs
    /// a third of the checked path.
    #[inline(always)]
    pub fn read_states(&self, vrs: &[u32], values: &mut [f64]) -> bool {
        // Before initialization ends the state may still have to be computed.
        if !self.state.initial_state_ready {
            return false;
        }
        let mut all_finite = true;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let Some(&code) = self.table.direct.get(*vr as usize) else { return false };
            // The codes of the time and of other rows are beyond every state index.
            *value = match self.state.x.get(code as usize) {
                Some(&x) => x,
                None if code == DIRECT_TIME => self.state.t,
                None => return false,
            };
            all_finite &= value.is_finite();
        }
        all_finite
    }

    /// Brings the outputs up to date before row `i` is read, when `Model::outputs` computes it
    /// (from the pass of the output derivatives when a master asks for them at every step:
    /// [`Core::shared_outputs`]).
    #[inline(always)]
    fn refresh_outputs_for(&mut self, i: usize) {
        if self.state.outputs_dirty && self.table.computed.get(i) == Some(&true) {
            if self.trajectory.shares_outputs {
                self.shared_outputs();
            } else {
                self.trajectory.current = false;
                self.state.refresh_outputs();
            }
        }
    }

    /// Reads Real variables (see `Core::prepare_read`). A value that is not finite is
    /// refused, naming it; after initialization that breaks the instance. Outputs are computed
    /// at the first one read, derivatives at the first der(x).
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64], phase: Phase) -> CallResult {
        self.prepare_read(phase)?;
        let mut dx: Option<Vec<f64>> = None;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            self.refresh_outputs_for(i);
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::State(k))) => self.state.x[*k],
                Some(Slot::Model(Access::Real { get, .. })) => get(&self.state.model),
                Some(Slot::Control(c)) if !c.is_integer() => self.control_value(*c),
                Some(Slot::Time) => self.state.t,
                Some(Slot::Derivative(k)) => {
                    let State { model, t, x, .. } = &self.state;
                    dx.get_or_insert_with(|| {
                        let mut dx = vec![0.0; M::N_STATES];
                        model.derivatives(*t, x, &mut dx);
                        dx
                    })[*k]
                }
                _ => return Err(self.unknown(*vr, BaseType::Real, false)),
            };
        }
        if values.iter().take(vrs.len()).all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.non_finite(vrs, values, phase))
        }
    }

    /// The refusal of a read that gave a value that is not finite (the first of `values`).
    /// Never a silent NaN or inf. The solver refuses non-finite states during a step, but
    /// outputs are computed lazily, in the reads: one that overflowed means the solution
    /// diverged, and the instance is broken as after a failed step.
    #[cold]
    #[inline(never)]
    fn non_finite(&self, vrs: &[u32], values: &[f64], phase: Phase) -> Failure {
        let (vr, value) = vrs.iter().zip(values.iter()).find(|(_, v)| !v.is_finite()).expect("a value is not finite");
        let name = self.table.rows[*vr as usize].name;
        let t = self.state.t;
        let message = format!("{name} = {value} at t = {t} s is not finite: the solution diverged ({DIVERGED_ADVICE})");
        // While initializing, the parameters can still be corrected: the instance is not broken.
        // Under Model Exchange the states are the importer's, who may set others.
        match phase {
            Phase::Initializing | Phase::Event | Phase::ContinuousTime => Failure::error(message),
            Phase::Running => Failure::broken(format!("{message}; the instance is now in the Error state")),
        }
    }

    /// Reads Integer variables.
    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32], phase: Phase) -> CallResult {
        self.prepare_read(phase)?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            self.refresh_outputs_for(i);
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::Integer { get, .. })) => get(&self.state.model),
                // Counters saturate rather than wrap: FMI integers are 32-bit.
                Some(Slot::Control(c)) if c.is_integer() => self.control_value(*c).min(i32::MAX as f64) as i32,
                _ => return Err(self.unknown(*vr, BaseType::Integer, false)),
            };
        }
        Ok(())
    }

    /// Reads Boolean variables.
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool], phase: Phase) -> CallResult {
        self.prepare_read(phase)?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            self.refresh_outputs_for(i);
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::Boolean { get, .. })) => get(&self.state.model),
                _ => return Err(self.unknown(*vr, BaseType::Boolean, false)),
            };
        }
        Ok(())
    }

    /// Reads String variables: each value copied out, so the front end owns what it hands the
    /// importer (the model may change its own strings at the next call).
    pub fn get_string(&mut self, vrs: &[u32], phase: Phase) -> CallResult<Vec<String>> {
        self.prepare_read(phase)?;
        let mut values = Vec::with_capacity(vrs.len());
        for vr in vrs {
            let i = *vr as usize;
            self.refresh_outputs_for(i);
            match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::String { get, .. })) => {
                    values.push(get(&self.state.model).to_owned());
                }
                _ => return Err(self.unknown(*vr, BaseType::String, false)),
            }
        }
        Ok(values)
    }

    /// Sets String variables (all or nothing, like [`Core::set_real`]). A value with a NUL
    /// character is refused: it could not be handed back through C.
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str], phase: Phase, state: &str) -> CallResult {
        for (vr, value) in vrs.iter().zip(values.iter()) {
            let i = self.settable(*vr, phase, state)?;
            if !matches!(self.table.rows[i].slot, Slot::Model(Access::String { set: Some(_), .. })) {
                return Err(self.unknown(*vr, BaseType::String, true));
            }
            if value.contains('\0') {
                return Err(Failure::error(format!(
                    "{} = {value:?} refused: a String value cannot hold a NUL character",
                    self.table.rows[i].name
                )));
            }
        }
        let mut changed = false;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            if let Slot::Model(Access::String { get, set: Some(set) }) = &self.table.rows[*vr as usize].slot {
                changed |= get(&self.state.model) != *value;
                set(&mut self.state.model, value);
            }
        }
        self.after_set(phase, changed);
        Ok(())
    }

    /// Checks that the row of `vr` may be set now (the fixed/tunable/input rules); returns its
    /// index. `state` names the front end's state for the message.
    fn settable(&self, vr: u32, phase: Phase, state: &str) -> CallResult<usize> {
        let row = self.table.row(vr).ok_or_else(|| Failure::error(format!("value reference {vr} is not a variable of this FMU")))?;
        if row.variability == Variability::Constant {
            return Err(Failure::error(format!("'{}' is a constant and can never be set", row.name)));
        }
        if !row.is_settable() {
            let what = match row.causality {
                Causality::Output => "an output",
                Causality::CalculatedParameter => "a calculated parameter",
                Causality::Local => "a local variable",
                _ => "not settable",
            };
            return Err(Failure::error(format!("'{}' is {what} and cannot be set", row.name)));
        }
        if phase == Phase::ContinuousTime {
            if row.causality == Causality::Input && row.variability == Variability::Continuous {
                return Ok(vr as usize);
            }
            return Err(Failure::error(format!(
                "'{}' can be set in state {state} only if it is a continuous-time input: enter event mode first{}",
                row.name,
                if row.causality == Causality::Parameter && row.variability != Variability::Tunable {
                    format!(" (and it is a fixed parameter, settable only before {})", self.names.exit_initialization)
                } else {
                    String::new()
                }
            )));
        }
        let allowed = match (row.causality, row.variability) {
            (Causality::Input, _) => true,
            (_, Variability::Tunable) => true,
            _ => phase == Phase::Initializing,
        };
        if !allowed {
            return Err(Failure::error(format!(
                "parameter '{}' is fixed and can be set only before {} (now in state {state})",
                row.name, self.names.exit_initialization
            )));
        }
        Ok(vr as usize)
    }

    /// Records that settable values were set; `changed`: at least one to a value other than
    /// the one it had (compared bit for bit).
    fn after_set(&mut self, phase: Phase, changed: bool) {
        self.version += 1;
        if phase == Phase::Initializing {
            self.state.initial_state_ready = false;
        }
        if changed {
            // What the model derives from its parameters follows them (a tunable one, or any
            // before initialization ends).
            refresh(&mut self.state.model);
        }
        self.state.outputs_dirty = true;
        // A new input or parameter value changes the right-hand side from this communication
        // point on: the solver's pending step (computed with the old value) and its cached
        // derivative are thrown away, and integration restarts here. Setting the value it
        // already had (an importer that sets every input at every step) changes nothing.
        if changed {
            if let Some(integrator) = self.state.integrator.as_mut() {
                integrator.invalidate();
            }
        }
    }

    /// Sets Real variables. Non-finite values are refused at once, naming the variable. All or
    /// nothing: every value is checked before any is stored, so a refused call changes nothing.
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64], phase: Phase, state: &str) -> CallResult {
        for (vr, value) in vrs.iter().zip(values.iter()) {
            let i = self.settable(*vr, phase, state)?;
            let name = self.table.rows[i].name;
            if !value.is_finite() {
                return Err(Failure::error(format!("{name} = {value} refused: the value must be finite")));
            }
            match &self.table.rows[i].slot {
                Slot::Model(Access::Real { set: Some(_), .. }) => {}
                Slot::Control(c) if !c.is_integer() => c.check(*value).map_err(Failure::error)?,
                _ => return Err(self.unknown(*vr, BaseType::Real, true)),
            }
        }
        let mut changed = false;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            match &self.table.rows[*vr as usize].slot {
                Slot::Model(Access::Real { get, set: Some(set) }) => {
                    changed |= get(&self.state.model).to_bits() != value.to_bits();
                    set(&mut self.state.model, *value);
                    if !self.state.drives.is_empty() {
                        self.input_set(*vr as usize, *value);
                    }
                }
                Slot::Control(c) => {
                    changed |= self.state.controls.get(*c).map(f64::to_bits) != Some(value.to_bits());
                    c.store(&mut self.state.controls, *value)
                }
                _ => unreachable!("checked above"),
            }
        }
        self.after_set(phase, changed);
        Ok(())
    }

    /// Sets Integer variables (all or nothing, like [`Core::set_real`]).
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32], phase: Phase, state: &str) -> CallResult {
        for (vr, value) in vrs.iter().zip(values.iter()) {
            let i = self.settable(*vr, phase, state)?;
            match &self.table.rows[i].slot {
                Slot::Model(Access::Integer { set: Some(_), .. }) => {}
                Slot::Control(c) if c.is_integer() => c.check(f64::from(*value)).map_err(Failure::error)?,
                _ => return Err(self.unknown(*vr, BaseType::Integer, true)),
            }
        }
        let mut changed = false;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            match &self.table.rows[*vr as usize].slot {
                Slot::Model(Access::Integer { get, set: Some(set) }) => {
                    changed |= get(&self.state.model) != *value;
                    set(&mut self.state.model, *value)
                }
                Slot::Control(c) => {
                    changed |= self.state.controls.get(*c) != Some(f64::from(*value));
                    c.store(&mut self.state.controls, f64::from(*value))
                }
                _ => unreachable!("checked above"),
            }
        }
        self.after_set(phase, changed);
        Ok(())
    }

    /// Sets Boolean variables (all or nothing, like [`Core::set_real`]).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool], phase: Phase, state: &str) -> CallResult {
        for vr in vrs {
            let i = self.settable(*vr, phase, state)?;
            if !matches!(self.table.rows[i].slot, Slot::Model(Access::Boolean { set: Some(_), .. })) {
                return Err(self.unknown(*vr, BaseType::Boolean, true));
            }
        }
        let mut changed = false;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            if let Slot::Model(Access::Boolean { get, set: Some(set) }) = &self.table.rows[*vr as usize].slot {
                changed |= get(&self.state.model) != *value;
                set(&mut self.state.model, *value);
            }
        }
        self.after_set(phase, changed);
        Ok(())
    }

    /// Computes the outputs at the current time and state (so a read right after costs
    /// nothing more) and names the first state or computed Real that is not finite:
    /// `Some("name = value")`. Parameters and inputs are finite by construction.
    fn first_non_finite(&mut self) -> Option<String> {
        let State { model, t, x, .. } = &mut self.state;
        model.outputs(*t, x);
        self.state.outputs_dirty = false;
        self.trajectory.current = false;
        let (model, x) = (&self.state.model, &self.state.x);
        self.table.rows.iter().zip(&self.table.computed).find_map(|(row, &computed)| {
            let value = match &row.slot {
                Slot::Model(Access::State(i)) => x[*i],
                Slot::Model(Access::Real { get, .. }) if computed => get(model),
                _ => return None,
            };
            (!value.is_finite()).then(|| format!("{} = {value}", row.name))
        })
    }

    /// The message for a step whose result is not finite.
    fn diverged(bad: &str, t0: f64, t_end: f64) -> String {
        format!("the solution diverged between t = {t0} and t = {t_end}: {bad} is not finite ({DIVERGED_ADVICE})")
    }

    /// Ends the experiment early at the current time (`Discard`, terminated); a broken
    /// instance instead if the state or the outputs there are not finite.
    #[cold]
    #[inline(never)]
    fn stop_early(&mut self, t_start: f64, reason: &str) -> CallResult<StepEnd> {
        if let Some(bad) = self.first_non_finite() {
            let message = Self::diverged(&bad, t_start, self.state.t);
            return Err(self.fail_step(t_start, message));
        }
        self.state.terminated = true;
        self.state.last_successful_time = self.state.t;
        self.state.last_step_status = Status::Discard;
        let msg = format!("the simulation ended at t = {} s: {reason}", self.state.t);
        self.logger.status(Status::Discard, &msg);
        Ok(StepEnd::EndedEarly)
    }

    /// A computation failed inside a step: restore the state at the step's start (so outputs
    /// stay finite); the instance is broken.
    #[cold]
    #[inline(never)]
    fn fail_step(&mut self, t_start: f64, message: String) -> Failure {
        self.state.x.copy_from_slice(&self.x_start);
        self.state.t = t_start;
        self.state.outputs_dirty = true;
        self.state.last_step_status = Status::Error;
        Failure::broken(message)
    }

    /// The step's checks of its arguments: `current` must be the FMU's time (to rounding) and
    /// `h` finite and not negative.
    #[cold]
    #[inline(never)]
    fn check_step_arguments(&self, current: f64, h: f64) -> CallResult {
        let t0 = self.state.t;
        if !(current.is_finite() && (current - t0).abs() <= 1e-9 * t0.abs().max(1.0)) {
            return Err(Failure::error(format!("currentCommunicationPoint = {current} does not match the FMU's time {t0}")));
        }
        if !(h.is_finite() && h >= 0.0) {
            return Err(Failure::error(format!("communicationStepSize = {h} must be finite and not negative")));
        }
        Ok(())
    }

    #[cold]
    #[inline(never)]
    fn past_stop(&self, t_end: f64, stop: f64) -> Failure {
        Failure::error(format!("the step to t = {t_end} would pass the stop time {stop} set in {}", self.names.setup))
    }

    /// The rest of the step from `t0` to `t_end` after the solver's first call stopped short of
    /// `t_end` with `first` (an event, or a failure): events are handled and the solver called
    /// again until `t_end`. `Some(end)` when the step ends early there.
    #[inline(never)]
    fn continue_after(&mut self, first: Result<Advance, SolverError>, t0: f64, t_end: f64) -> CallResult<Option<StepEnd>> {
        let mut outcome = first;
        let mut events = 0usize;
        loop {
            match outcome {
                Ok(Advance::Reached) => return Ok(None),
                Ok(Advance::Event { fired }) => {
                    events += 1;
                    if let Some(end) = self.handle_event(t0, t_end, events, &fired)? {
                        return Ok(Some(end));
                    }
                }
                Err(e) => return Err(self.fail_step(t0, format!("the solver failed between t = {t0} and t = {t_end}: {e}"))),
            }
            if self.state.t >= t_end {
                return Ok(None);
            }
            outcome = self.advance(t_end);
        }
    }

    /// The model's response to the `events`-th event of the step from `t0` to `t_end`, at the
    /// current time: `Some(end)` when it ends the step (and the experiment) there. Out of
    /// line: most steps have no event, and they need not pay for setting this up.
    #[inline(never)]
    fn handle_event(&mut self, t0: f64, t_end: f64, events: usize, fired: &[bool]) -> CallResult<Option<StepEnd>> {
        if events > MAX_EVENTS_PER_STEP {
            let msg = format!("more than {MAX_EVENTS_PER_STEP} events between t = {t0} and t = {t_end}: the model is chattering");
            return Err(self.fail_step(t0, msg));
        }
        self.version += 1;
        let State { model, x, t, integrator, .. } = &mut self.state;
        let te = *t;
        let outcome = model.on_event(te, x, fired);
        if let Some(integrator) = integrator.as_mut() {
            integrator.invalidate();
        }
        if self.logger.wants(LOG_EVENTS) {
            let which: Vec<usize> = fired.iter().enumerate().filter(|(_, f)| **f).map(|(i, _)| i).collect();
            self.logger.log(Status::Ok, LOG_EVENTS, &format!("event at t = {te} s (indicators {which:?})"));
        }
        match outcome {
            Ok(EventOutcome::Continue | EventOutcome::Unchanged) => Ok(None),
            Ok(EventOutcome::Stop { reason }) => self.stop_early(t0, &reason).map(Some),
            Err(e) => Err(self.fail_step(t0, format!("the model failed at the event at t = {te}: {e}"))),
        }
    }

    /// One communication step from `current` over `h`, handling events: `Completed`, or
    /// `EndedEarly` when the model ended the experiment inside it. Always inlined into the
    /// front ends' DoStep (one frame fewer per communication step); events and failures
    /// continue out of line.
    #[inline(always)]
    pub fn do_step(&mut self, current: f64, h: f64) -> CallResult<StepEnd> {
        // The usual call, at the FMU's own time with a positive finite step, passes one test;
        // anything else gets the full checks (out of line, with their messages).
        if !(current == self.state.t && h > 0.0 && h <= f64::MAX) {
            self.check_step_arguments(current, h)?;
            if h == 0.0 {
                return Ok(StepEnd::Completed);
            }
        }
        let t0 = self.state.t;
        let t_end = current + h;
        if let Some(stop) = self.state.stop_time {
            // The plain test first: a step that ends by the stop time needs no allowance.
            if t_end > stop && t_end > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(self.past_stop(t_end, stop));
            }
        }
        // The state has M::N_STATES values; copying that constant length compiles to a few
        // moves instead of a call to memmove (measurable at one call per communication step).
        let n = M::N_STATES;
        self.x_start[..n].copy_from_slice(&self.state.x[..n]);
        let mut reached = false;
        if self.state.t < t_end {
            // The usual step: one call of the solver that reaches t_end. Events and failures
            // continue out of line.
            match self.advance(t_end) {
                Ok(Advance::Reached) => reached = true,
                other => {
                    if let Some(end) = self.continue_after(other, t0, t_end)? {
                        return Ok(end);
                    }
                }
            }
        }
        self.finish_step(t0, t_end, reached)
    }

    /// The solver's advance from the current time towards `t_end`: the model as it is, or,
    /// with inputs driven by polynomials, the model with its inputs at each stage's time.
    #[inline(always)]
    fn advance(&mut self, t_end: f64) -> Result<Advance, SolverError> {
        if !self.state.drives.is_empty() {
            return self.advance_driven(t_end);
        }
        let State { model, x, t, integrator, .. } = &mut self.state;
        let integrator = integrator.as_mut().expect("the integrator exists once started");
        integrator.advance(System::of(&*model), t, x, t_end)
    }

    /// [`Core::advance`] with driven inputs, which are left at their values at the time reached.
    #[inline(never)]
    fn advance_driven(&mut self, t_end: f64) -> Result<Advance, SolverError> {
        let rows = &self.table.rows;
        // The usual one driven input's stage on the stack, without the vector's bookkeeping.
        let one;
        let stages: &[interpolation::Stage<M>] = match &self.state.drives[..] {
            [drive] => {
                one = [interpolation::Stage::of(drive, rows)];
                &one
            }
            drives => {
                self.stages.clear();
                self.stages.extend(drives.iter().map(|d| interpolation::Stage::of(d, rows)));
                &self.stages
            }
        };
        let State { model, x, t, integrator, .. } = &mut self.state;
        let integrator = integrator.as_mut().expect("the integrator exists once started");
        let outcome = integrator.advance(&interpolation::Driven::new(model, stages), t, x, t_end);
        // The inputs at the time reached, from the stages (`Drive::at`'s numbers, without
        // finding the setters and dividing the coefficients again): at t_end when the step
        // reached it, where `finish_step` then lands, told so by its caller.
        let reached = if matches!(outcome, Ok(Advance::Reached)) { t_end } else { self.state.t };
        interpolation::set_inputs_at(&mut self.state.model, stages, reached);
        self.state.outputs_dirty = true;
        outcome
    }

    /// The end of a communication step that reached `t_end`: time lands exactly on it, the
    /// model's communication-point work (a constraint projection) runs, and the step's status
    /// is recorded. Shared by [`Core::do_step`] and [`Core::step_to_event`]. `inputs_at_end`:
    /// the step's last call of the solver reached `t_end`, and nothing ran since, so the driven
    /// inputs are at their values there already ([`Core::advance_driven`]).
    #[inline(always)]
    fn finish_step(&mut self, t0: f64, t_end: f64, inputs_at_end: bool) -> CallResult<StepEnd> {
        // Land exactly on the communication point whatever the solver's rounding.
        self.state.t = t_end;
        if !inputs_at_end && !self.state.drives.is_empty() {
            self.sync_inputs();
        }
        // A projection here that changes x is seen by the integrator at the next step, which
        // compares x with the state it left and then drops its cached derivative.
        let State { model, x, t, .. } = &mut self.state;
        let outcome = model.communication_point(*t, x);
        self.state.outputs_dirty = true;
        match outcome {
            Ok(continued @ (EventOutcome::Continue | EventOutcome::Unchanged)) => {
                // A model's own communication-point work may change its fields: what was
                // derived from them (the lift kept for output derivatives) is stale.
                if matches!(continued, EventOutcome::Continue) {
                    self.version += 1;
                }
                // The solver checks the states; outputs (which can overflow first, an energy
                // ~ omega^2) are computed only when read, and get_real refuses a non-finite one.
                self.state.last_successful_time = self.state.t;
                self.state.last_step_status = Status::Ok;
                Ok(StepEnd::Completed)
            }
            Ok(EventOutcome::Stop { reason }) => {
                // The model's work may have changed its fields before it ended the experiment.
                self.version += 1;
                self.stop_early(t0, &reason)
            }
            Err(e) => Err(self.fail_step(t0, format!("the model failed at t = {t_end}: {e}"))),
        }
    }

    /// A communication step from `current` over `h` that stops at the first located event
    /// (for FMI 3.0's Event Mode and early return; either version could use it): the step
    /// reaches `t_end` ([`StepStop::Ended`], as [`Core::do_step`] ends it), or time and states
    /// are at the event, before the model has handled it ([`StepStop::Event`]); the caller then
    /// hands `fired` to [`Core::handle_located_event`] and steps on from there. No
    /// communication-point work runs at the event, so the arithmetic is that of `do_step`,
    /// which handles the event at the same place and goes on.
    pub fn step_to_event(&mut self, current: f64, h: f64) -> CallResult<StepStop> {
        if !(current == self.state.t && h > 0.0 && h <= f64::MAX) {
            self.check_step_arguments(current, h)?;
            if h == 0.0 {
                return Ok(StepStop::Ended(StepEnd::Completed));
            }
        }
        let t0 = self.state.t;
        let t_end = current + h;
        if let Some(stop) = self.state.stop_time {
            if t_end > stop && t_end > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(self.past_stop(t_end, stop));
            }
        }
        let n = M::N_STATES;
        self.x_start[..n].copy_from_slice(&self.state.x[..n]);
        let mut reached = false;
        if self.state.t < t_end {
            match self.advance(t_end) {
                Ok(Advance::Reached) => reached = true,
                // Out of line, as in `do_step`: most steps reach t_end.
                other => return self.stopped_short(other, t0, t_end),
            }
        }
        self.finish_step(t0, t_end, reached).map(StepStop::Ended)
    }

    /// [`Core::step_to_event`] when the solver stopped at an event, or failed.
    #[inline(never)]
    fn stopped_short(&mut self, outcome: Result<Advance, SolverError>, t0: f64, t_end: f64) -> CallResult<StepStop> {
        match outcome {
            Ok(Advance::Reached) => self.finish_step(t0, t_end, true).map(StepStop::Ended),
            Ok(Advance::Event { fired }) => {
                self.state.outputs_dirty = true;
                self.state.last_successful_time = self.state.t;
                self.state.last_step_status = Status::Ok;
                Ok(StepStop::Event { fired })
            }
            Err(e) => Err(self.fail_step(t0, format!("the solver failed between t = {t0} and t = {t_end}: {e}"))),
        }
    }

    /// The model's response to the event [`Core::step_to_event`] stopped at (`fired`: the
    /// indicators that changed sign), at the current time: `Some(EndedEarly)` when the model
    /// ends the experiment there (logged as `do_step` logs it).
    pub fn handle_located_event(&mut self, fired: &[bool]) -> CallResult<Option<StepEnd>> {
        let t = self.state.t;
        // A failure restores the state before the event.
        let n = M::N_STATES;
        self.x_start[..n].copy_from_slice(&self.state.x[..n]);
        let end = self.handle_event(t, t, 1, fired)?;
        self.state.outputs_dirty = true;
        Ok(end)
    }

    /// The status of the last step.
    pub fn last_step_status(&self) -> Status {
        self.state.last_step_status
    }

    /// The time the last successful step reached.
    pub fn last_successful_time(&self) -> f64 {
        self.state.last_successful_time
    }

    /// True once the model ended the experiment.
    pub fn terminated(&self) -> bool {
        self.state.terminated
    }

    /// A copy of everything needed to continue from here, the solver's pending step included
    /// (so a rollback, or the copy serialized and restored in another instance, continues bit
    /// for bit as this instance does).
    pub fn capture(&self) -> State<M> {
        self.state.clone()
    }

    /// Continues from a captured state: this instance's pending step gives way to the one the
    /// state captured.
    pub fn restore(&mut self, state: &State<M>) {
        self.version += 1;
        self.state = state.clone();
    }
}
