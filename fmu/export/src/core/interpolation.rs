//! Inputs that follow a polynomial in time over a Co-Simulation step
//! (`fmi2SetRealInputDerivatives`, `canInterpolateInputs`).
//!
//! An importer that knows how an input moves gives its time derivatives at the current
//! communication point; the input is then, from that time t_a on,
//! u(t) = u_a + u'_a (t - t_a) + u''_a (t - t_a)^2 / 2 + u'''_a (t - t_a)^3 / 6,
//! and the solver sees that value at every stage of every internal step, not the value held
//! from the step's start. Derivatives up to [`MAX_ORDER`] are taken. The polynomial goes on
//! until the importer sets the input or its derivatives again: a set re-anchors it at the
//! current time (its value the new one, its derivatives those the polynomial has there), so
//! the order in which an importer sets an input and its derivatives at a point does not matter.
//! An input whose derivatives are all zero is held, by the same code and arithmetic as an
//! input that never had any (a run that sets none is bit for bit what it was).
//!
//! After a step, the input's variable holds the polynomial's value at the FMU's time: the
//! outputs read there, and their derivatives ([`crate::core::derivatives`]), see the input
//! the step ended with.

use serde::{Deserialize, Serialize};
use solvers::OdeSystem;

use super::{CallResult, Core, Failure, System};
use crate::model::{Access, Causality, Model, Variability};
use crate::table::Slot;

/// The highest order of the input derivatives these FMUs take, and of the output derivatives
/// they give (`maxOutputDerivativeOrder`).
pub const MAX_ORDER: usize = 3;

/// One input's polynomial: its value and derivatives at the anchor time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct Drive {
    /// The input's row in the table (its value reference).
    pub row: usize,
    pub anchor: f64,
    pub value: f64,
    /// The first [`MAX_ORDER`] time derivatives at the anchor.
    pub derivatives: [f64; MAX_ORDER],
}

impl Drive {
    /// The value at `t`: the Taylor polynomial in Horner form.
    #[inline]
    pub fn at(&self, t: f64) -> f64 {
        horner(self.anchor, &self.coefficients(), t)
    }

    /// The polynomial's coefficients in powers of (t - anchor): the derivatives over k!.
    #[inline]
    fn coefficients(&self) -> [f64; MAX_ORDER + 1] {
        let [d1, d2, d3] = self.derivatives;
        [self.value, d1, d2 / 2.0, d3 / 6.0]
    }

    /// The derivatives at `t` (the polynomial's, shifted from the anchor).
    pub fn derivatives_at(&self, t: f64) -> [f64; MAX_ORDER] {
        let s = t - self.anchor;
        let [d1, d2, d3] = self.derivatives;
        [d1 + s * (d2 + s * (d3 / 2.0)), d2 + s * d3, d3]
    }

    /// Moves the anchor to `t`, the polynomial unchanged.
    pub fn shift_to(&mut self, t: f64) {
        if t != self.anchor {
            (self.value, self.derivatives) = (self.at(t), self.derivatives_at(t));
            self.anchor = t;
        }
    }

    /// Moves the anchor to `t` with the new value `value` there: [`Drive::shift_to`] and the
    /// value set, without the old polynomial's value at `t`.
    pub fn anchor_at(&mut self, t: f64, value: f64) {
        if t != self.anchor {
            self.derivatives = self.derivatives_at(t);
            self.anchor = t;
        }
        self.value = value;
    }
}

/// The polynomial with `coefficients` in powers of (t - anchor), at `t`.
#[inline(always)]
fn horner(anchor: f64, coefficients: &[f64; MAX_ORDER + 1], t: f64) -> f64 {
    let s = t - anchor;
    let [c0, c1, c2, c3] = *coefficients;
    c0 + s * (c1 + s * (c2 + s * c3))
}

/// True when `row` takes time derivatives: a continuous Real input with a setter.
fn interpolable<M>(row: &crate::table::Row<M>) -> bool {
    row.causality == Causality::Input
        && row.variability == Variability::Continuous
        && matches!(row.slot, Slot::Model(Access::Real { set: Some(_), .. }))
}

/// A Real input's setter, from the variable table.
type Setter<M> = fn(&mut M, f64);

