//! The FMI 2.0 front ends: the Co-Simulation and the Model Exchange state machines over the
//! model core. Each call is checked against the standard's table (`state_machine`), handed to
//! the core, and the core's outcome turned into a status and the next state. The calls both
//! interfaces share and the Co-Simulation ones are here, the Model Exchange ones in
//! `model_exchange`; the C glue (`ffi`) only converts pointers and statuses around them, and
//! one `fmi2Instantiate` makes an instance of either by `fmuType`. `describe` writes the
//! modelDescription.xml.

pub mod describe;
pub mod ffi;
mod model_exchange;
pub mod state_machine;

use std::ffi::CString;

use crate::core::{CallResult, Core, Failure, Names, Phase, State, StepEnd};
use crate::logging::{Logger, Status, LOG_CALLS};
use crate::model::Model;
use crate::table::Table;
pub use model_exchange::EventInfo;
use state_machine::{Call, FmiState, Interface};

/// The FMI 2.0 names the core's messages refer to.
const NAMES: Names =
    Names { setup: "fmi2SetupExperiment", exit_initialization: "fmi2ExitInitializationMode", real: "Real", integer: "Integer" };

/// A live FMI 2.0 instance of model `M`, for one interface.
pub struct Instance<M: Model> {
    core: Core<M>,
    state: FmiState,
    interface: Interface,
    /// The C strings the last `fmi2GetString` handed out.
    returned_strings: Vec<CString>,
}

impl<M: Model> Instance<M> {
    /// A new Co-Simulation instance in state Instantiated with the table's start values.
    pub fn new(name: &str, logger: Logger) -> Instance<M> {
        Self::for_interface(name, logger, Interface::CoSimulation)
    }

    /// A new instance of `interface` in state Instantiated with the table's start values.
    pub fn for_interface(name: &str, logger: Logger, interface: Interface) -> Instance<M> {
        Instance { core: Core::new(name, logger, NAMES), state: FmiState::Instantiated, interface, returned_strings: Vec::new() }
    }

    /// Lets the model read the FMU's resources from `dir` (at instantiation).
    pub fn load_resources(&mut self, dir: &std::path::Path) -> Result<(), crate::model::ModelError> {
        self.core.load_resources(dir)
    }

    /// The current state-machine state.
    pub fn state(&self) -> FmiState {
        self.state
    }

    /// The interface the instance was created for.
    pub fn interface(&self) -> Interface {
        self.interface
    }

    /// The instance's variable table.
    pub fn table(&self) -> &Table<M> {
        self.core.table()
    }

    /// The model's current time.
    pub fn time(&self) -> f64 {
        self.core.time()
    }

    /// The instance's logger.
    pub fn logger(&mut self) -> &mut Logger {
        &mut self.core.logger
    }

    /// Refuses `call` when the state machine does not allow it now, or when it belongs to the
    /// other interface.
    #[inline]
    pub fn check(&self, call: Call) -> CallResult {
        if self.permits(call) {
            Ok(())
        } else {
            Err(self.illegal(call))
        }
    }

    /// True when `call` is allowed now (what [`Instance::check`] decides, as a flag).
    #[inline(always)]
    pub fn permits(&self, call: Call) -> bool {
        call.is_allowed_in(self.state) && call.interface().is_none_or(|i| i == self.interface)
    }

    // Out of line: every call passes `check`, and its message would otherwise be set up on
    // the hot path of fmi2DoStep, fmi2GetDerivatives and fmi2GetReal.
    #[cold]
    #[inline(never)]
    fn illegal(&self, call: Call) -> Failure {
        match call.interface() {
            Some(interface) if interface != self.interface => Failure::error(format!(
                "{} is a {} function, but this instance was instantiated for {}: illegal call sequence",
                call.name(),
                interface.name(),
                self.interface.name()
            )),
            _ => Failure::error(format!("{} is not allowed in state {}: illegal call sequence", call.name(), self.state.name())),
        }
    }

    /// Logs a call in the `logCalls` category (formatting only when someone listens).
    pub fn trace(&mut self, call: Call, args: impl FnOnce() -> String) {
        if self.core.logger.wants(LOG_CALLS) {
            let msg = format!("{}({})", call.name(), args());
            self.core.logger.log(Status::Ok, LOG_CALLS, &msg);
        }
    }

    /// Where the core's variable rules stand: parameters may be set until initialization ends.
    fn phase(&self) -> Phase {
        match self.state {
            FmiState::Instantiated | FmiState::InitializationMode => Phase::Initializing,
            FmiState::ContinuousTimeMode => Phase::ContinuousTime,
            _ if self.interface == Interface::ModelExchange => Phase::Event,
            _ => Phase::Running,
        }
    }

    /// A failure that broke the instance moves it to the Error state.
    #[inline]
    fn settle<T>(&mut self, result: CallResult<T>) -> CallResult<T> {
        if let Err(f) = &result {
            if f.broken {
                self.state = FmiState::Error;
            }
        }
        result
    }

