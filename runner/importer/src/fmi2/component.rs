//! An instantiated FMI 2.0 component (fmi2Instantiate .. fmi2FreeInstance) and the calls both
//! interfaces share: setup, initialization, setting and reading variables, and the checks that
//! turn a status into an error message with the FMU's logged reason.

use std::ffi::{c_int, CString};

use fmi_c::fmi2 as c;

use super::{Binary, Callbacks};
use crate::call_log::{self, boolean, list};
use crate::model::{Kind, Variable};
use crate::reader::Buffer;
use crate::trace::{self, Call};
use crate::{Fmu, Reader, Value};

pub(crate) const OK: c_int = c::Status::Ok as c_int;
pub(crate) const WARNING: c_int = c::Status::Warning as c_int;
pub(crate) const DISCARD: c_int = c::Status::Discard as c_int;
pub(crate) const ERROR: c_int = c::Status::Error as c_int;
pub(crate) const FATAL: c_int = c::Status::Fatal as c_int;

/// One instance of an FMI 2.0 FMU, of either interface.
pub(crate) struct Component<'a> {
    pub(crate) binary: &'a Binary,
    pub(crate) name: String,
    pub(crate) raw: c::Component,
    // Must stay at a fixed address for the instance's lifetime: the FMU keeps pointers into it.
    pub(crate) callbacks: Box<Callbacks>,
    /// fmi2Terminate is allowed now: the instance left initialization (Co-Simulation:
    /// stepComplete or stepFailed; Model Exchange: event or continuous-time mode) and no call
    /// has since returned fmi2Error, after which only fmi2Reset and fmi2FreeInstance are.
    pub(crate) terminate_allowed: bool,
    pub(crate) fatal: bool,
    /// The model time reached (NaN before fmi2SetupExperiment), for [`trace`].
    pub(crate) time: f64,
}

