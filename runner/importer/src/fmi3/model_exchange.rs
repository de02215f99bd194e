//! An FMI 3.0 Model Exchange instance, integrated by the runner with the toolkit's own solvers:
//! the FMI 3.0 calls behind the integration the versions share ([`crate::exchange`]).
//! `fmi3CompletedIntegratorStep` is called only when the FMU declares
//! `needsCompletedIntegratorStep`, as the standard has it; the numbers of states and event
//! indicators are asked of the FMU after initialization (structural parameters may change them).

use std::ffi::{c_int, c_void, CString};

use fmi_c::fmi3 as c;

use fmi_schema::fmi3 as schema;

use super::component::Component;
use super::{log_message, Binary, Environment, ModelExchangeApi};
use crate::call_log::{self, boolean, list};
use crate::exchange::{EventUpdate, Exchange, Names, StateStructure};
use crate::logging::LogContext;
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Value, Variable};

/// One Model Exchange instance of an FMI 3.0 FMU, with the runner's integrator.
pub type ModelExchange<'a> = crate::exchange::ModelExchange<Exchange3<'a>>;

/// An FMI 3.0 instance made by fmi3InstantiateModelExchange, with its Model Exchange functions.
pub struct Exchange3<'a> {
    component: Component<'a>,
    api: ModelExchangeApi,
    needs_completed_integrator_step: bool,
    /// `fmi3GetDirectionalDerivative`, when the FMU declares providesDirectionalDerivatives.
    directional: Option<c::GetDirectionalDerivative>,
}

/// The states of an FMI 3.0 description for the implicit methods' Jacobian: the ModelStructure's
/// `ContinuousStateDerivative`s mapped to their states' value references, and each
/// derivative's dependencies on the states (others are constant during integration). `None`
/// when a derivative names no state, or a state is an array (whose elements the value
/// references do not tell apart).
pub(crate) fn state_structure(md: &schema::ModelDescription) -> Option<StateStructure> {
    let derivatives = &md.model_structure.continuous_state_derivatives;
    let mut structure = StateStructure { pattern: Some(Vec::new()), ..StateStructure::default() };
    for unknown in derivatives {
        let derivative = md.variable_by_reference(unknown.value_reference)?;
        let state = md.variable_by_reference(derivative.derivative()?)?;
        if !derivative.dimensions.is_empty() || !state.dimensions.is_empty() {
            return None;
        }
        structure.derivatives.push(derivative.value_reference);
        structure.states.push(state.value_reference);
    }
    for unknown in derivatives {
        let row =
            unknown.dependencies.as_ref().map(|deps| deps.iter().filter_map(|d| structure.states.iter().position(|s| s == d)).collect());
        match (row, structure.pattern.as_mut()) {
            (Some(row), Some(pattern)) => pattern.push(row),
            _ => structure.pattern = None,
        }
    }
    Some(structure)
}

/// fmi3InstantiateModelExchange; `debug_logging` sets loggingOn.
pub(crate) fn instantiate<'a>(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<ModelExchange<'a>, String> {
    let api = binary.api.model_exchange.expect("resolved for Model Exchange");
    let env = Box::new(Environment { name: name.to_owned(), log: LogContext::default() });
    let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
    trace::enter(Call::Fmi3InstantiateModelExchange, f64::NAN);
    let entered = call_log::enter("fmi3InstantiateModelExchange", || {
        format!(
            "instanceName={name:?}, instantiationToken={:?}, resourcePath={:?}, visible=fmi3False, loggingOn={}",
            fmu.token,
            fmu.resource_uri,
            boolean(3, debug_logging)
        )
    });
    // SAFETY: every pointer is valid for the call; the environment outlives the instance.
    let instance = unsafe {
        (api.instantiate_model_exchange)(
            c_name.as_ptr(),
            fmu.token.as_ptr(),
            fmu.resource_uri.as_ptr(),
            false,
            debug_logging,
            &*env as *const Environment as *mut c_void,
            Some(log_message),
        )
    };
    call_log::returned_instance(entered, instance);
    let component = Component::new(binary, name, instance, env, "fmi3InstantiateModelExchange")?;
    let capabilities = fmu.description.model_exchange.as_ref();
    let needs = capabilities.is_some_and(|me| me.needs_completed_integrator_step);
    let directional =
        binary.api.functions.get_directional_derivative.filter(|_| capabilities.is_some_and(|me| me.provides_directional_derivative));
    let (nx, nz) = (fmu.description.number_of_continuous_states, fmu.description.number_of_event_indicators);
    let exchange = Exchange3 { component, api, needs_completed_integrator_step: needs, directional };
    Ok(crate::exchange::ModelExchange::new(exchange, nx, nz, fmu.states.clone()))
}

