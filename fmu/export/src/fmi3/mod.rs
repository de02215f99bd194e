//! FMI 3.0 for the one front end (`crate::frontend`): its state tables (`state_machine`), its
//! C functions (`ffi`), its modelDescription.xml (`describe`), and the one call whose meaning
//! is its own: `fmi3DoStep`, with Event Mode and early return.
//!
//! Co-Simulation steps three ways, by what the importer asked for at instantiation:
//! - neither Event Mode nor early return: as FMI 2.0, events handled inside the step;
//! - `eventModeUsed` and `earlyReturnAllowed`: the step stops at a located event, before the
//!   model handles it, with `eventHandlingNeeded` and `earlyReturn`; the importer enters Event
//!   Mode, where `fmi3UpdateDiscreteStates` lets the model handle it, and steps on from there;
//! - early return without Event Mode: the step stops right after the model handled the event,
//!   with `earlyReturn`, so the importer sees the event's time;
//! - Event Mode without early return: the FMU cannot stop inside a step, so it handles the
//!   events there, as FMI 2.0 does.
//!
//! The event indicators are variables in FMI 3.0 (ModelStructure/EventIndicator names them):
//! `event_indicator_<k>`, Float64 locals after the table's rows, readable with `fmi3GetFloat64`.

pub mod describe;
pub mod ffi;
pub mod state_machine;

use serde::{Deserialize, Serialize};

use crate::core::{CallResult, Names, StepEnd, StepStop};
use crate::frontend::{self, Call, Row, Version, Words};
pub use crate::frontend::{event_indicator_name, Setup};
use crate::model::Model;
use state_machine::FmiState;

/// FMI 3.0, as the front end's [`Version`].
pub struct Fmi3;

impl Version for Fmi3 {
    type State = FmiState;
    type Saved = Machine;

    const NAMES: Names = Names {
        setup: "fmi3EnterInitializationMode",
        exit_initialization: "fmi3ExitInitializationMode",
        real: "Float64",
        integer: "Int32",
    };
    const WORDS: Words = Words {
        vrs: "valueReferences[]",
        values: "values[]",
        n_states: "nContinuousStates",
        n_indicators: "nEventIndicators",
        states: "continuousStates[]",
        derivatives: "derivatives[]",
        indicators: "eventIndicators[]",
        nominals: "nominals[]",
        fmu_state: "FMUState",
        token: "instantiationToken",
        unknowns: "unknowns[]",
        knowns: "knowns[]",
        seed: "seed[]",
        sensitivity: "sensitivity[]",
        n_unknowns: "nUnknowns",
        n_knowns: "nKnowns",
    };
    const COMPONENT_MAGIC: u64 = 0x464d_4933_494e_5354; // "FMI3INST"
    const INDICATOR_VARIABLES: bool = true;

    const INSTANTIATED: FmiState = FmiState::Instantiated;
    const INITIALIZATION_MODE: FmiState = FmiState::InitializationMode;
    const STEP_MODE: FmiState = FmiState::StepMode;
    const EVENT_MODE: FmiState = FmiState::EventMode;
    const CONTINUOUS_TIME_MODE: FmiState = FmiState::ContinuousTimeMode;
    const TERMINATED: FmiState = FmiState::Terminated;
    const ERROR: FmiState = FmiState::Error;

    #[inline(always)]
    fn row(call: Call) -> Row {
        state_machine::row(call)
    }

    /// Not FMI 2.0's tag, so a state of one version is refused by the other instead of misread.
    fn state_tag<M: Model>() -> u64 {
        frontend::ffi::model_tag::<M>().rotate_left(17) ^ 0x0000_0000_0000_0030
    }

    fn save(state: FmiState, pending_event: &Option<Vec<bool>>) -> Machine {
        Machine { state, pending_event: pending_event.clone() }
    }

    fn restore(saved: &Machine) -> (FmiState, Option<Vec<bool>>) {
        (saved.state, saved.pending_event.clone())
    }
}

/// What an FMI 3.0 FMU state holds besides the core's state: the state-machine state and an
/// event a step stopped at that Event Mode has still to handle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Machine {
    pub state: FmiState,
    pub pending_event: Option<Vec<bool>>,
}

/// What `fmi3DoStep` returns besides its status.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepResult {
    pub event_handling_needed: bool,
    pub terminate_simulation: bool,
    pub early_return: bool,
    pub last_successful_time: f64,
}

/// A live FMI 3.0 instance of model `M`.
pub type Instance<M> = frontend::Instance<Fmi3, M>;