impl<'a> Component<'a> {
    /// fmi2Instantiate for `fmu_type`; `debug_logging` sets loggingOn.
    pub(crate) fn instantiate(
        fmu: &'a Fmu,
        binary: &'a Binary,
        name: &str,
        debug_logging: bool,
        fmu_type: c::Type,
    ) -> Result<Component<'a>, String> {
        let callbacks = Callbacks::new();
        let c_name = CString::new(name).map_err(|_| format!("instance name {name:?} contains a NUL byte"))?;
        trace::enter(Call::Instantiate, f64::NAN);
        let entered = call_log::enter("fmi2Instantiate", || {
            let kind = if fmu_type == c::CO_SIMULATION { "fmi2CoSimulation" } else { "fmi2ModelExchange" };
            format!(
                "instanceName={name:?}, fmuType={kind}, fmuGUID={:?}, fmuResourceLocation={:?}, visible=fmi2False, loggingOn={}",
                fmu.token,
                fmu.resource_uri,
                boolean(2, debug_logging)
            )
        });
        // SAFETY: every pointer is valid for the call; the callbacks outlive the component.
        let raw = unsafe {
            (binary.api.instantiate)(
                c_name.as_ptr(),
                fmu_type,
                fmu.token.as_ptr(),
                fmu.resource_uri.as_ptr(),
                &callbacks.functions,
                c::FALSE,
                debug_logging as c::Boolean,
            )
        };
        call_log::returned_instance(entered, raw);
        let component = Component { binary, name: name.to_owned(), raw, callbacks, terminate_allowed: false, fatal: false, time: f64::NAN };
        if raw.is_null() {
            return Err(component.failure("fmi2Instantiate", "returned NULL"));
        }
        Ok(component)
    }

    /// An error message for a failed call, with the last problem the FMU logged.
    pub(crate) fn failure(&self, call: &str, what: &str) -> String {
        match self.callbacks.log.take_reason() {
            Some(message) => format!("{}: {call} {what}: {message}", self.name),
            None => format!("{}: {call} {what} ({})", self.name, crate::logging::NO_REASON),
        }
    }

    /// Ok for fmi2OK and fmi2Warning, else the failure with the FMU's logged reason. Inlined
    /// (it follows every doStep and read), with the failure path kept out of line.
    #[inline]
    pub(crate) fn check(&mut self, call: &str, status: c_int) -> Result<(), String> {
        match status {
            OK | WARNING => Ok(()),
            _ => Err(self.refused(call, status)),
        }
    }

    /// Records what a status other than OK or Warning means for the calls still allowed.
    #[cold]
    pub(crate) fn note_status(&mut self, status: c_int) {
        if status == FATAL {
            self.fatal = true;
            trace::note_fatal();
        }
        if status == ERROR || status == FATAL {
            self.terminate_allowed = false;
        }
    }

    /// The failure of `call` at model time `t` (a step from it), with the FMU's reason.
    #[cold]
    #[inline(never)]
    pub(crate) fn refused_at(&mut self, call: &str, t: f64, status: c_int) -> String {
        self.refused(&format!("{call} at t = {t}"), status)
    }

    #[cold]
    fn refused(&mut self, call: &str, status: c_int) -> String {
        self.note_status(status);
        self.failure(call, &format!("returned {}", c::status_name(status)))
    }

    /// fmi2SetupExperiment with an optional relative tolerance and a defined stop time.
    pub(crate) fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.time = start;
        trace::enter(Call::SetupExperiment, start);
        // An infinite stop time is none: stepping from outside runs as long as it is asked to.
        let stop_defined = stop.is_finite();
        let entered = call_log::enter("fmi2SetupExperiment", || {
            format!(
                "toleranceDefined={}, tolerance={:?}, startTime={start:?}, stopTimeDefined={}, stopTime={:?}",
                boolean(2, tolerance.is_some()),
                tolerance.unwrap_or(0.0),
                boolean(2, stop_defined),
                if stop_defined { stop } else { 0.0 }
            )
        });
        let status = unsafe {
            (self.binary.api.setup_experiment)(
                self.raw,
                tolerance.is_some() as c_int,
                tolerance.unwrap_or(0.0),
                start,
                stop_defined as c_int,
                if stop_defined { stop } else { 0.0 },
            )
        };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2SetupExperiment", status)
    }

    /// fmi2Reset: back to the state right after instantiation (set up and initialize again).
    pub(crate) fn reset(&mut self) -> Result<(), String> {
        let Some(reset) = self.binary.api.functions.reset else {
            return Err(format!("{}: the FMU does not export fmi2Reset", self.name));
        };
        trace::enter(Call::Reset, self.time);
        let entered = call_log::enter("fmi2Reset", String::new);
        // SAFETY: the component is live.
        let status = unsafe { reset(self.raw) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2Reset", status)?;
        self.terminate_allowed = false;
        self.time = f64::NAN;
        Ok(())
    }

    /// The FMU's state, serialized (fmi2GetFMUstate, fmi2SerializedFMUstateSize,
    /// fmi2SerializeFMUstate; the state freed again).
    pub(crate) fn get_state(&mut self) -> Result<Vec<u8>, String> {
        let f = &self.binary.api.functions;
        let (Some(get), Some(size), Some(serialize), Some(free)) =
            (f.get_fmu_state, f.serialized_fmu_state_size, f.serialize_fmu_state, f.free_fmu_state)
        else {
            return Err(format!("{}: the FMU does not export fmi2GetFMUstate and fmi2SerializeFMUstate", self.name));
        };
        let mut state: c::FmuState = std::ptr::null_mut();
        trace::enter(Call::GetFmuState, self.time);
        let entered = call_log::enter("fmi2GetFMUstate", String::new);
        // SAFETY: the component is live; `state` receives the FMU's handle.
        let status = unsafe { get(self.raw, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2GetFMUstate", status)?;
        let mut n = 0usize;
        // SAFETY: a state this component returned, and an out pointer.
        let entered = call_log::enter("fmi2SerializedFMUstateSize", String::new);
        let status = unsafe { size(self.raw, state, &mut n) };
        call_log::returned_with(entered, || c::status_name(status), || format!("size={n}"));
        let bytes = self.check("fmi2SerializedFMUstateSize", status).and_then(|()| {
            if n > crate::state::MAX_STATE_BYTES {
                return Err(format!("{}: fmi2SerializedFMUstateSize gave {n} bytes", self.name));
            }
            let mut bytes = vec![0u8; n];
            // SAFETY: `n` writable bytes, as the FMU asked for.
            let entered = call_log::enter("fmi2SerializeFMUstate", || format!("size={n}"));
            let status = unsafe { serialize(self.raw, state, bytes.as_mut_ptr().cast(), n) };
            call_log::returned(entered, || c::status_name(status));
            self.check("fmi2SerializeFMUstate", status).map(|()| bytes)
        });
        let entered = call_log::enter("fmi2FreeFMUstate", String::new);
        // SAFETY: the state is this component's, freed once.
        let status = unsafe { free(self.raw, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        bytes
    }

    /// Sets the FMU's state from `bytes` of [`Component::get_state`] (fmi2DeSerializeFMUstate,
    /// fmi2SetFMUstate; the state freed again).
    pub(crate) fn set_state(&mut self, bytes: &[u8]) -> Result<(), String> {
        let f = &self.binary.api.functions;
        let (Some(deserialize), Some(set), Some(free)) = (f.de_serialize_fmu_state, f.set_fmu_state, f.free_fmu_state) else {
            return Err(format!("{}: the FMU does not export fmi2DeSerializeFMUstate and fmi2SetFMUstate", self.name));
        };
        let mut state: c::FmuState = std::ptr::null_mut();
        trace::enter(Call::SetFmuState, self.time);
        // SAFETY: `bytes.len()` readable bytes; `state` receives the FMU's handle.
        let entered = call_log::enter("fmi2DeSerializeFMUstate", || format!("size={}", bytes.len()));
        let status = unsafe { deserialize(self.raw, bytes.as_ptr().cast(), bytes.len(), &mut state) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2DeSerializeFMUstate", status)?;
        // SAFETY: a state this component made.
        let entered = call_log::enter("fmi2SetFMUstate", String::new);
        let status = unsafe { set(self.raw, state) };
        call_log::returned(entered, || c::status_name(status));
        let result = self.check("fmi2SetFMUstate", status);
        let entered = call_log::enter("fmi2FreeFMUstate", String::new);
        // SAFETY: freed once.
        let status = unsafe { free(self.raw, &mut state) };
        call_log::returned(entered, || c::status_name(status));
        result?;
        self.terminate_allowed = true;
        Ok(())
    }

    /// fmi2EnterInitializationMode.
    pub(crate) fn enter_initialization_mode(&mut self) -> Result<(), String> {
        trace::enter(Call::EnterInitializationMode, self.time);
        let entered = call_log::enter("fmi2EnterInitializationMode", String::new);
        let status = unsafe { (self.binary.api.enter_initialization_mode)(self.raw) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2EnterInitializationMode", status)
    }

    /// fmi2ExitInitializationMode.
    pub(crate) fn exit_initialization_mode(&mut self) -> Result<(), String> {
        trace::enter(Call::ExitInitializationMode, self.time);
        let entered = call_log::enter("fmi2ExitInitializationMode", String::new);
        let status = unsafe { (self.binary.api.exit_initialization_mode)(self.raw) };
        call_log::returned(entered, || c::status_name(status));
        self.check("fmi2ExitInitializationMode", status)?;
        self.terminate_allowed = true;
        Ok(())
    }

    /// Sets one variable (fmi2Set<Type> with one value reference).
    pub(crate) fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        let vr = variable.value_reference;
        let comp = self.raw;
        let api = &self.binary.api;
        let time = self.time;
        // SAFETY: one value reference and one value, both valid for the call.
        let status = unsafe {
            match value {
                Value::Real(v) => {
                    trace::enter(Call::SetReal, time);
                    let entered = call_log::enter("fmi2SetReal", || format!("vr=[{vr}], nvr=1, value=[{v:?}]"));
                    let status = (api.set_real)(comp, &vr, 1, v);
                    call_log::returned(entered, || c::status_name(status));
                    status
                }
                Value::Integer(v) => {
                    trace::enter(Call::SetInteger, time);
                    let entered = call_log::enter("fmi2SetInteger", || format!("vr=[{vr}], nvr=1, value=[{v}]"));
                    let status = (api.set_integer)(comp, &vr, 1, v);
                    call_log::returned(entered, || c::status_name(status));
                    status
                }
                Value::Boolean(v) => {
                    trace::enter(Call::SetBoolean, time);
                    let entered = call_log::enter("fmi2SetBoolean", || format!("vr=[{vr}], nvr=1, value=[{}]", boolean(2, *v)));
                    let status = (api.set_boolean)(comp, &vr, 1, &(*v as c_int));
                    call_log::returned(entered, || c::status_name(status));
                    status
                }
                Value::String(v) => {
                    trace::enter(Call::SetString, time);
                    let s = CString::new(v.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))?;
                    let entered = call_log::enter("fmi2SetString", || format!("vr=[{vr}], nvr=1, value=[{v:?}]"));
                    let status = (api.set_string)(comp, &vr, 1, &s.as_ptr());
                    call_log::returned(entered, || c::status_name(status));
                    status
                }
                Value::Int(_) | Value::Binary(_) | Value::List(_) => {
                    return Err(format!("{}: {value:?} is not a value of an FMI 2.0 variable", variable.name));
                }
            }
        };
        if status == OK || status == WARNING {
            // The message is made only on failure: inputs are set at every step.
            return Ok(());
        }
        let kind = match variable.kind {
            Kind::Boolean => "Boolean",
            Kind::String => "String",
            Kind::Integer | Kind::Enumeration => "Integer",
            _ => "Real",
        };
        self.check(&format!("fmi2Set{kind} of {}", variable.name), status)
    }

    /// Reads a String variable (fmi2GetString with one value reference): the FMU's text copied
    /// at once, as the FMU may reuse its memory at the next call.
    pub(crate) fn get_string(&mut self, variable: &Variable) -> Result<String, String> {
        if variable.kind != Kind::String {
            return Err(format!("{} is a {}, not a String", variable.name, variable.kind.as_str()));
        }
        let Some(get) = self.binary.api.functions.get_string else {
            return Err(format!("{}: the FMU does not export fmi2GetString", self.name));
        };
        let vr = variable.value_reference;
        let mut value: c::FmiString = std::ptr::null();
        trace::enter(Call::GetString, self.time);
        // SAFETY: one value reference and room for one pointer.
        let entered = call_log::enter("fmi2GetString", || format!("vr=[{vr}], nvr=1"));
        let status = unsafe { get(self.raw, &vr, 1, &mut value) };
        call_log::returned(entered, || c::status_name(status));
        self.check(&format!("fmi2GetString of {}", variable.name), status)?;
        // SAFETY: a non-NULL pointer from the FMU is a NUL-terminated string until its next call.
        unsafe { crate::text_of(value, &variable.name, "fmi2GetString") }
    }

    /// Reads the variables of `reader` into `out` (one f64 per variable, Booleans as 0/1).
    #[inline(always)]
    pub(crate) fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        if reader.direct {
            // Only Reals (the usual sweep): they are in `out`'s order, so read straight into it.
            if let Some(group) = reader.groups.first() {
                trace::enter(Call::GetReal, self.time);
                let (get_real, raw, vrs, values, n) = (self.binary.api.get_real, self.raw, &group.vrs, out.as_mut_ptr(), out.len());
                let status = call_log::call(
                    "fmi2GetReal",
                    || format!("vr={}, nvr={n}", list(vrs)),
                    || unsafe { get_real(raw, vrs.as_ptr(), n, values) },
                    c::status_name,
                    // SAFETY: the `n` values the call just wrote.
                    |_| format!("value={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
                );
                self.check("fmi2GetReal", status)?;
            }
            return Ok(());
        }
        self.read_groups(reader)?;
        reader.gather(out);
        Ok(())
    }

    /// Sets Real variables, `values[k]` to `vrs[k]`, in one fmi2SetReal call (a master's
    /// inputs at every step: no allocation).
    #[inline]
    pub(crate) fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        debug_assert_eq!(vrs.len(), values.len());
        trace::enter(Call::SetReal, self.time);
        let n = vrs.len().min(values.len());
        let (set_real, raw) = (self.binary.api.set_real, self.raw);
        let status = call_log::call(
            "fmi2SetReal",
            || format!("vr={}, nvr={n}, value={}", list(&vrs[..n]), list(&values[..n])),
            // SAFETY: `n` value references and as many values, valid for the call.
            || unsafe { set_real(raw, vrs.as_ptr(), n, values.as_ptr()) },
            c::status_name,
            |_| String::new(),
        );
        self.check("fmi2SetReal", status)
    }

    /// [`Component::read`] for variables of several types, through the reader's buffers.
    fn read_groups(&mut self, reader: &mut Reader) -> Result<(), String> {
        let comp = self.raw;
        for group in &mut reader.groups {
            let (vrs, n) = (group.vrs.as_ptr(), group.vrs.len());
            let api = &self.binary.api;
            // SAFETY: each buffer holds one value per value reference of its group.
            let time = self.time;
            let (call, status) = unsafe {
                match &mut group.buffer {
                    Buffer::F64(b) => {
                        trace::enter(Call::GetReal, time);
                        let entered = call_log::enter("fmi2GetReal", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.get_real)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmi2GetReal", status)
                    }
                    Buffer::I32(b) => {
                        trace::enter(Call::GetInteger, time);
                        let entered = call_log::enter("fmi2GetInteger", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.get_integer)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmi2GetInteger", status)
                    }
                    Buffer::IntBool(b) => {
                        trace::enter(Call::GetBoolean, time);
                        let entered = call_log::enter("fmi2GetBoolean", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.get_boolean)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmi2GetBoolean", status)
                    }
                    Buffer::Text(texts) => {
                        let Some(get_string) = api.functions.get_string else {
                            return Err(format!("{}: the FMU does not export fmi2GetString", self.name));
                        };
                        trace::enter(Call::GetString, time);
                        let mut pointers = vec![std::ptr::null::<std::ffi::c_char>(); n];
                        let entered = call_log::enter("fmi2GetString", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = get_string(comp, vrs, n, pointers.as_mut_ptr());
                        if status == OK || status == WARNING {
                            for (text, &p) in texts.iter_mut().zip(&pointers) {
                                // SAFETY: the FMU returned NUL-terminated strings valid until its next call.
                                *text =
                                    if p.is_null() { String::new() } else { std::ffi::CStr::from_ptr(p).to_string_lossy().into_owned() };
                            }
                        }
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(texts)));
                        ("fmi2GetString", status)
                    }
                    _ => return Err(format!("{}: a {} variable cannot be read from an FMI 2.0 FMU", self.name, group.kind)),
                }
            };
            self.check(call, status)?;
        }
        Ok(())
    }
}

impl Drop for Component<'_> {
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
                let entered = call_log::enter("fmi2Terminate", String::new);
                let status = (self.binary.api.terminate)(self.raw);
                call_log::returned(entered, || c::status_name(status));
            }
            trace::enter(Call::FreeInstance, self.time);
            let entered = call_log::enter("fmi2FreeInstance", String::new);
            (self.binary.api.free_instance)(self.raw);
            call_log::returned(entered, || "(void)");
        }
    }
}
