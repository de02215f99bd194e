//! An FMI 3.0 Co-Simulation instance. It uses Event Mode when the FMU has it (`hasEventMode`)
//! and lets the FMU return early at an event when it says it may (`mightReturnEarlyFromDoStep`):
//! a communication step is then a loop of `fmi3DoStep` calls, each event handled in Event Mode
//! (`fmi3UpdateDiscreteStates` until no update is needed), until the step's end is reached.

use std::ffi::{c_void, CString};

use fmi_c::fmi3 as c;

use super::component::{Component, OK, WARNING};
use super::{log_message, Binary, CoSimulationApi, Environment};
use crate::call_log::{self, boolean, list};
use crate::logging::LogContext;
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Step, Value, Variable};

/// More rounds of `fmi3UpdateDiscreteStates` than this at one event means the FMU never settles.
pub const MAX_EVENT_ITERATIONS: usize = 1000;

/// One Co-Simulation instance of an FMI 3.0 FMU.
pub struct CoSimulation<'a> {
    component: Component<'a>,
    cs: CoSimulationApi,
    event_mode: bool,
    early_return: bool,
}

impl<'a> CoSimulation<'a> {
    /// fmi3InstantiateCoSimulation; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<CoSimulation<'a>, String> {
        let caps = fmu.description.co_simulation.clone().unwrap_or_default();
        let cs = binary.api.co_simulation.expect("resolved for Co-Simulation");
        let env = Box::new(Environment { name: name.to_owned(), log: LogContext::default() });
        let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
        trace::enter(Call::Fmi3Instantiate, f64::NAN);
        let entered = call_log::enter("fmi3InstantiateCoSimulation", || {
            format!(
                "instanceName={name:?}, instantiationToken={:?}, resourcePath={:?}, visible=fmi3False, loggingOn={}, eventModeUsed={}, earlyReturnAllowed={}, requiredIntermediateVariables=[], nRequiredIntermediateVariables=0",
                fmu.token,
                fmu.resource_uri,
                boolean(3, debug_logging),
                boolean(3, caps.has_event_mode),
                boolean(3, caps.might_return_early_from_do_step)
            )
        });
        // SAFETY: every pointer is valid for the call; the environment outlives the instance.
        let instance = unsafe {
            (cs.instantiate_co_simulation)(
                c_name.as_ptr(),
                fmu.token.as_ptr(),
                fmu.resource_uri.as_ptr(),
                false,
                debug_logging,
                caps.has_event_mode,
                caps.might_return_early_from_do_step,
                std::ptr::null(),
                0,
                &*env as *const Environment as *mut c_void,
                Some(log_message),
                None,
            )
        };
        call_log::returned_instance(entered, instance);
        let component = Component::new(binary, name, instance, env, "fmi3InstantiateCoSimulation")?;
        Ok(CoSimulation { component, cs, event_mode: caps.has_event_mode, early_return: caps.might_return_early_from_do_step })
    }

    /// Keeps tolerance, start and stop time for fmi3EnterInitializationMode.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.component.setup_experiment(tolerance, start, stop)
    }

    /// fmi3EnterInitializationMode with the experiment's tolerance, start and stop time.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        self.component.enter_initialization_mode()
    }

    /// fmi3ExitInitializationMode, then (with Event Mode) the initial event iteration and
    /// fmi3EnterStepMode.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        self.component.exit_initialization_mode()?;
        if self.event_mode {
            if self.update_discrete_states("after initialization")? {
                return Err(format!("{}: the FMU asked to terminate the simulation during initialization", self.component.name));
            }
            trace::enter(Call::Fmi3EnterStepMode, f64::NAN);
            let entered = call_log::enter("fmi3EnterStepMode", String::new);
            let status = unsafe { (self.cs.enter_step_mode)(self.component.instance) };
            call_log::returned(entered, || c::status_name(status));
            self.component.check("fmi3EnterStepMode", status)?;
        }
        Ok(())
    }

    /// fmi3UpdateDiscreteStates until no further update is needed; true when the FMU asks to
    /// terminate the simulation.
    fn update_discrete_states(&mut self, when: &str) -> Result<bool, String> {
        for _ in 0..MAX_EVENT_ITERATIONS {
            trace::enter(Call::Fmi3UpdateDiscreteStates, f64::NAN);
            let (status, update) = self.component.update_discrete_states();
            self.component.check("fmi3UpdateDiscreteStates", status)?;
            if update.terminate {
                return Ok(true);
            }
            if !update.again {
                return Ok(false);
            }
        }
        Err(format!(
            "{}: event iteration {when} did not converge: fmi3UpdateDiscreteStates still asked for an update after {MAX_EVENT_ITERATIONS} rounds",
            self.component.name
        ))
    }

    /// fmi3Reset: back to the state right after instantiation.
    pub fn reset(&mut self) -> Result<(), String> {
        self.component.reset()
    }

    /// The FMU's state, serialized.
    pub fn get_state(&mut self) -> Result<Vec<u8>, String> {
        self.component.get_state()
    }

    /// Sets the FMU's state from bytes of [`CoSimulation::get_state`].
    pub fn set_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.component.set_state(bytes)
    }

    /// Reads a String variable, each element of an array (fmi3GetString).
    pub fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String> {
        self.component.get_string(variable)
    }

    /// Sets one variable (a scalar, or an array whole); structural parameters are set in
    /// Configuration Mode, which this enters and leaves around the call.
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// Reads the variables of `reader` into `out` (one f64 per element, Booleans as 0/1).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    /// Sets Real scalars, `values[k]` to `vrs[k]`, in one call.
    #[inline]
    pub fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        self.component.set_reals(vrs, values)
    }

    /// fmi3GetOutputDerivatives: `out[k]` = the `orders[k]`-th time derivative of the Float64
    /// output `vrs[k]` (FMUs with `maxOutputDerivativeOrder` > 0).
    #[inline(always)]
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], out: &mut [f64]) -> Result<(), String> {
        let Some(get) = self.component.binary.api.functions.get_output_derivatives else {
            return Err(crate::not_exported(&self.component.name, "fmi3GetOutputDerivatives"));
        };
        let (instance, n, values) = (self.component.instance, vrs.len().min(orders.len()).min(out.len()), out.as_mut_ptr());
        trace::enter(Call::Fmi3Get, f64::NAN);
        let status = call_log::call(
            "fmi3GetOutputDerivatives",
            move || format!("valueReferences={}, nValueReferences={n}, orders={}, nValues={n}", list(&vrs[..n]), list(&orders[..n])),
            // SAFETY: `n` value references of scalars and orders, room for `n` values.
            move || unsafe { get(instance, vrs.as_ptr(), n, orders.as_ptr(), values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            move |_| format!("values={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        );
        self.component.check("fmi3GetOutputDerivatives", status)
    }

    /// One `fmi3DoStep` from `t` over `h`: [`Step::Done`] at `t + h`; [`Step::Event`] when the
    /// FMU needs event handling (at `t + h`, or earlier when it returned early), which
    /// [`CoSimulation::handle_event`] then does; [`Step::Ended`] when the FMU terminates.
    /// Inlined into the run loop, with everything but a plain completed step out of line.
    #[inline(always)]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        let (mut event, mut terminate, mut early, mut last) = (false, false, false, t);
        trace::enter(Call::Fmi3DoStep, t);
        let (do_step, instance) = (self.cs.do_step, self.component.instance);
        let (status, event, terminate, early, last) = call_log::call(
            "fmi3DoStep",
            || format!("currentCommunicationPoint={t:?}, communicationStepSize={h:?}, noSetFMUStatePriorToCurrentPoint=fmi3True"),
            || {
                let status = unsafe { do_step(instance, t, h, true, &mut event, &mut terminate, &mut early, &mut last) };
                (status, event, terminate, early, last)
            },
            |(status, ..)| c::status_name(status),
            |(_, event, terminate, early, last)| {
                format!(
                    "eventHandlingNeeded={}, terminateSimulation={}, earlyReturn={}, lastSuccessfulTime={last:?}",
                    boolean(3, event),
                    boolean(3, terminate),
                    boolean(3, early)
                )
            },
        );
        if status != OK && status != WARNING {
            return Err(self.component.refused_at("fmi3DoStep", t, status));
        }
        if event || terminate || early {
            return self.stopped_step(t, t + h, event, terminate, early, last);
        }
        Ok(Step::Done)
    }

    /// What a step that asked for event handling, termination or returned early means.
    #[cold]
    #[inline(never)]
    fn stopped_step(&mut self, t: f64, t_end: f64, event: bool, terminate: bool, early: bool, last: f64) -> Result<Step, String> {
        let reached = if early && self.early_return { last } else { t_end };
        if terminate {
            let reason = self.component.env.log.take_problem().unwrap_or_else(|| "the FMU asked to terminate the simulation".to_owned());
            return Ok(Step::Ended { reason: crate::model_ended(&format!("t = {reached}"), &reason), last_time: Some(reached) });
        }
        if event && self.event_mode {
            return Ok(Step::Event { time: reached });
        }
        if reached < t_end {
            // Returned early without asking for event handling: the rest of the step is still to do.
            if reached <= t || reached.is_nan() {
                return Err(format!("{}: fmi3DoStep returned early at t = {reached} without advancing from t = {t}", self.component.name));
            }
            return Ok(Step::Event { time: reached });
        }
        Ok(Step::Done)
    }

    /// Handles the event a step stopped at, in Event Mode: `Ok(Some(reason))` when the FMU
    /// asks to terminate the simulation there.
    pub fn handle_event(&mut self, time: f64) -> Result<Option<String>, String> {
        if !self.event_mode {
            return Ok(None);
        }
        trace::enter(Call::Fmi3EnterEventMode, time);
        let entered = call_log::enter("fmi3EnterEventMode", String::new);
        let status = unsafe { (self.component.binary.api.enter_event_mode)(self.component.instance) };
        call_log::returned(entered, || c::status_name(status));
        self.component.check("fmi3EnterEventMode", status)?;
        if self.update_discrete_states(&format!("at t = {time}"))? {
            let reason = self.component.env.log.take_problem().unwrap_or_else(|| "the FMU asked to terminate the simulation".to_owned());
            return Ok(Some(crate::model_ended(&format!("t = {time}"), &reason)));
        }
        trace::enter(Call::Fmi3EnterStepMode, time);
        let entered = call_log::enter("fmi3EnterStepMode", String::new);
        let status = unsafe { (self.cs.enter_step_mode)(self.component.instance) };
        call_log::returned(entered, || c::status_name(status));
        self.component.check("fmi3EnterStepMode", status)?;
        Ok(None)
    }
}
