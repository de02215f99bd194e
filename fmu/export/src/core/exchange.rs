//! The core's Model Exchange operations: the importer integrates, the core answers.
//!
//! The importer sets the time and the continuous states, asks for the derivatives and the
//! event indicators, reports each completed integrator step, and at an event lets the model
//! update its discrete state. The core keeps for every indicator a reference value: its value
//! when continuous-time mode began, moved forward at each completed step where it has not
//! changed sign. An event fires the indicators whose sign differs from their reference, by the
//! rule of the toolkit's own solver (a reference of exactly zero fires nothing: the indicator
//! must first leave zero), so a model behaves the same under either interface.
//!
//! Models with algebraic constraints (the linkages' loop closure) report their drift
//! (`Model::constraint_drift`). Where Co-Simulation projects at every communication point, here
//! a drift beyond the relative tolerance makes `fmi2CompletedIntegratorStep` ask for a step
//! event, whose event update projects (`Model::communication_point`) and reports the new
//! states with `valuesOfContinuousStatesChanged`.

use super::{CallResult, Core, Failure, State};
use crate::logging::{Status, LOG_EVENTS};
use crate::model::{EventOutcome, Model};

/// What `fmi2CompletedIntegratorStep` tells the importer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StepCompleted {
    /// An event is due here: an indicator changed sign or the constraints drifted.
    pub enter_event_mode: bool,
    /// The model ended the experiment.
    pub terminate_simulation: bool,
}

/// What an event update (`fmi2NewDiscreteStates`) tells the importer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EventUpdate {
    /// The model ended the experiment here (a landing, a limit position); the reason was logged.
    pub terminate_simulation: bool,
    /// The event changed the continuous states (an impact, a projection): the importer must
    /// read them again.
    pub values_changed: bool,
}

/// Whether an indicator with reference value `r` has changed sign at value `z` (the solvers'
/// rule: a reference of exactly 0 never fires).
#[inline]
fn crossed(r: f64, z: f64) -> bool {
    (r < 0.0 && z >= 0.0) || (r > 0.0 && z <= 0.0)
}

/// True when `a` and `b` hold the same bits.
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

impl<M: Model> Core<M> {
    /// The relative tolerance of the experiment (what a step event's drift is measured by).
    fn relative_tolerance(&self) -> f64 {
        self.state.tolerance.unwrap_or(M::info().tolerance)
    }

    /// The event indicators at the current time and state.
    fn indicators_now(&self) -> Vec<f64> {
        let mut z = vec![0.0; M::N_EVENT_INDICATORS];
        let State { model, t, x, .. } = &self.state;
        model.event_indicators(*t, x, &mut z);
        z
    }

    /// Ends initialization for Model Exchange: the parameters and solver controls are checked
    /// as for Co-Simulation and the initial state computed; no solver is started, the
    /// importer integrates. The instance then waits in event mode.
    pub fn start_exchange(&mut self) -> CallResult {
        self.ensure_initial_state()?;
        let rtol = self.relative_tolerance();
        self.state.controls.settings(rtol).map_err(Failure::error)?;
        self.state.t = self.state.start_time;
        if let Some(bad) = self.first_non_finite() {
            return Err(Failure::error(format!("the parameters give {bad} at the start, which is not finite: check the parameters")));
        }
        self.state.integrator = None;
        self.state.z_ref = self.indicators_now();
        self.state.last_successful_time = self.state.t;
        Ok(())
    }

    /// `fmi2SetTime`.
    #[inline]
    pub fn set_time(&mut self, t: f64) -> CallResult {
        if self.try_set_time(t) {
            Ok(())
        } else {
            Err(Failure::error(format!("time = {t} must be finite")))
        }
    }

    /// [`Core::set_time`] without its message: false (and nothing changed) when `t` is refused.
    /// The importer calls it before every evaluation, so it is kept to a test and two stores.
    #[inline(always)]
    pub fn try_set_time(&mut self, t: f64) -> bool {
        if !t.is_finite() {
            return false;
        }
        self.state.t = t;
        self.state.outputs_dirty = true;
        true
    }