    /// `fmi2SetupExperiment`.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        self.check(Call::SetupExperiment)?;
        self.core.setup(tolerance, start_time, stop_time)
    }

    /// `fmi2EnterInitializationMode`.
    pub fn enter_initialization_mode(&mut self) -> CallResult {
        self.check(Call::EnterInitializationMode)?;
        self.state = FmiState::InitializationMode;
        Ok(())
    }

    /// `fmi2ExitInitializationMode`: checks parameters and solver controls; Co-Simulation
    /// starts the solver and can step, Model Exchange enters event mode.
    pub fn exit_initialization_mode(&mut self) -> CallResult {
        self.check(Call::ExitInitializationMode)?;
        match self.interface {
            Interface::CoSimulation => {
                self.core.start()?;
                self.state = FmiState::StepComplete;
            }
            Interface::ModelExchange => {
                self.core.start_exchange()?;
                self.state = FmiState::EventMode;
            }
        }
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
        self.core.reset();
        self.state = FmiState::Instantiated;
        Ok(())
    }

    /// `fmi2GetReal` of states and time, when the state machine allows it (see
    /// [`Core::read_states`]): false sends the call down the checked path.
    #[inline(always)]
    pub fn read_states(&self, vrs: &[u32], values: &mut [f64]) -> bool {
        self.permits(Call::GetReal) && self.core.read_states(vrs, values)
    }

    /// `fmi2GetReal`, in one pass.
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
        self.check(Call::GetReal)?;
        let result = self.core.get_real(vrs, values, self.phase());
        self.settle(result)
    }

    /// `fmi2GetInteger`.
    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32]) -> CallResult {
        self.check(Call::GetInteger)?;
        self.core.get_integer(vrs, values, self.phase())
    }

    /// `fmi2GetBoolean`.
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> CallResult {
        self.check(Call::GetBoolean)?;
        self.core.get_boolean(vrs, values, self.phase())
    }

    /// `fmi2GetString`: the values as C strings, which the instance keeps until its next
    /// `fmi2GetString` (or until it is freed): FMI 2.0 lets the importer use them until its
    /// next call into the instance, and longer does no harm.
    pub fn get_string(&mut self, vrs: &[u32]) -> CallResult<&[CString]> {
        self.check(Call::GetString)?;
        let values = self.core.get_string(vrs, self.phase())?;
        let texts: Result<Vec<CString>, _> = values.into_iter().map(CString::new).collect();
        self.returned_strings = texts.map_err(|_| Failure::error("a String value holds a NUL character and cannot be handed out"))?;
        Ok(&self.returned_strings)
    }

    /// `fmi2SetReal` (all or nothing: a refused call changes nothing).
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> CallResult {
        self.check(Call::SetReal)?;
        self.core.set_real(vrs, values, self.phase(), self.state.name())
    }

    /// `fmi2SetInteger` (all or nothing).
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> CallResult {
        self.check(Call::SetInteger)?;
        self.core.set_integer(vrs, values, self.phase(), self.state.name())
    }

    /// `fmi2SetBoolean` (all or nothing).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> CallResult {
        self.check(Call::SetBoolean)?;
        self.core.set_boolean(vrs, values, self.phase(), self.state.name())
    }

    /// `fmi2SetString` (all or nothing; the texts are copied).
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> CallResult {
        self.check(Call::SetString)?;
        self.core.set_string(vrs, values, self.phase(), self.state.name())
    }

    /// `fmi2DoStep`: integrates from the current communication point over `h`, handling events.
    /// Returns `Ok` or `Discard` (the model ended the experiment early).
    pub fn do_step(&mut self, current: f64, h: f64) -> CallResult<Status> {
        self.check(Call::DoStep)?;
        match self.core.do_step(current, h) {
            Ok(StepEnd::Completed) => Ok(Status::Ok),
            Ok(StepEnd::EndedEarly) => {
                self.state = FmiState::StepFailed;
                Ok(Status::Discard)
            }
            Err(f) => self.settle(Err(f)),
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

    /// `fmi2GetFMUstate`: a copy of everything needed to continue from here, with the
    /// state-machine state.
    pub fn get_fmu_state(&self) -> CallResult<(State<M>, FmiState)> {
        self.check(Call::GetFMUstate)?;
        Ok((self.core.capture(), self.state))
    }

    /// `fmi2SetFMUstate`: continues from a captured state, including its state-machine state.
    /// A state taken in a mode of the other interface is refused.
    pub fn set_fmu_state(&mut self, saved: &(State<M>, FmiState)) -> CallResult {
        self.check(Call::SetFMUstate)?;
        if saved.1.interface().is_some_and(|i| i != self.interface) {
            return Err(Failure::error(format!(
                "the FMU state was taken from a {} instance in state {}; this instance is for {}",
                saved.1.interface().map_or("", Interface::name),
                saved.1.name(),
                self.interface.name()
            )));
        }
        self.core.restore(&saved.0);
        self.state = saved.1;
        Ok(())
    }

    /// Replaces the logger's debug settings (`fmi2SetDebugLogging`).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> CallResult {
        self.check(Call::SetDebugLogging)?;
        self.core.logger.set_debug_logging(on, categories).map_err(Failure::error)
    }

    /// Marks the instance unusable after a panic in model code.
    pub fn poison(&mut self) {
        self.state = FmiState::Error;
    }
}

impl<M: Model> crate::glue::GlueInstance for Instance<M> {
    fn poison(&mut self) {
        Instance::poison(self)
    }

    fn logger(&mut self) -> &mut Logger {
        Instance::logger(self)
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
        assert!(e.contains(&format!("value reference {rate} is 'rate' of type Real, not an Integer variable")), "{e}");
        let e = h.instance.get_real(&[999], &mut [0.0]).unwrap_err().message;
        assert!(e.contains("value reference 999 is not a Real variable"), "{e}");
    }
}