impl Exchange for Exchange3<'_> {
    const NAMES: Names = Names {
        set_time: (Call::Fmi3SetTime, "fmi3SetTime"),
        set_continuous_states: (Call::Fmi3SetContinuousStates, "fmi3SetContinuousStates"),
        get_derivatives: (Call::Fmi3GetContinuousStateDerivatives, "fmi3GetContinuousStateDerivatives"),
        get_event_indicators: (Call::Fmi3GetEventIndicators, "fmi3GetEventIndicators"),
        get_continuous_states: (Call::Fmi3GetContinuousStates, "fmi3GetContinuousStates"),
        enter_event_mode: (Call::Fmi3EnterEventMode, "fmi3EnterEventMode"),
        update_discrete_states: (Call::Fmi3UpdateDiscreteStates, "fmi3UpdateDiscreteStates"),
        enter_continuous_time_mode: (Call::Fmi3EnterContinuousTimeMode, "fmi3EnterContinuousTimeMode"),
        completed_integrator_step: (Call::Fmi3CompletedIntegratorStep, "fmi3CompletedIntegratorStep"),
        get_directional_derivative: (Call::Fmi3GetDirectionalDerivative, "fmi3GetDirectionalDerivative"),
        again_flag: "discreteStatesNeedUpdate",
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
        &self.component.env.log
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
        let raw = self.component.instance;
        call_log::call(
            "fmi3SetTime",
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
        let raw = self.component.instance;
        call_log::call(
            "fmi3SetContinuousStates",
            || format!("continuousStates={}, nContinuousStates={}", list(x), x.len()),
            // SAFETY: an array of x.len() states.
            || unsafe { set_continuous_states(raw, x.as_ptr(), x.len()) },
            c::status_name,
            |_| String::new(),
        )
    }

    #[inline(always)]
    fn get_derivatives(&self, dx: &mut [f64]) -> c_int {
        let get_continuous_state_derivatives = self.api.get_continuous_state_derivatives;
        let (raw, values, n) = (self.component.instance, dx.as_mut_ptr(), dx.len());
        call_log::call(
            "fmi3GetContinuousStateDerivatives",
            || format!("nContinuousStates={n}"),
            // SAFETY: an array of n values.
            || unsafe { get_continuous_state_derivatives(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("derivatives={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    #[inline(always)]
    fn get_event_indicators(&self, z: &mut [f64]) -> c_int {
        let get_event_indicators = self.api.get_event_indicators;
        let (raw, values, n) = (self.component.instance, z.as_mut_ptr(), z.len());
        call_log::call(
            "fmi3GetEventIndicators",
            || format!("nEventIndicators={n}"),
            // SAFETY: an array of n values.
            || unsafe { get_event_indicators(raw, values, n) },
            c::status_name,
            // SAFETY: the `n` values the call just wrote.
            |_| format!("eventIndicators={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    fn get_continuous_states(&self, x: &mut [f64]) -> c_int {
        let entered = call_log::enter("fmi3GetContinuousStates", || format!("nContinuousStates={}", x.len()));
        // SAFETY: an array of x.len() states.
        let status = unsafe { (self.api.get_continuous_states)(self.component.instance, x.as_mut_ptr(), x.len()) };
        call_log::returned_with(entered, || c::status_name(status), || format!("continuousStates={}", list(x)));
        status
    }

    fn enter_event_mode(&self) -> c_int {
        let entered = call_log::enter("fmi3EnterEventMode", String::new);
        // SAFETY: a live instance.
        let status = unsafe { (self.component.binary.api.enter_event_mode)(self.component.instance) };
        call_log::returned(entered, || c::status_name(status));
        status
    }

    fn update_discrete_states(&self) -> (c_int, EventUpdate) {
        self.component.update_discrete_states()
    }

    fn enter_continuous_time_mode(&self) -> c_int {
        let entered = call_log::enter("fmi3EnterContinuousTimeMode", String::new);
        // SAFETY: a live instance.
        let status = unsafe { (self.api.enter_continuous_time_mode)(self.component.instance) };
        call_log::returned(entered, || c::status_name(status));
        status
    }

    fn needs_completed_integrator_step(&self) -> bool {
        self.needs_completed_integrator_step
    }

    fn completed_integrator_step(&self) -> (c_int, bool, bool) {
        let (mut enter, mut terminate) = (false, false);
        // SAFETY: valid out pointers.
        let entered = call_log::enter("fmi3CompletedIntegratorStep", || "noSetFMUStatePriorToCurrentPoint=fmi3True".to_owned());
        let status = unsafe { (self.api.completed_integrator_step)(self.component.instance, true, &mut enter, &mut terminate) };
        call_log::returned_with(
            entered,
            || c::status_name(status),
            || format!("enterEventMode={}, terminateSimulation={}", boolean(3, enter), boolean(3, terminate)),
        );
        (status, enter, terminate)
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
        self.component.get_string(variable)
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
        let (instance, values, n) = (self.component.instance, out.as_mut_ptr(), out.len());
        // The closures take their values by copy (`move`): nothing is stored for the log unless
        // it is on.
        call_log::call(
            "fmi3GetDirectionalDerivative",
            move || format!("unknowns={}, knowns={}, seed={}", list(unknowns), list(knowns), list(seed)),
            // SAFETY: arrays of the lengths passed (scalar unknowns and knowns: one value each).
            move || unsafe {
                f(instance, unknowns.as_ptr(), unknowns.len(), knowns.as_ptr(), knowns.len(), seed.as_ptr(), seed.len(), values, n)
            },
            c::status_name,
            // SAFETY: the `n` values of `out`, which the call just wrote.
            move |_| format!("sensitivity={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
        )
    }

    /// fmi3GetNumberOfContinuousStates and fmi3GetNumberOfEventIndicators (allowed in Event
    /// Mode, where initialization leaves the instance): structural parameters may have changed
    /// the description's numbers.
    fn sizes(&mut self, nx: usize, nz: usize) -> Result<(usize, usize), String> {
        let (mut states, mut indicators) = (nx, nz);
        let start = self.component.start_time();
        trace::enter(Call::Fmi3GetNumberOfContinuousStates, start);
        // SAFETY: valid out pointers.
        let entered = call_log::enter("fmi3GetNumberOfContinuousStates", String::new);
        let status = unsafe { (self.api.get_number_of_continuous_states)(self.component.instance, &mut states) };
        call_log::returned_with(entered, || c::status_name(status), || format!("nContinuousStates={states}"));
        self.component.check("fmi3GetNumberOfContinuousStates", status)?;
        let entered = call_log::enter("fmi3GetNumberOfEventIndicators", String::new);
        let status = unsafe { (self.api.get_number_of_event_indicators)(self.component.instance, &mut indicators) };
        call_log::returned_with(entered, || c::status_name(status), || format!("nEventIndicators={indicators}"));
        self.component.check("fmi3GetNumberOfEventIndicators", status)?;
        // A count past any description's sizes is a broken answer, not an array to allocate.
        const MOST: usize = 1 << 24;
        if states > MOST || indicators > MOST {
            return Err(format!(
                "{}: the FMU reports {states} continuous states and {indicators} event indicators, more than the {MOST} the runner accepts",
                self.component.name
            ));
        }
        Ok((states, indicators))
    }
}
