//! The FMI 3.0 front end: the Co-Simulation (with Event Mode and early return) and Model
//! Exchange state machines over the same model core as FMI 2.0. Each call is checked against
//! the standard's table (`state_machine`), handed to the core, and the core's outcome turned
//! into a status and the next state; the C glue (`ffi`) only converts pointers and statuses,
//! and `describe` writes the FMI 3.0 modelDescription.xml from the same variable table.
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

use std::ffi::CString;

use serde::{Deserialize, Serialize};

use crate::core::{CallResult, Core, EventUpdate, Failure, Names, Phase, State, StepCompleted, StepEnd, StepStop};
use crate::logging::{Logger, Status, LOG_CALLS};
use crate::model::Model;
use crate::table::Table;
use state_machine::{Call, FmiState, Interface};

/// The FMI 3.0 names the core's messages refer to.
const NAMES: Names =
    Names { setup: "fmi3EnterInitializationMode", exit_initialization: "fmi3ExitInitializationMode", real: "Float64", integer: "Int32" };

/// The name of event indicator `k`'s variable.
pub fn event_indicator_name(k: usize) -> String {
    format!("event_indicator_{k}")
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

/// What `fmi3UpdateDiscreteStates` returns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscreteUpdate {
    pub discrete_states_need_update: bool,
    pub terminate_simulation: bool,
    pub nominals_of_continuous_states_changed: bool,
    pub values_of_continuous_states_changed: bool,
    /// `nextEventTimeDefined` and `nextEventTime`: these models have no time events.
    pub next_event_time: Option<f64>,
}

/// How an instance was created: its interface and, for Co-Simulation, what the importer
/// allows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Setup {
    pub interface: Interface,
    pub event_mode_used: bool,
    pub early_return_allowed: bool,
}

/// A live FMI 3.0 instance of model `M`.
pub struct Instance<M: Model> {
    core: Core<M>,
    machine: Machine,
    setup: Setup,
    /// The C strings the last `fmi3GetString` handed out.
    returned_strings: Vec<CString>,
}

impl<M: Model> Instance<M> {
    /// A new instance in state Instantiated with the table's start values.
    pub fn new(name: &str, logger: Logger, setup: Setup) -> Instance<M> {
        Instance {
            core: Core::new(name, logger, NAMES),
            machine: Machine { state: FmiState::Instantiated, pending_event: None },
            setup,
            returned_strings: Vec::new(),
        }
    }

