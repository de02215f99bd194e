//! FMI 2.0 for the one front end (`crate::frontend`): its state tables (`state_machine`), its
//! C functions (`ffi`), its modelDescription.xml (`describe`), and the one call whose meaning
//! is its own: `fmi2DoStep`, which reports a model that ended the experiment inside the step
//! as `fmi2Discard` and the state StepFailed (FMI 3.0 answers `terminateSimulation`). One
//! `fmi2Instantiate` makes an instance of either interface by `fmuType`.

pub mod describe;
pub mod ffi;
pub mod state_machine;

use crate::core::{CallResult, Names, StepEnd};
use crate::frontend::{self, Call, Row, Version, Words};
use crate::logging::Status;
use crate::model::Model;
use state_machine::FmiState;

/// FMI 2.0, as the front end's [`Version`].
pub struct Fmi2;

impl Version for Fmi2 {
    type State = FmiState;
    /// FMI 2.0's FMU states keep the state machine's state alone (no early return, so no
    /// pending event).
    type Saved = FmiState;

    const NAMES: Names =
        Names { setup: "fmi2SetupExperiment", exit_initialization: "fmi2ExitInitializationMode", real: "Real", integer: "Integer" };
    const WORDS: Words = Words {
        vrs: "vr[]",
        values: "value[]",
        n_states: "nx",
        n_indicators: "ni",
        states: "x[]",
        derivatives: "derivatives[]",
        indicators: "eventIndicators[]",
        nominals: "x_nominal[]",
        fmu_state: "FMUstate",
        token: "GUID",
        unknowns: "vUnknown_ref[]",
        knowns: "vKnown_ref[]",
        seed: "dvKnown[]",
        sensitivity: "dvUnknown[]",
        n_unknowns: "nUnknown",
        n_knowns: "nKnown",
    };
    const COMPONENT_MAGIC: u64 = 0x464d_4932_434f_4d50; // "FMI2COMP"
    const INDICATOR_VARIABLES: bool = false;

    const INSTANTIATED: FmiState = FmiState::Instantiated;
    const INITIALIZATION_MODE: FmiState = FmiState::InitializationMode;
    const STEP_MODE: FmiState = FmiState::StepComplete;
    const EVENT_MODE: FmiState = FmiState::EventMode;
    const CONTINUOUS_TIME_MODE: FmiState = FmiState::ContinuousTimeMode;
    const TERMINATED: FmiState = FmiState::Terminated;
    const ERROR: FmiState = FmiState::Error;

    #[inline(always)]
    fn row(call: Call) -> Row {
        state_machine::row(call)
    }

    fn state_tag<M: Model>() -> u64 {
        frontend::ffi::model_tag::<M>()
    }

    fn save(state: FmiState, _pending_event: &Option<Vec<bool>>) -> FmiState {
        state
    }

    fn restore(saved: &FmiState) -> (FmiState, Option<Vec<bool>>) {
        (*saved, None)
    }
}

/// A live FMI 2.0 instance of model `M`, for one interface.
pub type Instance<M> = frontend::Instance<Fmi2, M>;

impl<M: Model> Instance<M> {
    /// `fmi2DoStep`: integrates from the current communication point over `h`, handling events.
    /// Returns `Ok` or `Discard` (the model ended the experiment early).
    pub fn do_step(&mut self, current: f64, h: f64) -> CallResult<Status> {
        self.check(Call::DoStep)?;
        let result = self.core.do_step(current, h);
        match self.settle(result)? {
            StepEnd::Completed => Ok(Status::Ok),
            StepEnd::EndedEarly => {
                self.state = FmiState::StepFailed;
                Ok(Status::Discard)
            }
        }
    }

    /// `fmi2GetStatus(fmi2DoStepStatus)`: the status of the last step.
    pub fn do_step_status(&self) -> CallResult<Status> {
        self.check(Call::GetStatus)?;
        Ok(self.core.last_step_status())
    }

    /// `fmi2GetRealStatus(fmi2LastSuccessfulTime)`.
    pub fn last_successful_time(&self) -> CallResult<f64> {
        self.check(Call::GetRealStatus)?;
        Ok(self.core.last_successful_time())
    }

    /// `fmi2GetBooleanStatus(fmi2Terminated)`: true once the model ended the experiment.
    pub fn terminated(&self) -> CallResult<bool> {
        self.check(Call::GetBooleanStatus)?;
        Ok(self.core.terminated())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::harness::Harness;
    use crate::model::{ModelError, ModelInfo, Variability, Variable, Variables};
    use serde::{Deserialize, Serialize};

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

    impl Variables for Growth {
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
    }

    impl fmu_export::Equations<f64> for Growth {
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

    impl Model for Growth {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo {
                identifier: "growth",
                description: "exponential growth",
                stop_time: 1.0,
                tolerance: 1e-6,
                output_interval: 0.1,
                documentation: "",
            }
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
        assert!(e.contains(&format!("value reference {rate} is 'rate' of type Real, not an Integer variable")), "{e}");
        let e = h.instance.get_real(&[999], &mut [0.0]).unwrap_err().message;
        assert!(e.contains("value reference 999 is not a Real variable"), "{e}");
    }
}
