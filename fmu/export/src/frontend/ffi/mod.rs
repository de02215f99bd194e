//! The C boundary of both versions: the generic bodies of the C functions, which each
//! version's `extern "C"` functions (`fmi2::ffi`, `fmi3::ffi`) call with their arguments. A
//! body finds the instance behind the component pointer ([`Component`], tagged per version),
//! checks the call against the state machine and its pointers and lengths, and runs the
//! instance's method inside the unwinding guard ([`with_instance`]): nothing panics across the
//! C boundary, and every refusal is logged and returned as a status. Here: the guard,
//! instantiation, and C strings and arrays; beside it the typed getters and setters
//! (`variables`), FMU states (`fmu_state`, in a [`StateBox`] tagged per model and version),
//! the Model Exchange calls (`model_exchange`) and the derivatives (`derivatives`).
//!
//! Safety: every `unsafe fn` here takes what the standard promises of the importer's
//! arguments: a component pointer is NULL or one instantiation returned and not yet freed, and
//! an array pointer is NULL or holds the number of values passed with it.

#![allow(clippy::missing_safety_doc)]

mod derivatives;
mod fmu_state;
mod model_exchange;
mod variables;

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

pub use derivatives::{get_directional_derivative, get_output_derivatives, get_sensitivity, set_input_derivatives};
pub use fmu_state::{
    deserialize_fmu_state, free_fmu_state, get_fmu_state, serialize_fmu_state, serialized_fmu_state_size, set_fmu_state, StateBox,
};
pub use model_exchange::{
    completed_integrator_step, get_continuous_states, get_derivatives, get_event_indicators, get_nominals_of_continuous_states,
    set_continuous_states, set_time,
};
pub use variables::{get_boolean, get_integer, get_real, get_string, set_boolean, set_integer, set_real, set_string, CBoolean};

use super::{Call, Instance, Setup, Version};
use crate::core::{CallResult, Failure};
use crate::logging::{Logger, Status};
use crate::model::Model;
use crate::table::Table;

/// A tag unique to the model and its table, stored in FMU states and serialized buffers.
pub fn model_tag<M: Model>() -> u64 {
    crate::table::guid_hash::<M>()
}

/// Makes a C string for the logger, escaping `%` because FMI 2.0's logger treats it as a
/// format (FMI 3.0's does not, but an importer may pass the text to printf all the same).
pub fn c_message(s: &str) -> CString {
    CString::new(s.replace('%', "%%").replace('\0', " ")).expect("NULs removed")
}

/// The UTF-8 text `p` points at; `None` for NULL or text that is not UTF-8.
///
/// # Safety
/// `p` is NULL or a NUL-terminated string that outlives the result.
pub unsafe fn opt_str<'a>(p: *const c_char) -> Option<&'a str> {
    if p.is_null() {
        None
    } else {
        CStr::from_ptr(p).to_str().ok()
    }
}

/// The texts of a String setter's `pointers` (one per value reference of `vrs`, named from
/// `table` in refusals): a NULL pointer or text that is not UTF-8 is refused, naming the
/// variable and the element (`what[i]`), instead of being read.
///
/// # Safety
/// Each pointer is NULL or a NUL-terminated string that outlives the result.
pub unsafe fn texts<'a, M>(pointers: &[*const c_char], vrs: &[u32], table: &Table<M>, call: &str, what: &str) -> CallResult<Vec<&'a str>> {
    let name = |i: usize| vrs.get(i).and_then(|vr| table.row(*vr)).map_or("?", |r| r.name);
    pointers
        .iter()
        .enumerate()
        .map(|(i, p)| {
            if p.is_null() {
                return Err(Failure::error(format!("{call}: {what}[{i}] (for '{}') is a NULL pointer, not a string", name(i))));
            }
            CStr::from_ptr(*p)
                .to_str()
                .map_err(|e| Failure::error(format!("{call}: {what}[{i}] (for '{}') is not valid UTF-8 text ({e})", name(i))))
        })
        .collect()
}

/// The message of a caught panic.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_owned()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "unknown panic".to_owned()
    }
}