    /// The current state-machine state.
    pub fn state(&self) -> FmiState {
        self.machine.state
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

    /// Lets the model read the FMU's resources from `dir` (at instantiation).
    pub fn load_resources(&mut self, dir: &std::path::Path) -> Result<(), crate::model::ModelError> {
        self.core.load_resources(dir)
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

    /// True when `call` is allowed now.
    #[inline(always)]
    pub fn permits(&self, call: Call) -> bool {
        call.is_allowed_in(self.machine.state) && call.interface().is_none_or(|i| i == self.setup.interface)
    }

    #[cold]
    #[inline(never)]
    fn illegal(&self, call: Call) -> Failure {
        match call.interface() {
            Some(interface) if interface != self.setup.interface => Failure::error(format!(
                "{} is a {} function, but this instance was instantiated for {}: illegal call sequence",
                call.name(),
                interface.name(),
                self.setup.interface.name()
            )),
            _ => Failure::error(format!("{} is not allowed in state {}: illegal call sequence", call.name(), self.machine.state.name())),
        }
    }

    /// Refuses a call the table allows but that does not apply to these FMUs, naming why.
    pub fn not_applicable(&self, call: Call, why: &str) -> CallResult {
        self.check(call)?;
        Err(Failure::error(format!("{}: {why}", call.name())))
    }

    /// Logs a call in the `logCalls` category (formatting only when someone listens).
    pub fn trace(&mut self, call: Call, args: impl FnOnce() -> String) {
        if self.core.logger.wants(LOG_CALLS) {
            let msg = format!("{}({})", call.name(), args());
            self.core.logger.log(Status::Ok, LOG_CALLS, &msg);
        }
    }

    /// Where the core's variable rules stand.
    fn phase(&self) -> Phase {
        match self.machine.state {
            FmiState::Instantiated | FmiState::InitializationMode => Phase::Initializing,
            FmiState::ContinuousTimeMode => Phase::ContinuousTime,
            FmiState::EventMode if self.setup.interface == Interface::ModelExchange => Phase::Event,
            _ => Phase::Running,
        }
    }

    /// A failure that broke the instance moves it to the Error state.
    #[inline]
    fn settle<T>(&mut self, result: CallResult<T>) -> CallResult<T> {
        if let Err(f) = &result {
            if f.broken {
                self.machine.state = FmiState::Error;
            }
        }
        result
    }

    /// `fmi3EnterInitializationMode`: the experiment's tolerance, start and stop time.
    pub fn enter_initialization_mode(&mut self, tolerance: Option<f64>, start_time: f64, stop_time: Option<f64>) -> CallResult {
        self.check(Call::EnterInitializationMode)?;
        self.core.setup(tolerance, start_time, stop_time)?;
        self.machine.state = FmiState::InitializationMode;
        Ok(())
    }

    /// `fmi3ExitInitializationMode`: checks parameters and solver controls; Co-Simulation
    /// starts the solver and enters Step Mode (Event Mode with `eventModeUsed`), Model
    /// Exchange enters Event Mode.
    pub fn exit_initialization_mode(&mut self) -> CallResult {
        self.check(Call::ExitInitializationMode)?;
        match self.setup.interface {
            Interface::CoSimulation => {
                self.core.start()?;
                self.machine.state = if self.setup.event_mode_used { FmiState::EventMode } else { FmiState::StepMode };
            }
            Interface::ModelExchange => {
                self.core.start_exchange()?;
                self.machine.state = FmiState::EventMode;
            }
        }
        self.machine.pending_event = None;
        Ok(())
    }

    /// `fmi3EnterEventMode`: Model Exchange at an event; Co-Simulation (only with
    /// `eventModeUsed`) after a step that asked for event handling, or whenever the importer
    /// has an event of its own.
    pub fn enter_event_mode(&mut self) -> CallResult {
        self.check(Call::EnterEventMode)?;
        if self.setup.interface == Interface::CoSimulation && !self.setup.event_mode_used {
            return Err(Failure::error(
                "fmi3EnterEventMode: this Co-Simulation instance was instantiated with eventModeUsed = false: illegal call sequence",
            ));
        }
        self.machine.state = FmiState::EventMode;
        Ok(())
    }

    /// `fmi3UpdateDiscreteStates`: Model Exchange, the event at the current time and states
    /// (the core's `event_update`); Co-Simulation, the event the last step stopped at, if any.
    /// One update settles every event of these models.
    pub fn update_discrete_states(&mut self) -> CallResult<DiscreteUpdate> {
        self.check(Call::UpdateDiscreteStates)?;
        let (terminate_simulation, values_changed) = match self.setup.interface {
            Interface::ModelExchange => {
                let result = self.core.event_update();
                let EventUpdate { terminate_simulation, values_changed } = self.settle(result)?;
                (terminate_simulation, values_changed)
            }
            Interface::CoSimulation => match self.machine.pending_event.take() {
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
        if self.machine.pending_event.is_some() {
            return Err(Failure::error(format!(
                "fmi3EnterStepMode: the event at t = {} s the last step stopped at is not handled yet: call fmi3UpdateDiscreteStates first",
                self.core.time()
            )));
        }
        self.machine.state = FmiState::StepMode;
        Ok(())
    }

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
            self.machine.pending_event = Some(fired);
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

    /// `fmi3Terminate`.
    pub fn terminate(&mut self) -> CallResult {
        self.check(Call::Terminate)?;
        self.machine.state = FmiState::Terminated;
        self.machine.pending_event = None;
        Ok(())
    }

    /// `fmi3Reset`: back to Instantiated with the start values (logging settings are kept).
    pub fn reset(&mut self) -> CallResult {
        self.check(Call::Reset)?;
        self.core.reset();
        self.machine = Machine { state: FmiState::Instantiated, pending_event: None };
        Ok(())
    }

    /// The number of rows of the variable table; the event indicators' value references
    /// follow it.
    fn rows(&self) -> usize {
        self.core.table().rows.len()
    }

    /// `fmi3GetFloat64` of states and time, when the state machine allows it (see
    /// [`crate::core::Core::read_states`]): false sends the call down the checked path.
    #[inline(always)]
    pub fn read_states(&self, vrs: &[u32], values: &mut [f64]) -> bool {
        self.permits(Call::GetFloat64) && self.core.read_states(vrs, values)
    }

    /// `fmi3GetFloat64`: the table's Real variables and the event indicators.
    pub fn get_float64(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
        self.check(Call::GetFloat64)?;
        let rows = self.rows();
        let result = if vrs.iter().all(|&vr| (vr as usize) < rows) {
            self.core.get_real(vrs, values, self.phase())
        } else {
            self.get_float64_with_indicators(vrs, values)
        };
        self.settle(result)
    }

    /// [`Instance::get_float64`] of a list that names event indicators, one value at a time.
    #[cold]
    #[inline(never)]
    fn get_float64_with_indicators(&mut self, vrs: &[u32], values: &mut [f64]) -> CallResult {
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
                return Err(Failure::error(format!("value reference {vr} is not a Float64 variable of this FMU")));
            }
        }
        Ok(())
    }

    /// `fmi3GetInt32`.
    pub fn get_int32(&mut self, vrs: &[u32], values: &mut [i32]) -> CallResult {
        self.check(Call::GetInt32)?;
        self.core.get_integer(vrs, values, self.phase())
    }

    /// `fmi3GetBoolean`.
    pub fn get_boolean(&mut self, vrs: &[u32], values: &mut [bool]) -> CallResult {
        self.check(Call::GetBoolean)?;
        self.core.get_boolean(vrs, values, self.phase())
    }

    /// `fmi3GetString`: the values as C strings, which the instance keeps until its next
    /// `fmi3GetString` (or until it is freed), at least as long as FMI 3.0 asks.
    pub fn get_string(&mut self, vrs: &[u32]) -> CallResult<&[CString]> {
        self.check(Call::GetString)?;
        let values = self.core.get_string(vrs, self.phase())?;
        let texts: Result<Vec<CString>, _> = values.into_iter().map(CString::new).collect();
        self.returned_strings = texts.map_err(|_| Failure::error("a String value holds a NUL character and cannot be handed out"))?;
        Ok(&self.returned_strings)
    }

    /// `fmi3SetString` (all or nothing; the texts are copied).
    pub fn set_string(&mut self, vrs: &[u32], values: &[&str]) -> CallResult {
        self.check(Call::SetString)?;
        self.core.set_string(vrs, values, self.phase(), self.machine.state.name())
    }

    /// Refuses to set an event indicator (a computed local), naming it.
    fn refuse_indicators(&self, vrs: &[u32]) -> CallResult {
        let rows = self.rows();
        match vrs.iter().find(|&&vr| (vr as usize) >= rows && (vr as usize) - rows < M::N_EVENT_INDICATORS) {
            Some(&vr) => {
                Err(Failure::error(format!("'{}' is a local variable and cannot be set", event_indicator_name(vr as usize - rows))))
            }
            None => Ok(()),
        }
    }

    /// `fmi3SetFloat64` (all or nothing: a refused call changes nothing).
    pub fn set_float64(&mut self, vrs: &[u32], values: &[f64]) -> CallResult {
        self.check(Call::SetFloat64)?;
        self.refuse_indicators(vrs)?;
        self.core.set_real(vrs, values, self.phase(), self.machine.state.name())
    }

    /// `fmi3SetInt32` (all or nothing).
    pub fn set_int32(&mut self, vrs: &[u32], values: &[i32]) -> CallResult {
        self.check(Call::SetInt32)?;
        self.core.set_integer(vrs, values, self.phase(), self.machine.state.name())
    }

    /// `fmi3SetBoolean` (all or nothing).
    pub fn set_boolean(&mut self, vrs: &[u32], values: &[bool]) -> CallResult {
        self.check(Call::SetBoolean)?;
        self.core.set_boolean(vrs, values, self.phase(), self.machine.state.name())
    }

    /// `fmi3GetFMUState`: a copy of everything needed to continue from here.
    pub fn get_fmu_state(&self) -> CallResult<(State<M>, Machine)> {
        self.check(Call::GetFMUState)?;
        Ok((self.core.capture(), self.machine.clone()))
    }

    /// `fmi3SetFMUState`: continues from a captured state, including its state-machine state.
    /// A state taken in a mode of the other interface, or in Event Mode by a Co-Simulation
    /// instance that does not use it, is refused.
    pub fn set_fmu_state(&mut self, saved: &(State<M>, Machine)) -> CallResult {
        self.check(Call::SetFMUState)?;
        let state = saved.1.state;
        let foreign = state.interface().is_some_and(|i| i != self.setup.interface)
            || (self.setup.interface == Interface::CoSimulation
                && !self.setup.event_mode_used
                && (state == FmiState::EventMode || saved.1.pending_event.is_some()));
        if foreign {
            return Err(Failure::error(format!(
                "fmi3SetFMUState: the FMU state was taken in state {} by an instance this one ({}{}) cannot continue",
                state.name(),
                self.setup.interface.name(),
                if self.setup.interface == Interface::CoSimulation && !self.setup.event_mode_used { ", without Event Mode" } else { "" }
            )));
        }
        self.core.restore(&saved.0);
        self.machine = saved.1.clone();
        Ok(())
    }

    /// Replaces the logger's debug settings (`fmi3SetDebugLogging`).
    pub fn set_debug_logging(&mut self, on: bool, categories: &[&str]) -> CallResult {
        self.check(Call::SetDebugLogging)?;
        self.core.logger.set_debug_logging(on, categories).map_err(Failure::error)
    }

    /// Marks the instance unusable after a panic in model code.
    pub fn poison(&mut self) {
        self.machine.state = FmiState::Error;
    }

    // Model Exchange (FMI 3.0 chapter 3), as FMI 2.0's with the 3.0 names.

    /// Refuses an array argument whose length is not the model's.
    fn check_length(call: Call, what: &str, n: usize, expected: usize) -> CallResult {
        if n == expected {
            Ok(())
        } else {
            Err(Failure::error(format!("{}: {what} = {n}, but this FMU has {expected}", call.name())))
        }
    }

    /// `fmi3EnterContinuousTimeMode`.
    pub fn enter_continuous_time_mode(&mut self) -> CallResult {
        self.check(Call::EnterContinuousTimeMode)?;
        self.core.enter_continuous_time()?;
        self.machine.state = FmiState::ContinuousTimeMode;
        Ok(())
    }

    /// `fmi3CompletedIntegratorStep`.
    pub fn completed_integrator_step(&mut self) -> CallResult<StepCompleted> {
        self.check(Call::CompletedIntegratorStep)?;
        self.core.completed_integrator_step()
    }

    /// `fmi3SetTime`: in Continuous-Time Mode, and in Event Mode only for a model without
    /// continuous states.
    #[inline]
    pub fn set_time(&mut self, t: f64) -> CallResult {
        self.check(Call::SetTime)?;
        if !(M::N_STATES == 0 || self.machine.state == FmiState::ContinuousTimeMode) {
            return Err(Failure::error(format!(
                "fmi3SetTime is not allowed in state {} of an FMU with continuous states (time advances in Continuous-Time Mode): illegal call sequence",
                self.machine.state.name()
            )));
        }
        self.core.set_time(t)
    }

    /// `fmi3SetContinuousStates`.
    #[inline]
    pub fn set_continuous_states(&mut self, x: &[f64]) -> CallResult {
        self.check(Call::SetContinuousStates)?;
        Self::check_length(Call::SetContinuousStates, "nContinuousStates", x.len(), M::N_STATES)?;
        self.core.set_continuous_states(x)
    }

    /// `fmi3GetContinuousStateDerivatives`: `fmi3Discard` for derivatives that are not finite.
    #[inline]
    pub fn get_continuous_state_derivatives(&mut self, dx: &mut [f64]) -> CallResult {
        self.check(Call::GetContinuousStateDerivatives)?;
        Self::check_length(Call::GetContinuousStateDerivatives, "nContinuousStates", dx.len(), M::N_STATES)?;
        let initializing = self.machine.state == FmiState::InitializationMode;
        self.core.derivatives(dx, initializing)
    }

    /// `fmi3GetEventIndicators`.
    pub fn get_event_indicators(&mut self, z: &mut [f64]) -> CallResult {
        self.check(Call::GetEventIndicators)?;
        Self::check_length(Call::GetEventIndicators, "nEventIndicators", z.len(), M::N_EVENT_INDICATORS)?;
        let initializing = self.machine.state == FmiState::InitializationMode;
        self.core.event_indicators(z, initializing)
    }

    /// `fmi3GetContinuousStates`.
    pub fn get_continuous_states(&mut self, x: &mut [f64]) -> CallResult {
        self.check(Call::GetContinuousStates)?;
        Self::check_length(Call::GetContinuousStates, "nContinuousStates", x.len(), M::N_STATES)?;
        let initializing = self.machine.state == FmiState::InitializationMode;
        self.core.continuous_states(x, initializing)
    }

    /// `fmi3GetNominalsOfContinuousStates`: 1 for every state (none declares a nominal).
    pub fn get_nominals_of_continuous_states(&mut self, nominals: &mut [f64]) -> CallResult {
        self.check(Call::GetNominalsOfContinuousStates)?;
        Self::check_length(Call::GetNominalsOfContinuousStates, "nContinuousStates", nominals.len(), M::N_STATES)?;
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

        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x.copy_from_slice(&[1.0, 0.0]);
            Ok(())
        }

        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[1];
            dx[1] = -9.81;
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
        i.enter_initialization_mode(None, 0.0, None).unwrap();
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
        i.get_float64(&[0, 1], &mut x).unwrap();
        x
    }

    /// A value reference of the wrong type is refused in FMI 3.0's type names (Float64, Int32),
    /// not FMI 2.0's, which the core's messages would otherwise carry.
    #[test]
    fn wrongly_typed_references_are_named_in_fmi3_types() {
        let mut i = started(false, false);
        let e = i.get_int32(&[0], &mut [0]).unwrap_err().message;
        assert!(e.contains("value reference 0 is 'h' of type Float64, not an Int32 variable"), "{e}");
        let e = i.get_float64(&[2], &mut [0.0]).unwrap_err().message;
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
        stops.get_int32(&[2], &mut bounces).unwrap();
        assert_eq!(bounces, [0]);
        stops.enter_event_mode().unwrap();
        let u = stops.update_discrete_states().unwrap();
        assert!(u.values_of_continuous_states_changed && !u.terminate_simulation && !u.discrete_states_need_update);
        stops.get_int32(&[2], &mut bounces).unwrap();
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
        i.get_float64(&[n, 0], &mut z).unwrap();
        assert_eq!(z, [1.0, 1.0]);
        let e = i.set_float64(&[n], &[0.0]).unwrap_err().message;
        assert!(e.contains("event_indicator_0"), "{e}");
        assert!(i.get_float64(&[n + 1], &mut z[..1]).is_err());
    }
}
