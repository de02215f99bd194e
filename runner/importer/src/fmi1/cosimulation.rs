//! An FMI 1.0 Co-Simulation instance (a slave): the FMU integrates itself, one `fmiDoStep` per
//! communication step.

use std::ffi::{c_int, CString};

use fmi_c::fmi1 as c;

use super::component::{Component, Ending, DISCARD, OK, WARNING};
use super::{Binary, Registration, SlaveApi};
use crate::call_log::{self, boolean};
use crate::fmi2::cosimulation::{get_real_output_derivatives, set_real_input_derivatives};
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Step, Value, Variable};

/// The MIME type of a stand-alone slave (the only kind the runner runs).
const MIME_TYPE: &str = "application/x-fmu-sharedlibrary";

/// One Co-Simulation instance of an FMI 1.0 FMU.
pub struct CoSimulation<'a> {
    component: Component<'a>,
    api: SlaveApi,
    /// The experiment, kept for fmiInitializeSlave: start and stop time (infinite: none).
    start: f64,
    stop: f64,
}

impl<'a> CoSimulation<'a> {
    /// fmiInstantiateSlave; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<CoSimulation<'a>, String> {
        let api = binary.api.slave.expect("resolved for Co-Simulation");
        let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
        let mime = CString::new(MIME_TYPE).expect("no NUL");
        let registration = Registration::new(name);
        trace::enter(Call::Fmi1InstantiateSlave, f64::NAN);
        let entered = call_log::enter("fmiInstantiateSlave", || {
            format!(
                "instanceName={name:?}, fmuGUID={:?}, fmuLocation={:?}, mimeType={MIME_TYPE:?}, timeout=0.0, visible=fmiFalse, interactive=fmiFalse, loggingOn={}",
                fmu.token,
                fmu.resource_uri,
                boolean(1, debug_logging)
            )
        });
        // SAFETY: every pointer is valid for the call; the callbacks are static functions.
        let raw = unsafe {
            (api.instantiate_slave)(
                c_name.as_ptr(),
                fmu.token.as_ptr(),
                fmu.resource_uri.as_ptr(),
                mime.as_ptr(),
                0.0,
                c::FALSE,
                c::FALSE,
                c::SlaveCallbacks::standard(),
                debug_logging as c::Boolean,
            )
        };
        call_log::returned_instance(entered, raw);
        let ending = Ending {
            terminate: (api.terminate_slave, Call::Fmi1TerminateSlave, "fmiTerminateSlave"),
            free: (api.free_slave_instance, Call::Fmi1FreeSlaveInstance, "fmiFreeSlaveInstance"),
        };
        let component = Component::new(binary, name, registration, ending, (raw, "fmiInstantiateSlave"))?;
        Ok(CoSimulation { component, api, start: 0.0, stop: f64::INFINITY })
    }

    /// Keeps the start and stop time for fmiInitializeSlave (FMI 1.0 has no tolerance for a
    /// slave).
    pub fn setup_experiment(&mut self, _tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        (self.start, self.stop) = (start, stop);
        self.component.time = start;
        Ok(())
    }

    /// Nothing to call: FMI 1.0 sets start values between instantiation and fmiInitializeSlave.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        Ok(())
    }

    /// fmiInitializeSlave with the experiment's start and (when finite) stop time.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        let stop_defined = self.stop.is_finite();
        trace::enter(Call::Fmi1InitializeSlave, self.start);
        let entered = call_log::enter("fmiInitializeSlave", || {
            format!(
                "tStart={:?}, StopTimeDefined={}, tStop={:?}",
                self.start,
                boolean(1, stop_defined),
                if stop_defined { self.stop } else { 0.0 }
            )
        });
        // SAFETY: a live component and scalar arguments.
        let status = unsafe {
            (self.api.initialize_slave)(
                self.component.raw,
                self.start,
                stop_defined as c::Boolean,
                if stop_defined { self.stop } else { 0.0 },
            )
        };
        call_log::returned(entered, || c::status_name(status));
        self.component.check("fmiInitializeSlave", status)?;
        self.component.terminate_allowed = true;
        Ok(())
    }

    /// fmiResetSlave: back to the state right after instantiation.
    pub fn reset(&mut self) -> Result<(), String> {
        let Some(reset) = self.component.binary.api.functions.reset_slave else {
            return Err(format!("{}: the FMU does not export fmiResetSlave", self.component.name));
        };
        trace::enter(Call::Fmi1ResetSlave, self.component.time);
        // SAFETY: a live component.
        let entered = call_log::enter("fmiResetSlave", String::new);
        let status = unsafe { reset(self.component.raw) };
        call_log::returned(entered, || c::status_name(status));
        self.component.check("fmiResetSlave", status)?;
        self.component.terminate_allowed = false;
        Ok(())
    }

    /// FMI 1.0 has no FMU state to get.
    pub fn get_state(&mut self) -> Result<Vec<u8>, String> {
        Err(format!("{}: FMI 1.0 has no FMU state to save (fmi2GetFMUstate came with FMI 2.0)", self.component.name))
    }

    /// FMI 1.0 has no FMU state to set.
    pub fn set_state(&mut self, _bytes: &[u8]) -> Result<(), String> {
        Err(format!("{}: FMI 1.0 has no FMU state to restore (fmi2SetFMUstate came with FMI 2.0)", self.component.name))
    }

    /// Reads a String variable (fmiGetString).
    pub fn get_string(&mut self, variable: &Variable) -> Result<String, String> {
        self.component.get_string(variable)
    }

    /// Sets one variable.
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// fmiSetRealInputDerivatives: the `orders[k]`-th time derivative of the Real input
    /// `vrs[k]` is `values[k]`, for an FMU that interpolates inputs.
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> Result<(), String> {
        let Some(set) = self.component.binary.api.functions.set_real_input_derivatives else {
            return Err(format!("{}: the FMU does not export fmiSetRealInputDerivatives", self.component.name));
        };
        trace::enter(Call::Fmi1Set, self.component.time);
        let status = set_real_input_derivatives("fmiSetRealInputDerivatives", set, self.component.raw, vrs, orders, values, c::status_name);
        self.component.check("fmiSetRealInputDerivatives", status)
    }

    /// fmiGetRealOutputDerivatives: `out[k]` = the `orders[k]`-th time derivative of `vrs[k]`.
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], out: &mut [f64]) -> Result<(), String> {
        let Some(get) = self.component.binary.api.functions.get_real_output_derivatives else {
            return Err(format!("{}: the FMU does not export fmiGetRealOutputDerivatives", self.component.name));
        };
        trace::enter(Call::Fmi1Get, self.component.time);
        let status = get_real_output_derivatives("fmiGetRealOutputDerivatives", get, self.component.raw, vrs, orders, out, c::status_name);
        self.component.check("fmiGetRealOutputDerivatives", status)
    }

    /// Reads the variables of `reader` into `out`.
    #[inline(always)]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    /// Sets Real scalars, `values[k]` to `vrs[k]`, in one call.
    #[inline]
    pub fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        self.component.set_reals(vrs, values)
    }

    /// fmiDoStep from `t` over `h`; a discarded step ends the run at the slave's last
    /// successful time.
    #[inline(always)]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        trace::enter(Call::Fmi1DoStep, t);
        let (do_step, raw) = (self.api.do_step, self.component.raw);
        let status = call_log::call(
            "fmiDoStep",
            || format!("currentCommunicationPoint={t:?}, communicationStepSize={h:?}, newStep=fmiTrue"),
            // SAFETY: a live component and scalar arguments.
            || unsafe { do_step(raw, t, h, c::TRUE) },
            c::status_name,
            |_| String::new(),
        );
        if status == DISCARD {
            return Ok(self.discarded(t));
        }
        if status != OK && status != WARNING {
            return Err(self.component.refused_at("fmiDoStep", t, status));
        }
        self.component.time = t + h;
        Ok(Step::Done)
    }

    /// After fmiDiscard from the step at `t`: the slave could not complete it, so the run ends
    /// where the slave got to (fmiLastSuccessfulTime, when it tells).
    #[cold]
    fn discarded(&mut self, t: f64) -> Step {
        let reason = self.component.registration.log().take_reason().unwrap_or_else(|| "no reason logged".to_owned());
        let last_time = self.component.binary.api.functions.get_real_status.and_then(|get| {
            let mut last = f64::NAN;
            trace::enter(Call::Fmi1GetRealStatus, t);
            // SAFETY: a live component and an out pointer.
            let entered = call_log::enter("fmiGetRealStatus", || "s=fmiLastSuccessfulTime".to_owned());
            let status: c_int = unsafe { get(self.component.raw, c::LAST_SUCCESSFUL_TIME, &mut last) };
            call_log::returned_with(entered, || c::status_name(status), || format!("value={last:?}"));
            (status == OK || status == WARNING).then_some(last).filter(|t| t.is_finite())
        });
        let when = match last_time {
            Some(last) => format!("t = {last}"),
            None => format!("the step from t = {t}"),
        };
        Step::Ended { reason: format!("the slave discarded the step (fmiDiscard) at {when}: {reason}"), last_time }
    }
}
