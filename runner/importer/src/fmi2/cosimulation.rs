//! An FMI 2.0 Co-Simulation instance: the FMU integrates itself, one `fmi2DoStep` per
//! communication step.

use std::ffi::c_int;

use fmi_c::fmi2 as c;

use super::component::{Component, DISCARD, OK, WARNING};
use super::{Binary, CoSimulationApi};
use crate::call_log::{self, list};
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Step, Value, Variable};

/// One Co-Simulation instance of an FMI 2.0 FMU.
pub struct CoSimulation<'a> {
    component: Component<'a>,
    cs: CoSimulationApi,
}

impl<'a> CoSimulation<'a> {
    /// fmi2Instantiate as Co-Simulation; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<CoSimulation<'a>, String> {
        let cs = binary.api.co_simulation.expect("resolved for Co-Simulation");
        Ok(CoSimulation { component: Component::instantiate(fmu, binary, name, debug_logging, c::CO_SIMULATION)?, cs })
    }

    /// fmi2SetupExperiment with an optional relative tolerance and a defined stop time.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.component.setup_experiment(tolerance, start, stop)
    }

    /// fmi2EnterInitializationMode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        self.component.enter_initialization_mode()
    }

    /// fmi2ExitInitializationMode.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        self.component.exit_initialization_mode()
    }

    /// fmi2Reset: back to the state right after instantiation.
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

    /// Reads a String variable (fmi2GetString).
    pub fn get_string(&mut self, variable: &Variable) -> Result<String, String> {
        self.component.get_string(variable)
    }

    /// Sets one variable (`fmi2Set<Type>` with one value reference).
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// fmi2SetRealInputDerivatives of the first derivative of the Real input `variable`, for an
    /// FMU that interpolates inputs over a step (`canInterpolateInputs`).
    pub fn set_input_derivative(&mut self, variable: &Variable, derivative: f64) -> Result<(), String> {
        self.set_input_derivatives(&[variable.value_reference], &[1], &[derivative])
            .map_err(|e| format!("{e} (the derivative of {})", variable.name))
    }

    /// fmi2SetRealInputDerivatives: the `orders[k]`-th time derivative of the Real input
    /// `vrs[k]` is `values[k]`, for an FMU that interpolates inputs (`canInterpolateInputs`).
    #[inline(always)]
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> Result<(), String> {
        let Some(set) = self.component.binary.api.functions.set_real_input_derivatives else {
            return Err(crate::not_exported(&self.component.name, "fmi2SetRealInputDerivatives"));
        };
        trace::enter(Call::SetReal, self.component.time);
        let status =
            set_real_input_derivatives("fmi2SetRealInputDerivatives", set, self.component.raw, vrs, orders, values, c::status_name);
        self.component.check("fmi2SetRealInputDerivatives", status)
    }

    /// fmi2GetRealOutputDerivatives: `out[k]` = the `orders[k]`-th time derivative of the Real
    /// output `vrs[k]` (FMUs with `maxOutputDerivativeOrder` > 0).
    #[inline(always)]
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], out: &mut [f64]) -> Result<(), String> {
        let Some(get) = self.component.binary.api.functions.get_real_output_derivatives else {
            return Err(crate::not_exported(&self.component.name, "fmi2GetRealOutputDerivatives"));
        };
        trace::enter(Call::GetReal, self.component.time);
        let status = get_real_output_derivatives("fmi2GetRealOutputDerivatives", get, self.component.raw, vrs, orders, out, c::status_name);
        self.component.check("fmi2GetRealOutputDerivatives", status)
    }

    /// Reads the variables of `reader` into `out` (one f64 per variable, Booleans as 0/1).
    #[inline(always)]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    /// Sets Real scalars, `values[k]` to `vrs[k]`, in one call.
    #[inline]
    pub fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        self.component.set_reals(vrs, values)
    }

    /// fmi2DoStep from `t` over `h`; a discard with fmi2Terminated becomes [`Step::Ended`].
    /// Inlined into the run loop, with the discard handling out of line.
    #[inline(always)]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        trace::enter(Call::DoStep, t);
        let (do_step, raw) = (self.cs.do_step, self.component.raw);
        let status = call_log::call(
            "fmi2DoStep",
            || format!("currentCommunicationPoint={t:?}, communicationStepSize={h:?}, noSetFMUStatePriorToCurrentPoint=fmi2True"),
            || unsafe { do_step(raw, t, h, c::TRUE) },
            c::status_name,
            |_| String::new(),
        );
        if status == DISCARD {
            return self.discarded(t);
        }
        if status != OK && status != WARNING {
            return Err(self.component.refused_at("fmi2DoStep", t, status));
        }
        self.component.time = t + h;
        Ok(Step::Done)
    }

    /// After fmi2Discard from the step at `t`: [`Step::Ended`] if the model terminated.
    #[cold]
    fn discarded(&mut self, t: f64) -> Result<Step, String> {
        let (get_boolean_status, get_real_status) = (self.cs.get_boolean_status, self.cs.get_real_status);
        let raw = self.component.raw;
        let mut terminated: c_int = 0;
        trace::enter(Call::GetBooleanStatus, t);
        let entered = call_log::enter("fmi2GetBooleanStatus", || "s=fmi2Terminated".to_owned());
        let s = unsafe { get_boolean_status(raw, c::TERMINATED, &mut terminated) };
        call_log::returned_with(entered, || c::status_name(s), || format!("value={}", call_log::boolean(2, terminated != 0)));
        self.component.check("fmi2GetBooleanStatus(fmi2Terminated)", s)?;
        let reason = self.component.callbacks.log.take_problem().unwrap_or_else(|| "no reason logged".to_owned());
        if terminated == 0 {
            return Err(format!("{}: fmi2DoStep at t = {t} returned fmi2Discard without terminating: {reason}", self.component.name));
        }
        let mut last = f64::NAN;
        trace::enter(Call::GetRealStatus, t);
        let entered = call_log::enter("fmi2GetRealStatus", || "s=fmi2LastSuccessfulTime".to_owned());
        let s = unsafe { get_real_status(raw, c::LAST_SUCCESSFUL_TIME, &mut last) };
        call_log::returned_with(entered, || c::status_name(s), || format!("value={last:?}"));
        let last_time = (s == OK || s == WARNING).then_some(last).filter(|t| t.is_finite());
        let when = match last_time {
            Some(last) => format!("t = {last}"),
            None => format!("the step from t = {t}"),
        };
        Ok(Step::Ended { reason: crate::model_ended(&when, &reason), last_time })
    }
}

