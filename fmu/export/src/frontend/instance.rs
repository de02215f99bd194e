//! The instance both versions serve: the model core, the state machine's state, and how the
//! instance was created. Each call is checked against the version's table, handed to the core,
//! and the core's outcome turned into the next state. The Model Exchange calls are in
//! `model_exchange`; the calls whose meaning differs between the versions (the step) are in
//! the version modules.

use std::ffi::CString;

use super::{Call, DiscreteUpdate, Interface, MachineState, Setup, Version};
use crate::core::{CallResult, Core, EventUpdate, Failure, Phase, State};
use crate::logging::{Logger, Status, LOG_CALLS};
use crate::model::Model;
use crate::table::Table;

/// A live instance of model `M` in FMI version `V`.
pub struct Instance<V: Version, M: Model> {
    pub(crate) core: Core<M>,
    pub(crate) state: V::State,
    pub(crate) setup: Setup,
    /// Co-Simulation with Event Mode (FMI 3.0): the event a step stopped at, which Event Mode
    /// has still to handle.
    pub(crate) pending_event: Option<Vec<bool>>,
    /// The C strings the last String getter handed out.
    returned_strings: Vec<CString>,
}

impl<V: Version, M: Model> Instance<V, M> {
    /// A new instance in state Instantiated with the table's start values.
    pub fn new(name: &str, logger: Logger, setup: Setup) -> Instance<V, M> {
        Instance {
            core: Core::new(name, logger, V::NAMES),
            state: V::INSTANTIATED,
            setup,
            pending_event: None,
            returned_strings: Vec::new(),
        }
    }

    /// A new instance of `interface`, without Event Mode or early return.
    pub fn for_interface(name: &str, logger: Logger, interface: Interface) -> Instance<V, M> {
        Self::new(name, logger, Setup::plain(interface))
    }

    /// Lets the model read the FMU's resources from `dir` (at instantiation).
    pub fn load_resources(&mut self, dir: &std::path::Path) -> Result<(), crate::model::ModelError> {
        self.core.load_resources(dir)
    }

    /// The current state-machine state.
    pub fn state(&self) -> V::State {
        self.state
    }

    /// The interface the instance was created for.
    pub fn interface(&self) -> Interface {
        self.setup.interface
    }

    /// How the instance was created.
    pub fn setup(&self) -> Setup {
        self.setup
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
        let row = V::row(call);
        row.allowed & self.state.bit() != 0 && row.interface.is_none_or(|i| i == self.setup.interface)
    }

    // Out of line: every call passes `check`, and its message would otherwise be set up on
    // the hot paths (DoStep, GetDerivatives, GetReal).
    #[cold]
    #[inline(never)]
    fn illegal(&self, call: Call) -> Failure {
        let row = V::row(call);
        match row.interface {
            Some(interface) if interface != self.setup.interface => Failure::error(format!(
                "{} is a {} function, but this instance was instantiated for {}: illegal call sequence",
                row.name,
                interface.name(),
                self.setup.interface.name()
            )),
            _ => Failure::error(format!("{} is not allowed in state {}: illegal call sequence", row.name, self.state.name())),
        }
    }

    /// Refuses a call the state machine allows now but these FMUs do not serve, naming why
    /// (the table's reason).
    pub fn refuse(&self, call: Call) -> CallResult {
        self.check(call)?;
        let row = V::row(call);
        Err(Failure::error(format!("{}: {}", row.name, row.refused.unwrap_or("this FMU does not provide it"))))
    }

    /// Logs a call in the `logCalls` category (formatting only when someone listens).
    pub fn trace(&mut self, call: Call, args: impl FnOnce() -> String) {
        if self.core.logger.wants(LOG_CALLS) {
            let msg = format!("{}({})", V::name(call), args());
            self.core.logger.log(Status::Ok, LOG_CALLS, &msg);
        }
    }

    /// Where the core's variable rules stand: parameters may be set until initialization
    /// ends; under Model Exchange the states are the importer's.
    pub(crate) fn phase(&self) -> Phase {
        if self.state == V::INSTANTIATED || self.state == V::INITIALIZATION_MODE {
            Phase::Initializing
        } else if self.state == V::CONTINUOUS_TIME_MODE {
            Phase::ContinuousTime
        } else if self.setup.interface == Interface::ModelExchange {
            Phase::Event
        } else {
            Phase::Running
        }
    }

