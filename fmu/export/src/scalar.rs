//! The number type of a model's equations.
//!
//! A model is written once, generic over its number type `T` ([`Scalar`]): the FMU simulates
//! with `T = f64`, and the toolkit differentiates the same code exactly by running it on dual
//! numbers (forward-mode automatic differentiation, the `num-dual` crate): a [`Dual64`] carries
//! a value and its derivative along one direction through every operation, so the equations
//! give the directional derivatives `fmi2GetDirectionalDerivative` asks for, to rounding, with
//! no derivative written by hand. Higher-order duals ([`Dual2_64`], [`Dual3_64`]) carry the
//! second and third derivatives along a direction through the same code: the time derivatives
//! of an output along the trajectory (FMI's output derivatives) come from them.
//!
//! What a model writes with `T` reads as with `f64`: `+ - * /` between `T`s and with `f64` on
//! the right (`x * 2.0`; a constant on the left is `T::from(2.0)`), the functions of nalgebra's
//! [`RealField`] (`sin`, `cos`, `sin_cos`, `sqrt`, `atan2`, `hypot`, `powi`, `exp`, ...), and
//! nalgebra's vectors and matrices of `T`, their decompositions included. A comparison looks at
//! the value ([`Scalar::value`]): branches follow the value, and the derivative is that of the
//! branch taken (the regime's equations).
//!
//! For `f64` every operation is the `f64` one (nalgebra's functions call the standard
//! library's), so a model's simulation is bit for bit what it was when written on `f64`.

use std::ops::{Add, Div, Mul, Sub};

use nalgebra::RealField;
pub use num_dual::{Dual2_64, Dual3_64, Dual64, DualSVec64};

use crate::phase_cosine::PhaseCosine;

/// A number a model's equations run on: `f64`, or a dual number carrying derivatives.
///
/// ```
/// use fmu_export::{Dual64, Scalar};
///
/// // m x'' = -k x: the acceleration, written once.
/// fn acceleration<T: Scalar>(k: T, m: T, x: T) -> T {
///     -(k * x) / m
/// }
/// assert_eq!(acceleration(4.0, 2.0, 0.5), -1.0);
/// // Its derivative with respect to x (seed 1 on x): -k / m, exactly.
/// let d = acceleration(Dual64::from(4.0), Dual64::from(2.0), Dual64::new(0.5, 1.0));
/// assert_eq!((d.value(), d.eps), (-1.0, -2.0));
/// ```
pub trait Scalar:
    RealField + Copy + From<f64> + Add<f64, Output = Self> + Sub<f64, Output = Self> + Mul<f64, Output = Self> + Div<f64, Output = Self>
{
    /// The value (the real part of a dual number).
    fn value(self) -> f64;

    /// cos(self) with `memo` remembering a nearby anchor between calls: for `f64` the
    /// [`PhaseCosine`] (within one ulp of libm's cosine, and bit for bit the same whatever the
    /// memo held); for dual numbers the plain cosine, whose derivative parts are exact. For
    /// the toolkit's [`Harmonic`](crate::harmonic::Harmonic).
    #[doc(hidden)]
    fn cos_near(self, memo: &PhaseCosine) -> Self {
        let _ = memo;
        self.cos()
    }
}

impl Scalar for f64 {
    #[inline(always)]
    fn value(self) -> f64 {
        self
    }

    #[inline(always)]
    fn cos_near(self, memo: &PhaseCosine) -> f64 {
        memo.cos(self)
    }
}

impl Scalar for Dual64 {
    #[inline]
    fn value(self) -> f64 {
        self.re
    }
}

impl<const N: usize> Scalar for DualSVec64<N> {
    #[inline]
    fn value(self) -> f64 {
        self.re
    }
}

impl Scalar for Dual2_64 {
    #[inline]
    fn value(self) -> f64 {
        self.re
    }
}

impl Scalar for Dual3_64 {
    #[inline]
    fn value(self) -> f64 {
        self.re
    }
}

/// The length |v| of a vector, with the derivative 0 where v is zero to within `noise` (the
/// rounding of the terms v is computed from). The length has a kink at the zero vector (it
/// grows as |dv| whichever way v moves), so no derivative exists there; 0 is the symmetric
/// one, which central differences give too. A vector that is zero but for rounding points in
/// a direction rounding chose, so the derivative of its length would be as arbitrary: a
/// model's loop-closure gap is such a vector after every projection, and its length's
/// derivative is asked for exactly there. The value is nalgebra's `norm`, bit for bit.
pub fn length<T: Scalar, const D: usize>(v: &nalgebra::SVector<T, D>, noise: f64) -> T {
    let squared = v.norm_squared();
    if squared.value() <= noise * noise {
        T::from(squared.value().sqrt())
    } else {
        squared.sqrt()
    }
}
