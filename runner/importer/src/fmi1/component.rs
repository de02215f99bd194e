//! An instantiated FMI 1.0 component of either interface (instantiated .. freed) and the calls
//! both share: setting and reading variables, and the checks that turn a status into an error
//! message with the FMU's logged reason.

use std::ffi::{c_int, CString};

use fmi_c::fmi1 as c;

use super::{Binary, Registration};
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
pub(crate) struct Ending {
    pub(crate) terminate: (unsafe extern "C" fn(c::Component) -> c_int, Call),
    pub(crate) free: (unsafe extern "C" fn(c::Component), Call),
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
                Value::Real(v) => ("Real", (api.set_real)(comp, &vr, 1, v)),
                Value::Integer(v) => ("Integer", (api.set_integer)(comp, &vr, 1, v)),
                Value::Boolean(v) => ("Boolean", (api.set_boolean)(comp, &vr, 1, &(*v as c::Boolean))),
                Value::String(v) => {
                    let s = CString::new(v.as_str()).map_err(|_| format!("the value of {} contains a NUL byte", variable.name))?;
                    ("String", (api.set_string)(comp, &vr, 1, &s.as_ptr()))
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
        let status = unsafe { get(self.raw, &vr, 1, &mut value) };
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
                // SAFETY: as many value references as values.
                let status = unsafe { (self.binary.api.common.get_real)(self.raw, group.vrs.as_ptr(), out.len(), out.as_mut_ptr()) };
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
        // SAFETY: as many value references as values, valid for the call.
        let status = unsafe { (self.binary.api.common.set_real)(self.raw, vrs.as_ptr(), vrs.len().min(values.len()), values.as_ptr()) };
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
                    Buffer::F64(b) => ("fmiGetReal", (api.common.get_real)(comp, vrs, n, b.as_mut_ptr())),
                    Buffer::I32(b) => ("fmiGetInteger", (api.common.get_integer)(comp, vrs, n, b.as_mut_ptr())),
                    Buffer::CharBool(b) => ("fmiGetBoolean", (api.common.get_boolean)(comp, vrs, n, b.as_mut_ptr())),
                    Buffer::Text(texts) => {
                        let Some(get_string) = api.functions.get_string else {
                            return Err(format!("{}: the FMU does not export fmiGetString", self.name));
                        };
                        let mut pointers = vec![std::ptr::null::<std::ffi::c_char>(); n];
                        let status = get_string(comp, vrs, n, pointers.as_mut_ptr());
                        if status == OK || status == WARNING {
                            for (text, &p) in texts.iter_mut().zip(&pointers) {
                                // SAFETY: NUL-terminated strings valid until the FMU's next call.
                                *text =
                                    if p.is_null() { String::new() } else { std::ffi::CStr::from_ptr(p).to_string_lossy().into_owned() };
                            }
                        }
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
                trace::enter(self.ending.terminate.1, self.time);
                (self.ending.terminate.0)(self.raw);
            }
            trace::enter(self.ending.free.1, self.time);
            (self.ending.free.0)(self.raw);
        }
    }
}
