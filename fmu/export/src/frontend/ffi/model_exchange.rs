//! The Model Exchange calls. SetTime, SetContinuousStates and GetDerivatives come once per
//! evaluation of the derivatives, several times per solver step of the importer: their usual
//! call is done in place and answers OK directly; anything else takes the general path (out
//! of line, so the usual call does not set up its frame), which checks the call again and
//! explains the refusal. SetTime and SetContinuousStates run no model code, so their usual
//! call cannot unwind.

use std::ffi::{c_int, c_void};
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::variables::CBoolean;
use super::{instance_mut, ok, simple, slice, slice_mut, with_instance};
use crate::core::{CallResult, Failure};
use crate::frontend::{Call, Instance, Version};
use crate::logging::Status;
use crate::model::Model;

/// `SetTime`.
#[inline(always)]
pub unsafe fn set_time<V: Version, M: Model>(c: *mut c_void, time: f64) -> c_int {
    if let Some(inst) = instance_mut::<V, M>(c) {
        if inst.try_set_time(time) {
            return Status::Ok as c_int;
        }
    }
    set_time_in_full::<V, M>(c, time)
}

#[cold]
#[inline(never)]
unsafe fn set_time_in_full<V: Version, M: Model>(c: *mut c_void, time: f64) -> c_int {
    simple::<V, M>(c, Call::SetTime, |inst| inst.set_time(time))
}

/// `SetContinuousStates`.
#[inline(always)]
pub unsafe fn set_continuous_states<V: Version, M: Model>(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
    if let Some(inst) = instance_mut::<V, M>(c) {
        if !x.is_null() && inst.try_set_continuous_states(std::slice::from_raw_parts(x, nx)) {
            return Status::Ok as c_int;
        }
    }
    set_continuous_states_in_full::<V, M>(c, x, nx)
}

#[cold]
#[inline(never)]
unsafe fn set_continuous_states_in_full<V: Version, M: Model>(c: *mut c_void, x: *const f64, nx: usize) -> c_int {
    let call = Call::SetContinuousStates;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        let x = slice(x, nx, V::name(call), V::WORDS.states)?;
        ok(inst.set_continuous_states(x))
    })
}

/// `fmi2GetDerivatives`, `fmi3GetContinuousStateDerivatives`.
#[inline(always)]
pub unsafe fn get_derivatives<V: Version, M: Model>(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
    if let Some(inst) = instance_mut::<V, M>(c) {
        if !dx.is_null() {
            let out = std::slice::from_raw_parts_mut(dx, nx);
            // The model's code runs: inside the unwinding guard.
            if let Ok(Some(true)) = catch_unwind(AssertUnwindSafe(|| inst.try_get_derivatives(out))) {
                return Status::Ok as c_int;
            }
        }
    }
    get_derivatives_in_full::<V, M>(c, dx, nx)
}

/// The general path of `GetDerivatives` (evaluates the derivatives again: a refusal counts
/// twice in `n_rhs`, the usual call once).
#[cold]
#[inline(never)]
unsafe fn get_derivatives_in_full<V: Version, M: Model>(c: *mut c_void, dx: *mut f64, nx: usize) -> c_int {
    fill::<V, M>(c, Call::GetDerivatives, dx, nx, V::WORDS.derivatives, Instance::get_derivatives)
}

/// `GetEventIndicators`.
pub unsafe fn get_event_indicators<V: Version, M: Model>(c: *mut c_void, z: *mut f64, ni: usize) -> c_int {
    fill::<V, M>(c, Call::GetEventIndicators, z, ni, V::WORDS.indicators, Instance::get_event_indicators)
}

/// `GetContinuousStates`.
pub unsafe fn get_continuous_states<V: Version, M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    fill::<V, M>(c, Call::GetContinuousStates, x, nx, V::WORDS.states, Instance::get_continuous_states)
}

/// `GetNominalsOfContinuousStates`.
pub unsafe fn get_nominals_of_continuous_states<V: Version, M: Model>(c: *mut c_void, x: *mut f64, nx: usize) -> c_int {
    fill::<V, M>(c, Call::GetNominalsOfContinuousStates, x, nx, V::WORDS.nominals, Instance::get_nominals_of_continuous_states)
}

/// A call that fills the importer's array `out` of `n` values (`what` in messages): checked,
/// then handed to `get`.
unsafe fn fill<V: Version, M: Model>(
    c: *mut c_void,
    call: Call,
    out: *mut f64,
    n: usize,
    what: &str,
    get: impl FnOnce(&mut Instance<V, M>, &mut [f64]) -> CallResult,
) -> c_int {
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        let out = slice_mut(out, n, V::name(call), what)?;
        ok(get(inst, out))
    })
}

/// `CompletedIntegratorStep`: fills `*enter_event_mode` and `*terminate_simulation`.
pub unsafe fn completed_integrator_step<V: Version, M: Model, B: CBoolean>(
    c: *mut c_void,
    enter_event_mode: *mut B,
    terminate_simulation: *mut B,
) -> c_int {
    let call = Call::CompletedIntegratorStep;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        if enter_event_mode.is_null() || terminate_simulation.is_null() {
            return Err(Failure::error(format!("{}: enterEventMode or terminateSimulation is NULL", V::name(call))));
        }
        let step = inst.completed_integrator_step()?;
        *enter_event_mode = B::from_bool(step.enter_event_mode);
        *terminate_simulation = B::from_bool(step.terminate_simulation);
        Ok(Status::Ok)
    })
}
