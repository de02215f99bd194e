//! An FMI 1.0 Model Exchange instance, integrated by the runner with the toolkit's own solvers:
//! the FMI 1.0 calls behind the integration the versions share ([`crate::exchange`]).
//!
//! FMI 1.0 has no event mode to enter or leave: an event is handled by `fmiEventUpdate` until
//! `iterationConverged`, which is the shared driver's discrete update; `fmiInitialize` does the
//! initial event iteration itself and returns its event info, which stands for the driver's
//! first update after initialization.

use std::cell::Cell;
use std::ffi::{c_int, CString};

use fmi_c::fmi1 as c;

use super::component::{Component, Ending, OK};
use super::{Binary, ModelApi, Registration};
use crate::call_log::{self, boolean, list};
use crate::exchange::{EventUpdate, Exchange, Names};
use crate::logging::LogContext;
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Value, Variable};

/// One Model Exchange instance of an FMI 1.0 FMU, with the runner's integrator.
pub type ModelExchange<'a> = crate::exchange::ModelExchange<Exchange1<'a>>;

/// An FMI 1.0 model instance with its Model Exchange functions.
pub struct Exchange1<'a> {
    component: Component<'a>,
    api: ModelApi,
    /// The relative tolerance for fmiInitialize (`None`: not tolerance-controlled).
    tolerance: Option<f64>,
    /// The event info of fmiInitialize, not yet handed to the driver.
    initial: Cell<Option<c::EventInfo>>,
}

/// fmiInstantiateModel; `debug_logging` sets loggingOn.
pub(crate) fn instantiate<'a>(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<ModelExchange<'a>, String> {
    let api = binary.api.model.expect("resolved for Model Exchange");
    let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
    let registration = Registration::new(name);
    trace::enter(Call::Fmi1InstantiateModel, f64::NAN);
    let entered = call_log::enter("fmiInstantiateModel", || {
        format!("instanceName={name:?}, GUID={:?}, loggingOn={}", fmu.token, boolean(1, debug_logging))
    });
    // SAFETY: every pointer is valid for the call; the callbacks are static functions.
    let raw =
        unsafe { (api.instantiate_model)(c_name.as_ptr(), fmu.token.as_ptr(), c::ModelCallbacks::standard(), debug_logging as c::Boolean) };
    call_log::returned_instance(entered, raw);
    let ending = Ending {
        terminate: (api.terminate, Call::Fmi1Terminate, "fmiTerminate"),
        free: (api.free_model_instance, Call::Fmi1FreeModelInstance, "fmiFreeModelInstance"),
    };
    let component = Component::new(binary, name, registration, ending, (raw, "fmiInstantiateModel"))?;
    let (nx, nz) = (fmu.description.number_of_continuous_states, fmu.description.number_of_event_indicators);
    let exchange = Exchange1 { component, api, tolerance: None, initial: Cell::new(None) };
    Ok(crate::exchange::ModelExchange::new(exchange, nx, nz, None))
}

/// The driver's update from FMI 1.0's event info.
fn update_of(info: &c::EventInfo) -> EventUpdate {
    EventUpdate {
        again: info.iteration_converged == 0,
        terminate: info.terminate_simulation != 0,
        next_event_time: (info.upcoming_time_event != 0).then_some(info.next_event_time),
    }
}

/// The event info fmiInitialize and fmiEventUpdate return, for the call log.
fn event_info(info: &c::EventInfo) -> String {
    format!(
        "iterationConverged={}, stateValueReferencesChanged={}, stateValuesChanged={}, terminateSimulation={}, upcomingTimeEvent={}, nextEventTime={:?}",
        boolean(1, info.iteration_converged != 0),
        boolean(1, info.state_value_references_changed != 0),
        boolean(1, info.state_values_changed != 0),
        boolean(1, info.terminate_simulation != 0),
        boolean(1, info.upcoming_time_event != 0),
        info.next_event_time
    )
}