/// The `n` values at `p` (`call` and `what` name them in the refusal of a NULL pointer).
///
/// # Safety
/// `p` is NULL or points at `n` values that outlive the result.
pub unsafe fn slice<'a, T>(p: *const T, n: usize, call: &str, what: &str) -> CallResult<&'a [T]> {
    if n == 0 {
        Ok(&[])
    } else if p.is_null() {
        Err(null_array(call, what, n))
    } else {
        Ok(std::slice::from_raw_parts(p, n))
    }
}

/// The `n` writable values at `p` (see [`slice()`]).
///
/// # Safety
/// `p` is NULL or points at `n` values, writable and unaliased while the result lives.
pub unsafe fn slice_mut<'a, T>(p: *mut T, n: usize, call: &str, what: &str) -> CallResult<&'a mut [T]> {
    if n == 0 {
        Ok(&mut [])
    } else if p.is_null() {
        Err(null_array(call, what, n))
    } else {
        Ok(std::slice::from_raw_parts_mut(p, n))
    }
}

// Out of line, so the hot calls do not set up this message's arguments on every call.
#[cold]
#[inline(never)]
fn null_array(call: &str, what: &str, n: usize) -> Failure {
    Failure::error(format!("{call}: {what} is NULL but its length is {n}"))
}

/// Copies `text` NUL-terminated into `buffer` when it fits; returns the bytes needed
/// (including the NUL), like `snprintf`, so the caller can size its buffer.
///
/// # Safety
/// `buffer` is NULL or points at `size` writable bytes.
pub unsafe fn copy_out(text: &str, buffer: *mut c_char, size: usize) -> usize {
    let needed = text.len() + 1;
    if !buffer.is_null() && size >= needed {
        std::ptr::copy_nonoverlapping(text.as_ptr(), buffer as *mut u8, text.len());
        *buffer.add(text.len()) = 0;
    }
    needed
}

// The failure paths are out of line: the success path of every call, fmiXDoStep and
// fmiXGetReal/Float64 above all, stays small.

/// Logs a refused or failed call (`call` is its C name, e.g. "fmi2DoStep"; a message that
/// already names an FMI function is logged as it is) and returns its status code.
#[cold]
#[inline(never)]
fn report_failure<V: Version, M: Model>(
    instance: &mut Instance<V, M>,
    call: &'static str,
    Failure { status, message, .. }: Failure,
) -> c_int {
    let version = call.get(..4).unwrap_or(call);
    let message = if message.starts_with(version) { message } else { format!("{call}: {message}") };
    instance.logger().status(status, &message);
    status as c_int
}

/// Logs a panic caught in the model code, puts the instance in the Error state, returns Error.
#[cold]
#[inline(never)]
fn report_panic<V: Version, M: Model>(instance: &mut Instance<V, M>, call: &'static str, payload: Box<dyn std::any::Any + Send>) -> c_int {
    instance.poison();
    let msg = format!("{call}: internal error in the model code ({}); the instance is now in the Error state", panic_message(&*payload));
    instance.logger().status(Status::Error, &msg);
    Status::Error as c_int
}

/// What a component pointer (`fmi2Component`, `fmi3Instance`) points at: the version's tag, to
/// recognise our own pointers, then the instance.
// repr(C): the tag at offset 0 for every model, so that checking a foreign pointer reads
// inside it (see layout_tests).
#[repr(C)]
pub struct Component<V: Version, M: Model> {
    magic: u64,
    pub(super) instance: Instance<V, M>,
}

