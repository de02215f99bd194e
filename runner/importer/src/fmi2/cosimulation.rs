//! An FMI 2.0 Co-Simulation instance: the FMU integrates itself, one `fmi2DoStep` per
//! communication step.

use std::ffi::c_int;

use fmi_c::fmi2 as c;

use super::component::{Component, DISCARD, OK, WARNING};
use super::Binary;
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Step, Value, Variable};

/// One Co-Simulation instance of an FMI 2.0 FMU.
pub struct CoSimulation<'a> {
    component: Component<'a>,
}

impl<'a> CoSimulation<'a> {
    /// fmi2Instantiate as Co-Simulation; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<CoSimulation<'a>, String> {
        Ok(CoSimulation { component: Component::instantiate(fmu, binary, name, debug_logging, c::CO_SIMULATION)? })
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

    /// Reads a String variable (fmi2GetString).
    pub fn get_string(&mut self, variable: &Variable) -> Result<String, String> {
        self.component.get_string(variable)
    }

    /// Sets one variable (fmi2Set<Type> with one value reference).
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// fmi2SetRealInputDerivatives of the first derivative of the Real input `variable`, for an
    /// FMU that interpolates inputs over a step (`canInterpolateInputs`).
    pub fn set_input_derivative(&mut self, variable: &Variable, derivative: f64) -> Result<(), String> {
        let Some(set) = self.component.binary.api.set_real_input_derivatives else {
            return Err(format!("{}: the FMU does not export fmi2SetRealInputDerivatives", self.component.name));
        };
        let (vr, order): (c::ValueReference, c::Integer) = (variable.value_reference, 1);
        trace::enter(Call::SetReal, self.component.time);
        // SAFETY: one value reference, order and value, valid for the call.
        let status = unsafe { set(self.component.raw, &vr, 1, &order, &derivative) };
        self.component.check(&format!("fmi2SetRealInputDerivatives of {}", variable.name), status)
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
        let do_step = self.component.binary.api.do_step.expect("resolved for Co-Simulation");
        trace::enter(Call::DoStep, t);
        let status = unsafe { do_step(self.component.raw, t, h, c::TRUE) };
        if status == DISCARD {
            return self.discarded(t);
        }
        self.component.check("fmi2DoStep", status)?;
        self.component.time = t + h;
        Ok(Step::Done)
    }

    /// After fmi2Discard from the step at `t`: [`Step::Ended`] if the model terminated.
    #[cold]
    fn discarded(&mut self, t: f64) -> Result<Step, String> {
        let api = &self.component.binary.api;
        let (get_boolean_status, get_real_status) = (api.get_boolean_status.expect("resolved"), api.get_real_status.expect("resolved"));
        let raw = self.component.raw;
        let mut terminated: c_int = 0;
        trace::enter(Call::GetBooleanStatus, t);
        let s = unsafe { get_boolean_status(raw, c::TERMINATED, &mut terminated) };
        self.component.check("fmi2GetBooleanStatus(fmi2Terminated)", s)?;
        let reason = self.component.callbacks.log.take_problem().unwrap_or_else(|| "no reason logged".to_owned());
        if terminated == 0 {
            return Err(format!("{}: fmi2DoStep at t = {t} returned fmi2Discard without terminating: {reason}", self.component.name));
        }
        let mut last = f64::NAN;
        trace::enter(Call::GetRealStatus, t);
        let s = unsafe { get_real_status(raw, c::LAST_SUCCESSFUL_TIME, &mut last) };
        let last_time = (s == OK || s == WARNING).then_some(last).filter(|t| t.is_finite());
        let when = match last_time {
            Some(last) => format!("t = {last}"),
            None => format!("the step from t = {t}"),
        };
        Ok(Step::Ended { reason: format!("the model ended the simulation at {when}: {reason}"), last_time })
    }
}
