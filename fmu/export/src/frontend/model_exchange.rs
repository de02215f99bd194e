//! The Model Exchange front end (FMI 2.0.4 chapter 3, FMI 3.0.2 chapter 3): its calls on an
//! [`Instance`] created for Model Exchange, checked against the version's state machine and
//! handed to the core. The importer integrates: it sets time and states in Continuous-Time
//! Mode, asks for derivatives and event indicators, reports completed steps, and at events
//! enters Event Mode, where the model updates its discrete state until it is settled
//! ([`Instance::update_discrete_states`]).

use super::{Call, Instance, MachineState, Version};
use crate::core::{CallResult, Failure, StepCompleted};
use crate::model::Model;

impl<V: Version, M: Model> Instance<V, M> {
    /// Refuses an array argument whose length is not the model's: `what` and its length `n`.
    #[inline]
    fn check_length(call: Call, what: &str, n: usize, expected: usize) -> CallResult {
        if n == expected {
            Ok(())
        } else {
            Err(Self::wrong_length(call, what, n, expected))
        }
    }

    #[cold]
    #[inline(never)]
    fn wrong_length(call: Call, what: &str, n: usize, expected: usize) -> Failure {
        Failure::error(format!("{}: {what} = {n}, but this FMU has {expected}", V::name(call)))
    }

    /// `EnterContinuousTimeMode`.
    pub fn enter_continuous_time_mode(&mut self) -> CallResult {
        self.check(Call::EnterContinuousTimeMode)?;
        self.core.enter_continuous_time()?;
        self.state = V::CONTINUOUS_TIME_MODE;
        Ok(())
    }

    /// `CompletedIntegratorStep`: whether to enter Event Mode (a step event, or a sign change
    /// the importer did not locate) and whether the model ended the experiment.
    pub fn completed_integrator_step(&mut self) -> CallResult<StepCompleted> {
        self.check(Call::CompletedIntegratorStep)?;
        self.core.completed_integrator_step()
    }

    /// `SetTime`: in Continuous-Time Mode, and in Event Mode only for a model without
    /// continuous states (FMI 2.0's footnote 8 of the table: time moves on there only in a
    /// purely discrete-time FMU; FMI 3.0 likewise).
    #[inline]
    pub fn set_time(&mut self, t: f64) -> CallResult {
        self.check(Call::SetTime)?;
        if !self.time_settable() {
            return Err(Failure::error(format!(
                "{} is not allowed in state {} of an FMU with continuous states (time advances in Continuous-Time Mode): illegal call sequence",
                V::name(Call::SetTime),
                self.state.name()
            )));
        }
        self.core.set_time(t)
    }

    /// The state-dependent half of `SetTime`'s rule (the table's half is its row's).
    #[inline(always)]
    fn time_settable(&self) -> bool {
        M::N_STATES == 0 || self.state == V::CONTINUOUS_TIME_MODE
    }

    /// `SetContinuousStates`.
    #[inline]
    pub fn set_continuous_states(&mut self, x: &[f64]) -> CallResult {
        self.check(Call::SetContinuousStates)?;
        Self::check_length(Call::SetContinuousStates, V::WORDS.n_states, x.len(), M::N_STATES)?;
        self.core.set_continuous_states(x)
    }

    /// `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`: `Discard` for derivatives
    /// that are not finite. In Initialization Mode, at the initial states the values set so
    /// far give.
    #[inline]
    pub fn get_derivatives(&mut self, dx: &mut [f64]) -> CallResult {
        self.check(Call::GetDerivatives)?;
        Self::check_length(Call::GetDerivatives, V::WORDS.n_states, dx.len(), M::N_STATES)?;
        let initializing = self.state == V::INITIALIZATION_MODE;
        self.core.derivatives(dx, initializing)
    }

    /// The usual `SetTime` (allowed now, a finite time), done: true; false leaves the
    /// instance unchanged for [`Instance::set_time`] to refuse with its reason. The importer
    /// calls these three hot paths before and for every evaluation of the derivatives.
    #[inline(always)]
    pub fn try_set_time(&mut self, t: f64) -> bool {
        self.permits(Call::SetTime) && self.time_settable() && self.core.try_set_time(t)
    }

    /// The usual `SetContinuousStates` (allowed now, the model's number of finite values).
    #[inline(always)]
    pub fn try_set_continuous_states(&mut self, x: &[f64]) -> bool {
        self.permits(Call::SetContinuousStates) && x.len() == M::N_STATES && self.core.try_set_continuous_states(x)
    }

