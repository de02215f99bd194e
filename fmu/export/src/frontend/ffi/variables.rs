//! The typed getters and setters. Every variable of these FMUs is a scalar, so the value
//! array has one value per value reference (`n_values`, FMI 3.0's `nValues`; FMI 2.0 passes
//! `n`).

use std::ffi::{c_char, c_int, c_void};

use super::{instance_mut, ok, slice, slice_mut, texts, with_instance};
use crate::core::{CallResult, Failure};
use crate::frontend::{Call, Instance, Version};
use crate::logging::Status;
use crate::model::Model;

/// The name an argument has in messages and traces (`vr[]` is `vr`).
fn bare(word: &'static str) -> &'static str {
    word.trim_end_matches("[]")
}

/// Refuses a value array whose length (FMI 3.0's `nValues`) is not the number of value
/// references: every variable of these FMUs is a scalar. FMI 2.0 passes `n` for both.
#[inline(always)]
fn check_values<V: Version>(call: Call, n_vr: usize, n_values: usize) -> CallResult {
    if n_vr == n_values {
        Ok(())
    } else {
        Err(wrong_length::<V>(call, n_vr, n_values))
    }
}

#[cold]
#[inline(never)]
fn wrong_length<V: Version>(call: Call, n_vr: usize, n_values: usize) -> Failure {
    Failure::error(format!("{}: nValues = {n_values} but the {n_vr} value references are scalars with {n_vr} values", V::name(call)))
}

/// `fmi2GetReal`, `fmi3GetFloat64`. A read of states and time only, the sweep's at every
/// communication point, is served before the unwinding guard (nothing on that path can
/// panic); any other read, and any problem, takes the checked path.
#[inline(always)]
pub unsafe fn get_real<V: Version, M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut f64, n_values: usize) -> c_int {
    if n > 0 && n_values == n && !vr.is_null() && !values.is_null() {
        if let Some(inst) = instance_mut::<V, M>(c) {
            // SAFETY: FMI's contract: vr points at n value references, values at n_values (= n)
            // writable values (states and time are scalars).
            let (vrs, out) = (std::slice::from_raw_parts(vr, n), std::slice::from_raw_parts_mut(values, n));
            if inst.read_states(vrs, out) {
                return Status::Ok as c_int;
            }
        }
    }
    checked_get_real::<V, M>(c, vr, n, values, n_values)
}

#[inline(never)]
unsafe fn checked_get_real<V: Version, M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut f64, n_values: usize) -> c_int {
    let call = Call::GetReal;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, f64>(inst, call, vr, n, values, n_values)?;
        ok(inst.get_real(vrs, values))
    })
}

/// A getter's arrays, after the state machine's verdict and the lengths.
pub(super) unsafe fn get_arguments<'a, V: Version, M: Model, T>(
    inst: &Instance<V, M>,
    call: Call,
    vr: *const u32,
    n: usize,
    values: *mut T,
    n_values: usize,
) -> CallResult<(&'a [u32], &'a mut [T])> {
    inst.check(call)?;
    check_values::<V>(call, n, n_values)?;
    let name = V::name(call);
    Ok((slice(vr, n, name, V::WORDS.vrs)?, slice_mut(values, n, name, V::WORDS.values)?))
}

/// A setter's arrays, after the state machine's verdict and the lengths.
pub(super) unsafe fn set_arguments<'a, V: Version, M: Model, T>(
    inst: &Instance<V, M>,
    call: Call,
    vr: *const u32,
    n: usize,
    values: *const T,
    n_values: usize,
) -> CallResult<(&'a [u32], &'a [T])> {
    inst.check(call)?;
    check_values::<V>(call, n, n_values)?;
    let name = V::name(call);
    Ok((slice(vr, n, name, V::WORDS.vrs)?, slice(values, n, name, V::WORDS.values)?))
}

/// Logs a setter's arguments under `logCalls`.
fn trace_set<V: Version, M: Model>(inst: &mut Instance<V, M>, call: Call, vrs: &[u32], values: &dyn std::fmt::Debug) {
    inst.trace(call, || format!("{}={vrs:?}, {}={values:?}", bare(V::WORDS.vrs), bare(V::WORDS.values)));
}

