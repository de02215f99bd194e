//! [`Taylor3`]: third-order dual numbers that know when they are constants.
//!
//! The output derivatives evaluate a model's equations in third-order dual numbers along the
//! trajectory ([`crate::core::derivatives::trajectory`]); the lifted model holds its
//! parameters in the same type, with derivative parts zero. A product of two [`Dual3_64`]s
//! costs 16 multiplications whatever they hold, so `amplitude * k * c` paid as much for the
//! parameters as for the trajectory's own numbers. A [`Taylor3`] remembers that it was made
//! from a plain `f64` (a parameter, a literal, what only such numbers gave): a product or
//! quotient with one costs the other's four parts times a number, and of two of them one
//! multiplication. Every other operation is the [`Dual3_64`]'s.
//!
//! The derivative parts are those [`Dual3_64`] gives, bit for bit, but for the sign of a zero:
//! where num-dual adds the constant's zero parts times the other's (`0 * v + c * w`), this skips
//! the zero term, which only changes `-0 + 0` into `0`.
//!
//! The value part is what the same operation gives in `f64`, bit for bit: the toolkit then
//! serves a model's `f64` outputs from the pass that computes their derivatives
//! ([`crate::core::derivatives::Trajectory`]) instead of evaluating them twice. num-dual's own
//! value parts differ from `f64` in a few operations (a quotient is `a * (1 / b)`, `powi` and
//! `powf` multiply out three powers, `tan` and `tanh` divide, `hypot` squares and takes the
//! root, `mul_add` does not fuse); here those take the `f64` operation's value, and
//! `cos_near` the memoized cosine's (what the `f64` model computes).

use std::fmt;
use std::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign};

use approx::{AbsDiffEq, RelativeEq, UlpsEq};
use nalgebra::{ComplexField, Field, RealField, SimdValue};
use num_dual::Dual3_64;
use num_traits::{FromPrimitive, Num, One, Signed, Zero};
use simba::scalar::{SubsetOf, SupersetOf};

/// A [`Dual3_64`] and whether its derivative parts are known to be zero (see the module
/// documentation).
#[derive(Clone, Copy, Debug)]
pub struct Taylor3 {
    /// The number.
    pub dual: Dual3_64,
    /// Its derivative parts are zero: it came from an `f64` and constants alone.
    pub constant: bool,
}

impl Taylor3 {
    /// The number `dual`, derivative parts and all.
    #[inline(always)]
    pub fn varying(dual: Dual3_64) -> Taylor3 {
        Taylor3 { dual, constant: false }
    }

    /// The constant `value`.
    #[inline(always)]
    pub fn constant(value: f64) -> Taylor3 {
        Taylor3 { dual: Dual3_64::from(value), constant: true }
    }

    /// `dual`, constant when `self` is: a function of a constant is one.
    #[inline(always)]
    fn like(self, dual: Dual3_64) -> Taylor3 {
        Taylor3 { dual, constant: self.constant }
    }

    /// The number with its value part `value` (what `f64` computes), derivatives as they are.
    #[inline(always)]
    fn valued(mut self, value: f64) -> Taylor3 {
        self.dual.re = value;
        self
    }

    /// `dual`, constant when `self` and `other` both are.
    #[inline(always)]
    fn with(self, other: Taylor3, dual: Dual3_64) -> Taylor3 {
        Taylor3 { dual, constant: self.constant && other.constant }
    }
}

impl From<f64> for Taylor3 {
    #[inline(always)]
    fn from(value: f64) -> Taylor3 {
        Taylor3::constant(value)
    }
}

impl PartialEq for Taylor3 {
    #[inline]
    fn eq(&self, other: &Taylor3) -> bool {
        self.dual == other.dual
    }
}

impl PartialOrd for Taylor3 {
    #[inline]
    fn partial_cmp(&self, other: &Taylor3) -> Option<std::cmp::Ordering> {
        self.dual.partial_cmp(&other.dual)
    }
}

impl fmt::Display for Taylor3 {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        self.dual.fmt(f)
    }
}

impl Add for Taylor3 {
    type Output = Taylor3;
    #[inline(always)]
    fn add(self, other: Taylor3) -> Taylor3 {
        self.with(other, self.dual + other.dual)
    }
}

impl Sub for Taylor3 {
    type Output = Taylor3;
    #[inline(always)]
    fn sub(self, other: Taylor3) -> Taylor3 {
        self.with(other, self.dual - other.dual)
    }
}