    /// The usual `GetDerivatives`: `None` when the call is not allowed, `dx` has the wrong
    /// length or the instance is initializing (nothing computed), else whether the
    /// derivatives are all finite.
    #[inline(always)]
    pub fn try_get_derivatives(&mut self, dx: &mut [f64]) -> Option<bool> {
        (self.permits(Call::GetDerivatives) && self.state != V::INITIALIZATION_MODE && dx.len() == M::N_STATES)
            .then(|| self.core.derivatives_into(dx))
    }

    /// `GetEventIndicators`.
    pub fn get_event_indicators(&mut self, z: &mut [f64]) -> CallResult {
        self.check(Call::GetEventIndicators)?;
        Self::check_length(Call::GetEventIndicators, V::WORDS.n_indicators, z.len(), M::N_EVENT_INDICATORS)?;
        let initializing = self.state == V::INITIALIZATION_MODE;
        self.core.event_indicators(z, initializing)
    }

    /// `GetContinuousStates`.
    pub fn get_continuous_states(&mut self, x: &mut [f64]) -> CallResult {
        self.check(Call::GetContinuousStates)?;
        Self::check_length(Call::GetContinuousStates, V::WORDS.n_states, x.len(), M::N_STATES)?;
        let initializing = self.state == V::INITIALIZATION_MODE;
        self.core.continuous_states(x, initializing)
    }

    /// `GetNominalsOfContinuousStates`: 1 for every state (the standard's default: the
    /// states' scales are not declared).
    pub fn get_nominals_of_continuous_states(&mut self, nominals: &mut [f64]) -> CallResult {
        self.check(Call::GetNominalsOfContinuousStates)?;
        Self::check_length(Call::GetNominalsOfContinuousStates, V::WORDS.n_states, nominals.len(), M::N_STATES)?;
        nominals.fill(1.0);
        Ok(())
    }

    /// `fmi3GetNumberOfEventIndicators`.
    pub fn number_of_event_indicators(&self) -> CallResult<usize> {
        self.check(Call::GetNumberOfEventIndicators)?;
        Ok(M::N_EVENT_INDICATORS)
    }