impl<M: Model> Instance<M> {
    /// `fmi3DoStep` from `current` over `h` (see the module documentation for the three
    /// ways). The model ending the experiment inside the step (a landing, a limit position)
    /// answers `terminateSimulation` at the time it ended, with `fmi3OK`, and so does every
    /// later step.
    // The way the runner steps (early return allowed, no event in the step) is inlined into
    // fmi3DoStep, so one frame serves the usual call; the other ways are out of line (inlining
    // them all took more instructions than the call it saved). With the event arms of
    // Core::step_to_event out of line too: 33 instructions fewer per step on the Ex. 4 sweep.
    #[inline(always)]
    pub fn do_step(&mut self, current: f64, h: f64) -> CallResult<StepResult> {
        self.check(Call::DoStep)?;
        if !self.setup.early_return_allowed || self.core.terminated() {
            return self.step_otherwise(current, h);
        }
        let t_end = current + h;
        let result = self.core.step_to_event(current, h);
        match self.settle(result)? {
            StepStop::Ended(end) => Ok(self.step_result(end, t_end, true)),
            StepStop::Event { fired } => self.step_to_located_event(fired, t_end),
        }
    }

    /// [`Instance::do_step`] without early return, or after the model ended the experiment.
    #[inline(never)]
    fn step_otherwise(&mut self, current: f64, h: f64) -> CallResult<StepResult> {
        let t_end = current + h;
        if self.core.terminated() {
            // The model ended the experiment (a landing in Event Mode, say) and the importer
            // stepped on regardless (fmpy 0.3 does, after fmi3UpdateDiscreteStates said so):
            // the answer repeats terminateSimulation, and nothing moves.
            let t = self.core.last_successful_time();
            let early_return = self.setup.early_return_allowed && t < t_end;
            return Ok(StepResult { event_handling_needed: false, terminate_simulation: true, early_return, last_successful_time: t });
        }
        let result = self.core.do_step(current, h);
        let end = self.settle(result)?;
        Ok(self.step_result(end, t_end, false))
    }

    /// A step with early return that stopped at the event `fired`: in Event Mode the importer
    /// handles it; otherwise it is handled here and the step returns at the event's time.
    #[inline(never)]
    fn step_to_located_event(&mut self, fired: Vec<bool>, t_end: f64) -> CallResult<StepResult> {
        if self.setup.event_mode_used {
            self.pending_event = Some(fired);
            let t = self.core.time();
            return Ok(StepResult {
                event_handling_needed: true,
                terminate_simulation: false,
                early_return: t < t_end,
                last_successful_time: t,
            });
        }
        let result = self.core.handle_located_event(&fired);
        let end = self.settle(result)?.unwrap_or(StepEnd::Completed);
        let t = self.core.time();
        let mut r = self.step_result(end, t_end, true);
        if end == StepEnd::Completed {
            // Handled, and back to the importer at the event's time.
            r.early_return = t < t_end;
            r.last_successful_time = t;
        }
        Ok(r)
    }

