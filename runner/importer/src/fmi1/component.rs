//! An instantiated FMI 1.0 component of either interface (instantiated .. freed) and the calls
//! both share: setting and reading variables, and the checks that turn a status into an error
//! message with the FMU's logged reason.

use std::ffi::{c_int, CString};

use fmi_c::fmi1 as c;

use super::{Binary, Registration};
use crate::call_log::{self, boolean, list};
use crate::model::{Kind, Variable};
use crate::reader::Buffer;
use crate::trace::{self, Call};
use crate::{Reader, Value};

pub(crate) const OK: c_int = 0;
pub(crate) const WARNING: c_int = 1;
pub(crate) const DISCARD: c_int = 2;
pub(crate) const ERROR: c_int = 3;
pub(crate) const FATAL: c_int = 4;

/// How an instance of one interface ends: `fmiTerminate`/`fmiFreeModelInstance` or
/// `fmiTerminateSlave`/`fmiFreeSlaveInstance`.
#[derive(Clone, Copy)]
/// Each with its trace code and its name in the call log.
pub(crate) struct Ending {
    pub(crate) terminate: (unsafe extern "C" fn(c::Component) -> c_int, Call, &'static str),
    pub(crate) free: (unsafe extern "C" fn(c::Component), Call, &'static str),
}

/// One instance of an FMI 1.0 FMU.
pub(crate) struct Component<'a> {
    pub(crate) binary: &'a Binary,
    pub(crate) name: String,
    pub(crate) raw: c::Component,
    pub(crate) ending: Ending,
    /// Its log, found by the logger through the registry while the instance lives.
    pub(crate) registration: Registration,
    /// Initialized and no fmiError since: terminating is allowed.
    pub(crate) terminate_allowed: bool,
    pub(crate) fatal: bool,
    /// The model time reached (NaN before the start time is known), for [`trace`].
    pub(crate) time: f64,
}

impl<'a> Component<'a> {
    /// Wraps the component `raw` that `instantiate` (named for messages) returned.
    pub(crate) fn new(
        binary: &'a Binary,
        name: &str,
        registration: Registration,
        ending: Ending,
        (raw, instantiate): (c::Component, &str),
    ) -> Result<Component<'a>, String> {
        let component =
            Component { binary, name: name.to_owned(), raw, ending, registration, terminate_allowed: false, fatal: false, time: f64::NAN };
        if raw.is_null() {
            return Err(component.failure(instantiate, "returned NULL"));
        }
        component.registration.instantiated(raw);
        Ok(component)
    }

    /// An error message for a failed call, with the last problem the FMU logged.
    pub(crate) fn failure(&self, call: &str, what: &str) -> String {
        match self.registration.log().take_reason() {
            Some(message) => format!("{}: {call} {what}: {message}", self.name),
            None => format!("{}: {call} {what} ({})", self.name, crate::logging::NO_REASON),
        }
    }

    /// Ok for fmiOK and fmiWarning, else the failure with the FMU's logged reason.
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

