//! One FMU instance in safe Rust: the state machine, variable access, stepping with events,
//! and FMU state capture. The C glue (`ffi`) only converts pointers and statuses around it.

use serde::{Deserialize, Serialize};

use crate::controls::{Control, Controls};
use crate::logging::{Logger, Status, LOG_CALLS, LOG_EVENTS};
use crate::model::{Access, Causality, EventOutcome, Model, Variability};
use crate::solver::{Advance, Integrator, OdeSystem, SolverError};
use crate::state_machine::{Call, FmiState};
use crate::table::{Slot, Table};

/// Why a call failed: the status to return and the message to log.
#[derive(Debug, Clone, PartialEq)]
pub struct Failure {
    pub status: Status,
    pub message: String,
}

impl Failure {
    /// An `fmi2Error` with `message`.
    pub fn error(message: impl Into<String>) -> Failure {
        Failure { status: Status::Error, message: message.into() }
    }
}

/// Result of an instance call.
pub type CallResult<T = ()> = Result<T, Failure>;

/// More events than this in one communication step means the model is chattering.
const MAX_EVENTS_PER_STEP: usize = 10_000;

/// What to try when a solution diverges, for the messages that say so.
const DIVERGED_ADVICE: &str =
    "the model may be unstable, or the step too large: with euler or rk4 reduce fixed_step, with dopri5 reduce tolerance/abs_tol";

/// Everything an FMU state captures: enough to continue bit for bit from where it was taken.
#[derive(Clone, Serialize, Deserialize)]
#[serde(bound = "M: Model")]
pub struct Core<M> {
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
    /// The model ended the experiment (`fmi2Terminated` status).
    pub(crate) terminated: bool,
    pub(crate) last_successful_time: f64,
    pub(crate) last_step_status: i32,
    /// The state-machine state when the FMU state was captured.
    pub(crate) phase: FmiState,
}

impl<M: Model> Core<M> {
    /// Brings the values `Model::outputs` computes up to date with (t, x).
    #[inline]
    fn refresh_outputs(&mut self) {
        if self.outputs_dirty {
            self.model.outputs(self.t, &self.x);
            self.outputs_dirty = false;
        }
    }

    fn new() -> Core<M> {
        Core {
            model: M::default(),
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
            last_step_status: Status::Ok as i32,
            phase: FmiState::Instantiated,
        }
    }
}

/// Every model is an ODE system for the solver. The solver then holds `&M` itself rather than
/// a wrapper around it, so the compiler knows the stage buffers it writes cannot alias the
/// model's parameters, and can share work between stages.
impl<M: Model> OdeSystem for M {
    #[inline]
    fn dim(&self) -> usize {
        M::N_STATES
    }
    // Always inlined into the solver's stages, to keep values in registers across them.
    #[inline(always)]
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        self.derivatives(t, x, dx)
    }
    fn n_event_indicators(&self) -> usize {
        M::N_EVENT_INDICATORS
    }
    fn event_indicators(&self, t: f64, x: &[f64], z: &mut [f64]) {
        Model::event_indicators(self, t, x, z)
    }
}

/// A live FMU instance of model `M`.
pub struct Instance<M: Model> {
    pub name: String,
    pub logger: Logger,
    table: Table<M>,
    state: FmiState,
    core: Core<M>,
    /// Scratch copy of the state at the start of a step, to restore after a solver failure.
    x_start: Vec<f64>,
}

impl<M: Model> Instance<M> {
    /// A new instance in state Instantiated with the table's start values.
    pub fn new(name: &str, logger: Logger) -> Instance<M> {
        Instance { name: name.to_owned(), logger, table: Table::new(), state: FmiState::Instantiated, core: Core::new(), x_start: vec![0.0; M::N_STATES] }
    }

    /// The current state-machine state.
    pub fn state(&self) -> FmiState {
        self.state
    }

    /// The instance's variable table.
    pub fn table(&self) -> &Table<M> {
        &self.table
    }

    /// The model's current time.
    pub fn time(&self) -> f64 {
        self.core.t
    }