    /// `fmi3GetNumberOfContinuousStates`.
    pub fn number_of_continuous_states(&self) -> CallResult<usize> {
        self.check(Call::GetNumberOfContinuousStates)?;
        Ok(M::N_STATES)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi2::state_machine::FmiState;
    use crate::harness::Harness;
    use crate::logging::Status;
    use crate::model::{EventOutcome, ModelError, ModelInfo, Variable, Variables};
    use serde::{Deserialize, Serialize};

    /// A ball dropped from h0 that bounces with restitution e (an event: v <- -e v) and ends
    /// the experiment at its `last`-th bounce; `g` is tunable, `drop` an input added to g.
    #[derive(Debug, Clone, Serialize, Deserialize)]
    struct Ball {
        h0: f64,
        e: f64,
        g: f64,
        push: f64,
        last: i32,
        bounces: i32,
    }

    impl Default for Ball {
        fn default() -> Self {
            Ball { h0: 1.0, e: 0.5, g: 9.81, push: 0.0, last: 3, bounces: 0 }
        }
    }

    impl Variables for Ball {
        fn variables() -> Vec<Variable<Self>> {
            vec![
                Variable::parameter("h0", "", |m| m.h0, |m, v| m.h0 = v),
                Variable::parameter("e", "", |m| m.e, |m, v| m.e = v),
                Variable::<Ball>::parameter("g", "", |m| m.g, |m, v| m.g = v).variability(crate::model::Variability::Tunable),
                Variable::input("push", "", |m| m.push, |m, v| m.push = v),
                Variable::integer_parameter("last", "", |m| m.last, |m, v| m.last = v),
                Variable::state("h", "", 0),
                Variable::state("v", "", 1),
                Variable::integer_output("bounces", "", |m| m.bounces),
            ]
        }
    }

    impl fmu_export::Equations<f64> for Ball {
        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            self.bounces = 0;
            x[0] = self.h0;
            x[1] = 0.0;
            Ok(())
        }

        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[1];
            dx[1] = -self.g + self.push + 0.0 * x[0].ln();
        }
    }

    impl Model for Ball {
        const N_STATES: usize = 2;
        const N_EVENT_INDICATORS: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo {
                identifier: "ball",
                description: "a bouncing ball",
                stop_time: 3.0,
                tolerance: 1e-6,
                output_interval: 0.01,
                documentation: "",
            }
        }

        fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
            z[0] = x[0];
        }

        fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
            if fired[0] && x[1] < 0.0 {
                self.bounces += 1;
                x[1] *= -self.e;
                if self.bounces == self.last {
                    return Ok(EventOutcome::Stop { reason: format!("bounce {} reached", self.bounces) });
                }
            }
            Ok(EventOutcome::Continue)
        }
    }

    fn vr(h: &Harness<Ball>, name: &str) -> u32 {
        h.instance.table().value_reference(name).unwrap()
    }

    /// Instantiated, initialized, in continuous-time mode with the initial states.
    fn running() -> Harness<Ball> {
        let mut h = Harness::<Ball>::model_exchange();
        h.instance.setup_experiment(None, 0.0, None).unwrap();
        h.instance.enter_initialization_mode().unwrap();
        h.instance.exit_initialization_mode().unwrap();
        assert_eq!(h.instance.state(), FmiState::EventMode);
        let info = h.instance.update_discrete_states().unwrap();
        assert!(!info.discrete_states_need_update && !info.terminate_simulation && !info.values_of_continuous_states_changed);
        h.instance.enter_continuous_time_mode().unwrap();
        h
    }

    /// The whole Model Exchange sequence on the ball, driven here as an importer would: the
    /// derivatives are the model's, a crossing of h through 0 is an event whose update reverses
    /// the velocity (valuesOfContinuousStatesChanged), and the third bounce ends the
    /// experiment with terminateSimulation and a logged reason.
    #[test]
    fn the_event_machinery_runs_as_the_standard_describes() {
        let mut h = running();
        let mut x = [0.0; 2];
        h.instance.get_continuous_states(&mut x).unwrap();
        assert_eq!(x, [1.0, 0.0]);
        let mut dx = [0.0; 2];
        h.instance.set_time(0.1).unwrap();
        h.instance.set_continuous_states(&[0.5, -2.0]).unwrap();
        h.instance.get_derivatives(&mut dx).unwrap();
        assert_eq!(dx, [-2.0, -9.81]);
        assert_eq!(h.get("der(v)").unwrap(), -9.81, "der(x) variables read the derivatives");
        assert_eq!(h.get("time").unwrap(), 0.1);
        let step = h.instance.completed_integrator_step().unwrap();
        assert!(!step.enter_event_mode && !step.terminate_simulation);
        // Just past the ground: the indicator changed sign.
        for bounce in 1..=3 {
            h.instance.set_continuous_states(&[-1e-12, -3.0]).unwrap();
            assert!(
                h.instance.completed_integrator_step().unwrap().enter_event_mode,
                "a sign change the importer did not locate asks for an event"
            );
            h.instance.enter_event_mode().unwrap();
            let info = h.instance.update_discrete_states().unwrap();
            assert_eq!(h.get("bounces").unwrap(), bounce as f64);
            if bounce < 3 {
                assert!(info.values_of_continuous_states_changed && !info.terminate_simulation && !info.discrete_states_need_update);
                // A second update at the same instant finds nothing new.
                let again = h.instance.update_discrete_states().unwrap();
                assert!(!again.values_of_continuous_states_changed);
                h.instance.enter_continuous_time_mode().unwrap();
                h.instance.get_continuous_states(&mut x).unwrap();
                assert_eq!(x, [-1e-12, 1.5]);
                // Up through the ground again: an event too, which changes nothing.
                h.instance.set_continuous_states(&[0.2, 1.0]).unwrap();
                assert!(h.instance.completed_integrator_step().unwrap().enter_event_mode);
                h.instance.enter_event_mode().unwrap();
                assert!(!h.instance.update_discrete_states().unwrap().values_of_continuous_states_changed);
                h.instance.enter_continuous_time_mode().unwrap();
                // Above the ground: the reference moves with the completed steps.
                h.instance.set_continuous_states(&[0.1, -1.0]).unwrap();
                assert!(!h.instance.completed_integrator_step().unwrap().enter_event_mode);
            } else {
                assert!(info.terminate_simulation);
                assert!(
                    h.messages().iter().any(|m| m.contains("the simulation ended at t = 0.1 s: bounce 3 reached")),
                    "{:?}",
                    h.messages()
                );
                let e = h.instance.enter_continuous_time_mode().unwrap_err().message;
                assert!(e.contains("terminateSimulation"), "{e}");
                assert!(h.instance.update_discrete_states().unwrap().terminate_simulation);
            }
        }
        h.instance.terminate().unwrap();
        assert_eq!(h.instance.state(), FmiState::Terminated);
        // n_steps and n_rhs count the importer's steps and derivative evaluations.
        assert_eq!((h.get("n_steps").unwrap(), h.get("n_rhs").unwrap()), (8.0, 1.0));
    }

    /// Each illegal call returns an error naming the call and the state (or the interface),
    /// and leaves the state unchanged.
    #[test]
    fn illegal_calls_are_refused_with_the_reason() {
        let mut h = Harness::<Ball>::model_exchange();
        let e = h.instance.get_derivatives(&mut [0.0; 2]).unwrap_err().message;
        assert!(e.contains("fmi2GetDerivatives is not allowed in state Instantiated"), "{e}");
        let mut h = running();
        let e = h.instance.do_step(0.0, 0.1).unwrap_err().message;
        assert!(e.contains("fmi2DoStep is a Co-Simulation function, but this instance was instantiated for Model Exchange"), "{e}");
        let e = h.instance.update_discrete_states().unwrap_err().message;
        assert!(e.contains("fmi2NewDiscreteStates is not allowed in state ContinuousTimeMode"), "{e}");
        let e = h.instance.set_integer(&[vr(&h, "last")], &[5]).unwrap_err().message;
        assert!(e.contains("fmi2SetInteger is not allowed in state ContinuousTimeMode"), "{e}");
        let e = h.instance.set_real(&[vr(&h, "g")], &[1.0]).unwrap_err().message;
        assert!(e.contains("'g' can be set in state ContinuousTimeMode only if it is a continuous-time input"), "{e}");
        h.instance.set_real(&[vr(&h, "push")], &[1.0]).unwrap();
        let e = h.instance.set_continuous_states(&[1.0]).unwrap_err().message;
        assert!(e.contains("nx = 1, but this FMU has 2"), "{e}");
        h.instance.enter_event_mode().unwrap();
        let e = h.instance.set_continuous_states(&[1.0, 0.0]).unwrap_err().message;
        assert!(e.contains("fmi2SetContinuousStates is not allowed in state EventMode"), "{e}");
        let e = h.instance.completed_integrator_step().unwrap_err().message;
        assert!(e.contains("not allowed in state EventMode"), "{e}");
        // Event mode: tunable parameters and inputs, not fixed parameters.
        h.instance.set_real(&[vr(&h, "g")], &[1.62]).unwrap();
        let e = h.instance.set_real(&[vr(&h, "h0")], &[2.0]).unwrap_err().message;
        assert!(
            e.contains("parameter 'h0' is fixed and can be set only before fmi2ExitInitializationMode (now in state EventMode)"),
            "{e}"
        );
        assert_eq!(h.instance.state(), FmiState::EventMode);
        let mut status = Harness::<Ball>::new();
        let e = status.instance.enter_event_mode().unwrap_err().message;
        assert!(e.contains("fmi2EnterEventMode is a Model Exchange function, but this instance was instantiated for Co-Simulation"), "{e}");
    }

    /// Values the importer gives or asks for that are not finite: refused states leave the
    /// instance as it was (fmi2Discard), derivatives that overflow are fmi2Discard with the
    /// variable named, and the instance stays usable.
    #[test]
    fn values_that_are_not_finite_are_discarded_not_fatal() {
        let mut h = running();
        let f = h.instance.set_continuous_states(&[f64::NAN, 0.0]).unwrap_err();
        assert_eq!(f.status, Status::Discard);
        assert!(f.message.contains("x[0] = NaN is not finite"), "{}", f.message);
        let mut x = [0.0; 2];
        h.instance.get_continuous_states(&mut x).unwrap();
        assert_eq!(x, [1.0, 0.0]);
        // The derivative has 0 * ln(h), which is NaN for h < 0.
        h.instance.set_continuous_states(&[-1.0, 0.0]).unwrap();
        let f = h.instance.get_derivatives(&mut [0.0; 2]).unwrap_err();
        assert_eq!(f.status, Status::Discard);
        assert!(f.message.contains("der(v) = NaN at t = 0 s is not finite"), "{}", f.message);
        assert_eq!(h.instance.state(), FmiState::ContinuousTimeMode);
        h.instance.set_continuous_states(&[0.5, 0.0]).unwrap();
        h.instance.get_derivatives(&mut [0.0; 2]).unwrap();
        assert!(h.instance.set_time(f64::INFINITY).unwrap_err().message.contains("must be finite"));
    }

    /// A captured FMU state brings back the mode and the indicator references; a state taken
    /// in a mode of the other interface is refused.
    #[test]
    fn fmu_states_restore_the_mode_and_stay_within_their_interface() {
        let mut h = running();
        h.instance.set_continuous_states(&[0.3, -1.0]).unwrap();
        h.instance.completed_integrator_step().unwrap();
        let saved = h.instance.get_fmu_state().unwrap();
        h.instance.set_continuous_states(&[-0.1, -1.0]).unwrap();
        h.instance.enter_event_mode().unwrap();
        h.instance.update_discrete_states().unwrap();
        assert_eq!(h.get("bounces").unwrap(), 1.0);
        h.instance.set_fmu_state(&saved).unwrap();
        assert_eq!((h.instance.state(), h.get("bounces").unwrap()), (FmiState::ContinuousTimeMode, 0.0));
        h.instance.set_continuous_states(&[-0.1, -1.0]).unwrap();
        assert!(h.instance.completed_integrator_step().unwrap().enter_event_mode, "the restored reference still sees the crossing");
        let mut cs = Harness::<Ball>::new();
        let e = cs.instance.set_fmu_state(&saved).unwrap_err().message;
        assert!(e.contains("taken in state ContinuousTimeMode by an instance this one (Co-Simulation) cannot continue"), "{e}");
    }

    /// x, y on a circle of radius r turning at w: integrated by forward Euler the radius
    /// drifts outward by a factor sqrt(1 + (w h)^2) per step.
    #[derive(Debug, Clone, Serialize, Deserialize)]
    struct Ring {
        r: f64,
    }

    impl Default for Ring {
        fn default() -> Self {
            Ring { r: 2.0 }
        }
    }

    impl Variables for Ring {
        fn variables() -> Vec<Variable<Self>> {
            vec![Variable::parameter("r", "", |m| m.r, |m, v| m.r = v), Variable::state("x", "", 0), Variable::state("y", "", 1)]
        }
    }

    impl fmu_export::Equations<f64> for Ring {
        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x[0] = self.r;
            x[1] = 0.0;
            Ok(())
        }

        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = -x[1];
            dx[1] = x[0];
        }
    }

    impl Model for Ring {
        const N_STATES: usize = 2;

        fn info() -> ModelInfo {
            ModelInfo {
                identifier: "ring",
                description: "a point on a circle",
                stop_time: 1.0,
                tolerance: 1e-6,
                output_interval: 0.1,
                documentation: "",
            }
        }

        fn constraint_drift(&self, x: &[f64]) -> f64 {
            (x[0].hypot(x[1]) - self.r).abs() / self.r
        }

        fn communication_point(&mut self, _t: f64, x: &mut [f64]) -> Result<EventOutcome, ModelError> {
            let scale = self.r / x[0].hypot(x[1]);
            x[0] *= scale;
            x[1] *= scale;
            Ok(EventOutcome::Continue)
        }
    }

    /// A drift beyond the relative tolerance is a step event: fmi2CompletedIntegratorStep asks
    /// for event mode, whose update projects the states back onto the constraint and reports
    /// valuesOfContinuousStatesChanged; a drift within the tolerance is left alone.
    #[test]
    fn constraint_drift_is_projected_at_a_step_event() {
        let mut h = Harness::<Ring>::model_exchange();
        h.instance.setup_experiment(Some(1e-6), 0.0, None).unwrap();
        h.instance.enter_initialization_mode().unwrap();
        h.instance.exit_initialization_mode().unwrap();
        h.instance.update_discrete_states().unwrap();
        h.instance.enter_continuous_time_mode().unwrap();
        h.instance.set_continuous_states(&[2.0 * (1.0 + 1e-7), 0.0]).unwrap();
        assert!(!h.instance.completed_integrator_step().unwrap().enter_event_mode, "a drift of 1e-7 < rtol 1e-6 is left");
        h.instance.set_continuous_states(&[0.0, 2.0 * (1.0 + 1e-5)]).unwrap();
        assert!(h.instance.completed_integrator_step().unwrap().enter_event_mode);
        h.instance.enter_event_mode().unwrap();
        let info = h.instance.update_discrete_states().unwrap();
        assert!(info.values_of_continuous_states_changed && !info.terminate_simulation);
        let mut x = [0.0; 2];
        h.instance.get_continuous_states(&mut x).unwrap();
        assert_eq!(x, [0.0, 2.0]);
    }
}
