//! C-boundary helpers both front ends share (FMI 2.0's `fmi2::ffi`, FMI 3.0's `fmi3::ffi`):
//! C strings in and out, argument arrays, panic messages, and the tag of FMU states.

use std::ffi::{c_char, c_int, CStr, CString};

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

/// The `n` writable values at `p` (see [`slice`]).
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

/// What the C glue of either version needs of its instance when a call fails or panics.
pub trait GlueInstance {
    /// Puts the instance in the Error state.
    fn poison(&mut self);
    /// The instance's logger.
    fn logger(&mut self) -> &mut Logger;
}

// The failure paths are out of line: the success path of every call, fmiXDoStep and
// fmiXGetReal/Float64 above all, stays small.

/// Logs a refused or failed call (`call` is its C name, e.g. "fmi2DoStep"; a message that
/// already names an FMI function is logged as it is) and returns its status code.
#[cold]
#[inline(never)]
pub fn report_failure(instance: &mut impl GlueInstance, call: &'static str, Failure { status, message, .. }: Failure) -> c_int {
    let version = call.get(..4).unwrap_or(call);
    let message = if message.starts_with(version) { message } else { format!("{call}: {message}") };
    instance.logger().status(status, &message);
    status as c_int
}

/// Logs a panic caught in the model code, puts the instance in the Error state, returns Error.
#[cold]
#[inline(never)]
pub fn report_panic(instance: &mut impl GlueInstance, call: &'static str, payload: Box<dyn std::any::Any + Send>) -> c_int {
    instance.poison();
    let msg = format!("{call}: internal error in the model code ({}); the instance is now in the Error state", panic_message(&*payload));
    instance.logger().status(Status::Error, &msg);
    Status::Error as c_int
}
