//! An FMI 2.0 Model Exchange instance, integrated by the runner with the toolkit's own solvers:
//! the FMI 2.0 calls behind the integration the versions share ([`crate::exchange`]).

use std::ffi::c_int;

use fmi_c::fmi2 as c;

use fmi_schema::fmi2 as schema;

use super::component::Component;
use super::{Binary, ExchangeApi};
use crate::call_log::{self, boolean, list};
use crate::exchange::{EventUpdate, Exchange, Names, StateStructure};
use crate::logging::LogContext;
use crate::trace::Call;
use crate::{Fmu, Reader, Value, Variable};

/// One Model Exchange instance of an FMI 2.0 FMU, with the runner's integrator.
pub type ModelExchange<'a> = crate::exchange::ModelExchange<Exchange2<'a>>;

/// An FMI 2.0 component instantiated for Model Exchange, with its Model Exchange functions.
pub struct Exchange2<'a> {
    component: Component<'a>,
    api: ExchangeApi,
    /// `fmi2GetDirectionalDerivative`, when the FMU declares providesDirectionalDerivative.
    directional: Option<c::GetDirectionalDerivative>,
}

/// The states of an FMI 2.0 description for the implicit methods' Jacobian: ModelStructure
/// `Derivatives` (1-based variable indices) mapped to the value references of the derivatives
/// and their states, and each derivative's dependencies on the states (dependencies on other
/// knowns, inputs and the like, are constant during integration). `None` when a derivative
/// names no state.
pub(crate) fn state_structure(md: &schema::ModelDescription) -> Option<StateStructure> {
    let variable = |index: u32| md.model_variables.get((index as usize).checked_sub(1)?);
    let derivatives = &md.model_structure.derivatives;
    let mut structure = StateStructure { pattern: Some(Vec::new()), ..StateStructure::default() };
    let mut state_indices = Vec::new();
    for unknown in derivatives {
        let derivative = variable(unknown.index)?;
        let state_index = derivative.derivative()?;
        structure.derivatives.push(derivative.value_reference);
        structure.states.push(variable(state_index)?.value_reference);
        state_indices.push(state_index);
    }
    for unknown in derivatives {
        let row = unknown.dependencies.as_ref().map(|deps| deps.iter().filter_map(|d| state_indices.iter().position(|s| s == d)).collect());
        match (row, structure.pattern.as_mut()) {
            (Some(row), Some(pattern)) => pattern.push(row),
            _ => structure.pattern = None,
        }
    }
    Some(structure)
}

/// fmi2Instantiate as Model Exchange; `debug_logging` sets loggingOn.
pub(crate) fn instantiate<'a>(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<ModelExchange<'a>, String> {
    let api = binary.api.exchange.expect("resolved for Model Exchange");
    let component = Component::instantiate(fmu, binary, name, debug_logging, c::MODEL_EXCHANGE)?;
    let (nx, nz) = (fmu.description.number_of_continuous_states, fmu.description.number_of_event_indicators);
    let declared = fmu.description.model_exchange.as_ref().is_some_and(|me| me.provides_directional_derivative);
    let directional = binary.api.functions.get_directional_derivative.filter(|_| declared);
    Ok(crate::exchange::ModelExchange::new(Exchange2 { component, api, directional }, nx, nz, fmu.states.clone()))
}

