//! An FMI 2.0 Model Exchange instance, integrated by the runner with the toolkit's own solvers
//! (crate `solvers`): the FMU supplies derivatives and event indicators, the runner's
//! integrator steps through each communication interval and locates state events on its
//! dense output by the sign changes of the indicators, and the FMU's event machinery runs at
//! every state event, time event (`nextEventTime`) and step event
//! (`fmi2CompletedIntegratorStep`): event mode, `fmi2NewDiscreteStates` until no further
//! discrete update is needed (at most [`MAX_EVENT_ITERATIONS`] times), continuous-time mode,
//! the states read back. `terminateSimulation` ends the run as an early end.

use std::cell::{Cell, RefCell};
use std::ffi::c_int;

use fmi_c::fmi2 as c;
use solvers::{Advance, Integrator, OdeSystem, Settings};

use super::component::{Component, DISCARD, ERROR, FATAL, OK, WARNING};
use super::{Binary, ExchangeApi};
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Solver, Step, Value, Variable};

/// Most `fmi2NewDiscreteStates` calls one event may take before the run is stopped: an event
/// iteration that does not settle in this many super-dense steps will not settle at all.
pub const MAX_EVENT_ITERATIONS: usize = 1000;

/// Most events one communication step may have (the FMU is then chattering).
const MAX_EVENTS_PER_STEP: usize = 10_000;

/// The relative tolerance when neither the run nor the FMU's DefaultExperiment gives one.
const DEFAULT_TOLERANCE: f64 = 1e-6;

/// What went wrong inside the integrator's calls of the FMU, for the error message.
#[derive(Debug, Clone)]
struct Trouble {
    /// The FMU's status (fmi2Discard, fmi2Error, ...) or OK for non-finite values.
    status: c_int,
    message: String,
}

/// The FMU seen as the integrator's ODE system: every right-hand side sets the time (when it
/// changed) and the states and asks for the derivatives; every indicator evaluation likewise.
/// A failing call cannot return an error through `OdeSystem`: it records the trouble and
/// returns NaN, on which the integrator stops (an fmi2Error or fmi2Fatal poisons every later
/// call, so the FMU is not called again).
///
/// `N` is the number of states when it is one of the small sizes the runner is compiled for
/// (0 otherwise, and `nx` holds it): the integrator's stage loops then have a constant length,
/// which the compiler unrolls, as in an FMU's own solver.
struct System<'s, const N: usize> {
    api: &'s ExchangeApi,
    raw: c::Component,
    component: &'s Component<'s>,
    nx: usize,
    nz: usize,
    /// The time last given to fmi2SetTime.
    time_set: Cell<f64>,
    /// Set with the first fmi2Error or fmi2Fatal, or a non-finite event indicator: no further
    /// call. Apart from `poisoned` so the hot path tests a flag.
    stopped: Cell<bool>,
    poisoned: RefCell<Option<Trouble>>,
    /// The last fmi2Discard or non-finite derivative (the integrator may retry a smaller step).
    last_discard: RefCell<Option<Trouble>>,
}

impl<const N: usize> System<'_, N> {
    /// Sets time and states for an evaluation at (t, x); false once poisoned or on failure.
    #[inline(always)]
    fn place(&self, t: f64, x: &[f64]) -> bool {
        if self.stopped.get() {
            return false;
        }
        if t != self.time_set.get() {
            trace::enter(Call::SetTime, t);
            let status = unsafe { (self.api.set_time)(self.raw, t) };
            if !accepted(status) {
                self.trouble("fmi2SetTime", t, status, false);
                return false;
            }
            self.time_set.set(t);
        }
        let nx = self.dim();
        if nx > 0 {
            trace::enter(Call::SetContinuousStates, t);
            let status = unsafe { (self.api.set_continuous_states)(self.raw, x.as_ptr(), nx) };
            if !accepted(status) {
                self.trouble("fmi2SetContinuousStates", t, status, false);
                return false;
            }
        }
        true
    }

    /// Records a status other than fmi2OK and fmi2Warning: fmi2Discard as a refusal the
    /// integrator may retry with a smaller step, unless `discard_stops`; worse stops the run.
    #[cold]
    #[inline(never)]
    fn trouble(&self, call: &str, t: f64, status: c_int, discard_stops: bool) {
        let reason = self.component.callbacks.log.take_problem().unwrap_or_else(|| "the FMU logged no reason".to_owned());
        let trouble = Trouble { status, message: format!("{call} at t = {t} returned {}: {reason}", c::status_name(status)) };
        if status == DISCARD && !discard_stops {
            *self.last_discard.borrow_mut() = Some(trouble);
        } else {
            self.stopped.set(true);
            *self.poisoned.borrow_mut() = Some(trouble);
        }
    }

    #[cold]
    #[inline(never)]
    fn non_finite(&self, call: &str, t: f64, what: &str, values: &[f64], poison: bool) {
        let i = values.iter().position(|v| !v.is_finite()).unwrap_or(0);
        let trouble = Trouble { status: OK, message: format!("{call} at t = {t} returned {what}[{i}] = {}", values[i]) };
        if poison {
            self.stopped.set(true);
            *self.poisoned.borrow_mut() = Some(trouble);
        } else {
            *self.last_discard.borrow_mut() = Some(trouble);
        }
    }
}