impl Mul for Taylor3 {
    type Output = Taylor3;
    /// num-dual's product, without the constant's zero parts.
    #[inline(always)]
    fn mul(self, other: Taylor3) -> Taylor3 {
        match (self.constant, other.constant) {
            (false, false) => Taylor3::varying(self.dual * other.dual),
            (true, false) => Taylor3::varying(other.dual * self.dual.re),
            (false, true) => Taylor3::varying(self.dual * other.dual.re),
            (true, true) => Taylor3::constant(self.dual.re * other.dual.re),
        }
    }
}

impl Div for Taylor3 {
    type Output = Taylor3;
    /// num-dual's quotient's derivative parts (the product with the divisor's reciprocal,
    /// `1 / re`), without a constant divisor's zero parts; the value `f64`'s quotient.
    #[inline(always)]
    fn div(self, other: Taylor3) -> Taylor3 {
        let value = self.dual.re / other.dual.re;
        if other.constant {
            if self.constant {
                return Taylor3::constant(value);
            }
            Taylor3::varying(self.dual * (1.0 / other.dual.re)).valued(value)
        } else {
            Taylor3::varying(self.dual / other.dual).valued(value)
        }
    }
}

impl Rem for Taylor3 {
    type Output = Taylor3;
    fn rem(self, other: Taylor3) -> Taylor3 {
        self.with(other, self.dual % other.dual)
    }
}

impl Neg for Taylor3 {
    type Output = Taylor3;
    #[inline(always)]
    fn neg(self) -> Taylor3 {
        self.like(-self.dual)
    }
}

/// The operations with an `f64` on the right and the assigning operators, from the above.
macro_rules! derived_ops {
    ($($op:ident $method:ident $assign:ident $assign_method:ident),*) => {$(
        impl $op<f64> for Taylor3 {
            type Output = Taylor3;
            #[inline(always)]
            fn $method(self, other: f64) -> Taylor3 {
                self.like(self.dual.$method(other))
            }
        }
        impl $assign for Taylor3 {
            #[inline(always)]
            fn $assign_method(&mut self, other: Taylor3) {
                *self = (*self).$method(other);
            }
        }
    )*};
}
derived_ops!(Add add AddAssign add_assign, Sub sub SubAssign sub_assign, Mul mul MulAssign mul_assign, Div div DivAssign div_assign);

impl RemAssign for Taylor3 {
    fn rem_assign(&mut self, other: Taylor3) {
        *self = *self % other;
    }
}

impl Zero for Taylor3 {
    fn zero() -> Taylor3 {
        Taylor3::constant(0.0)
    }
    fn is_zero(&self) -> bool {
        self.dual.is_zero()
    }
}

impl One for Taylor3 {
    fn one() -> Taylor3 {
        Taylor3::constant(1.0)
    }
}

impl Num for Taylor3 {
    type FromStrRadixErr = <f64 as Num>::FromStrRadixErr;
    fn from_str_radix(text: &str, radix: u32) -> Result<Taylor3, Self::FromStrRadixErr> {
        f64::from_str_radix(text, radix).map(Taylor3::constant)
    }
}

impl Signed for Taylor3 {
    fn abs(&self) -> Taylor3 {
        self.like(Signed::abs(&self.dual))
    }
    fn abs_sub(&self, other: &Taylor3) -> Taylor3 {
        self.with(*other, self.dual.abs_sub(&other.dual))
    }
    fn signum(&self) -> Taylor3 {
        Taylor3::constant(Signed::signum(&self.dual).re)
    }
    fn is_positive(&self) -> bool {
        self.dual.is_positive()
    }
    fn is_negative(&self) -> bool {
        self.dual.is_negative()
    }
}

impl FromPrimitive for Taylor3 {
    fn from_i64(n: i64) -> Option<Taylor3> {
        f64::from_i64(n).map(Taylor3::constant)
    }
    fn from_u64(n: u64) -> Option<Taylor3> {
        f64::from_u64(n).map(Taylor3::constant)
    }
    fn from_f64(n: f64) -> Option<Taylor3> {
        Some(Taylor3::constant(n))
    }
}

impl AbsDiffEq for Taylor3 {
    type Epsilon = Taylor3;
    fn default_epsilon() -> Taylor3 {
        Taylor3::constant(f64::default_epsilon())
    }
    fn abs_diff_eq(&self, other: &Taylor3, epsilon: Taylor3) -> bool {
        self.dual.abs_diff_eq(&other.dual, epsilon.dual)
    }
}