    /// Refuses `call` when the state machine does not allow it now.
    #[inline]
    pub fn check(&self, call: Call) -> CallResult {
        if call.is_allowed_in(self.state) {
            Ok(())
        } else {
            Err(Self::illegal(call, self.state))
        }
    }

    // Out of line: every call passes `check`, and its message would otherwise be set up on
    // the hot path of fmi2DoStep and fmi2GetReal.
    #[cold]
    #[inline(never)]
    fn illegal(call: Call, state: FmiState) -> Failure {
        Failure::error(format!("{} is not allowed in state {}: illegal call sequence", call.name(), state.name()))
    }

    /// Logs a call in the `logCalls` category (formatting only when someone listens).
    pub fn trace(&mut self, call: Call, args: impl FnOnce() -> String) {
        if self.logger.wants(LOG_CALLS) {
            let msg = format!("{}({})", call.name(), args());
            self.logger.log(Status::Ok, LOG_CALLS, &msg);
        }
    }

    /// `fmi2SetupExperiment`.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        self.check(Call::SetupExperiment)?;
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
        self.core.start_time = start_time;
        self.core.t = start_time;
        self.core.stop_time = stop_time;
        self.core.tolerance = tolerance;
        Ok(())
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> CallResult {
        self.check(Call::EnterInitializationMode)?;
        self.state = FmiState::InitializationMode;
        Ok(())
    }

    /// Computes the initial state from the current parameters (once per parameter change).
    fn ensure_initial_state(&mut self) -> CallResult {
        if !self.core.initial_state_ready {
            let mut x = vec![0.0; M::N_STATES];
            self.core.model.initial_state(&mut x).map_err(|e| Failure::error(format!("the parameters were refused: {e}")))?;
            if let Some(i) = x.iter().position(|v| !v.is_finite()) {
                return Err(Failure::error(format!("the initial state {i} is {}: check the parameters", x[i])));
            }
            self.core.x = x;
            self.core.initial_state_ready = true;
            self.core.outputs_dirty = true;
        }
        Ok(())
    }

    /// `fmi2ExitInitializationMode`: checks parameters and solver controls, starts the solver.
    pub fn exit_initialization_mode(&mut self) -> CallResult {
        self.check(Call::ExitInitializationMode)?;
        self.ensure_initial_state()?;
        let rtol = self.core.tolerance.unwrap_or(M::info().tolerance);
        let settings = self.core.controls.settings(rtol).map_err(Failure::error)?;
        self.core.t = self.core.start_time;
        if let Some(bad) = self.first_non_finite() {
            return Err(Failure::error(format!("the parameters give {bad} at the start, which is not finite: check the parameters")));
        }
        self.core.integrator = Some(Integrator::new(settings, M::N_STATES, M::N_EVENT_INDICATORS));
        self.core.last_successful_time = self.core.t;
        self.state = FmiState::StepComplete;
        Ok(())
    }

    /// `fmi2Terminate`.
    pub fn terminate(&mut self) -> CallResult {
        self.check(Call::Terminate)?;
        self.state = FmiState::Terminated;
        Ok(())
    }

    /// `fmi2Reset`: back to Instantiated with the start values (logging settings are kept).
    pub fn reset(&mut self) -> CallResult {
        self.check(Call::Reset)?;
        self.core = Core::new();
        self.state = FmiState::Instantiated;
        Ok(())
    }

    /// Before a read: in initialization mode the state is first computed from the parameters.
    /// The reads then run `Model::outputs` at the first variable it computes, at most once per
    /// step, so reading states, parameters or inputs (what a sweep's metrics mostly read)
    /// costs no model evaluation.
    fn prepare_read(&mut self) -> CallResult {
        if self.state == FmiState::InitializationMode {
            self.ensure_initial_state()?;
        }
        Ok(())
    }

    /// Refuses `vr` for a call on `kind` variables, naming the variable when `vr` is one of
    /// another type (the usual mistake: a value reference from the wrong list).
    fn unknown(&self, vr: u32, kind: &str) -> Failure {
        match self.table.row(vr) {
            Some(row) => Failure::error(format!("value reference {vr} is '{}' of type {:?}, not a {kind} variable", row.name, row.base_type)),
            None => Failure::error(format!("value reference {vr} is not a {kind} variable of this FMU")),
        }
    }