/// A driven input as the solver's stages evaluate it: its setter, and its polynomial with the
/// coefficients divided out once per step rather than at every stage (the same numbers as
/// [`Drive::at`]'s).
pub(crate) struct Stage<M> {
    set: Setter<M>,
    anchor: f64,
    coefficients: [f64; MAX_ORDER + 1],
}

impl<M> Stage<M> {
    /// The stage form of `drive`, a settable Real input of `rows`.
    pub fn of(drive: &Drive, rows: &[crate::table::Row<M>]) -> Stage<M> {
        match rows[drive.row].slot {
            Slot::Model(Access::Real { set: Some(set), .. }) => Stage { set, anchor: drive.anchor, coefficients: drive.coefficients() },
            _ => unreachable!("only settable Real inputs are driven"),
        }
    }
}

/// Sets each driven input of `stages` on `model` to its polynomial's value at `t`.
#[inline(always)]
pub(crate) fn set_inputs_at<M>(model: &mut M, stages: &[Stage<M>], t: f64) {
    for input in stages {
        (input.set)(model, horner(input.anchor, &input.coefficients, t));
    }
}

/// The model with its driven inputs, as the solver's ODE system: each evaluation sets the
/// inputs to their polynomials' values at its time first. The model is borrowed mutably for
/// the step; the solver's calls take `&self`, so it sits in an `UnsafeCell` (a `RefCell`'s
/// borrow flag, checked and written at every stage, cost quarter_car 8 instructions a stage).
pub(crate) struct Driven<'a, M> {
    model: std::cell::UnsafeCell<&'a mut M>,
    inputs: &'a [Stage<M>],
}

impl<'a, M: Model> Driven<'a, M> {
    pub fn new(model: &'a mut M, inputs: &'a [Stage<M>]) -> Driven<'a, M> {
        Driven { model: std::cell::UnsafeCell::new(model), inputs }
    }

    /// The model with its inputs at `t`, borrowed until the caller's evaluation ends.
    #[inline(always)]
    fn at(&self, t: f64) -> &M {
        // SAFETY: the one reference to the model out of the cell at a time: `Driven` is not
        // `Sync` (the cell), the mutable borrow ends with the setters below, and the shared one
        // returned lives only through the `rhs` or `event_indicators` call that asked for it,
        // which does not call back into this system.
        let model: &mut M = unsafe { &mut **self.model.get() };
        let set = |model: &mut M, input: &Stage<M>| (input.set)(model, horner(input.anchor, &input.coefficients, t));
        match self.inputs {
            // The usual case, one driven input, without the loop's bookkeeping at every stage.
            [input] => set(model, input),
            inputs => inputs.iter().for_each(|input| set(model, input)),
        }
        model
    }
}

impl<M: Model> OdeSystem for Driven<'_, M> {
    fn dim(&self) -> usize {
        M::N_STATES
    }
    // Always inlined into the solver's stages, as the held model's (`System::rhs`).
    #[inline(always)]
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        System::of(self.at(t)).rhs(t, x, dx)
    }
    fn n_event_indicators(&self) -> usize {
        M::N_EVENT_INDICATORS
    }
    fn event_indicators(&self, t: f64, x: &[f64], z: &mut [f64]) {
        Model::event_indicators(self.at(t), t, x, z)
    }
}