impl RelativeEq for Taylor3 {
    fn default_max_relative() -> Taylor3 {
        Taylor3::constant(f64::default_max_relative())
    }
    fn relative_eq(&self, other: &Taylor3, epsilon: Taylor3, max_relative: Taylor3) -> bool {
        self.dual.relative_eq(&other.dual, epsilon.dual, max_relative.dual)
    }
}

impl UlpsEq for Taylor3 {
    fn default_max_ulps() -> u32 {
        f64::default_max_ulps()
    }
    fn ulps_eq(&self, other: &Taylor3, epsilon: Taylor3, max_ulps: u32) -> bool {
        self.dual.ulps_eq(&other.dual, epsilon.dual, max_ulps)
    }
}

impl SimdValue for Taylor3 {
    type Element = Taylor3;
    type SimdBool = bool;
    const LANES: usize = 1;
    fn splat(value: Taylor3) -> Taylor3 {
        value
    }
    fn extract(&self, _: usize) -> Taylor3 {
        *self
    }
    unsafe fn extract_unchecked(&self, _: usize) -> Taylor3 {
        *self
    }
    fn replace(&mut self, _: usize, value: Taylor3) {
        *self = value;
    }
    unsafe fn replace_unchecked(&mut self, _: usize, value: Taylor3) {
        *self = value;
    }
    fn select(self, condition: bool, other: Taylor3) -> Taylor3 {
        if condition {
            self
        } else {
            other
        }
    }
}

impl SubsetOf<Taylor3> for Taylor3 {
    fn to_superset(&self) -> Taylor3 {
        *self
    }
    fn from_superset_unchecked(element: &Taylor3) -> Taylor3 {
        *element
    }
    fn is_in_subset(_: &Taylor3) -> bool {
        true
    }
}

impl SupersetOf<f64> for Taylor3 {
    fn is_in_subset(&self) -> bool {
        true
    }
    fn to_subset_unchecked(&self) -> f64 {
        self.dual.re
    }
    fn from_subset(element: &f64) -> Taylor3 {
        Taylor3::constant(*element)
    }
}

impl SupersetOf<f32> for Taylor3 {
    fn is_in_subset(&self) -> bool {
        SupersetOf::<f32>::is_in_subset(&self.dual.re)
    }
    fn to_subset_unchecked(&self) -> f32 {
        self.dual.re.to_subset_unchecked()
    }
    fn from_subset(element: &f32) -> Taylor3 {
        Taylor3::constant(f64::from(*element))
    }
}

impl Field for Taylor3 {}

/// Functions of one number: num-dual's, a constant's result a constant.
macro_rules! unary {
    ($($name:ident),*) => {$(
        #[inline]
        fn $name(self) -> Taylor3 {
            self.like(ComplexField::$name(self.dual))
        }
    )*};
}

impl ComplexField for Taylor3 {
    type RealField = Taylor3;

    unary!(floor, ceil, round, trunc, fract, recip, sin, cos, asin, acos, atan, sinh, cosh, asinh, acosh, atanh);

    // num-dual divides the sine by the cosine: the value is f64's.
    #[inline]
    fn tan(self) -> Taylor3 {
        self.like(ComplexField::tan(self.dual)).valued(self.dual.re.tan())
    }
    #[inline]
    fn tanh(self) -> Taylor3 {
        self.like(ComplexField::tanh(self.dual)).valued(self.dual.re.tanh())
    }
    unary!(log2, log10, ln, ln_1p, sqrt, exp, exp2, exp_m1, cbrt, abs, modulus, norm1);