    /// A failure that broke the instance moves it to the Error state.
    #[inline]
    pub(crate) fn settle<T>(&mut self, result: CallResult<T>) -> CallResult<T> {
        if let Err(f) = &result {
            if f.broken {
                self.state = V::ERROR;
            }
        }
        result
    }

    /// `fmi2SetupExperiment` (FMI 3.0 passes the experiment to
    /// [`Instance::enter_initialization_mode_with`]).
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        self.check(Call::SetupExperiment)?;
        self.core.setup(tolerance, start_time, stop_time)
    }

    /// `fmi2EnterInitializationMode`, after [`Instance::setup_experiment`].
    pub fn enter_initialization_mode(&mut self) -> CallResult {
        self.check(Call::EnterInitializationMode)?;
        self.state = V::INITIALIZATION_MODE;
        Ok(())
    }

    /// `fmi3EnterInitializationMode`: the experiment's tolerance, start and stop time, and the
    /// mode, in one call.
    pub fn enter_initialization_mode_with(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        self.check(Call::EnterInitializationMode)?;
        self.core.setup(tolerance, start_time, stop_time)?;
        self.state = V::INITIALIZATION_MODE;
        Ok(())
    }

    /// `ExitInitializationMode`: checks parameters and solver controls; Co-Simulation starts
    /// the solver and can step (FMI 3.0 with `eventModeUsed`: from Event Mode), Model Exchange
    /// enters Event Mode.
    pub fn exit_initialization_mode(&mut self) -> CallResult {
        self.check(Call::ExitInitializationMode)?;
        match self.setup.interface {
            Interface::CoSimulation => {
                self.core.start()?;
                self.state = if self.setup.event_mode_used { V::EVENT_MODE } else { V::STEP_MODE };
            }
            Interface::ModelExchange => {
                self.core.start_exchange()?;
                self.state = V::EVENT_MODE;
            }
        }
        self.pending_event = None;
        Ok(())
    }

    /// `EnterEventMode`: Model Exchange at an event; FMI 3.0 Co-Simulation (only with
    /// `eventModeUsed`) after a step that asked for event handling, or whenever the importer
    /// has an event of its own.
    pub fn enter_event_mode(&mut self) -> CallResult {
        self.check(Call::EnterEventMode)?;
        if self.setup.interface == Interface::CoSimulation && !self.setup.event_mode_used {
            return Err(Failure::error(format!(
                "{}: this Co-Simulation instance was instantiated with eventModeUsed = false: illegal call sequence",
                V::name(Call::EnterEventMode)
            )));
        }
        self.state = V::EVENT_MODE;
        Ok(())
    }

    /// `fmi2NewDiscreteStates`, `fmi3UpdateDiscreteStates`: Model Exchange, the event at the
    /// current time and states (the core's `event_update`); Co-Simulation (FMI 3.0 Event
    /// Mode), the event the last step stopped at, if any. One update settles every event of
    /// these models.
    pub fn update_discrete_states(&mut self) -> CallResult<DiscreteUpdate> {
        self.check(Call::UpdateDiscreteStates)?;
        let (terminate_simulation, values_changed) = match self.setup.interface {
            Interface::ModelExchange => {
                let result = self.core.event_update();
                let EventUpdate { terminate_simulation, values_changed } = self.settle(result)?;
                (terminate_simulation, values_changed)
            }
            Interface::CoSimulation => match self.pending_event.take() {
                Some(fired) => {
                    let before = self.states_now();
                    let result = self.core.handle_located_event(&fired);
                    let end = self.settle(result)?;
                    (end.is_some(), before != self.states_now())
                }
                None => (self.core.terminated(), false),
            },
        };
        Ok(DiscreteUpdate {
            discrete_states_need_update: false,
            terminate_simulation,
            nominals_of_continuous_states_changed: false,
            values_of_continuous_states_changed: values_changed,
            next_event_time: None,
        })
    }

    /// The continuous states' bits now.
    fn states_now(&mut self) -> Vec<u64> {
        let mut x = vec![0.0; M::N_STATES];
        let _ = self.core.continuous_states(&mut x, false);
        x.iter().map(|v| v.to_bits()).collect()
    }

    /// `fmi3EnterStepMode`: from Event Mode back to stepping; refused while an event the last
    /// step stopped at has not been handled.
    pub fn enter_step_mode(&mut self) -> CallResult {
        self.check(Call::EnterStepMode)?;
        if self.pending_event.is_some() {
            return Err(Failure::error(format!(
                "{}: the event at t = {} s the last step stopped at is not handled yet: call {} first",
                V::name(Call::EnterStepMode),
                self.core.time(),
                V::name(Call::UpdateDiscreteStates)
            )));
        }
        self.state = V::STEP_MODE;
        Ok(())
    }

    /// `Terminate`.
    pub fn terminate(&mut self) -> CallResult {
        self.check(Call::Terminate)?;
        self.state = V::TERMINATED;
        self.pending_event = None;
        Ok(())
    }

    /// `Reset`: back to Instantiated with the start values (logging settings are kept).
    pub fn reset(&mut self) -> CallResult {
        self.check(Call::Reset)?;
        self.core.reset();
        self.state = V::INSTANTIATED;
        self.pending_event = None;
        Ok(())
    }

    /// The number of rows of the variable table; FMI 3.0's event indicators' value
    /// references follow it.
    fn rows(&self) -> usize {
        self.core.table().rows.len()
    }

    /// The Real getter of states and time, when the state machine allows it (see
    /// [`Core::read_states`]): false sends the call down the checked path.
    #[inline(always)]
    pub fn read_states(&self, vrs: &[u32], values: &mut [f64]) -> bool {
        self.permits(Call::GetReal) && self.core.read_states(vrs, values)
    }

    /// `fmi2GetReal`, `fmi3GetFloat64` (with FMI 3.0's event indicators), in one pass.
    pub fn get_real(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
        self.check(Call::GetReal)?;
        let result = if V::INDICATOR_VARIABLES && vrs.iter().any(|&vr| vr as usize >= self.rows()) {
            self.get_real_with_indicators(vrs, values)
        } else {
            self.core.get_real(vrs, values, self.phase())
        };
        self.settle(result)
    }

    /// [`Instance::get_real`] of a list that names event indicators, one value at a time.
    #[cold]
    #[inline(never)]
    fn get_real_with_indicators(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
        let rows = self.rows();
        let initializing = self.phase() == Phase::Initializing;
        let mut z = vec![0.0; M::N_EVENT_INDICATORS];
        let mut have_z = false;
        for (vr, value) in vrs.iter().zip(values.iter_mut()) {
            let i = *vr as usize;
            if i < rows {
                self.core.get_real(std::slice::from_ref(vr), std::slice::from_mut(value), self.phase())?;
            } else if i - rows < M::N_EVENT_INDICATORS {
                if !have_z {
                    self.core.event_indicators(&mut z, initializing)?;
                    have_z = true;
                }
                *value = z[i - rows];
            } else {
                return Err(Failure::error(format!("value reference {vr} is not a {} variable of this FMU", V::NAMES.real)));
            }
        }
        Ok(())
    }

    /// `fmi2GetInteger`, `fmi3GetInt32`.
    pub fn get_integer(&mut self, vrs: &[u32], values: &mut [i32]) -> CallResult {
        self.check(Call::GetInteger)?;
        self.core.get_integer(vrs, values, self.phase())
    }

    /// `GetBoolean`.
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> CallResult {
        self.check(Call::GetBoolean)?;
        self.core.get_boolean(vrs, values, self.phase())
    }

    /// `GetString`: the values as C strings, which the instance keeps until its next String
    /// getter (or until it is freed): FMI 2.0 lets the importer use them until its next call
    /// into the instance, FMI 3.0 likewise, and longer does no harm.
    pub fn get_string(&mut self, vrs: &[u32]) -> CallResult<&[CString]> {
        self.check(Call::GetString)?;
        let values = self.core.get_string(vrs, self.phase())?;
        let texts: Result<Vec<CString>, _> = values.into_iter().map(CString::new).collect();
        self.returned_strings = texts.map_err(|_| Failure::error("a String value holds a NUL character and cannot be handed out"))?;
        Ok(&self.returned_strings)
    }

    /// Refuses to set one of FMI 3.0's event indicators (a computed local), naming it.
    fn refuse_indicators(&self, vrs: &[u32]) -> CallResult {
        let rows = self.rows();
        match vrs.iter().find(|&&vr| (vr as usize) >= rows && (vr as usize) - rows < M::N_EVENT_INDICATORS) {
            Some(&vr) => {
                Err(Failure::error(format!("'{}' is a local variable and cannot be set", super::event_indicator_name(vr as usize - rows))))
            }
            None => Ok(()),
        }
    }

    /// `fmi2SetReal`, `fmi3SetFloat64` (all or nothing: a refused call changes nothing).
    pub fn set_real(&mut self, vrs: &[u32], values: &[f64]) -> CallResult {
        self.check(Call::SetReal)?;
        if V::INDICATOR_VARIABLES {
            self.refuse_indicators(vrs)?;
        }
        self.core.set_real(vrs, values, self.phase(), self.state.name())
    }

    /// `fmi2SetInteger`, `fmi3SetInt32` (all or nothing).
    pub fn set_integer(&mut self, vrs: &[u32], values: &[i32]) -> CallResult {
        self.check(Call::SetInteger)?;
        self.core.set_integer(vrs, values, self.phase(), self.state.name())
    }

    /// `SetBoolean` (all or nothing).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> CallResult {
        self.check(Call::SetBoolean)?;
        self.core.set_boolean(vrs, values, self.phase(), self.state.name())
    }

    /// `SetString` (all or nothing; the texts are copied).
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> CallResult {
        self.check(Call::SetString)?;
        self.core.set_string(vrs, values, self.phase(), self.state.name())
    }

    /// `GetFMUState`: a copy of everything needed to continue from here, with the state
    /// machine's state.
    pub fn get_fmu_state(&self) -> CallResult<(State<M>, V::Saved)> {
        self.check(Call::GetFMUState)?;
        Ok((self.core.capture(), V::save(self.state, &self.pending_event)))
    }

    /// `SetFMUState`: continues from a captured state, including its state machine's. A state
    /// taken in a mode of the other interface, or in Event Mode by a Co-Simulation instance
    /// that does not use it, is refused.
    pub fn set_fmu_state(&mut self, saved: &(State<M>, V::Saved)) -> CallResult {
        self.check(Call::SetFMUState)?;
        let (state, pending_event) = V::restore(&saved.1);
        let without_event_mode = self.setup.interface == Interface::CoSimulation && !self.setup.event_mode_used;
        // FMI 3.0's Co-Simulation has an Event Mode (with eventModeUsed), FMI 2.0's none.
        let could_have_event_mode = V::EVENT_MODE.interface().is_none();
        // FMI 3.0's Event Mode belongs to both interfaces, what the core holds there does not:
        // a Co-Simulation instance's own solver, which a Model Exchange instance never starts.
        let other_core = saved.0.integrator.is_some() != (self.setup.interface == Interface::CoSimulation);
        let foreign = state.interface().is_some_and(|i| i != self.setup.interface)
            || (without_event_mode && (state == V::EVENT_MODE || pending_event.is_some()))
            || (state == V::EVENT_MODE && other_core);
        if foreign {
            return Err(Failure::error(format!(
                "the FMU state was taken in state {} by an instance this one ({}{}) cannot continue",
                state.name(),
                self.setup.interface.name(),
                if without_event_mode && could_have_event_mode { ", without Event Mode" } else { "" }
            )));
        }
        self.core.restore(&saved.0);
        self.state = state;
        self.pending_event = pending_event;
        Ok(())
    }

    /// Replaces the logger's debug settings (`SetDebugLogging`).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> CallResult {
        self.check(Call::SetDebugLogging)?;
        self.core.logger.set_debug_logging(on, categories).map_err(Failure::error)
    }

    /// Marks the instance unusable after a panic in model code.
    pub fn poison(&mut self) {
        self.state = V::ERROR;
    }
}