    /// The outputs of a step that ended with `end`.
    fn step_result(&self, end: StepEnd, t_end: f64, early_return_allowed: bool) -> StepResult {
        match end {
            StepEnd::Completed => {
                StepResult { event_handling_needed: false, terminate_simulation: false, early_return: false, last_successful_time: t_end }
            }
            StepEnd::EndedEarly => {
                let t = self.core.last_successful_time();
                StepResult {
                    event_handling_needed: false,
                    terminate_simulation: true,
                    early_return: early_return_allowed && t < t_end,
                    last_successful_time: t,
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frontend::Interface;
    use crate::logging::Logger;
    use crate::model::{EventOutcome, ModelError, ModelInfo, Variable, Variables};
    use serde::{Deserialize, Serialize};

    /// A ball dropped from 1 m that bounces with restitution 0.5 (an event: v <- -v/2).
    #[derive(Debug, Clone, Default, Serialize, Deserialize)]
    struct Ball {
        bounces: i32,
    }

    impl Variables for Ball {
        fn variables() -> Vec<Variable<Self>> {
            vec![Variable::state("h", "", 0), Variable::state("v", "", 1), Variable::integer_output("bounces", "", |m| m.bounces)]
        }
    }

    impl fmu_export::Equations<f64> for Ball {
        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x.copy_from_slice(&[1.0, 0.0]);
            Ok(())
        }

        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[1];
            dx[1] = -9.81;
        }
    }

    impl Model for Ball {
        const N_STATES: usize = 2;
        const N_EVENT_INDICATORS: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo {
                identifier: "ball3",
                description: "a bouncing ball",
                stop_time: 2.0,
                tolerance: 1e-8,
                output_interval: 0.1,
                documentation: "",
            }
        }

        fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
            z[0] = x[0];
        }

        fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
            if fired[0] && x[1] < 0.0 {
                self.bounces += 1;
                x[1] *= -0.5;
            }
            Ok(EventOutcome::Continue)
        }
    }

    fn started(event_mode_used: bool, early_return_allowed: bool) -> Instance<Ball> {
        let setup = Setup { interface: Interface::CoSimulation, event_mode_used, early_return_allowed };
        let mut i = Instance::<Ball>::new("ball", Logger::new(None, false), setup);
        i.enter_initialization_mode_with(None, 0.0, None).unwrap();
        i.exit_initialization_mode().unwrap();
        if event_mode_used {
            assert_eq!(i.state(), FmiState::EventMode);
            assert!(!i.update_discrete_states().unwrap().terminate_simulation);
            i.enter_step_mode().unwrap();
        }
        assert_eq!(i.state(), FmiState::StepMode);
        i
    }

    fn h_v(i: &mut Instance<Ball>) -> [f64; 2] {
        let mut x = [0.0; 2];
        i.get_real(&[0, 1], &mut x).unwrap();
        x
    }

    /// A value reference of the wrong type is refused in FMI 3.0's type names (Float64, Int32),
    /// not FMI 2.0's, which the core's messages would otherwise carry.
    #[test]
    fn wrongly_typed_references_are_named_in_fmi3_types() {
        let mut i = started(false, false);
        let e = i.get_integer(&[0], &mut [0]).unwrap_err().message;
        assert!(e.contains("value reference 0 is 'h' of type Float64, not an Int32 variable"), "{e}");
        let e = i.get_real(&[2], &mut [0.0]).unwrap_err().message;
        assert!(e.contains("value reference 2 is 'bounces' of type Int32, not a Float64 variable"), "{e}");
    }

    /// The first bounce, at sqrt(2/g) = 0.4515 s, inside the step from 0.4 to 0.5: with Event
    /// Mode the step stops there unhandled, Event Mode handles it, and stepping on to 0.5 ends
    /// where the step that handles it inside (FMI 2.0's way) ends, to rounding.
    #[test]
    fn a_step_stops_at_the_event_and_event_mode_handles_it() {
        let mut inside = started(false, false);
        let mut stops = started(true, true);
        for k in 0..4 {
            let t = f64::from(k) * 0.1;
            assert!(!inside.do_step(t, 0.1).unwrap().event_handling_needed);
            assert!(!stops.do_step(t, 0.1).unwrap().event_handling_needed);
        }
        let r = stops.do_step(0.4, 0.1).unwrap();
        let t_bounce = (2.0 / 9.81_f64).sqrt();
        assert!(r.event_handling_needed && r.early_return && !r.terminate_simulation);
        assert!((r.last_successful_time - t_bounce).abs() < 1e-9, "{}", r.last_successful_time);
        assert!(stops.enter_step_mode().is_err(), "the pending event must be handled first");
        let mut bounces = [0];
        stops.get_integer(&[2], &mut bounces).unwrap();
        assert_eq!(bounces, [0]);
        stops.enter_event_mode().unwrap();
        let u = stops.update_discrete_states().unwrap();
        assert!(u.values_of_continuous_states_changed && !u.terminate_simulation && !u.discrete_states_need_update);
        stops.get_integer(&[2], &mut bounces).unwrap();
        assert_eq!(bounces, [1]);
        stops.enter_step_mode().unwrap();
        // On from the bounce; the ball, located just below the ground, crosses it upwards
        // right after (an event the model ignores), as inside the FMI 2.0 step.
        let mut t = r.last_successful_time;
        let mut more = 0;
        loop {
            let r = stops.do_step(t, 0.5 - t).unwrap();
            if !r.event_handling_needed {
                assert!(!r.early_return);
                break;
            }
            more += 1;
            stops.enter_event_mode().unwrap();
            assert!(!stops.update_discrete_states().unwrap().values_of_continuous_states_changed);
            stops.enter_step_mode().unwrap();
            t = r.last_successful_time;
        }
        assert!(more <= 1);
        assert!((inside.do_step(0.4, 0.1).unwrap().last_successful_time - 0.5).abs() < 1e-15);
        let (a, b) = (h_v(&mut inside), h_v(&mut stops));
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12, "{a:?} {b:?}");
    }

    /// Early return without Event Mode: the model handles the event, and the step returns at
    /// its time with the handled state.
    #[test]
    fn early_return_without_event_mode_returns_the_handled_event() {
        let mut i = started(false, true);
        for k in 0..4 {
            i.do_step(f64::from(k) * 0.1, 0.1).unwrap();
        }
        let r = i.do_step(0.4, 0.1).unwrap();
        assert!(!r.event_handling_needed && r.early_return && r.last_successful_time < 0.5);
        assert!(h_v(&mut i)[1] > 0.0, "the ball goes up again");
        assert!(i.enter_event_mode().is_err(), "no Event Mode without eventModeUsed");
    }

    /// The event indicator is a Float64 variable after the table's, readable and not settable.
    #[test]
    fn the_event_indicator_is_a_variable() {
        let mut i = started(false, false);
        let n = i.table().rows.len() as u32;
        let mut z = [0.0; 2];
        i.get_real(&[n, 0], &mut z).unwrap();
        assert_eq!(z, [1.0, 1.0]);
        let e = i.set_real(&[n], &[0.0]).unwrap_err().message;
        assert!(e.contains("event_indicator_0"), "{e}");
        assert!(i.get_real(&[n + 1], &mut z[..1]).is_err());
    }
}
