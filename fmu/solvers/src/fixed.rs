//! Fixed-step forward Euler and classic RK4, with cubic Hermite dense output for events.

use super::events;
use super::{step_floor, Advance, Integrator, Method, OdeSystem, SolverError, MAX_STEPS_PER_CALL};

/// Step boundary result: `Ok((t_reached, outcome))`, or the error with the last good time.
pub(super) type StepResult = Result<(f64, Advance), (f64, SolverError)>;

impl Integrator {
    /// Euler/RK4 over [t0, t_end] on the grid t0 + k*fixed_step, ending with one shorter step.
    pub(super) fn advance_fixed<S: OdeSystem>(&mut self, sys: &S, t0: f64, t_end: f64) -> StepResult {
        let h = self.settings.fixed_step;
        let rk4 = self.settings.method == Method::Rk4;
        // A remainder this small is rounding noise of t0 + k*h (or a negligible
        // sliver): merging it into the last step avoids a near-zero step.
        let merge = (1e-12 * h).max(step_floor(t0.abs().max(t_end.abs())));
        // A step that cannot move time (below the floor at the far end of the interval) would
        // have the loop below count grid points that all round to the same time.
        if h < step_floor(t0.abs().max(t_end.abs())) {
            return Err((t0, SolverError::StepSizeTooSmall { t: t0, h }));
        }
        let accepted_before = self.n_steps;
        // The derivative cache is the adaptive methods' concept; fixed methods always start a step fresh.
        self.fsal_valid = false;
        let mut tc = t0;
        let mut k: u64 = 0;
        loop {
            if k >= MAX_STEPS_PER_CALL {
                return Err((tc, self.too_many_steps(tc, accepted_before)));
            }
            k += 1;
            // Boundaries are computed from t0, never accumulated, so they do not drift.
            let mut tn = t0 + k as f64 * h;
            if tn >= t_end - merge {
                tn = t_end;
            }
            if tn <= tc {
                continue;
            }
            let hs = tn - tc;
            let w = &mut self.work;
            sys.rhs(tc, &self.x_int, &mut self.k1);
            let finite = if rk4 {
                let [k2, k3, k4, ..] = &mut w.k;
                rk4_step(sys, tc, hs, tn, &self.x_int, &self.k1, k2, k3, k4, &mut w.xs, &mut w.next)
            } else {
                euler_step(hs, &self.x_int, &self.k1, &mut w.next)
            };
            self.n_rhs += if rk4 { 4 } else { 1 };
            if !finite {
                return Err((tc, SolverError::NonFinite { t: tn }));
            }
            self.n_steps += 1;
            if self.n_ind > 0 {
                sys.event_indicators(tn, &w.next, &mut w.zn);
                if events::any_crossed(&self.z_left, &w.zn) {
                    // Hermite needs the slope at the step end too.
                    let f1 = &mut w.k[5];
                    sys.rhs(tn, &w.next, f1);
                    self.n_rhs += 1;
                    let (x0, x1, f0, f1) = (&self.x_int, &w.next, &self.k1, &w.k[5]);
                    w.za.copy_from_slice(&self.z_left);
                    w.zb.copy_from_slice(&w.zn);
                    let xs = &mut w.xs;
                    let tb = events::locate(tc, tn, &self.z_left, &mut w.za, &mut w.zb, &mut w.zm, |tm, z| {
                        hermite(tc, hs, tm, x0, x1, f0, f1, xs);
                        sys.event_indicators(tm, xs, z);
                    });
                    if tb == tn {
                        std::mem::swap(&mut self.x_int, &mut w.next);
                    } else {
                        hermite(tc, hs, tb, &self.x_int, &w.next, &self.k1, &w.k[5], &mut w.xs);
                        std::mem::swap(&mut self.x_int, &mut w.xs);
                    }
                    let fired = events::fired(&self.z_left, &w.zb);
                    self.z_left.copy_from_slice(&w.zb);
                    return Ok((tb, Advance::Event { fired }));
                }
                self.z_left.copy_from_slice(&w.zn);
            }
            std::mem::swap(&mut self.x_int, &mut w.next);
            tc = tn;
            if tn == t_end {
                return Ok((t_end, Advance::Reached));
            }
        }
    }
}

/// x1 = x0 + h f0; returns whether x1 is finite.
#[inline]
pub(super) fn euler_step(h: f64, x0: &[f64], f0: &[f64], x1: &mut [f64]) -> bool {
    let mut ok = true;
    for ((y, &x), &f) in x1.iter_mut().zip(x0).zip(f0) {
        *y = x + h * f;
        ok &= y.is_finite();
    }
    ok
}

/// One classic RK4 step from (t, x0) with k1 = f(t, x0); `t1` is the exact step end time.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn rk4_step<S: OdeSystem>(
    sys: &S,
    t: f64,
    h: f64,
    t1: f64,
    x0: &[f64],
    k1: &[f64],
    k2: &mut [f64],
    k3: &mut [f64],
    k4: &mut [f64],
    xs: &mut [f64],
    x1: &mut [f64],
) -> bool {
    // Slices of the model's constant size, as in Dopri5's `step`: unrolled loops, no bounds
    // checks, and a right-hand side cheap enough to inline.
    let n = sys.dim();
    let (x0, k1, xs, x1) = (&x0[..n], &k1[..n], &mut xs[..n], &mut x1[..n]);
    let (k2, k3, k4) = (&mut k2[..n], &mut k3[..n], &mut k4[..n]);
    let hh = 0.5 * h;
    let tm = t + hh;
    for ((y, &x), &a) in xs.iter_mut().zip(x0).zip(k1) {
        *y = x + hh * a;
    }
    sys.rhs(tm, xs, k2);
    for ((y, &x), &a) in xs.iter_mut().zip(x0).zip(k2.iter()) {
        *y = x + hh * a;
    }
    sys.rhs(tm, xs, k3);
    for ((y, &x), &a) in xs.iter_mut().zip(x0).zip(k3.iter()) {
        *y = x + h * a;
    }
    sys.rhs(t1, xs, k4);
    let h6 = h / 6.0;
    let mut ok = true;
    for i in 0..n {
        x1[i] = x0[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]);
        ok &= x1[i].is_finite();
    }
    ok
}

/// Cubic Hermite interpolant through (t0, x0, f0) and (t0 + h, x1, f1), evaluated at `t`.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn hermite(t0: f64, h: f64, t: f64, x0: &[f64], x1: &[f64], f0: &[f64], f1: &[f64], out: &mut [f64]) {
    let s = (t - t0) / h;
    let s1 = 1.0 - s;
    let h00 = (1.0 + 2.0 * s) * s1 * s1;
    let h01 = s * s * (3.0 - 2.0 * s);
    let h10 = h * s * s1 * s1;
    let h11 = -h * s * s * s1;
    let n = out.len();
    let (x0, x1, f0, f1) = (&x0[..n], &x1[..n], &f0[..n], &f1[..n]);
    for i in 0..n {
        out[i] = h00 * x0[i] + h01 * x1[i] + h10 * f0[i] + h11 * f1[i];
    }
}