/// Runs `body` on the instance behind `c`: checks the pointer, catches panics, logs failures.
pub unsafe fn with_instance<V: Version, M: Model>(
    c: *mut c_void,
    call: Call,
    body: impl FnOnce(&mut Instance<V, M>) -> CallResult<Status>,
) -> c_int {
    let component = c as *mut Component<V, M>;
    if component.is_null() || (*component).magic != V::COMPONENT_MAGIC {
        // Nothing to log through: the logger lives in the instance.
        return Status::Error as c_int;
    }
    // The status code is formed inside the unwinding guard: catch_unwind then hands back a
    // plain c_int. Handing back the call's Result made the compiler store its 4-byte status and
    // reload it as 8 bytes, a store-forwarding stall that cost fmi2DoStep 4 % of a sweep.
    let result = catch_unwind(AssertUnwindSafe(|| match body(&mut (*component).instance) {
        Ok(status) => status as c_int,
        Err(failure) => report_failure(&mut (*component).instance, V::name(call), failure),
    }));
    match result {
        Ok(code) => code,
        Err(payload) => report_panic(&mut (*component).instance, V::name(call), payload),
    }
}

/// The instance behind `c` when it is one of ours, for the hot paths that answer before the
/// unwinding guard.
#[inline(always)]
pub unsafe fn instance_mut<'a, V: Version, M: Model>(c: *mut c_void) -> Option<&'a mut Instance<V, M>> {
    let component = c as *mut Component<V, M>;
    if component.is_null() || (*component).magic != V::COMPONENT_MAGIC {
        None
    } else {
        Some(&mut (*component).instance)
    }
}

/// A call that takes no arguments but the instance: `body`'s outcome as the status.
pub unsafe fn simple<V: Version, M: Model>(c: *mut c_void, call: Call, body: impl FnOnce(&mut Instance<V, M>) -> CallResult) -> c_int {
    with_instance::<V, M>(c, call, |inst| ok(body(inst)))
}

/// A call the state machine may allow but these FMUs do not serve: checks the state, logs the
/// table's reason, returns Error.
pub unsafe fn refuse<V: Version, M: Model>(c: *mut c_void, call: Call) -> c_int {
    simple::<V, M>(c, call, |inst| inst.refuse(call))
}

/// `Ok` as the status of a call that succeeded.
pub fn ok(r: CallResult) -> CallResult<Status> {
    r.map(|()| Status::Ok)
}

/// What instantiation found in the importer's arguments (each version reads its own).
pub struct Request<'a> {
    /// The C name of the instantiation call, for messages.
    pub call: &'static str,
    pub logger: Logger,
    pub name: Option<&'a str>,
    /// The interface asked for, or why it is refused (FMI 2.0's `fmuType`).
    pub setup: Result<Setup, String>,
    /// The GUID or instantiation token.
    pub token: Option<&'a str>,
    /// The resources folder, when the importer gave one.
    pub resources: Option<std::path::PathBuf>,
}

/// The checks both versions' instantiations make, inside the unwinding guard: `request` reads
/// the importer's arguments (`None`: nothing to log through, refused quietly). A new component,
/// or NULL with a logged reason.
pub unsafe fn instantiate<'a, V: Version, M: Model>(request: impl FnOnce() -> Option<Request<'a>>) -> *mut c_void {
    let result = catch_unwind(AssertUnwindSafe(|| {
        let Some(Request { call, mut logger, name, setup, token, resources }) = request() else { return std::ptr::null_mut() };
        let refuse = |logger: &mut Logger, why: String| {
            logger.status(Status::Error, &format!("{call}: {why}"));
            std::ptr::null_mut()
        };
        let name = match name {
            Some(name) if !name.is_empty() => name,
            _ => return refuse(&mut logger, "instanceName must be a non-empty string".to_owned()),
        };
        let setup = match setup {
            Ok(setup) => setup,
            Err(why) => return refuse(&mut logger, why),
        };
        let expected = crate::table::guid::<M>();
        match token {
            Some(t) if t == expected => {}
            other => {
                return refuse(
                    &mut logger,
                    format!(
                        "{} {:?} does not match this FMU's {expected}: the modelDescription.xml and the binary are from different builds",
                        V::WORDS.token,
                        other.unwrap_or("(NULL)")
                    ),
                )
            }
        }
        let mut instance = Instance::<V, M>::new(name, logger, setup);
        if let Some(dir) = resources {
            if let Err(e) = instance.load_resources(&dir) {
                return refuse(instance.logger(), format!("the FMU's resources ({}): {e}", dir.display()));
            }
        }
        let component = Box::new(Component { magic: V::COMPONENT_MAGIC, instance });
        Box::into_raw(component) as *mut c_void
    }));
    result.unwrap_or(std::ptr::null_mut())
}