    fn from_real(re: Taylor3) -> Taylor3 {
        re
    }
    fn real(self) -> Taylor3 {
        self
    }
    fn imaginary(self) -> Taylor3 {
        Taylor3::zero()
    }
    fn modulus_squared(self) -> Taylor3 {
        self * self
    }
    fn argument(self) -> Taylor3 {
        Taylor3::zero()
    }
    fn scale(self, factor: Taylor3) -> Taylor3 {
        self * factor
    }
    fn unscale(self, factor: Taylor3) -> Taylor3 {
        self / factor
    }
    /// The product and sum's derivatives; the value fused, as `f64`'s `mul_add`.
    fn mul_add(self, a: Taylor3, b: Taylor3) -> Taylor3 {
        (self * a + b).valued(self.dual.re.mul_add(a.dual.re, b.dual.re))
    }
    fn hypot(self, other: Taylor3) -> Taylor3 {
        self.with(other, self.dual.hypot(other.dual)).valued(self.dual.re.hypot(other.dual.re))
    }
    fn conjugate(self) -> Taylor3 {
        self
    }
    #[inline]
    fn sin_cos(self) -> (Taylor3, Taylor3) {
        let (s, c) = self.dual.sin_cos();
        (self.like(s), self.like(c))
    }
    fn log(self, base: Taylor3) -> Taylor3 {
        self.with(base, self.dual.log(base.dual)).valued(self.dual.re.log(base.dual.re))
    }
    fn powi(self, n: i32) -> Taylor3 {
        self.like(self.dual.powi(n)).valued(self.dual.re.powi(n))
    }
    fn powf(self, n: Taylor3) -> Taylor3 {
        self.with(n, self.dual.powf(n.dual)).valued(self.dual.re.powf(n.dual.re))
    }
    fn powc(self, n: Taylor3) -> Taylor3 {
        self.powf(n)
    }
    fn is_finite(&self) -> bool {
        self.dual.re.is_finite()
    }
    fn try_sqrt(self) -> Option<Taylor3> {
        self.dual.try_sqrt().map(|d| self.like(d))
    }
    fn signum(self) -> Taylor3 {
        Signed::signum(&self)
    }
}

/// Constants of nalgebra's `RealField`.
macro_rules! constants {
    ($($name:ident),*) => {$(
        fn $name() -> Taylor3 {
            Taylor3::constant(<f64 as RealField>::$name())
        }
    )*};
}

impl RealField for Taylor3 {
    constants!(
        pi,
        two_pi,
        frac_pi_2,
        frac_pi_3,
        frac_pi_4,
        frac_pi_6,
        frac_pi_8,
        frac_1_pi,
        frac_2_pi,
        frac_2_sqrt_pi,
        e,
        log2_e,
        log10_e,
        ln_2,
        ln_10
    );

    fn is_sign_positive(&self) -> bool {
        self.dual.re.is_sign_positive()
    }
    fn is_sign_negative(&self) -> bool {
        self.dual.re.is_sign_negative()
    }
    fn copysign(self, sign: Taylor3) -> Taylor3 {
        self.like(self.dual.copysign(sign.dual))
    }
    fn max(self, other: Taylor3) -> Taylor3 {
        if other > self {
            other
        } else {
            self
        }
    }
    fn min(self, other: Taylor3) -> Taylor3 {
        if other < self {
            other
        } else {
            self
        }
    }
    fn clamp(self, min: Taylor3, max: Taylor3) -> Taylor3 {
        if self < min {
            min
        } else if self > max {
            max
        } else {
            self
        }
    }
    fn atan2(self, other: Taylor3) -> Taylor3 {
        self.with(other, self.dual.atan2(other.dual))
    }
    fn min_value() -> Option<Taylor3> {
        Some(Taylor3::constant(f64::MIN))
    }
    fn max_value() -> Option<Taylor3> {
        Some(Taylor3::constant(f64::MAX))
    }
}

impl crate::Scalar for Taylor3 {
    #[inline]
    fn value(self) -> f64 {
        self.dual.re
    }