/// fmi2OK or fmi2Warning.
#[inline(always)]
fn accepted(status: c_int) -> bool {
    status == OK || status == WARNING
}

impl<const N: usize> OdeSystem for System<'_, N> {
    #[inline(always)]
    fn dim(&self) -> usize {
        if N > 0 {
            N
        } else {
            self.nx
        }
    }

    #[inline(always)]
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        if !self.place(t, x) {
            dx.fill(f64::NAN);
            return;
        }
        let nx = self.dim();
        trace::enter(Call::GetDerivatives, t);
        let status = unsafe { (self.api.get_derivatives)(self.raw, dx.as_mut_ptr(), nx) };
        if !accepted(status) {
            self.trouble("fmi2GetDerivatives", t, status, false);
            dx.fill(f64::NAN);
        } else if !dx[..nx].iter().fold(true, |ok, v| ok & v.is_finite()) {
            self.non_finite("fmi2GetDerivatives", t, "derivatives", dx, false);
        }
    }

    fn n_event_indicators(&self) -> usize {
        self.nz
    }

    fn event_indicators(&self, t: f64, x: &[f64], z: &mut [f64]) {
        if !self.place(t, x) {
            z.fill(f64::NAN);
            return;
        }
        trace::enter(Call::GetEventIndicators, t);
        let status = unsafe { (self.api.get_event_indicators)(self.raw, z.as_mut_ptr(), self.nz) };
        // A missed sign change would pass silently: indicators that cannot be evaluated stop
        // the run, even with fmi2Discard.
        if !accepted(status) {
            self.trouble("fmi2GetEventIndicators", t, status, true);
            z.fill(f64::NAN);
        } else if !z.iter().all(|v| v.is_finite()) {
            self.non_finite("fmi2GetEventIndicators", t, "eventIndicators", z, true);
        }
    }
}

/// One Model Exchange instance of an FMI 2.0 FMU, with the runner's integrator.
pub struct ModelExchange<'a> {
    component: Component<'a>,
    api: ExchangeApi,
    nx: usize,
    nz: usize,
    solver: Solver,
    tolerance: Option<f64>,
    /// The experiment's stop time: no step of the integrator goes past it.
    stop: f64,
    integrator: Option<Integrator>,
    t: f64,
    x: Vec<f64>,
    next_event_time: Option<f64>,
}

/// The integrator from `t` towards `target` on the FMU as a [`System`] of `N` states (0: any
/// number); the outcome and what went wrong in the FMU's calls, if anything.
#[allow(clippy::too_many_arguments)]
fn integrate<const N: usize>(
    integrator: &mut Integrator,
    api: &ExchangeApi,
    component: &Component<'_>,
    nz: usize,
    t: &mut f64,
    x: &mut [f64],
    target: f64,
) -> (Result<Advance, solvers::SolverError>, Option<Trouble>, Option<Trouble>) {
    let system = System::<N> {
        api,
        raw: component.raw,
        component,
        nx: x.len(),
        nz,
        time_set: Cell::new(f64::NAN),
        stopped: Cell::new(false),
        poisoned: RefCell::new(None),
        last_discard: RefCell::new(None),
    };
    let outcome = integrator.advance(&system, t, x, target);
    (outcome, system.poisoned.into_inner(), system.last_discard.into_inner())
}