/// `FreeInstance`.
pub unsafe fn free_instance<V: Version, M: Model>(c: *mut c_void) {
    let component = c as *mut Component<V, M>;
    if component.is_null() || (*component).magic != V::COMPONENT_MAGIC {
        return;
    }
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (*component).magic = 0;
        drop(Box::from_raw(component));
    }));
}

/// `SetDebugLogging`.
pub unsafe fn set_debug_logging<V: Version, M: Model>(c: *mut c_void, on: bool, n: usize, categories: *const *const c_char) -> c_int {
    let call = Call::SetDebugLogging;
    with_instance::<V, M>(c, call, |inst| {
        let ptrs = slice(categories, n, V::name(call), "categories[]")?;
        let mut names = Vec::with_capacity(n);
        for p in ptrs {
            names.push(opt_str(*p).ok_or_else(|| Failure::error(format!("{}: a category is NULL or not UTF-8", V::name(call))))?);
        }
        ok(inst.set_debug_logging(on, &names))
    })
}

/// Logs the experiment both versions pass (fmi2SetupExperiment's arguments,
/// fmi3EnterInitializationMode's) under `logCalls`, the flags as the importer gave them.
pub fn trace_experiment<V: Version, M: Model, B: std::fmt::Display>(
    inst: &mut Instance<V, M>,
    call: Call,
    experiment: (B, f64, f64, B, f64),
) {
    let (tol_defined, tol, start, stop_defined, stop) = experiment;
    inst.trace(call, || {
        format!("toleranceDefined={tol_defined}, tolerance={tol}, startTime={start}, stopTimeDefined={stop_defined}, stopTime={stop}")
    });
}

/// What an instance or FMU-state pointer points at is recognised by the tag in its first 8
/// bytes, for every model: a pointer from another model's FMU (the fuzzer found one: an
/// offset_crank_slider FMI 2.0 state handed to quarter_car's fmi3SetFMUState) is read there,
/// inside whatever it points at, and refused. Without `repr(C)` the compiler put the tag after
/// the saved state, at an offset that depends on the model, past the end of a smaller model's box.
#[cfg(test)]
mod layout_tests {
    use serde::{Deserialize, Serialize};

    use crate::fmi2::Fmi2;
    use crate::fmi3::Fmi3;
    use crate::model::{Equations, Model, ModelError, ModelInfo, Variable, Variables};

    /// A model with a large state box (its parameters are part of the saved state).
    #[derive(Debug, Clone, Default, Serialize, Deserialize)]
    pub(crate) struct Big {
        k: [f64; 32],
    }

    impl Variables for Big {
        fn variables() -> Vec<Variable<Self>> {
            vec![Variable::parameter("k0", "", |m| m.k[0], |m, v| m.k[0] = v), Variable::state("x", "", 0), Variable::state("v", "", 1)]
        }
    }

    impl Model for Big {
        const N_STATES: usize = 2;
        fn info() -> ModelInfo {
            ModelInfo { identifier: "big", description: "", stop_time: 1.0, tolerance: 1e-6, output_interval: 0.1, documentation: "" }
        }
    }

    impl Equations<f64> for Big {
        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x.fill(0.0);
            Ok(())
        }
        fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[1];
            dx[1] = -self.k[0] * x[0];
        }
    }

    #[test]
    fn the_tag_comes_first_in_every_models_boxes() {
        assert_eq!(std::mem::offset_of!(super::fmu_state::StateBox<Fmi2, Big>, magic), 0);
        assert_eq!(std::mem::offset_of!(super::Component<Fmi2, Big>, magic), 0);
        assert_eq!(std::mem::offset_of!(super::fmu_state::StateBox<Fmi3, Big>, magic), 0);
        assert_eq!(std::mem::offset_of!(super::Component<Fmi3, Big>, magic), 0);
    }
}
