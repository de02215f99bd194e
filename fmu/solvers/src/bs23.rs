//! Bogacki–Shampine 3(2) (MATLAB's ode23, scipy's RK23): a 3rd-order solution with an embedded
//! 2nd-order one for the error estimate, FSAL (four stages, three evaluations per step), and
//! the cubic Hermite interpolant on the step's end values and slopes as its dense output, which
//! is 3rd order because both slopes come with the solution (Bogacki & Shampine 1989).

use super::adaptive::{self, Scheme, Stages};
use super::lanes;
use super::OdeSystem;

// Butcher tableau (Bogacki & Shampine 1989). The 3rd-order weights are the last row, which
// makes stage 4 = f(t1, x1).
const C2: f64 = 1.0 / 2.0;
const C3: f64 = 3.0 / 4.0;
const A21: f64 = 1.0 / 2.0;
const A32: f64 = 3.0 / 4.0;
const A41: f64 = 2.0 / 9.0;
const A42: f64 = 1.0 / 3.0;
const A43: f64 = 4.0 / 9.0;
// The 3rd-order weights minus the embedded 2nd-order ones (7/24, 1/4, 1/3, 1/8).
const E1: f64 = 2.0 / 9.0 - 7.0 / 24.0;
const E2: f64 = 1.0 / 3.0 - 1.0 / 4.0;
const E3: f64 = 4.0 / 9.0 - 1.0 / 3.0;
const E4: f64 = -1.0 / 8.0;

/// The Bogacki–Shampine 3(2) pair.
pub(super) struct Bs23;

impl Scheme for Bs23 {
    const STAGES: u64 = 3;
    const LAST: usize = 2;
    const ORDER: i32 = 3;
    // The classical controller with scipy's RK23 limits: shrink at most to 1/5, grow at most
    // 10x, exponent 1/3 for an error estimate of local order 3.
    const EXPO1: f64 = 1.0 / 3.0;
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
        // Slices of the model's constant size, as in Dopri5's `step`.
        let n = sys.dim();
        let [k2, k3, k4, ..] = k;
        let (x0, k1, xs, x1) = (&x0[..n], &k1[..n], &mut xs[..n], &mut x1[..n]);
        let (k2, k3, k4) = (&mut k2[..n], &mut k3[..n], &mut k4[..n]);
        lanes::fill!(xs, |i| x0[i] + h * (A21 * k1[i]));
        sys.rhs(t + C2 * h, xs, k2);
        lanes::fill!(xs, |i| x0[i] + h * (A32 * k2[i]));
        sys.rhs(t + C3 * h, xs, k3);
        lanes::fill!(x1, |i| x0[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]));
        sys.rhs(t1, x1, k4);
        let sum = lanes::sum!(n, |i| {
            let e = h * (E1 * k1[i] + E2 * k2[i] + E3 * k3[i] + E4 * k4[i]);
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

    /// The cubic Hermite interpolant in the form of DOPRI5's first four coefficients: x0,
    /// x1 - x0, and the two corrections from the slopes k1 and k4.
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
        let (x0, x1, k1, k4) = (&x0[..n], &x1[..n], &k1[..n], &k[Self::LAST][..n]);
        let (r0, rest) = dense.split_at_mut(n);
        let (r1, rest) = rest.split_at_mut(n);
        let (r2, rest) = rest.split_at_mut(n);
        let r3 = &mut rest[..n];
        lanes::fill!(r0, |i| x0[i]);
        lanes::fill!(r1, |i| x1[i] - x0[i]);
        lanes::fill!(r2, |i| h * k1[i] - (x1[i] - x0[i]));
        lanes::fill!(r3, |i| {
            let ydiff = x1[i] - x0[i];
            ydiff - h * k4[i] - (h * k1[i] - ydiff)
        });
    }

    // Inlined where `n` is the model's constant: unrolled, no bounds checks (one per communication point).
    #[inline(always)]
    fn eval(th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
        let th1 = 1.0 - th;
        let (r0, r1, r2, r3) = (&dense[..n], &dense[n..2 * n], &dense[2 * n..3 * n], &dense[3 * n..4 * n]);
        lanes::fill!(&mut out[..n], |i| r0[i] + th * (r1[i] + th1 * (r2[i] + th * r3[i])));
    }
}
