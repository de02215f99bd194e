//! An FMI 2.0 Co-Simulation instance (fmi2Instantiate .. fmi2FreeInstance).

use std::ffi::{c_int, CString};

use fmi_c::fmi2 as c;

use super::{Binary, Callbacks};
use crate::model::{Kind, Variable};
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Step, Value};

const OK: c_int = c::Status::Ok as c_int;
const WARNING: c_int = c::Status::Warning as c_int;
const DISCARD: c_int = c::Status::Discard as c_int;
const ERROR: c_int = c::Status::Error as c_int;
const FATAL: c_int = c::Status::Fatal as c_int;

/// One Co-Simulation instance of an FMI 2.0 FMU.
pub struct CoSimulation<'a> {
    binary: &'a Binary,
    name: String,
    component: c::Component,
    // Must stay at a fixed address for the instance's lifetime: the FMU keeps pointers into it.
    callbacks: Box<Callbacks>,
    /// fmi2Terminate is allowed now: the instance left initialization (stepComplete or
    /// stepFailed) and no call has since returned fmi2Error, after which only fmi2Reset and
    /// fmi2FreeInstance are.
    terminate_allowed: bool,
    fatal: bool,
    /// The model time reached (NaN before fmi2SetupExperiment), for [`trace`].
    time: f64,
}