impl Exchange for Exchange1<'_> {
    // Entering and leaving event mode have no FMI 1.0 call: their trace code is the event
    // update's, which is what FMI 1.0 calls at an event.
    const NAMES: Names = Names {
        set_time: (Call::Fmi1SetTime, "fmiSetTime"),
        set_continuous_states: (Call::Fmi1SetContinuousStates, "fmiSetContinuousStates"),
        get_derivatives: (Call::Fmi1GetDerivatives, "fmiGetDerivatives"),
        get_event_indicators: (Call::Fmi1GetEventIndicators, "fmiGetEventIndicators"),
        get_continuous_states: (Call::Fmi1GetContinuousStates, "fmiGetContinuousStates"),
        enter_event_mode: (Call::Fmi1EventUpdate, "fmiEventUpdate"),
        update_discrete_states: (Call::Fmi1EventUpdate, "fmiEventUpdate"),
        enter_continuous_time_mode: (Call::Fmi1EventUpdate, "fmiEventUpdate"),
        completed_integrator_step: (Call::Fmi1CompletedIntegratorStep, "fmiCompletedIntegratorStep"),
        get_directional_derivative: (Call::Fmi1GetDerivatives, "(FMI 1.0 has no directional derivatives)"),
        again_flag: "iterationConverged = false",
    };

    fn status_name(status: c_int) -> &'static str {
        c::status_name(status)
    }

    fn name(&self) -> &str {
        &self.component.name
    }

    fn log(&self) -> &LogContext {
        self.component.registration.log()
    }

    #[inline]
    fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        self.component.check(call, status)
    }

    fn note_status(&mut self, status: c_int) {
        self.component.note_status(status)
    }

    #[inline(always)]
    fn set_time(&self, t: f64) -> c_int {
        let (set_time, raw) = (self.api.set_time, self.component.raw);
        call_log::call(
            "fmiSetTime",
            || format!("time={t:?}"),
            // SAFETY: a live component and a scalar argument.
            || unsafe { set_time(raw, t) },
            c::status_name,
            |_| String::new(),
        )
    }

    #[inline(always)]
    fn set_continuous_states(&self, x: &[f64]) -> c_int {
        let (set_continuous_states, raw) = (self.api.set_continuous_states, self.component.raw);
        call_log::call(
            "fmiSetContinuousStates",
            || format!("x={}, nx={}", list(x), x.len()),
            // SAFETY: an array of x.len() states.
            || unsafe { set_continuous_states(raw, x.as_ptr(), x.len()) },
            c::status_name,
            |_| String::new(),
        )
    }

    #[inline(always)]
    fn get_derivatives(&self, dx: &mut [f64]) -> c_int {
        let (get_derivatives, raw, values, n) = (self.api.get_derivatives, self.component.raw, dx.as_mut_ptr(), dx.len());
        call_log::call(
            "fmiGetDerivatives",
            || format!("nx={n}"),
            // SAFETY: an array of n derivatives.
            || unsafe { get_derivatives(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("derivatives={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    #[inline(always)]
    fn get_event_indicators(&self, z: &mut [f64]) -> c_int {
        let (get_event_indicators, raw, values, n) = (self.api.get_event_indicators, self.component.raw, z.as_mut_ptr(), z.len());
        call_log::call(
            "fmiGetEventIndicators",
            || format!("ni={n}"),
            // SAFETY: an array of n indicators.
            || unsafe { get_event_indicators(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("eventIndicators={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    fn get_continuous_states(&self, x: &mut [f64]) -> c_int {
        let entered = call_log::enter("fmiGetContinuousStates", || format!("nx={}", x.len()));
        // SAFETY: an array of x.len() states.
        let status = unsafe { (self.api.get_continuous_states)(self.component.raw, x.as_mut_ptr(), x.len()) };
        call_log::returned_with(entered, || c::status_name(status), || format!("x={}", list(x)));
        status
    }

    fn enter_event_mode(&self) -> c_int {
        OK
    }

    /// fmiEventUpdate, except for the first update after initialization, which is
    /// fmiInitialize's event info when its iteration converged.
    fn update_discrete_states(&self) -> (c_int, EventUpdate) {
        if let Some(info) = self.initial.take().filter(|info| info.iteration_converged != 0) {
            return (OK, update_of(&info));
        }
        let mut info = c::EventInfo::default();
        // SAFETY: a valid out pointer.
        let entered = call_log::enter("fmiEventUpdate", || "intermediateResults=fmiFalse".to_owned());
        let status = unsafe { (self.api.event_update)(self.component.raw, c::FALSE, &mut info) };
        call_log::returned_with(entered, || c::status_name(status), || event_info(&info));
        (status, update_of(&info))
    }

    fn enter_continuous_time_mode(&self) -> c_int {
        OK
    }

    fn needs_completed_integrator_step(&self) -> bool {
        true
    }

    fn completed_integrator_step(&self) -> (c_int, bool, bool) {
        let mut call_event_update: c::Boolean = c::FALSE;
        // SAFETY: a valid out pointer.
        let entered = call_log::enter("fmiCompletedIntegratorStep", String::new);
        let status = unsafe { (self.api.completed_integrator_step)(self.component.raw, &mut call_event_update) };
        call_log::returned_with(entered, || c::status_name(status), || format!("callEventUpdate={}", boolean(1, call_event_update != 0)));
        (status, call_event_update != 0, false)
    }

    /// Keeps the tolerance for fmiInitialize and sets the start time (fmiSetTime), as FMI 1.0
    /// wants before initialization.
    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, _stop: f64) -> Result<(), String> {
        self.tolerance = tolerance;
        self.component.time = start;
        trace::enter(Call::Fmi1SetTime, start);
        let status = self.set_time(start);
        self.component.check("fmiSetTime", status)
    }

    fn enter_initialization_mode(&mut self) -> Result<(), String> {
        Ok(())
    }

    /// fmiInitialize; its event info is the driver's first update.
    fn exit_initialization_mode(&mut self) -> Result<(), String> {
        let mut info = c::EventInfo::default();
        trace::enter(Call::Fmi1Initialize, self.component.time);
        let entered = call_log::enter("fmiInitialize", || {
            format!("toleranceControlled={}, relativeTolerance={:?}", boolean(1, self.tolerance.is_some()), self.tolerance.unwrap_or(0.0))
        });
        // SAFETY: a live component and a valid out pointer.
        let status = unsafe {
            (self.api.initialize)(self.component.raw, self.tolerance.is_some() as c::Boolean, self.tolerance.unwrap_or(0.0), &mut info)
        };
        call_log::returned_with(entered, || c::status_name(status), || event_info(&info));
        self.component.check("fmiInitialize", status)?;
        self.component.terminate_allowed = true;
        self.initial.set(Some(info));
        Ok(())
    }

    fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String> {
        self.component.get_string(variable).map(|text| vec![text])
    }

    #[inline]
    fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    #[inline]
    fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        self.component.set_reals(vrs, values)
    }

    fn reset(&mut self) -> Result<(), String> {
        Err(format!("{}: FMI 1.0 Model Exchange has no reset (fmi2Reset came with FMI 2.0)", self.component.name))
    }

    fn get_state(&mut self) -> Result<Vec<u8>, String> {
        Err(format!("{}: FMI 1.0 has no FMU state to save (fmi2GetFMUstate came with FMI 2.0)", self.component.name))
    }

    fn set_state(&mut self, _bytes: &[u8]) -> Result<(), String> {
        Err(format!("{}: FMI 1.0 has no FMU state to restore (fmi2SetFMUstate came with FMI 2.0)", self.component.name))
    }

    fn provides_directional_derivative(&self) -> bool {
        false
    }

    fn directional_derivative(&self, _unknowns: &[u32], _knowns: &[u32], _seed: &[f64], _out: &mut [f64]) -> c_int {
        crate::exchange::ERROR
    }
}
