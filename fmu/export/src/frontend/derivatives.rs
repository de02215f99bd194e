//! The derivatives an importer may ask for, each one method whatever the FMI version: the C
//! layer (`ffi::derivatives`) has checked and converted the arrays (one value per value
//! reference, as every variable of these FMUs is a scalar, unless noted), and each version's
//! table says where the state machine allows the call and, for the ones these FMUs do not
//! provide, why they refuse it (with the capability flag their modelDescription.xml declares).
//! Providing one means computing it here, removing the table's reason and setting the flag in
//! the version's `describe`.
//!
//! The directional and adjoint derivatives are exact, from the model's own equations in dual
//! numbers (`core::derivatives`), in the mode the instance is in; a model written on f64 alone
//! declares neither capability and the core refuses them.

use super::{Call, Instance, Interface, Version};
use crate::core::derivatives::Mode;
use crate::core::CallResult;
use crate::logging::LOG_CALLS;
use crate::model::Model;

impl<V: Version, M: Model> Instance<V, M> {
    /// The mode whose equations the directional and adjoint derivatives differentiate now:
    /// Initialization Mode's before initialization ends, then Continuous-Time Mode's, Event
    /// Mode's (Model Exchange outside Continuous-Time Mode, and a Co-Simulation instance in
    /// FMI 3.0's Event Mode), and a communication point's otherwise.
    fn derivative_mode(&self) -> Mode {
        if self.state == V::INSTANTIATED || self.state == V::INITIALIZATION_MODE {
            Mode::Initialization
        } else if self.state == V::CONTINUOUS_TIME_MODE {
            Mode::ContinuousTime
        } else if self.setup.interface == Interface::ModelExchange || self.state == V::EVENT_MODE {
            Mode::Event
        } else {
            Mode::Step
        }
    }

    /// `fmi2GetDirectionalDerivative`, `fmi3GetDirectionalDerivative`:
    /// `sensitivity[i] = sum over j of d unknowns[i] / d knowns[j] * seed[j]` (`seed` has one
    /// value per known, `sensitivity` one per unknown), exact.
    pub fn get_directional_derivative(&mut self, unknowns: &[u32], knowns: &[u32], seed: &[f64], sensitivity: &mut [f64]) -> CallResult {
        let call = Call::GetDirectionalDerivative;
        self.check(call)?;
        let mode = self.derivative_mode();
        self.core.directional_derivative(unknowns, knowns, seed, sensitivity, mode, V::name(call))
    }

    /// The usual `GetDirectionalDerivative`, a column of the Jacobian of the instance's point
    /// ([`Core::try_directional_derivative`](crate::core::Core::try_directional_derivative)),
    /// when the call is allowed and not traced: whether the values are all finite; `None`
    /// leaves the call to [`Instance::get_directional_derivative`], nothing written.
    #[inline(always)]
    pub fn try_get_directional_derivative(
        &mut self,
        unknowns: &[u32],
        knowns: &[u32],
        seed: &[f64],
        sensitivity: &mut [f64],
    ) -> Option<bool> {
        if !self.permits(Call::GetDirectionalDerivative) || self.core.logger.wants(LOG_CALLS) {
            return None;
        }
        self.core.try_directional_derivative(unknowns, knowns, seed, sensitivity, self.derivative_mode())
    }

    /// `fmi3GetAdjointDerivative`:
    /// `sensitivity[j] = sum over i of seed[i] * d unknowns[i] / d knowns[j]` (`seed` has one
    /// value per unknown, `sensitivity` one per known), as exact.
    pub fn get_adjoint_derivative(&mut self, unknowns: &[u32], knowns: &[u32], seed: &[f64], sensitivity: &mut [f64]) -> CallResult {
        let call = Call::GetAdjointDerivative;
        self.check(call)?;
        let mode = self.derivative_mode();
        self.core.adjoint_derivative(unknowns, knowns, seed, sensitivity, mode, V::name(call))
    }

    /// `fmi2GetRealOutputDerivatives`, `fmi3GetOutputDerivatives`: `values[i]` = the
    /// `orders[i]`-th time derivative of output `vrs[i]` at the current communication point,
    /// exact along the trajectory (`core::derivatives::trajectory`); a model written on f64
    /// alone declares `maxOutputDerivativeOrder="0"` and is refused.
    pub fn get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> CallResult {
        let call = Call::GetOutputDerivatives;
        self.check(call)?;
        self.core.output_derivatives(vrs, orders, values, V::name(call))
    }

    /// [`Instance::get_output_derivatives`] when allowed now and its checks are known to pass
    /// (the request of the last call), not traced; `None` otherwise, and when computing fails or
    /// gives a value that is not finite: the full call checks, computes and explains.
    #[inline(always)]
    pub fn try_get_output_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &mut [f64]) -> Option<bool> {
        if !self.permits(Call::GetOutputDerivatives) || self.core.logger.wants(LOG_CALLS) {
            return None;
        }
        self.core.try_output_derivatives(vrs, orders, values)
    }

    /// `fmi2SetRealInputDerivatives`: input `vrs[i]`'s `orders[i]`-th time derivative at the
    /// current communication point is `values[i]`: the input follows its Taylor polynomial over
    /// the steps from here (`core::interpolation`).
    pub fn set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> CallResult {
        let call = Call::SetInputDerivatives;
        self.check(call)?;
        self.core.set_input_derivatives(vrs, orders, values, V::name(call))
    }

    /// [`Instance::set_input_derivatives`] when allowed now and its checks are known to pass
    /// (the inputs and orders of the last call, finite values), not traced: true when done,
    /// false (nothing changed) for the full call to check and explain.
    #[inline(always)]
    pub fn try_set_input_derivatives(&mut self, vrs: &[u32], orders: &[i32], values: &[f64]) -> bool {
        self.permits(Call::SetInputDerivatives)
            && !self.core.logger.wants(LOG_CALLS)
            && self.core.try_set_input_derivatives(vrs, orders, values)
    }
}
