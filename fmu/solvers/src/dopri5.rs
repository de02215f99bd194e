//! Dormand–Prince 5(4) (MATLAB's ode45, Hairer's DOPRI5, scipy's RK45): FSAL, the classical
//! step-size controller, and the 4th-order continuous extension of Dormand & Prince / Shampine.

use super::adaptive::{self, Scheme, Stages};
use super::lanes;
use super::OdeSystem;

// Butcher tableau (Dormand & Prince 1980).
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
// The 5th-order weights are the last row, which makes stage 7 = f(t1, x1) (FSAL).
const A71: f64 = 35.0 / 384.0;
const A73: f64 = 500.0 / 1113.0;
const A74: f64 = 125.0 / 192.0;
const A75: f64 = -2187.0 / 6784.0;
const A76: f64 = 11.0 / 84.0;
// Difference between the 5th- and the embedded 4th-order weights.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output (Dormand–Prince continuous extension of order 4).
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

/// The Dormand–Prince 5(4) pair.
pub(super) struct Dopri5;

impl Scheme for Dopri5 {
    const STAGES: u64 = 6;
    const LAST: usize = 5;
    const ORDER: i32 = 5;
    // The classical controller of scipy's RK45 (and of Hairer's DOPRI5 with beta = 0): exponent
    // 1/5, shrink at most to 1/5, grow at most 10x. It settles where err = 0.9^5 = 0.59; the PI
    // memory of Hairer's default (beta = 0.04) settles at 0.9^(1/0.13) = 0.45, which on the Ex. 4
    // sweep takes 5.8 % more steps for a result 1.4x as accurate: no better per evaluation.
    const EXPO1: f64 = 0.2;

    /// err^(1/5) without libm's pow (see root.rs).
    #[inline(always)]
    fn power(err: f64) -> f64 {
        super::root::fifth_root(err)
    }
    const SHRINK: f64 = 0.2;
    const GROWTH: f64 = 10.0;
    const DENSE_RHS: u64 = 0;

    #[inline]
    fn step<S: OdeSystem>(
        sys: &S,
        t: f64,
        h: f64,
        t1: f64,
        x0: &[f64],
        k1: &[f64],
        k: &mut Stages,
        xs: &mut [f64],
        x1: &mut [f64],
        rtol: f64,
        atol: f64,
    ) -> f64 {
        // `dim()` is a constant once `step` is instantiated for a model, so every slice below has
        // a known length: the stage loops unroll, and neither they nor an inlined right-hand side
        // keep bounds checks (which also makes the right-hand side cheap enough to inline).
        let n = sys.dim();
        let [k2, k3, k4, k5, k6, k7, ..] = k;
        let (x0, k1, xs, x1) = (&x0[..n], &k1[..n], &mut xs[..n], &mut x1[..n]);
        let (k2, k3, k4, k5, k6, k7) = (&mut k2[..n], &mut k3[..n], &mut k4[..n], &mut k5[..n], &mut k6[..n], &mut k7[..n]);
        lanes::fill!(xs, |i| x0[i] + h * (A21 * k1[i]));
        sys.rhs(t + C2 * h, xs, k2);
        lanes::fill!(xs, |i| x0[i] + h * (A31 * k1[i] + A32 * k2[i]));
        sys.rhs(t + C3 * h, xs, k3);
        lanes::fill!(xs, |i| x0[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]));
        sys.rhs(t + C4 * h, xs, k4);
        lanes::fill!(xs, |i| x0[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]));
        sys.rhs(t + C5 * h, xs, k5);
        lanes::fill!(xs, |i| x0[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]));
        sys.rhs(t1, xs, k6);
        lanes::fill!(x1, |i| x0[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i] + A76 * k6[i]));
        sys.rhs(t1, x1, k7);
        let sum = lanes::sum!(n, |i| {
            let e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
            let sk = adaptive::weight(atol, rtol, x0[i], x1[i]);
            let r = e / sk;
            r * r
        });
        if n == 0 {
            0.0
        } else {
            (sum / n as f64).sqrt()
        }
    }

    /// The coefficients of the continuous extension (Hairer's rcont1..5): x0, x1 - x0, the
    /// cubic Hermite corrections and the quartic term.
    #[inline(always)]
    fn fill_dense<S: OdeSystem>(
        sys: &S,
        _t: f64,
        h: f64,
        x0: &[f64],
        x1: &[f64],
        k1: &[f64],
        k: &mut Stages,
        _xs: &mut [f64],
        dense: &mut [f64],
    ) {
        let n = sys.dim();
        let [_, k3, k4, k5, k6, k7, ..] = k;
        let (x0, x1, k1) = (&x0[..n], &x1[..n], &k1[..n]);
        let (k3, k4, k5, k6, k7) = (&k3[..n], &k4[..n], &k5[..n], &k6[..n], &k7[..n]);
        let (r0, rest) = dense.split_at_mut(n);
        let (r1, rest) = rest.split_at_mut(n);
        let (r2, rest) = rest.split_at_mut(n);
        let (r3, rest) = rest.split_at_mut(n);
        let r4 = &mut rest[..n];
        lanes::fill!(r0, |i| x0[i]);
        lanes::fill!(r1, |i| x1[i] - x0[i]);
        lanes::fill!(r2, |i| h * k1[i] - (x1[i] - x0[i]));
        lanes::fill!(r3, |i| {
            let ydiff = x1[i] - x0[i];
            ydiff - h * k7[i] - (h * k1[i] - ydiff)
        });
        lanes::fill!(r4, |i| h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]));
    }

    // Inlined where `n` is the model's constant: unrolled, no bounds checks (one per communication point).
    #[inline(always)]
    fn eval(th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
        let th1 = 1.0 - th;
        let (r0, r1, r2, r3, r4) = (&dense[..n], &dense[n..2 * n], &dense[2 * n..3 * n], &dense[3 * n..4 * n], &dense[4 * n..5 * n]);
        lanes::fill!(&mut out[..n], |i| r0[i] + th * (r1[i] + th1 * (r2[i] + th * (r3[i] + th1 * r4[i]))));
    }
}