/// `SetRealInputDerivatives` of FMI 2.0 or 1.0 (`name`; the same C signature in both), logged:
/// the `orders[k]`-th time derivative of input `vrs[k]` is `values[k]`. Returns the status.
#[inline(always)]
pub(crate) fn set_real_input_derivatives(
    name: &'static str,
    set: c::SetRealInputDerivatives,
    raw: c::Component,
    vrs: &[u32],
    orders: &[i32],
    values: &[f64],
    status_name: fn(c_int) -> &'static str,
) -> c_int {
    let n = vrs.len().min(orders.len()).min(values.len());
    if !call_log::on() {
        // SAFETY: `n` value references, orders and values, valid for the call (without the log, a
        // master's call at every step: see `call_log::on`).
        return unsafe { set(raw, vrs.as_ptr(), n, orders.as_ptr(), values.as_ptr()) };
    }
    call_log::call(
        name,
        move || format!("vr={}, nvr={n}, order={}, value={}", list(&vrs[..n]), list(&orders[..n]), list(&values[..n])),
        // SAFETY: `n` value references, orders and values, valid for the call.
        move || unsafe { set(raw, vrs.as_ptr(), n, orders.as_ptr(), values.as_ptr()) },
        status_name,
        |_| String::new(),
    )
}

/// `GetRealOutputDerivatives` of FMI 2.0 or 1.0 (`name`; the same C signature in both), logged:
/// `out[k]` = the `orders[k]`-th time derivative of output `vrs[k]`. Returns the status.
#[inline(always)]
pub(crate) fn get_real_output_derivatives(
    name: &'static str,
    get: c::GetRealOutputDerivatives,
    raw: c::Component,
    vrs: &[u32],
    orders: &[i32],
    out: &mut [f64],
    status_name: fn(c_int) -> &'static str,
) -> c_int {
    let (n, values) = (vrs.len().min(orders.len()).min(out.len()), out.as_mut_ptr());
    if !call_log::on() {
        // SAFETY: `n` value references and orders, room for `n` values, valid for the call
        // (without the log, a master's call at every step: see `call_log::on`).
        return unsafe { get(raw, vrs.as_ptr(), n, orders.as_ptr(), values) };
    }
    call_log::call(
        name,
        move || format!("vr={}, nvr={n}, order={}", list(&vrs[..n]), list(&orders[..n])),
        // SAFETY: `n` value references and orders, room for `n` values, valid for the call.
        move || unsafe { get(raw, vrs.as_ptr(), n, orders.as_ptr(), values) },
        status_name,
        // SAFETY: the `n` values the call just wrote.
        move |_| format!("value={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
    )
}