impl<'a> CoSimulation<'a> {
    /// fmi2Instantiate as Co-Simulation; `debug_logging` sets loggingOn.
    pub(crate) fn new(fmu: &'a Fmu, binary: &'a Binary, name: &str, debug_logging: bool) -> Result<CoSimulation<'a>, String> {
        let callbacks = Callbacks::new();
        let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
        trace::enter(Call::Instantiate, f64::NAN);
        // SAFETY: every pointer is valid for the call; the callbacks outlive the component.
        let component = unsafe {
            (binary.api.instantiate)(
                c_name.as_ptr(),
                c::CO_SIMULATION,
                fmu.token.as_ptr(),
                fmu.resource_uri.as_ptr(),
                &callbacks.functions,
                c::FALSE,
                debug_logging as c::Boolean,
            )
        };
        let instance =
            CoSimulation { binary, name: name.to_owned(), component, callbacks, terminate_allowed: false, fatal: false, time: f64::NAN };
        if component.is_null() {
            return Err(instance.failure("fmi2Instantiate", "returned NULL"));
        }
        Ok(instance)
    }

    /// An error message for a failed call, with the last problem the FMU logged.
    fn failure(&self, call: &str, what: &str) -> String {
        match self.callbacks.log.take_problem() {
            Some(message) => format!("{}: {call} {what}: {message}", self.name),
            None => format!("{}: {call} {what} (the FMU logged no reason)", self.name),
        }
    }

    /// Ok for fmi2OK and fmi2Warning, else the failure with the FMU's logged reason. Inlined
    /// (it follows every doStep and read), with the failure path kept out of line.
    #[inline]
    fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        match status {
            OK | WARNING => Ok(()),
            _ => Err(self.refused(call, status)),
        }
    }

    #[cold]
    fn refused(&mut self, call: &str, status: c_int) -> String {
        if status == FATAL {
            self.fatal = true;
        }
        if status == ERROR || status == FATAL {
            self.terminate_allowed = false;
        }
        self.failure(call, &format!("returned {}", c::status_name(status)))
    }

    /// fmi2SetupExperiment with an optional relative tolerance and a defined stop time.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.time = start;
        trace::enter(Call::SetupExperiment, start);
        let status = unsafe {
            (self.binary.api.setup_experiment)(self.component, tolerance.is_some() as c_int, tolerance.unwrap_or(0.0), start, 1, stop)
        };
        self.check("fmi2SetupExperiment", status)
    }

    /// fmi2EnterInitializationMode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        trace::enter(Call::EnterInitializationMode, self.time);
        let status = unsafe { (self.binary.api.enter_initialization_mode)(self.component) };
        self.check("fmi2EnterInitializationMode", status)
    }

    /// fmi2ExitInitializationMode.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        trace::enter(Call::ExitInitializationMode, self.time);
        let status = unsafe { (self.binary.api.exit_initialization_mode)(self.component) };
        self.check("fmi2ExitInitializationMode", status)?;
        self.terminate_allowed = true;
        Ok(())
    }

    /// Sets one variable (fmi2Set<Type> with one value reference).
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        let vr = variable.value_reference;
        let comp = self.component;
        let api = &self.binary.api;
        let time = self.time;
        // SAFETY: one value reference and one value, both valid for the call.
        let status = unsafe {
            match value {
                Value::Real(v) => {
                    trace::enter(Call::SetReal, time);
                    (api.set_real)(comp, &vr, 1, v)
                }
                Value::Integer(v) => {
                    trace::enter(Call::SetInteger, time);
                    (api.set_integer)(comp, &vr, 1, v)
                }
                Value::Boolean(v) => {
                    trace::enter(Call::SetBoolean, time);
                    (api.set_boolean)(comp, &vr, 1, &(*v as c_int))
                }
                Value::String(v) => {
                    trace::enter(Call::SetString, time);
                    let s = CString::new(v.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))?;
                    (api.set_string)(comp, &vr, 1, &s.as_ptr())
                }
            }
        };
        let kind = match variable.kind {
            Kind::Real => "Real",
            Kind::Boolean => "Boolean",
            Kind::String => "String",
            Kind::Integer | Kind::Enumeration => "Integer",
        };
        self.check(&format!("fmi2Set{kind} of {}", variable.name), status)
    }

    /// Reads the variables of `reader` into `out` (one f64 per variable, Booleans as 0/1).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        if reader.integer_vrs.is_empty() && reader.boolean_vrs.is_empty() && out.len() == reader.real_vrs.len() {
            // Only Reals (the usual sweep): they are in `out`'s order, so read straight into it.
            if !out.is_empty() {
                trace::enter(Call::GetReal, self.time);
                let status = unsafe { (self.binary.api.get_real)(self.component, reader.real_vrs.as_ptr(), out.len(), out.as_mut_ptr()) };
                self.check("fmi2GetReal", status)?;
            }
            return Ok(());
        }
        self.read_mixed(reader, out)
    }

    /// [`CoSimulation::read`] for variables of several types, through the reader's buffers.
    fn read_mixed(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        let comp = self.component;
        let api = &self.binary.api;
        if !reader.real_vrs.is_empty() {
            trace::enter(Call::GetReal, self.time);
            let status = unsafe { (api.get_real)(comp, reader.real_vrs.as_ptr(), reader.real_vrs.len(), reader.real_buf.as_mut_ptr()) };
            self.check("fmi2GetReal", status)?;
        }
        if !reader.integer_vrs.is_empty() {
            trace::enter(Call::GetInteger, self.time);
            let status =
                unsafe { (api.get_integer)(comp, reader.integer_vrs.as_ptr(), reader.integer_vrs.len(), reader.integer_buf.as_mut_ptr()) };
            self.check("fmi2GetInteger", status)?;
        }
        if !reader.boolean_vrs.is_empty() {
            trace::enter(Call::GetBoolean, self.time);
            let status =
                unsafe { (api.get_boolean)(comp, reader.boolean_vrs.as_ptr(), reader.boolean_vrs.len(), reader.boolean_buf.as_mut_ptr()) };
            self.check("fmi2GetBoolean", status)?;
        }
        reader.gather(out);
        Ok(())
    }

    /// fmi2DoStep from `t` over `h`; a discard with fmi2Terminated becomes [`Step::Ended`].
    /// Inlined into the run loop, with the discard handling out of line.
    #[inline]
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        let do_step = self.binary.api.do_step.expect("resolved for Co-Simulation");
        trace::enter(Call::DoStep, t);
        let status = unsafe { do_step(self.component, t, h, c::TRUE) };
        if status == DISCARD {
            return self.discarded(t);
        }
        self.check("fmi2DoStep", status)?;
        self.time = t + h;
        Ok(Step::Done)
    }

    /// After fmi2Discard from the step at `t`: [`Step::Ended`] if the model terminated.
    #[cold]
    fn discarded(&mut self, t: f64) -> Result<Step, String> {
        let api = &self.binary.api;
        let (get_boolean_status, get_real_status) = (api.get_boolean_status.expect("resolved"), api.get_real_status.expect("resolved"));
        let mut terminated: c_int = 0;
        trace::enter(Call::GetBooleanStatus, t);
        let s = unsafe { get_boolean_status(self.component, c::TERMINATED, &mut terminated) };
        self.check("fmi2GetBooleanStatus(fmi2Terminated)", s)?;
        let reason = self.callbacks.log.take_problem().unwrap_or_else(|| "no reason logged".to_owned());
        if terminated == 0 {
            return Err(format!("{}: fmi2DoStep at t = {t} returned fmi2Discard without terminating: {reason}", self.name));
        }
        let mut last = f64::NAN;
        trace::enter(Call::GetRealStatus, t);
        let s = unsafe { get_real_status(self.component, c::LAST_SUCCESSFUL_TIME, &mut last) };
        let last_time = (s == OK || s == WARNING).then_some(last).filter(|t| t.is_finite());
        let when = match last_time {
            Some(last) => format!("t = {last}"),
            None => format!("the step from t = {t}"),
        };
        Ok(Step::Ended { reason: format!("the model ended the simulation at {when}: {reason}"), last_time })
    }
}

impl Drop for CoSimulation<'_> {
    fn drop(&mut self) {
        // After fmi2Fatal the standard allows no further call, not even fmi2FreeInstance.
        if self.fatal {
            return;
        }
        // SAFETY: the component is live; fmi2Terminate only where the standard allows it (a
        // call it refuses would log an "illegal call sequence"), and fmi2FreeInstance is the
        // last call.
        unsafe {
            if self.terminate_allowed {
                trace::enter(Call::Terminate, self.time);
                (self.binary.api.terminate)(self.component);
            }
            trace::enter(Call::FreeInstance, self.time);
            (self.binary.api.free_instance)(self.component);
        }
    }
}
