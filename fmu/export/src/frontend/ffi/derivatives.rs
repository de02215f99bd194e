//! The derivatives an importer may ask for (see the [`Instance`](crate::frontend::Instance)
//! methods of the same names, where they are computed or refused).

use std::ffi::{c_int, c_void};

use super::variables::{get_arguments, set_arguments};
use super::{ok, slice, slice_mut, with_instance};
use crate::core::Failure;
use crate::frontend::{Call, Version};
use crate::model::Model;

/// `GetDirectionalDerivative` and FMI 3.0's `GetAdjointDerivative` (`call` says which): each
/// array with its length. A directional derivative's seed has one value per known and its
/// sensitivity one per unknown, an adjoint's the reverse (FMI 2.0 passes those numbers for the
/// lengths it does not have).
pub unsafe fn get_sensitivity<V: Version, M: Model>(
    c: *mut c_void,
    call: Call,
    (unknowns, n_unknowns): (*const u32, usize),
    (knowns, n_knowns): (*const u32, usize),
    (seed, n_seed): (*const f64, usize),
    (sensitivity, n_sensitivity): (*mut f64, usize),
) -> c_int {
    with_instance::<V, M>(c, call, |inst| {
        let w = V::WORDS;
        inst.trace(call, || format!("{}={n_unknowns}, {}={n_knowns}", w.n_unknowns, w.n_knowns));
        inst.check(call)?;
        let name = V::name(call);
        let adjoint = call == Call::GetAdjointDerivative;
        let (seeds, results) = if adjoint { (n_unknowns, n_knowns) } else { (n_knowns, n_unknowns) };
        if (n_seed, n_sensitivity) != (seeds, results) {
            return Err(Failure::error(format!(
                "{name}: nSeed = {n_seed} and nSensitivity = {n_sensitivity}, but the {n_unknowns} unknowns and {n_knowns} knowns are scalars: {seeds} seed values and {results} sensitivities"
            )));
        }
        let unknowns = slice(unknowns, n_unknowns, name, w.unknowns)?;
        let knowns = slice(knowns, n_knowns, name, w.knowns)?;
        let seed = slice(seed, n_seed, name, w.seed)?;
        let sensitivity = slice_mut(sensitivity, n_sensitivity, name, w.sensitivity)?;
        ok(if adjoint {
            inst.get_adjoint_derivative(unknowns, knowns, seed, sensitivity)
        } else {
            inst.get_directional_derivative(unknowns, knowns, seed, sensitivity)
        })
    })
}

/// `fmi2GetRealOutputDerivatives`, `fmi3GetOutputDerivatives` (FMI 2.0 passes `n` for
/// `n_values`).
pub unsafe fn get_output_derivatives<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *mut f64,
    n_values: usize,
) -> c_int {
    let call = Call::GetOutputDerivatives;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = get_arguments::<V, M, f64>(inst, call, vr, n, values, n_values)?;
        let orders = slice(orders, n, V::name(call), "order[]")?;
        ok(inst.get_output_derivatives(vrs, orders, values))
    })
}

/// `fmi2SetRealInputDerivatives`.
pub unsafe fn set_input_derivatives<V: Version, M: Model>(
    c: *mut c_void,
    vr: *const u32,
    n: usize,
    orders: *const i32,
    values: *const f64,
) -> c_int {
    let call = Call::SetInputDerivatives;
    with_instance::<V, M>(c, call, |inst| {
        let (vrs, values) = set_arguments::<V, M, f64>(inst, call, vr, n, values, n)?;
        let orders = slice(orders, n, V::name(call), "order[]")?;
        ok(inst.set_input_derivatives(vrs, orders, values))
    })
}