impl Exchange for Exchange2<'_> {
    const NAMES: Names = Names {
        set_time: (Call::SetTime, "fmi2SetTime"),
        set_continuous_states: (Call::SetContinuousStates, "fmi2SetContinuousStates"),
        get_derivatives: (Call::GetDerivatives, "fmi2GetDerivatives"),
        get_event_indicators: (Call::GetEventIndicators, "fmi2GetEventIndicators"),
        get_continuous_states: (Call::GetContinuousStates, "fmi2GetContinuousStates"),
        enter_event_mode: (Call::EnterEventMode, "fmi2EnterEventMode"),
        update_discrete_states: (Call::NewDiscreteStates, "fmi2NewDiscreteStates"),
        enter_continuous_time_mode: (Call::EnterContinuousTimeMode, "fmi2EnterContinuousTimeMode"),
        completed_integrator_step: (Call::CompletedIntegratorStep, "fmi2CompletedIntegratorStep"),
        get_directional_derivative: (Call::GetDirectionalDerivative, "fmi2GetDirectionalDerivative"),
        again_flag: "newDiscreteStatesNeeded",
    };

    fn reset(&mut self) -> Result<(), String> {
        self.component.reset()
    }

    fn get_state(&mut self) -> Result<Vec<u8>, String> {
        self.component.get_state()
    }

    fn set_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        self.component.set_state(bytes)
    }

    fn status_name(status: c_int) -> &'static str {
        c::status_name(status)
    }

    fn name(&self) -> &str {
        &self.component.name
    }

    fn log(&self) -> &LogContext {
        &self.component.callbacks.log
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
        let set_time = self.api.set_time;
        let raw = self.component.raw;
        call_log::call(
            "fmi2SetTime",
            || format!("time={t:?}"),
            // SAFETY: a live instance and a scalar argument.
            || unsafe { set_time(raw, t) },
            c::status_name,
            |_| String::new(),
        )
    }

    #[inline(always)]
    fn set_continuous_states(&self, x: &[f64]) -> c_int {
        let set_continuous_states = self.api.set_continuous_states;
        let raw = self.component.raw;
        call_log::call(
            "fmi2SetContinuousStates",
            || format!("x={}, nx={}", list(x), x.len()),
            // SAFETY: an array of x.len() states.
            || unsafe { set_continuous_states(raw, x.as_ptr(), x.len()) },
            c::status_name,
            |_| String::new(),
        )
    }

    #[inline(always)]
    fn get_derivatives(&self, dx: &mut [f64]) -> c_int {
        let get_derivatives = self.api.get_derivatives;
        let (raw, values, n) = (self.component.raw, dx.as_mut_ptr(), dx.len());
        call_log::call(
            "fmi2GetDerivatives",
            || format!("nx={n}"),
            // SAFETY: an array of n values.
            || unsafe { get_derivatives(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("derivatives={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    #[inline(always)]
    fn get_event_indicators(&self, z: &mut [f64]) -> c_int {
        let get_event_indicators = self.api.get_event_indicators;
        let (raw, values, n) = (self.component.raw, z.as_mut_ptr(), z.len());
        call_log::call(
            "fmi2GetEventIndicators",
            || format!("ni={n}"),
            // SAFETY: an array of n values.
            || unsafe { get_event_indicators(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("eventIndicators={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    fn get_continuous_states(&self, x: &mut [f64]) -> c_int {
        let entered = call_log::enter("fmi2GetContinuousStates", || format!("nx={}", x.len()));
        // SAFETY: an array of x.len() states.
        let status = unsafe { (self.api.get_continuous_states)(self.component.raw, x.as_mut_ptr(), x.len()) };
        call_log::returned_with(entered, || c::status_name(status), || format!("x={}", list(x)));
        status
    }

    fn enter_event_mode(&self) -> c_int {
        let entered = call_log::enter("fmi2EnterEventMode", String::new);
        // SAFETY: a live component.
        let status = unsafe { (self.api.enter_event_mode)(self.component.raw) };
        call_log::returned(entered, || c::status_name(status));
        status
    }

    fn update_discrete_states(&self) -> (c_int, EventUpdate) {
        let mut info = c::EventInfo::default();
        // SAFETY: a valid out pointer.
        let entered = call_log::enter("fmi2NewDiscreteStates", String::new);
        let status = unsafe { (self.api.new_discrete_states)(self.component.raw, &mut info) };
        call_log::returned_with(
            entered,
            || c::status_name(status),
            || {
                format!(
                "newDiscreteStatesNeeded={}, terminateSimulation={}, nominalsOfContinuousStatesChanged={}, valuesOfContinuousStatesChanged={}, nextEventTimeDefined={}, nextEventTime={:?}",
                boolean(2, info.new_discrete_states_needed != 0),
                boolean(2, info.terminate_simulation != 0),
                boolean(2, info.nominals_of_continuous_states_changed != 0),
                boolean(2, info.values_of_continuous_states_changed != 0),
                boolean(2, info.next_event_time_defined != 0),
                info.next_event_time
            )
            },
        );
        let update = EventUpdate {
            again: info.new_discrete_states_needed != 0,
            terminate: info.terminate_simulation != 0,
            next_event_time: (info.next_event_time_defined != 0).then_some(info.next_event_time),
        };
        (status, update)
    }

    fn enter_continuous_time_mode(&self) -> c_int {
        let entered = call_log::enter("fmi2EnterContinuousTimeMode", String::new);
        // SAFETY: a live component.
        let status = unsafe { (self.api.enter_continuous_time_mode)(self.component.raw) };
        call_log::returned(entered, || c::status_name(status));
        status
    }

    fn needs_completed_integrator_step(&self) -> bool {
        true
    }

    fn completed_integrator_step(&self) -> (c_int, bool, bool) {
        let (mut enter, mut terminate): (c_int, c_int) = (0, 0);
        // SAFETY: valid out pointers.
        let entered = call_log::enter("fmi2CompletedIntegratorStep", || "noSetFMUStatePriorToCurrentPoint=fmi2True".to_owned());
        let status = unsafe { (self.api.completed_integrator_step)(self.component.raw, c::TRUE, &mut enter, &mut terminate) };
        call_log::returned_with(
            entered,
            || c::status_name(status),
            || format!("enterEventMode={}, terminateSimulation={}", boolean(2, enter != 0), boolean(2, terminate != 0)),
        );
        (status, enter != 0, terminate != 0)
    }

    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.component.setup_experiment(tolerance, start, stop)
    }

    fn enter_initialization_mode(&mut self) -> Result<(), String> {
        self.component.enter_initialization_mode()
    }

    fn exit_initialization_mode(&mut self) -> Result<(), String> {
        self.component.exit_initialization_mode()
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

    fn provides_directional_derivative(&self) -> bool {
        self.directional.is_some()
    }

    // Inlined as the derivatives are: a linearization makes one call per state and input.
    #[inline(always)]
    fn directional_derivative(&self, unknowns: &[u32], knowns: &[u32], seed: &[f64], out: &mut [f64]) -> c_int {
        let Some(f) = self.directional else { return crate::exchange::ERROR };
        let (raw, values, n) = (self.component.raw, out.as_mut_ptr(), out.len());
        // The closures take their values by copy (`move`): nothing is stored for the log unless
        // it is on.
        call_log::call(
            "fmi2GetDirectionalDerivative",
            move || format!("vUnknown_ref={}, vKnown_ref={}, dvKnown={}", list(unknowns), list(knowns), list(seed)),
            // SAFETY: arrays of the lengths passed (out as long as unknowns, seed as knowns).
            move || unsafe { f(raw, unknowns.as_ptr(), unknowns.len(), knowns.as_ptr(), knowns.len(), seed.as_ptr(), values) },
            c::status_name,
            // SAFETY: the `n` values of `out`, which the call just wrote.
            move |_| format!("dvUnknown={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }
}