/// A time within rounding of `t` (a time event at a communication point, given by the FMU
/// as a sum, may differ from the grid's product in the last bits).
fn near(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

impl<'a> ModelExchange<'a> {
    /// fmi2Instantiate as Model Exchange; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<ModelExchange<'a>, String> {
        let api = binary.api.exchange.expect("resolved for Model Exchange");
        let component = Component::instantiate(fmu, binary, name, debug_logging, c::MODEL_EXCHANGE)?;
        let (nx, nz) = (fmu.description.number_of_continuous_states, fmu.description.number_of_event_indicators);
        Ok(ModelExchange {
            component,
            api,
            nx,
            nz,
            solver: Solver::default(),
            tolerance: None,
            stop: f64::INFINITY,
            integrator: None,
            t: 0.0,
            x: vec![0.0; nx],
            next_event_time: None,
        })
    }

    /// The integrator for this run (before initialization ends).
    pub fn set_solver(&mut self, solver: Solver) {
        self.solver = solver;
    }

    /// fmi2SetupExperiment; the tolerance is also the integrator's relative tolerance.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.tolerance = tolerance;
        self.t = start;
        self.stop = stop;
        self.component.setup_experiment(tolerance, start, stop)
    }

    /// fmi2EnterInitializationMode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        self.component.enter_initialization_mode()
    }

    /// fmi2ExitInitializationMode, then the initial event iteration and continuous-time mode:
    /// the initial states are read and the integrator is started.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        self.component.exit_initialization_mode()?;
        let settings = Settings {
            method: self.solver.method,
            fixed_step: self.solver.fixed_step,
            rtol: self.tolerance.unwrap_or(DEFAULT_TOLERANCE),
            atol: self.solver.abs_tol,
            max_step: 0.0,
        };
        settings.validate().map_err(|e| format!("{}: the runner's integrator: {e}", self.component.name))?;
        if let Some(reason) = self.event_iteration()? {
            return Err(format!("{}: the model ended the simulation during its initial event iteration: {reason}", self.component.name));
        }
        let mut integrator = Integrator::new(settings, self.nx, self.nz);
        // The adaptive methods step across communication points, never past the stop time.
        integrator.set_stop_time(Some(self.stop));
        self.integrator = Some(integrator);
        Ok(())
    }

    /// Sets one variable (fmi2Set<Type> with one value reference).
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// Reads the variables of `reader` into `out` (the FMU holds the time and states reached).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    /// Accepted steps and right-hand-side evaluations of the runner's integrator so far.
    pub fn counters(&self) -> (u64, u64) {
        self.integrator.as_ref().map_or((0, 0), |i| (i.n_steps(), i.n_rhs()))
    }

    fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        self.component.check(call, status)
    }

    /// Gives the FMU the time and states the integrator reached.
    fn place(&mut self) -> Result<(), String> {
        trace::enter(Call::SetTime, self.t);
        let status = unsafe { (self.api.set_time)(self.component.raw, self.t) };
        self.check("fmi2SetTime", status)?;
        if self.nx > 0 {
            trace::enter(Call::SetContinuousStates, self.t);
            let status = unsafe { (self.api.set_continuous_states)(self.component.raw, self.x.as_ptr(), self.nx) };
            self.check("fmi2SetContinuousStates", status)?;
        }
        Ok(())
    }

    /// From event mode: fmi2NewDiscreteStates until no further update is needed, then
    /// continuous-time mode and the states read back. `Some(reason)` when the model ended the
    /// simulation (the instance stays in event mode, where fmi2Terminate is allowed).
    fn event_iteration(&mut self) -> Result<Option<String>, String> {
        let raw = self.component.raw;
        let mut info = c::EventInfo::default();
        let mut settled = false;
        for _ in 0..MAX_EVENT_ITERATIONS {
            info = c::EventInfo::default();
            trace::enter(Call::NewDiscreteStates, self.t);
            let status = unsafe { (self.api.new_discrete_states)(raw, &mut info) };
            self.check("fmi2NewDiscreteStates", status)?;
            if info.terminate_simulation != 0 {
                let reason =
                    self.component.callbacks.log.take_reason().unwrap_or_else(|| "terminateSimulation, no reason logged".to_owned());
                return Ok(Some(reason));
            }
            if info.new_discrete_states_needed == 0 {
                settled = true;
                break;
            }
        }
        if !settled {
            return Err(format!(
                "{}: the event iteration at t = {} did not converge: fmi2NewDiscreteStates still asked for another iteration (newDiscreteStatesNeeded) after {MAX_EVENT_ITERATIONS} calls",
                self.component.name, self.t
            ));
        }
        trace::enter(Call::EnterContinuousTimeMode, self.t);
        let status = unsafe { (self.api.enter_continuous_time_mode)(raw) };
        self.check("fmi2EnterContinuousTimeMode", status)?;
        // Read back whatever valuesOfContinuousStatesChanged says: one call per event, and an
        // FMU that forgets the flag still continues from its own states.
        if self.nx > 0 {
            trace::enter(Call::GetContinuousStates, self.t);
            let status = unsafe { (self.api.get_continuous_states)(raw, self.x.as_mut_ptr(), self.nx) };
            self.check("fmi2GetContinuousStates", status)?;
            if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
                return Err(format!("{}: fmi2GetContinuousStates at t = {} returned x[{i}] = {}", self.component.name, self.t, self.x[i]));
            }
        }
        self.next_event_time = (info.next_event_time_defined != 0).then_some(info.next_event_time);
        if let Some(te) = self.next_event_time {
            if !te.is_finite() {
                return Err(format!("{}: fmi2NewDiscreteStates at t = {} gave nextEventTime = {te}", self.component.name, self.t));
            }
        }
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(None)
    }

    /// Enters event mode at the current time and iterates the event.
    fn event(&mut self) -> Result<Option<String>, String> {
        trace::enter(Call::EnterEventMode, self.t);
        let status = unsafe { (self.api.enter_event_mode)(self.component.raw) };
        self.check("fmi2EnterEventMode", status)?;
        self.event_iteration()
    }

    /// The early end of the run at the current time.
    fn ended(&self, reason: String) -> Step {
        Step::Ended { reason: format!("the model ended the simulation at t = {}: {reason}", self.t), last_time: Some(self.t) }
    }

    /// Integrates from the communication point `t` over `h` with the runner's integrator,
    /// handling every event on the way.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        let t_end = t + h;
        let mut events = 0usize;
        while self.t < t_end {
            let time_event_due = self.next_event_time.filter(|&te| te < t_end || near(te, t_end));
            let target = match time_event_due {
                Some(te) if !near(te, t_end) => te.max(self.t),
                _ => t_end,
            };
            let outcome = self.advance(target)?;
            let (step_event, terminate) = self.completed_step()?;
            if terminate {
                let reason = self
                    .component
                    .callbacks
                    .log
                    .take_reason()
                    .unwrap_or_else(|| "terminateSimulation from fmi2CompletedIntegratorStep".to_owned());
                return Ok(self.ended(reason));
            }
            let time_event = time_event_due.is_some_and(|te| self.t >= te || near(self.t, te));
            let state_event = matches!(outcome, Advance::Event { .. });
            if state_event || time_event || step_event {
                events += 1;
                if events > MAX_EVENTS_PER_STEP {
                    return Err(format!(
                        "{}: more than {MAX_EVENTS_PER_STEP} events between t = {t} and t = {t_end}: the model is chattering",
                        self.component.name
                    ));
                }
                if let Some(reason) = self.event()? {
                    return Ok(self.ended(reason));
                }
            }
        }
        Ok(Step::Done)
    }

    /// The integrator from the current time towards `target`, which it reaches or stops
    /// short of at a state event; the FMU then holds the time and states reached.
    fn advance(&mut self, target: f64) -> Result<Advance, String> {
        let integrator = self.integrator.as_mut().ok_or_else(|| format!("{}: the run was not initialized", self.component.name))?;
        let t0 = self.t;
        let (outcome, poisoned, discard) = if target > self.t {
            let (api, component, t, x) = (&self.api, &self.component, &mut self.t, &mut self.x[..]);
            // The sizes of the lab's models and of most small FMUs get a solver with loops of
            // constant length; any other size the general one.
            match self.nx {
                1 => integrate::<1>(integrator, api, component, self.nz, t, x, target),
                2 => integrate::<2>(integrator, api, component, self.nz, t, x, target),
                3 => integrate::<3>(integrator, api, component, self.nz, t, x, target),
                4 => integrate::<4>(integrator, api, component, self.nz, t, x, target),
                5 => integrate::<5>(integrator, api, component, self.nz, t, x, target),
                6 => integrate::<6>(integrator, api, component, self.nz, t, x, target),
                _ => integrate::<0>(integrator, api, component, self.nz, t, x, target),
            }
        } else {
            (Ok(Advance::Reached), None, None)
        };
        if let Some(trouble) = poisoned {
            if trouble.status == ERROR || trouble.status == FATAL {
                self.component.note_status(trouble.status);
            }
            return Err(format!("{}: {}", self.component.name, trouble.message));
        }
        let name = &self.component.name;
        let outcome = outcome.map_err(|e| {
            let method = self.solver.method.name();
            let cause = discard.map_or(String::new(), |d| format!("; the cause: {}", d.message));
            format!("{name}: the runner's {method} integration from t = {t0} failed: {e}{cause}")
        })?;
        self.place()?;
        Ok(outcome)
    }

    /// fmi2CompletedIntegratorStep: (enterEventMode, terminateSimulation).
    fn completed_step(&mut self) -> Result<(bool, bool), String> {
        let (mut enter, mut terminate): (c_int, c_int) = (0, 0);
        trace::enter(Call::CompletedIntegratorStep, self.t);
        let status = unsafe { (self.api.completed_integrator_step)(self.component.raw, c::TRUE, &mut enter, &mut terminate) };
        self.check("fmi2CompletedIntegratorStep", status)?;
        Ok((enter != 0, terminate != 0))
    }
}