    /// `fmi2SetContinuousStates`: `x` has the model's number of states (the front end checks).
    /// A value that is not finite is refused with `Discard`, the states unchanged.
    #[inline]
    pub fn set_continuous_states(&mut self, x: &[f64]) -> CallResult {
        if self.try_set_continuous_states(x) {
            Ok(())
        } else {
            Err(self.non_finite_states(x))
        }
    }

    /// [`Core::set_continuous_states`] without its message: false (and nothing changed) when a
    /// value is not finite.
    #[inline(always)]
    pub fn try_set_continuous_states(&mut self, x: &[f64]) -> bool {
        let n = M::N_STATES;
        if !x[..n].iter().fold(true, |ok, v| ok & v.is_finite()) {
            return false;
        }
        self.state.x[..n].copy_from_slice(&x[..n]);
        self.state.outputs_dirty = true;
        true
    }

    #[cold]
    #[inline(never)]
    fn non_finite_states(&self, x: &[f64]) -> Failure {
        let i = x.iter().position(|v| !v.is_finite()).expect("a state is not finite");
        Failure { status: Status::Discard, message: format!("x[{i}] = {} is not finite; the states were not changed", x[i]), broken: false }
    }

    /// `fmi2GetContinuousStates` (during initialization the initial state from the parameters).
    pub fn continuous_states(&mut self, out: &mut [f64], initializing: bool) -> CallResult {
        if initializing {
            self.ensure_initial_state()?;
        }
        out.copy_from_slice(&self.state.x);
        Ok(())
    }

    /// `fmi2GetDerivatives` at the time and states last set (`initializing`: at the initial
    /// states the parameters set so far give). Derivatives that are not finite (states outside
    /// the model's domain, a diverging trial step) are returned with `Discard`, which asks the
    /// importer for a smaller step; the instance stays usable.
    #[inline]
    pub fn derivatives(&mut self, dx: &mut [f64], initializing: bool) -> CallResult {
        if initializing {
            self.ensure_initial_state()?;
        }
        if self.derivatives_into(dx) {
            Ok(())
        } else {
            Err(self.non_finite_derivatives(dx))
        }
    }

    /// [`Core::derivatives`] without its message: whether they are all finite.
    #[inline(always)]
    pub fn derivatives_into(&mut self, dx: &mut [f64]) -> bool {
        let n = M::N_STATES;
        let State { model, t, x, exchange_rhs, .. } = &mut self.state;
        model.derivatives(*t, &x[..n], &mut dx[..n]);
        *exchange_rhs += 1;
        dx[..n].iter().fold(true, |ok, v| ok & v.is_finite())
    }

    /// The refusal of derivatives `dx` that are not all finite (`Discard`, naming one).
    #[cold]
    #[inline(never)]
    pub fn non_finite_derivatives(&self, dx: &[f64]) -> Failure {
        let i = dx.iter().position(|v| !v.is_finite()).expect("a derivative is not finite");
        let name = self.table.rows.iter().find(|r| matches!(r.slot, crate::table::Slot::Derivative(k) if k == i)).map_or("?", |r| r.name);
        Failure {
            status: Status::Discard,
            message: format!(
                "{name} = {} at t = {} s is not finite for the states {:?}: they are outside the model's domain, or the solver's step was too large",
                dx[i], self.state.t, self.state.x
            ),
            broken: false,
        }
    }

    /// `fmi2GetEventIndicators` at the time and states last set.
    pub fn event_indicators(&mut self, z: &mut [f64], initializing: bool) -> CallResult {
        if initializing {
            self.ensure_initial_state()?;
        }
        let State { model, t, x, .. } = &self.state;
        model.event_indicators(*t, x, z);
        if let Some(i) = z.iter().position(|v| !v.is_finite()) {
            return Err(Failure::error(format!("event indicator {i} = {} at t = {} s is not finite", z[i], self.state.t)));
        }
        Ok(())
    }