    fn control_value(&self, c: Control) -> f64 {
        let counters = self.core.integrator.as_ref().map(|i| (i.n_steps(), i.n_rhs())).unwrap_or((0, 0));
        match c {
            Control::Solver => self.core.controls.solver as f64,
            Control::FixedStep => self.core.controls.fixed_step,
            Control::AbsTol => self.core.controls.abs_tol,
            Control::NSteps => counters.0 as f64,
            Control::NRhs => counters.1 as f64,
        }
    }

    /// `fmi2GetReal`, in one pass (see [`Instance::prepare_read`]).
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
        self.check(Call::GetReal)?;
        self.prepare_read()?;
        let mut all_finite = true;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::State(k))) => self.core.x[*k],
                Some(Slot::Model(Access::Real { get, .. })) => {
                    if self.table.computed[i] {
                        self.core.refresh_outputs();
                    }
                    get(&self.core.model)
                }
                Some(Slot::Control(c)) if !c.is_integer() => self.control_value(*c),
                _ => return Err(self.unknown(*vr, "Real")),
            };
            all_finite &= value.is_finite();
        }
        // Never a silent NaN or inf. The solver refuses non-finite states during a step, but
        // outputs are computed lazily, here: one that overflowed means the solution diverged,
        // and the instance goes to the Error state as after a failed step.
        if all_finite {
            return Ok(());
        }
        let (vr, value) = vrs.iter().zip(values.iter()).find(|(_, v)| !v.is_finite()).expect("a value is not finite");
        let name = self.table.rows[*vr as usize].name;
        let t = self.core.t;
        // While initializing, the parameters can still be corrected: no Error state then.
        if !matches!(self.state, FmiState::Instantiated | FmiState::InitializationMode) {
            self.state = FmiState::Error;
        }
        Err(Failure::error(format!(
            "fmi2GetReal: {name} = {value} at t = {t} s is not finite: the solution diverged ({DIVERGED_ADVICE}); the instance is now in the Error state"
        )))
    }

    /// `fmi2GetInteger`.
    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32]) -> CallResult {
        self.check(Call::GetInteger)?;
        self.prepare_read()?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::Integer { get, .. })) => {
                    if self.table.computed[i] {
                        self.core.refresh_outputs();
                    }
                    get(&self.core.model)
                }
                // Counters saturate rather than wrap: FMI integers are 32-bit.
                Some(Slot::Control(c)) if c.is_integer() => self.control_value(*c).min(i32::MAX as f64) as i32,
                _ => return Err(self.unknown(*vr, "Integer")),
            };
        }
        Ok(())
    }

    /// `fmi2GetBoolean`.
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> CallResult {
        self.check(Call::GetBoolean)?;
        self.prepare_read()?;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            *value = match self.table.rows.get(i).map(|r| &r.slot) {
                Some(Slot::Model(Access::Boolean { get, .. })) => {
                    if self.table.computed[i] {
                        self.core.refresh_outputs();
                    }
                    get(&self.core.model)
                }
                _ => return Err(self.unknown(*vr, "Boolean")),
            };
        }
        Ok(())
    }

    /// `fmi2GetString`: these FMUs have no String variables.
    pub fn get_string(&mut self, vrs: &[u32]) -> CallResult {
        self.check(Call::GetString)?;
        match vrs.first() {
            Some(vr) => Err(self.unknown(*vr, "String")),
            None => Ok(()),
        }
    }

    /// Checks that the row of `vr` may be set now; returns its index.
    fn settable(&self, vr: u32, call: Call) -> CallResult<usize> {
        let row = self.table.row(vr).ok_or_else(|| Failure::error(format!("{}: value reference {vr} is not a variable of this FMU", call.name())))?;
        if row.variability == Variability::Constant {
            return Err(Failure::error(format!("{}: '{}' is a constant and can never be set", call.name(), row.name)));
        }
        if !row.is_settable() {
            let what = match row.causality {
                Causality::Output => "an output",
                Causality::CalculatedParameter => "a calculated parameter",
                Causality::Local => "a local variable",
                _ => "not settable",
            };
            return Err(Failure::error(format!("{}: '{}' is {what} and cannot be set", call.name(), row.name)));
        }
        let initializing = matches!(self.state, FmiState::Instantiated | FmiState::InitializationMode);
        let allowed = match (row.causality, row.variability) {
            (Causality::Input, _) => true,
            (_, Variability::Tunable) => true,
            _ => initializing,
        };
        if !allowed {
            return Err(Failure::error(format!(
                "{}: parameter '{}' is fixed and can be set only before fmi2ExitInitializationMode (now in state {})",
                call.name(),
                row.name,
                self.state.name()
            )));
        }
        Ok(vr as usize)
    }

    /// Records that a settable value changed.
    fn after_set(&mut self) {
        if matches!(self.state, FmiState::Instantiated | FmiState::InitializationMode) {
            self.core.initial_state_ready = false;
        }
        self.core.outputs_dirty = true;
        // New inputs make any cached derivative stale.
        if let Some(integrator) = self.core.integrator.as_mut() {
            integrator.invalidate();
        }
    }

    /// `fmi2SetReal`. Non-finite values are refused at once, naming the variable. All or
    /// nothing: every value is checked before any is stored, so a refused call changes nothing.
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> CallResult {
        self.check(Call::SetReal)?;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            let i = self.settable(*vr, Call::SetReal)?;
            let name = self.table.rows[i].name;
            if !value.is_finite() {
                return Err(Failure::error(format!("fmi2SetReal: {name} = {value} refused: the value must be finite")));
            }
            match &self.table.rows[i].slot {
                Slot::Model(Access::Real { set: Some(_), .. }) => {}
                Slot::Control(Control::FixedStep) => {
                    if *value <= 0.0 {
                        return Err(Failure::error(format!("fmi2SetReal: fixed_step = {value} refused: the step must be greater than zero")));
                    }
                }
                Slot::Control(Control::AbsTol) => {
                    if *value < 0.0 {
                        return Err(Failure::error(format!("fmi2SetReal: abs_tol = {value} refused: the tolerance must not be negative")));
                    }
                }
                _ => return Err(self.unknown(*vr, "settable Real")),
            }
        }
        for (vr, value) in vrs.iter().zip(values.iter()) {
            match &self.table.rows[*vr as usize].slot {
                Slot::Model(Access::Real { set: Some(set), .. }) => set(&mut self.core.model, *value),
                Slot::Control(Control::FixedStep) => self.core.controls.fixed_step = *value,
                Slot::Control(Control::AbsTol) => self.core.controls.abs_tol = *value,
                _ => unreachable!("checked above"),
            }
        }
        self.after_set();
        Ok(())
    }

    /// `fmi2SetInteger` (all or nothing, like [`Instance::set_real`]).
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> CallResult {
        self.check(Call::SetInteger)?;
        for (vr, value) in vrs.iter().zip(values.iter()) {
            let i = self.settable(*vr, Call::SetInteger)?;
            match &self.table.rows[i].slot {
                Slot::Model(Access::Integer { set: Some(_), .. }) => {}
                Slot::Control(Control::Solver) => {
                    if crate::solver::Method::from_code(*value).is_none() {
                        return Err(Failure::error(format!(
                            "fmi2SetInteger: solver = {value} refused: use 0 (forward Euler), 1 (classical RK4) or 2 (Dormand-Prince 5(4))"
                        )));
                    }
                }
                _ => return Err(self.unknown(*vr, "settable Integer")),
            }
        }
        for (vr, value) in vrs.iter().zip(values.iter()) {
            match &self.table.rows[*vr as usize].slot {
                Slot::Model(Access::Integer { set: Some(set), .. }) => set(&mut self.core.model, *value),
                Slot::Control(Control::Solver) => self.core.controls.solver = *value,
                _ => unreachable!("checked above"),
            }
        }
        self.after_set();
        Ok(())
    }

    /// `fmi2SetBoolean` (all or nothing, like [`Instance::set_real`]).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> CallResult {
        self.check(Call::SetBoolean)?;
        for vr in vrs {
            let i = self.settable(*vr, Call::SetBoolean)?;
            if !matches!(self.table.rows[i].slot, Slot::Model(Access::Boolean { set: Some(_), .. })) {
                return Err(self.unknown(*vr, "settable Boolean"));
            }
        }
        for (vr, value) in vrs.iter().zip(values.iter()) {
            if let Slot::Model(Access::Boolean { set: Some(set), .. }) = &self.table.rows[*vr as usize].slot {
                set(&mut self.core.model, *value);
            }
        }
        self.after_set();
        Ok(())
    }

    /// `fmi2SetString`: these FMUs have no String variables.
    pub fn set_string(&mut self, vrs: &[u32]) -> CallResult {
        self.check(Call::SetString)?;
        match vrs.first() {
            Some(vr) => Err(self.unknown(*vr, "String")),
            None => Ok(()),
        }
    }

    /// Computes the outputs at the current time and state (so a read right after costs
    /// nothing more) and names the first state or computed Real that is not finite:
    /// `Some("name = value")`. Parameters and inputs are finite by construction.
    fn first_non_finite(&mut self) -> Option<String> {
        let Core { model, t, x, .. } = &mut self.core;
        model.outputs(*t, x);
        self.core.outputs_dirty = false;
        let (model, x) = (&self.core.model, &self.core.x);
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

    /// Ends the experiment early at the current time: `fmi2Discard`, `fmi2Terminated` true;
    /// an `fmi2Error` instead if the state or the outputs there are not finite.
    fn stop_early(&mut self, t_start: f64, reason: &str) -> CallResult<Status> {
        if let Some(bad) = self.first_non_finite() {
            let message = Self::diverged(&bad, t_start, self.core.t);
            return Err(self.fail_step(t_start, message));
        }
        self.core.terminated = true;
        self.core.last_successful_time = self.core.t;
        self.state = FmiState::StepFailed;
        self.core.last_step_status = Status::Discard as i32;
        let msg = format!("the simulation ended at t = {} s: {reason}", self.core.t);
        self.logger.status(Status::Discard, &msg);
        Ok(Status::Discard)
    }

    /// A computation failed inside a step: restore the state at the step's start (so outputs
    /// stay finite) and enter the Error state.
    fn fail_step(&mut self, t_start: f64, message: String) -> Failure {
        self.core.x.copy_from_slice(&self.x_start);
        self.core.t = t_start;
        self.core.outputs_dirty = true;
        self.core.last_step_status = Status::Error as i32;
        self.state = FmiState::Error;
        Failure::error(message)
    }

    /// fmi2DoStep's checks of its arguments: `current` must be the FMU's time (to rounding) and
    /// `h` finite and not negative.
    #[cold]
    #[inline(never)]
    fn check_step_arguments(&self, current: f64, h: f64) -> CallResult {
        let t0 = self.core.t;
        if !(current.is_finite() && (current - t0).abs() <= 1e-9 * t0.abs().max(1.0)) {
            return Err(Failure::error(format!("fmi2DoStep: currentCommunicationPoint = {current} does not match the FMU's time {t0}")));
        }
        if !(h.is_finite() && h >= 0.0) {
            return Err(Failure::error(format!("fmi2DoStep: communicationStepSize = {h} must be finite and not negative")));
        }
        Ok(())
    }

    #[cold]
    #[inline(never)]
    fn past_stop(t_end: f64, stop: f64) -> Failure {
        Failure::error(format!("fmi2DoStep: the step to t = {t_end} would pass the stop time {stop} set in fmi2SetupExperiment"))
    }

    /// The rest of the step from `t0` to `t_end` after the solver's first call stopped short of
    /// `t_end` with `first` (an event, or a failure): events are handled and the solver called
    /// again until `t_end`. `Some(status)` when the step ends early there.
    #[inline(never)]
    fn continue_after(&mut self, first: Result<Advance, SolverError>, t0: f64, t_end: f64) -> CallResult<Option<Status>> {
        let mut outcome = first;
        let mut events = 0usize;
        loop {
            match outcome {
                Ok(Advance::Reached) => return Ok(None),
                Ok(Advance::Event { fired }) => {
                    events += 1;
                    if let Some(status) = self.handle_event(t0, t_end, events, &fired)? {
                        return Ok(Some(status));
                    }
                }
                Err(e) => return Err(self.fail_step(t0, format!("the solver failed between t = {t0} and t = {t_end}: {e}"))),
            }
            if self.core.t >= t_end {
                return Ok(None);
            }
            let Core { model, x, t, integrator, .. } = &mut self.core;
            let integrator = integrator.as_mut().expect("the integrator exists in StepComplete");
            outcome = integrator.advance(&*model, t, x, t_end);
        }
    }

    /// The model's response to the `events`-th event of the step from `t0` to `t_end`, at the
    /// current time: `Some(status)` when it ends the step (and the experiment) there. Out of
    /// line: most steps have no event, and they need not pay for setting this up.
    #[inline(never)]
    fn handle_event(&mut self, t0: f64, t_end: f64, events: usize, fired: &[bool]) -> CallResult<Option<Status>> {
        if events > MAX_EVENTS_PER_STEP {
            let msg = format!("more than {MAX_EVENTS_PER_STEP} events between t = {t0} and t = {t_end}: the model is chattering");
            return Err(self.fail_step(t0, msg));
        }
        let Core { model, x, t, integrator, .. } = &mut self.core;
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
            Ok(EventOutcome::Continue) => Ok(None),
            Ok(EventOutcome::Stop { reason }) => self.stop_early(t0, &reason).map(Some),
            Err(e) => Err(self.fail_step(t0, format!("the model failed at the event at t = {te}: {e}"))),
        }
    }

    /// `fmi2DoStep`: integrates from the current communication point over `h`, handling events.
    /// Returns `Ok` or `Discard` (the model ended the experiment early).
    pub fn do_step(&mut self, current: f64, h: f64) -> CallResult<Status> {
        self.check(Call::DoStep)?;
        // The usual call, at the FMU's own time with a positive finite step, passes one test;
        // anything else gets the full checks (out of line, with their messages).
        if !(current == self.core.t && h > 0.0 && h <= f64::MAX) {
            self.check_step_arguments(current, h)?;
            if h == 0.0 {
                return Ok(Status::Ok);
            }
        }
        let t0 = self.core.t;
        let t_end = current + h;
        if let Some(stop) = self.core.stop_time {
            if t_end > stop + 1e-9 * stop.abs().max(1.0) {
                return Err(Self::past_stop(t_end, stop));
            }
        }
        // The state has M::N_STATES values; copying that constant length compiles to a few
        // moves instead of a call to memmove (measurable at one call per communication step).
        let n = M::N_STATES;
        self.x_start[..n].copy_from_slice(&self.core.x[..n]);
        if self.core.t < t_end {
            // The usual step: one call of the solver that reaches t_end. Events and failures
            // continue out of line.
            let Core { model, x, t, integrator, .. } = &mut self.core;
            let integrator = integrator.as_mut().expect("the integrator exists in StepComplete");
            match integrator.advance(&*model, t, x, t_end) {
                Ok(Advance::Reached) => {}
                other => {
                    if let Some(status) = self.continue_after(other, t0, t_end)? {
                        return Ok(status);
                    }
                }
            }
        }
        // Land exactly on the communication point whatever the solver's rounding.
        self.core.t = t_end;
        // A projection here that changes x is seen by the integrator at the next step, which
        // compares x with the state it left and then drops its cached derivative.
        let Core { model, x, t, .. } = &mut self.core;
        let outcome = model.communication_point(*t, x);
        self.core.outputs_dirty = true;
        match outcome {
            Ok(EventOutcome::Continue) => {
                // The solver checks the states; outputs (which can overflow first, an energy
                // ~ omega^2) are computed only when read, and get_real refuses a non-finite one.
                self.core.last_successful_time = self.core.t;
                self.core.last_step_status = Status::Ok as i32;
                Ok(Status::Ok)
            }
            Ok(EventOutcome::Stop { reason }) => self.stop_early(t0, &reason),
            Err(e) => Err(self.fail_step(t0, format!("the model failed at t = {t_end}: {e}"))),
        }
    }

    /// `fmi2GetStatus(fmi2DoStepStatus)`: the status of the last step.
    pub fn do_step_status(&self) -> CallResult<Status> {
        self.check(Call::GetStatus)?;
        Ok(match self.core.last_step_status {
            0 => Status::Ok,
            2 => Status::Discard,
            _ => Status::Error,
        })
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)`.
    pub fn last_successful_time(&self) -> CallResult<f64> {
        self.check(Call::GetRealStatus)?;
        Ok(self.core.last_successful_time)
    }

    /// `fmi2GetBooleanStatus(fmi2Terminated)`: true once the model ended the experiment.
    pub fn terminated(&self) -> CallResult<bool> {
        self.check(Call::GetBooleanStatus)?;
        Ok(self.core.terminated)
    }

    /// `fmi2GetFMUstate`: a copy of everything needed to continue from here.
    pub fn get_fmu_state(&self) -> CallResult<Core<M>> {
        self.check(Call::GetFMUstate)?;
        let mut core = self.core.clone();
        core.phase = self.state;
        // The copy may be serialized, which drops the buffers the integrator would compare a
        // projected state with at its next step: have it compare now.
        let Core { integrator, t, x, .. } = &mut core;
        if let Some(integrator) = integrator.as_mut() {
            integrator.settle(*t, x);
        }
        Ok(core)
    }

    /// `fmi2SetFMUstate`: continues from a captured state, including its state-machine state.
    pub fn set_fmu_state(&mut self, core: &Core<M>) -> CallResult {
        self.check(Call::SetFMUstate)?;
        self.core = core.clone();
        self.state = core.phase;
        Ok(())
    }

    /// Replaces the logger's debug settings (`fmi2SetDebugLogging`).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> CallResult {
        self.check(Call::SetDebugLogging)?;
        self.logger.set_debug_logging(on, categories).map_err(Failure::error)
    }

    /// Marks the instance unusable after a panic in model code.
    pub fn poison(&mut self) {
        self.state = FmiState::Error;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::Harness;
    use crate::model::{ModelError, ModelInfo, Variable};

    /// x' = rate x from x0, with the output `square` = scale x^2, which overflows long before
    /// x does, plus one parameter of each type and a constant.
    #[derive(Debug, Clone, Serialize, Deserialize)]
    struct Growth {
        rate: f64,
        x0: f64,
        scale: f64,
        n: i32,
        flag: bool,
        square: f64,
    }

    impl Default for Growth {
        fn default() -> Self {
            Growth { rate: 1.0, x0: 1.0, scale: 1.0, n: 1, flag: false, square: 1.0 }
        }
    }

    impl Model for Growth {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo { identifier: "growth", description: "exponential growth", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }

        fn variables() -> Vec<Variable<Self>> {
            vec![
                Variable::parameter("rate", "", |m| m.rate, |m, v| m.rate = v),
                Variable::parameter("x0", "", |m| m.x0, |m, v| m.x0 = v),
                Variable::parameter("scale", "", |m| m.scale, |m, v| m.scale = v),
                Variable::integer_parameter("n", "", |m| m.n, |m, v| m.n = v),
                Variable::boolean_parameter("flag", "", |m| m.flag, |m, v| m.flag = v),
                Variable::state("x", "", 0),
                Variable::output("square", "", |m| m.square),
                Variable::output("one", "", |_| 1.0).variability(Variability::Constant),
            ]
        }

        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x[0] = self.x0;
            Ok(())
        }

        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = self.rate * x[0];
        }

        fn outputs(&mut self, _t: f64, x: &[f64]) {
            self.square = self.scale * x[0] * x[0];
        }
    }

    fn vr(h: &Harness<Growth>, name: &str) -> u32 {
        h.instance.table().value_reference(name).unwrap()
    }

    /// Forward Euler at h rate = 1000 multiplies x by 1001 per step: x^2 overflows at step 52
    /// while x stays finite until step 103, so the solver's own state check cannot see it.
    /// Outputs are computed when read, so the read after step 52 must refuse square = inf,
    /// naming it, and leave the instance in the Error state (no further step).
    #[test]
    fn an_output_that_overflows_is_refused_when_read_and_stops_the_instance() {
        let mut h = Harness::<Growth>::started(&[("solver", 0.0), ("fixed_step", 1.0), ("rate", 1e3)], None).unwrap();
        let mut k = 0;
        let err = loop {
            k += 1;
            assert_eq!(h.step(1.0).unwrap(), Status::Ok);
            assert!(h.get("x").unwrap().is_finite(), "states stay finite: the solver checks them");
            match h.get("square") {
                Ok(square) => assert!(square.is_finite()),
                Err(e) => break e,
            }
        };
        assert_eq!(k, 52);
        assert!(err.contains("square = inf") && err.contains("diverged"), "{err}");
        assert_eq!(h.instance.state(), FmiState::Error);
        assert!(h.step(1.0).is_err(), "no step after the divergence");
    }

    /// Finite parameters whose initial outputs overflow are refused at initialization, and a
    /// read during initialization mode refuses to hand out the inf.
    #[test]
    fn initial_outputs_that_overflow_are_refused() {
        let mut h = Harness::<Growth>::new();
        h.set("scale", 1e300).unwrap();
        h.set("x0", 1e10).unwrap();
        h.instance.setup_experiment(None, 0.0, None).unwrap();
        h.instance.enter_initialization_mode().unwrap();
        let err = h.get("square").unwrap_err();
        assert!(err.contains("square = inf") && err.contains("not finite"), "{err}");
        let err = h.instance.exit_initialization_mode().unwrap_err().message;
        assert!(err.contains("square = inf"), "{err}");
        assert_eq!(h.instance.state(), FmiState::InitializationMode);
        h.set("scale", 1.0).unwrap();
        h.instance.exit_initialization_mode().unwrap();
    }

    /// A set call with one bad value changes nothing, not even the good values before it.
    #[test]
    fn refused_set_calls_change_nothing() {
        let mut h = Harness::<Growth>::new();
        let (rate, x0, n, flag, solver, x) = (vr(&h, "rate"), vr(&h, "x0"), vr(&h, "n"), vr(&h, "flag"), vr(&h, "solver"), vr(&h, "x"));
        let e = h.instance.set_real(&[rate, x0], &[2.0, f64::NAN]).unwrap_err();
        assert!(e.message.contains("x0 = NaN"), "{}", e.message);
        assert!(h.instance.set_real(&[rate, vr(&h, "fixed_step")], &[2.0, 0.0]).is_err());
        assert!(h.instance.set_integer(&[n, solver], &[5, 9]).is_err());
        assert!(h.instance.set_boolean(&[flag, x], &[true, true]).is_err());
        h.instance.setup_experiment(None, 0.0, None).unwrap();
        h.instance.enter_initialization_mode().unwrap();
        assert_eq!(h.get("rate").unwrap(), 1.0);
        assert_eq!(h.get("n").unwrap(), 1.0);
        assert_eq!(h.get("flag").unwrap(), 0.0);
        assert_eq!(h.get("solver").unwrap(), 2.0);
        // Good calls still apply every value.
        h.instance.set_real(&[rate, x0], &[2.0, 3.0]).unwrap();
        assert_eq!((h.get("rate").unwrap(), h.get("x").unwrap()), (2.0, 3.0));
    }

    /// A constant is refused as such; a value reference of another type is named.
    #[test]
    fn constants_and_wrongly_typed_references_are_named() {
        let mut h = Harness::<Growth>::new();
        let one = vr(&h, "one");
        let e = h.instance.set_real(&[one], &[1.0]).unwrap_err().message;
        assert!(e.contains("'one' is a constant and can never be set"), "{e}");
        h.initialize(None).unwrap();
        let rate = vr(&h, "rate");
        let e = h.instance.get_integer(&[rate], &mut [0]).unwrap_err().message;
        assert!(e.contains(&format!("value reference {rate} is 'rate' of type Real, not a Integer variable")), "{e}");
        let e = h.instance.get_real(&[999], &mut [0.0]).unwrap_err().message;
        assert!(e.contains("value reference 999 is not a Real variable"), "{e}");
    }
}