/// `fmi2GetInteger`, `fmi3GetInt32`.
pub unsafe fn get_integer<V: Version, M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *mut i32, n_values: usize) -> c_int {
    let call = Call::GetInteger;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, i32>(inst, call, vr, n, values, n_values)?;
        ok(inst.get_integer(vrs, values))
    })
}

/// A C boolean: FMI 2.0's `fmi2Boolean` (an int), FMI 3.0's `fmi3Boolean` (C's `bool`, read
/// as a byte where the importer may pass any).
pub trait CBoolean: Copy {
    /// The C value of `b`.
    fn from_bool(b: bool) -> Self;
    /// True for every nonzero value, as C reads it.
    fn is_true(self) -> bool;
}

impl CBoolean for c_int {
    fn from_bool(b: bool) -> Self {
        b as c_int
    }
    fn is_true(self) -> bool {
        self != 0
    }
}

impl CBoolean for bool {
    fn from_bool(b: bool) -> Self {
        b
    }
    fn is_true(self) -> bool {
        self
    }
}

impl CBoolean for u8 {
    fn from_bool(b: bool) -> Self {
        b as u8
    }
    fn is_true(self) -> bool {
        self != 0
    }
}

/// `GetBoolean`.
pub unsafe fn get_boolean<V: Version, M: Model, B: CBoolean>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut B,
    n_values: usize,
) -> c_int {
    let call = Call::GetBoolean;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, B>(inst, call, vr, n, values, n_values)?;
        let mut bools = vec![false; n];
        inst.get_boolean(vrs, &mut bools)?;
        for (v, b) in values.iter_mut().zip(bools) {
            *v = B::from_bool(b);
        }
        Ok(Status::Ok)
    })
}

/// `GetString`: `values[i]` points at the instance's copy of the value, valid until the next
/// String getter on the instance (or until it is freed).
pub unsafe fn get_string<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *mut *const c_char,
    n_values: usize,
) -> c_int {
    let call = Call::GetString;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, *const c_char>(inst, call, vr, n, values, n_values)?;
        for (out, text) in values.iter_mut().zip(inst.get_string(vrs)?) {
            *out = text.as_ptr();
        }
        Ok(Status::Ok)
    })
}

/// `fmi2SetReal`, `fmi3SetFloat64`.
pub unsafe fn set_real<V: Version, M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const f64, n_values: usize) -> c_int {
    let call = Call::SetReal;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = set_arguments::<V, M, f64>(inst, call, vr, n, values, n_values)?;
        trace_set(inst, call, vrs, &values);
        ok(inst.set_real(vrs, values))
    })
}

/// `fmi2SetInteger`, `fmi3SetInt32`.
pub unsafe fn set_integer<V: Version, M: Model>(c: *mut c_void, vr: *const u32, n: usize, values: *const i32, n_values: usize) -> c_int {
    let call = Call::SetInteger;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = set_arguments::<V, M, i32>(inst, call, vr, n, values, n_values)?;
        trace_set(inst, call, vrs, &values);
        ok(inst.set_integer(vrs, values))
    })
}

/// `SetBoolean`: each value read as C reads a boolean (nonzero is true).
pub unsafe fn set_boolean<V: Version, M: Model, B: CBoolean>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const B,
    n_values: usize,
) -> c_int {
    let call = Call::SetBoolean;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = set_arguments::<V, M, B>(inst, call, vr, n, values, n_values)?;
        let values: Vec<bool> = values.iter().map(|b| b.is_true()).collect();
        trace_set(inst, call, vrs, &values);
        ok(inst.set_boolean(vrs, &values))
    })
}

/// `SetString`: a NULL element or text that is not UTF-8 is refused, naming the variable.
pub unsafe fn set_string<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    values: *const *const c_char,
    n_values: usize,
) -> c_int {
    let call = Call::SetString;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, pointers) = set_arguments::<V, M, *const c_char>(inst, call, vr, n, values, n_values)?;
        let texts = texts(pointers, vrs, inst.table(), V::name(call), bare(V::WORDS.values))?;
        trace_set(inst, call, vrs, &texts);
        ok(inst.set_string(vrs, &texts))
    })
}