    /// The cosine's derivatives; the value the memo gives, as in the `f64` model.
    fn cos_near(self, memo: &crate::phase_cosine::PhaseCosine) -> Taylor3 {
        ComplexField::cos(self).valued(memo.cos(self.dual.re))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The numbers num-dual gives, bit for bit but for the sign of a zero part, for every
    /// combination of constant and varying operands of the operations that treat constants
    /// apart (the values are not exact in binary, so a different order of operations would
    /// show).
    #[test]
    fn products_and_quotients_are_num_duals() {
        let a = Dual3_64::new(0.3, 1.7, -2.9, 0.11);
        let b = Dual3_64::new(-1.3, 0.7, 5.3, -0.23);
        let (p, q) = (0.7, -2.9);
        let cases = [
            (Taylor3::varying(a), Taylor3::varying(b), a, b),
            (Taylor3::constant(p), Taylor3::varying(b), Dual3_64::from(p), b),
            (Taylor3::varying(a), Taylor3::constant(q), a, Dual3_64::from(q)),
            (Taylor3::constant(p), Taylor3::constant(q), Dual3_64::from(p), Dual3_64::from(q)),
        ];
        // A zero part compares as 0 whatever its sign (-0.0 == 0.0), any other by its bits.
        let bits = |d: Dual3_64| [d.re, d.v1, d.v2, d.v3].map(|v| if v == 0.0 { 0 } else { v.to_bits() });
        for (x, y, dx, dy) in cases {
            assert_eq!(bits((x * y).dual), bits(dx * dy), "{x} * {y}");
            // The quotient's value is f64's a / b, not num-dual's a * (1 / b).
            let (q, dq) = (bits((x / y).dual), bits(dx / dy));
            assert_eq!(q[1..], dq[1..], "{x} / {y}");
            assert_eq!((x / y).dual.re.to_bits(), (dx.re / dy.re).to_bits(), "{x} / {y}");
            assert_eq!(bits((x + y).dual), bits(dx + dy), "{x} + {y}");
            assert_eq!(bits((x - y).dual), bits(dx - dy), "{x} - {y}");
            assert_eq!((x * y).constant, x.constant && y.constant);
        }
        let (s, c) = Taylor3::varying(a).sin_cos();
        assert_eq!((bits(s.dual), bits(c.dual)), (bits(a.sin_cos().0), bits(a.sin_cos().1)));
        assert!(Taylor3::constant(p).sin().constant && !Taylor3::varying(a).sin().constant);
    }

    /// The value part of every operation whose num-dual value is computed another way than
    /// f64's is f64's, bit for bit (the outputs served from the derivatives' pass must be the
    /// f64 model's); the derivative parts stay num-dual's. The operands are not exact in
    /// binary, so `a * (1 / b)` against `a / b`, or an unfused `mul_add`, would show.
    #[test]
    fn values_are_those_of_f64() {
        // Each operation's operands are ones where num-dual's value is not f64's (checked).
        let dual = |re: f64| Dual3_64::new(re, 1.7, -2.9, 0.11);
        let derivatives = |d: Dual3_64| [d.v1, d.v2, d.v3].map(f64::to_bits);
        let (a, b, c, d, e, f, g) = (dual(0.3), dual(0.7), dual(2.9), dual(5.3), dual(0.61), dual(0.7), dual(1.3));
        let t = Taylor3::varying;
        let cases: [(&str, Taylor3, Dual3_64, f64); 8] = [
            ("a / b", t(a) / t(b), a / b, 0.3 / 0.7),
            ("tan a", ComplexField::tan(t(a)), ComplexField::tan(a), 0.3f64.tan()),
            ("tanh b", ComplexField::tanh(t(b)), ComplexField::tanh(b), 0.7f64.tanh()),
            ("g^5", ComplexField::powi(t(g), 5), ComplexField::powi(g, 5), 1.3f64.powi(5)),
            ("a^c", ComplexField::powf(t(a), t(c)), ComplexField::powf(a, c), 0.3f64.powf(2.9)),
            ("hypot(a, c)", ComplexField::hypot(t(a), t(c)), ComplexField::hypot(a, c), 0.3f64.hypot(2.9)),
            ("log_d a", ComplexField::log(t(a), t(d)), ComplexField::log(a, d), 0.3f64.log(5.3)),
            ("a e + f", ComplexField::mul_add(t(a), t(e), t(f)), a * e + f, 0.3f64.mul_add(0.61, 0.7)),
        ];
        for (what, t, d, f) in cases {
            assert_ne!(d.re.to_bits(), f.to_bits(), "{what} does not tell num-dual's value from f64's");
            assert_eq!(t.dual.re.to_bits(), f.to_bits(), "value of {what}");
            assert_eq!(derivatives(t.dual), derivatives(d), "derivatives of {what}");
        }
        assert_eq!((Taylor3::constant(0.3) / Taylor3::constant(0.7)).dual.re.to_bits(), (0.3f64 / 0.7).to_bits());
        let memo = crate::phase_cosine::PhaseCosine::default();
        for phase in [0.1, 2.6, 40.3, 1e3 + 0.37] {
            let c = crate::Scalar::cos_near(Taylor3::varying(Dual3_64::new(phase, 1.0, 0.0, 0.0)), &memo);
            assert_eq!(c.dual.re.to_bits(), memo.cos(phase).to_bits(), "cos_near at {phase}");
            assert_eq!(derivatives(c.dual), derivatives(Dual3_64::new(phase, 1.0, 0.0, 0.0).cos()), "cos_near at {phase}");
        }
    }
}