    /// Sets one variable (fmiSet<Type> with one value reference).
    pub(crate) fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        let vr = variable.value_reference;
        let (comp, api) = (self.raw, &self.binary.api.common);
        trace::enter(Call::Fmi1Set, self.time);
        // SAFETY: one value reference and one value, both valid for the call.
        let (kind, status) = unsafe {
            match value {
                Value::Real(v) => {
                    let entered = call_log::enter("fmiSetReal", || format!("vr=[{vr}], nvr=1, value=[{v:?}]"));
                    let status = (api.set_real)(comp, &vr, 1, v);
                    call_log::returned(entered, || c::status_name(status));
                    ("Real", status)
                }
                Value::Integer(v) => {
                    let entered = call_log::enter("fmiSetInteger", || format!("vr=[{vr}], nvr=1, value=[{v}]"));
                    let status = (api.set_integer)(comp, &vr, 1, v);
                    call_log::returned(entered, || c::status_name(status));
                    ("Integer", status)
                }
                Value::Boolean(v) => {
                    let entered = call_log::enter("fmiSetBoolean", || format!("vr=[{vr}], nvr=1, value=[{}]", boolean(1, *v)));
                    let status = (api.set_boolean)(comp, &vr, 1, &(*v as c::Boolean));
                    call_log::returned(entered, || c::status_name(status));
                    ("Boolean", status)
                }
                Value::String(v) => {
                    let s = CString::new(v.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))?;
                    let entered = call_log::enter("fmiSetString", || format!("vr=[{vr}], nvr=1, value=[{v:?}]"));
                    let status = (api.set_string)(comp, &vr, 1, &s.as_ptr());
                    call_log::returned(entered, || c::status_name(status));
                    ("String", status)
                }
                Value::Int(_) | Value::Binary(_) | Value::List(_) => {
                    return Err(format!("{}: {value:?} is not a value of an FMI 1.0 variable", variable.name));
                }
            }
        };
        if status == OK || status == WARNING {
            return Ok(());
        }
        self.check(&format!("fmiSet{kind} of {}", variable.name), status)
    }

    /// Reads a String variable (fmiGetString with one value reference), copied at once.
    pub(crate) fn get_string(&mut self, variable: &Variable) -> Result<String, String> {
        if variable.kind != Kind::String {
            return Err(format!("{} is a {}, not a String", variable.name, variable.kind.as_str()));
        }
        let Some(get) = self.binary.api.functions.get_string else {
            return Err(format!("{}: the FMU does not export fmiGetString", self.name));
        };
        let vr = variable.value_reference;
        let mut value: c::FmiString = std::ptr::null();
        trace::enter(Call::Fmi1Get, self.time);
        // SAFETY: one value reference and room for one pointer.
        let entered = call_log::enter("fmiGetString", || format!("vr=[{vr}], nvr=1"));
        let status = unsafe { get(self.raw, &vr, 1, &mut value) };
        call_log::returned(entered, || c::status_name(status));
        self.check(&format!("fmiGetString of {}", variable.name), status)?;
        // SAFETY: a non-NULL pointer from the FMU is a NUL-terminated string until its next call.
        unsafe { crate::text_of(value, &variable.name, "fmiGetString") }
    }

    /// Reads the variables of `reader` into `out` (one f64 per variable, Booleans as 0/1).
    #[inline(always)]
    pub(crate) fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        if reader.direct {
            // Only Reals: they are in `out`'s order, so read straight into it.
            if let Some(group) = reader.groups.first() {
                trace::enter(Call::Fmi1Get, self.time);
                let (get_real, raw, vrs, values, n) = (self.binary.api.common.get_real, self.raw, &group.vrs, out.as_mut_ptr(), out.len());
                let status = call_log::call(
                    "fmiGetReal",
                    || format!("vr={}, nvr={n}", list(vrs)),
                    // SAFETY: as many value references as values.
                    || unsafe { get_real(raw, vrs.as_ptr(), n, values) },
                    c::status_name,
                    // SAFETY: the `n` values the call just wrote.
                    |_| format!("value={}", list(unsafe { std::slice::from_raw_parts(values, n) })),
                );
                self.check("fmiGetReal", status)?;
            }
            return Ok(());
        }
        self.read_groups(reader)?;
        reader.gather(out);
        Ok(())
    }

    /// Sets Real variables, `values[k]` to `vrs[k]`, in one fmiSetReal call.
    #[inline]
    pub(crate) fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        trace::enter(Call::Fmi1Set, self.time);
        let n = vrs.len().min(values.len());
        let (set_real, raw) = (self.binary.api.common.set_real, self.raw);
        let status = call_log::call(
            "fmiSetReal",
            || format!("vr={}, nvr={n}, value={}", list(&vrs[..n]), list(&values[..n])),
            // SAFETY: `n` value references and as many values, valid for the call.
            || unsafe { set_real(raw, vrs.as_ptr(), n, values.as_ptr()) },
            c::status_name,
            |_| String::new(),
        );
        self.check("fmiSetReal", status)
    }

    /// [`Component::read`] for variables of several types, through the reader's buffers.
    fn read_groups(&mut self, reader: &mut Reader) -> Result<(), String> {
        let comp = self.raw;
        trace::enter(Call::Fmi1Get, self.time);
        for group in &mut reader.groups {
            let (vrs, n) = (group.vrs.as_ptr(), group.vrs.len());
            let api = &self.binary.api;
            // SAFETY: each buffer holds one value per value reference of its group.
            let (call, status) = unsafe {
                match &mut group.buffer {
                    Buffer::F64(b) => {
                        let entered = call_log::enter("fmiGetReal", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.common.get_real)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmiGetReal", status)
                    }
                    Buffer::I32(b) => {
                        let entered = call_log::enter("fmiGetInteger", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.common.get_integer)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmiGetInteger", status)
                    }
                    Buffer::CharBool(b) => {
                        let entered = call_log::enter("fmiGetBoolean", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = (api.common.get_boolean)(comp, vrs, n, b.as_mut_ptr());
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(b)));
                        ("fmiGetBoolean", status)
                    }
                    Buffer::Text(texts) => {
                        let Some(get_string) = api.functions.get_string else {
                            return Err(format!("{}: the FMU does not export fmiGetString", self.name));
                        };
                        let mut pointers = vec![std::ptr::null::<std::ffi::c_char>(); n];
                        let entered = call_log::enter("fmiGetString", || format!("vr={}, nvr={n}", list(&group.vrs)));
                        let status = get_string(comp, vrs, n, pointers.as_mut_ptr());
                        if status == OK || status == WARNING {
                            for (text, &p) in texts.iter_mut().zip(&pointers) {
                                // SAFETY: NUL-terminated strings valid until the FMU's next call.
                                *text =
                                    if p.is_null() { String::new() } else { std::ffi::CStr::from_ptr(p).to_string_lossy().into_owned() };
                            }
                        }
                        call_log::returned_with(entered, || c::status_name(status), || format!("value={}", list(texts)));
                        ("fmiGetString", status)
                    }
                    _ => return Err(format!("{}: a {} variable cannot be read from an FMI 1.0 FMU", self.name, group.kind)),
                }
            };
            self.check(call, status)?;
        }
        Ok(())
    }
}

impl Drop for Component<'_> {
    fn drop(&mut self) {
        // After fmiFatal no further call is allowed, not even freeing the instance; a NULL
        // instance is none to free.
        if self.fatal || self.raw.is_null() {
            return;
        }
        // SAFETY: the component is live; terminating only after initialization and no error,
        // and freeing is the last call.
        unsafe {
            if self.terminate_allowed {
                let (terminate, code, name) = self.ending.terminate;
                trace::enter(code, self.time);
                let entered = call_log::enter(name, String::new);
                let status = terminate(self.raw);
                call_log::returned(entered, || c::status_name(status));
            }
            let (free, code, name) = self.ending.free;
            trace::enter(code, self.time);
            let entered = call_log::enter(name, String::new);
            free(self.raw);
            call_log::returned(entered, || "(void)");
        }
    }
}