impl<M: Model> Core<M> {
    /// `fmi2SetRealInputDerivatives`: the `orders[i]`-th time derivative of input `vrs[i]` at
    /// the current time is `values[i]`. Each variable must be a continuous Real input, each
    /// order from 1 to [`MAX_ORDER`], each value finite; all or nothing, as a set. `function`
    /// names the call in messages.
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64], function: &str) -> CallResult {
        // A master sets the same inputs and orders at every step: those are checked once (the
        // kept request), the values at every call.
        if self.input_request.is(vrs, orders) {
            if !values.iter().all(|v| v.is_finite()) {
                let i = values.iter().position(|v| !v.is_finite()).expect("a value is not finite");
                return Err(self.input_derivative_refused(vrs[i], orders[i], values[i], function));
            }
        } else {
            self.input_request.forget();
            let rows = &self.table.rows;
            let takes = |vr: u32, order: i32, value: f64| {
                rows.get(vr as usize).is_some_and(interpolable) && (1..=MAX_ORDER as i32).contains(&order) && value.is_finite()
            };
            if let Some(((&vr, &order), &value)) = vrs.iter().zip(orders).zip(values).find(|((&vr, &o), &v)| !takes(vr, o, v)) {
                return Err(self.input_derivative_refused(vr, order, value, function));
            }
            self.input_request.keep(vrs, orders);
        }
        self.apply_input_derivatives(vrs, orders, values);
        Ok(())
    }

    /// [`Core::set_input_derivatives`] when its checks are known to pass: the inputs and
    /// orders of the last call (checked then), as a master sets them at every communication
    /// point, and finite values. False, nothing changed, otherwise (the full call explains).
    #[inline(always)]
    pub fn try_set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> bool {
        // A master's usual request, one input's three orders, as arrays.
        if let (Some(vr), Ok(values)) = (self.input_request.run_of::<MAX_ORDER>(vrs, orders), <&[f64; MAX_ORDER]>::try_from(values)) {
            let usable = values.iter().sum::<f64>().is_finite();
            if usable {
                self.set_drive_derivatives(vr as usize, *values);
            }
            return usable;
        }
        // Finite as a sum is: a NaN or an infinity among them makes it one (one pass, no branch
        // per value).
        let usable = values.len() == vrs.len() && self.input_request.is(vrs, orders) && values.iter().sum::<f64>().is_finite();
        if usable {
            self.apply_input_derivatives(vrs, orders, values);
        }
        usable
    }

    /// Sets checked derivatives (see [`Core::set_input_derivatives`]).
    #[inline(always)]
    fn apply_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) {
        let t = self.state.t;
        let (mut changed, mut zeroed) = (false, false);
        // An input's orders come one after another (a master passes 1 to 3 of the same input):
        // its polynomial is found, and moved to t, once for them.
        let n = vrs.len().min(orders.len()).min(values.len());
        let (vrs, orders, values) = (&vrs[..n], &orders[..n], &values[..n]);
        let mut k = 0;
        while k < n {
            let vr = vrs[k];
            let i = self.drive_at(vr as usize, t);
            let derivatives = &mut self.state.drives[i].derivatives;
            while k < n && vrs[k] == vr {
                let (order, value) = (orders[k], values[k]);
                let old = std::mem::replace(&mut derivatives[order as usize - 1], value);
                changed |= old.to_bits() != value.to_bits();
                zeroed |= value == 0.0;
                k += 1;
            }
        }
        self.drives_set(changed, zeroed);
    }

    /// Input `row`'s derivatives of orders 1 to [`MAX_ORDER`] are `derivatives` (checked): as
    /// [`Core::apply_input_derivatives`] sets them one by one, the three at once.
    #[inline(always)]
    fn set_drive_derivatives(&mut self, row: usize, derivatives: [f64; MAX_ORDER]) {
        let i = self.drive_at(row, self.state.t);
        let old = std::mem::replace(&mut self.state.drives[i].derivatives, derivatives);
        self.drives_set(old.map(f64::to_bits) != derivatives.map(f64::to_bits), derivatives.contains(&0.0));
    }

    /// After input derivatives were set: an input with no derivative left is held, as one that
    /// never had any (looked for when a value set was `zeroed`), what was derived from the
    /// instance is stale, and the solver restarts when a value `changed`.
    #[inline(always)]
    fn drives_set(&mut self, changed: bool, zeroed: bool) {
        if zeroed {
            self.state.drives.retain(|d| d.derivatives != [0.0; MAX_ORDER]);
        }
        self.version += 1;
        if changed {
            if let Some(integrator) = self.state.integrator.as_mut() {
                integrator.invalidate();
            }
        }
    }

    /// The place in `drives` of the polynomial of input `row` (a new one holding its value if
    /// it has none), anchored at `t`. Inlined into the input derivatives' call (a frame less
    /// per communication step).
    #[inline(always)]
    fn drive_at(&mut self, row: usize, t: f64) -> usize {
        let drives = &mut self.state.drives;
        let i = match drives.iter().position(|d| d.row == row) {
            Some(i) => i,
            None => {
                let Slot::Model(Access::Real { get, .. }) = self.table.rows[row].slot else { unreachable!("checked above") };
                drives.push(Drive { row, anchor: t, value: get(&self.state.model), derivatives: [0.0; MAX_ORDER] });
                drives.len() - 1
            }
        };
        drives[i].shift_to(t);
        i
    }

    /// Why `set_input_derivatives` refused input `vr`'s derivative of `order` = `value`.
    #[cold]
    #[inline(never)]
    fn input_derivative_refused(&self, vr: u32, order: i32, value: f64, function: &str) -> Failure {
        let Some(row) = self.table.rows.get(vr as usize) else {
            return Failure::error(format!("{function}: value reference {vr} is not a variable of this FMU"));
        };
        if !interpolable(row) {
            Failure::error(format!(
                "{function}: '{}' (value reference {vr}) is not a continuous Real input: only those have time derivatives to set",
                row.name
            ))
        } else if !(1..=MAX_ORDER as i32).contains(&order) {
            Failure::error(format!(
                "{function}: order {order} of '{}' refused: this FMU interpolates inputs with derivatives of order 1 to {MAX_ORDER}",
                row.name
            ))
        } else {
            Failure::error(format!("{function}: derivative {order} of '{}' = {value} refused: it must be finite", row.name))
        }
    }

    /// Re-anchors the polynomial of an input just set to `value` at the current time: its
    /// derivatives are moved there, its value is the new one (the old polynomial's value there
    /// is not needed).
    #[inline]
    pub(super) fn input_set(&mut self, row: usize, value: f64) {
        let t = self.state.t;
        if let Some(drive) = self.state.drives.iter_mut().find(|d| d.row == row) {
            drive.anchor_at(t, value);
        }
    }

    /// Moves every polynomial's anchor to `t` (the start time, when it is set).
    pub(super) fn anchor_inputs(&mut self, t: f64) {
        for drive in &mut self.state.drives {
            drive.anchor = t;
        }
    }

    /// The driven inputs' variables at their polynomials' values at the current time (after
    /// the solver moved it).
    pub(super) fn sync_inputs(&mut self) {
        let (model, t) = (&mut self.state.model, self.state.t);
        for drive in &self.state.drives {
            if let Slot::Model(Access::Real { set: Some(set), .. }) = self.table.rows[drive.row].slot {
                set(model, drive.at(t));
            }
        }
        self.state.outputs_dirty = true;
    }

    /// The driven inputs' fields with their values and derivatives at the current time, for
    /// the output derivatives (into `self.trajectory.inputs`).
    pub(super) fn input_derivatives(&mut self) {
        let t = self.state.t;
        let rows = &self.table.rows;
        let inputs = &mut self.trajectory.inputs;
        inputs.clear();
        inputs.extend(self.state.drives.iter().filter_map(|d| match (rows[d.row].field, &rows[d.row].slot) {
            (Some(f), Slot::Model(Access::Real { get, .. })) => Some((f, get(&self.state.model), d.derivatives_at(t))),
            _ => None,
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Taylor polynomial of a cubic is the cubic: values and derivatives anywhere, and
    /// after the anchor moves, are those of p(t) = 1 + 2 t + 3 t^2 + 4 t^3 (exact in binary:
    /// small integers and halves).
    #[test]
    fn a_drive_is_the_cubic_its_derivatives_give() {
        let p = |t: f64| 1.0 + 2.0 * t + 3.0 * t * t + 4.0 * t * t * t;
        let dp = |t: f64| [2.0 + 6.0 * t + 12.0 * t * t, 6.0 + 24.0 * t, 24.0];
        let mut d = Drive { row: 0, anchor: 0.0, value: 1.0, derivatives: dp(0.0) };
        for t in [0.0, 0.5, 1.0, -2.0, 3.5] {
            assert_eq!(d.at(t), p(t), "value at {t}");
            assert_eq!(d.derivatives_at(t), dp(t), "derivatives at {t}");
        }
        d.shift_to(1.5);
        assert_eq!((d.anchor, d.value, d.derivatives), (1.5, p(1.5), dp(1.5)));
        for t in [0.0, 2.0, 2.5] {
            assert_eq!(d.at(t), p(t), "value at {t} after the shift");
        }
    }
}