    /// `fmi2CompletedIntegratorStep`: the importer accepted the current time and states.
    /// Indicators that kept their sign move their reference here; one that changed sign, or a
    /// constraint drift beyond the tolerance, asks for an event.
    pub fn completed_integrator_step(&mut self) -> CallResult<StepCompleted> {
        self.state.exchange_steps += 1;
        let z = self.indicators_now();
        let mut crossing = false;
        for (r, &v) in self.state.z_ref.iter_mut().zip(&z) {
            if crossed(*r, v) {
                crossing = true;
            } else {
                *r = v;
            }
        }
        let drifted = self.state.model.constraint_drift(&self.state.x) > self.relative_tolerance();
        self.state.last_successful_time = self.state.t;
        Ok(StepCompleted { enter_event_mode: crossing || drifted, terminate_simulation: self.state.terminated })
    }

    /// `fmi2NewDiscreteStates`: the event at the current time and states. The indicators that
    /// changed sign go to `Model::on_event` (which may change the mode and the states, or end
    /// the experiment); a constraint drift beyond the tolerance is projected away. The
    /// reference values are then those of the new mode. One update settles every event of
    /// these models, so `newDiscreteStatesNeeded` is never set.
    pub fn event_update(&mut self) -> CallResult<EventUpdate> {
        if self.state.terminated {
            return Ok(EventUpdate { terminate_simulation: true, values_changed: false });
        }
        let t = self.state.t;
        // The event may change the model's discrete state (its regime).
        self.version += 1;
        let x_before = self.state.x.clone();
        let z = self.indicators_now();
        let fired: Vec<bool> = self.state.z_ref.iter().zip(&z).map(|(&r, &v)| crossed(r, v)).collect();
        self.state.outputs_dirty = true;
        if fired.iter().any(|&f| f) {
            if self.logger.wants(LOG_EVENTS) {
                let which: Vec<usize> = fired.iter().enumerate().filter(|(_, f)| **f).map(|(i, _)| i).collect();
                self.logger.log(Status::Ok, LOG_EVENTS, &format!("event at t = {t} s (indicators {which:?})"));
            }
            let State { model, x, .. } = &mut self.state;
            match model.on_event(t, x, &fired) {
                Ok(EventOutcome::Continue | EventOutcome::Unchanged) => {}
                Ok(EventOutcome::Stop { reason }) => return Ok(self.end_experiment(&reason, &x_before)),
                Err(e) => return Err(Failure::broken(format!("the model failed at the event at t = {t}: {e}"))),
            }
        }
        if self.state.model.constraint_drift(&self.state.x) > self.relative_tolerance() {
            let State { model, x, .. } = &mut self.state;
            match model.communication_point(t, x) {
                Ok(EventOutcome::Continue) => {
                    if self.logger.wants(LOG_EVENTS) {
                        self.logger.log(
                            Status::Ok,
                            LOG_EVENTS,
                            &format!("step event at t = {t} s: the states were projected onto the constraints"),
                        );
                    }
                }
                Ok(EventOutcome::Unchanged) => {}
                Ok(EventOutcome::Stop { reason }) => return Ok(self.end_experiment(&reason, &x_before)),
                Err(e) => return Err(Failure::broken(format!("the model failed at the step event at t = {t}: {e}"))),
            }
        }
        self.state.z_ref = self.indicators_now();
        Ok(EventUpdate { terminate_simulation: false, values_changed: !same_bits(&x_before, &self.state.x) })
    }

    /// The model ended the experiment at the current time: logged as Co-Simulation logs an
    /// early end, and every later event update repeats `terminateSimulation`.
    fn end_experiment(&mut self, reason: &str, x_before: &[f64]) -> EventUpdate {
        self.state.terminated = true;
        self.state.last_successful_time = self.state.t;
        let message = format!("the simulation ended at t = {} s: {reason}", self.state.t);
        self.logger.status(Status::Discard, &message);
        EventUpdate { terminate_simulation: true, values_changed: !same_bits(x_before, &self.state.x) }
    }

    /// `fmi2EnterContinuousTimeMode`: the indicators' references become their values in the
    /// mode the event left. Refused once the model has ended the experiment.
    pub fn enter_continuous_time(&mut self) -> CallResult {
        if self.state.terminated {
            return Err(Failure::error(format!(
                "the model ended the simulation at t = {} s (terminateSimulation); only fmi2Terminate, fmi2Reset or fmi2FreeInstance can follow",
                self.state.last_successful_time
            )));
        }
        self.state.z_ref = self.indicators_now();
        Ok(())
    }
}
