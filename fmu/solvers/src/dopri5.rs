//! Dormand–Prince 5(4) with FSAL, PI step-size control, Hairer's initial-step
//! heuristic and the 4th-order continuous extension for event location.

use super::events;
use super::fixed::StepResult;
use super::{all_finite, Advance, Integrator, OdeSystem, SolverError};

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

// Step-size controller (values of Hairer's DOPRI5).
/// Safety factor: aim a little below the tolerance so the next step is likely accepted.
const SAFE: f64 = 0.9;
/// PI memory exponent (Gustafsson); damps step-size oscillation on mildly stiff problems.
const BETA: f64 = 0.04;
const EXPO1: f64 = 0.2 - 0.75 * BETA;
/// Largest shrink (1/5) and growth (10x) per step.
const FAC_MIN: f64 = 0.2;
const FAC_MAX: f64 = 10.0;
/// Initial PI memory, as in DOPRI5.
pub(super) const ERR_OLD_INIT: f64 = 1e-4;
/// After a NaN/inf trial, retry with this fraction of the step, at most `MAX_NONFINITE` times in a row.
const NONFINITE_SHRINK: f64 = 0.2;
const MAX_NONFINITE: u32 = 40;

impl Integrator {
    /// Adaptive Dopri5 from t0 to t_end (or to the first event), steps clipped to land on t_end.
    pub(super) fn advance_dopri5<S: OdeSystem>(&mut self, sys: &S, t0: f64, t_end: f64) -> StepResult {
        let (rtol, atol) = (self.settings.rtol, self.settings.atol);
        let mut tc = t0;
        if !self.fsal_valid {
            sys.rhs(tc, &self.work.cur, &mut self.k1);
            self.n_rhs += 1;
            // No step size can repair a bad starting point.
            if !(all_finite(&self.k1) && all_finite(&self.work.cur)) {
                return Err((tc, SolverError::NonFinite { t: tc }));
            }
            self.fsal_valid = true;
        }
        if self.h <= 0.0 {
            let w = &mut self.work;
            let [k2, ..] = &mut w.k;
            self.h = initial_step(sys, tc, &w.cur, &self.k1, t_end - tc, rtol, atol, &mut w.xs, k2);
            self.n_rhs += 1;
        }
        let mut nonfinite = 0u32;
        loop {
            let remaining = t_end - tc;
            let h_prop = self.h;
            // Land exactly on t_end; stretching a step by up to 1% avoids a sliver step afterwards.
            let lands = 1.01 * h_prop >= remaining;
            let hs = if lands { remaining } else { h_prop };
            if !lands && h_prop < 16.0 * f64::EPSILON * tc.abs() {
                return Err((tc, SolverError::StepSizeTooSmall { t: tc, h: h_prop }));
            }
            let t1 = if lands { t_end } else { tc + hs };
            let w = &mut self.work;
            let err = step(sys, tc, hs, t1, &w.cur, &self.k1, &mut w.k, &mut w.xs, &mut w.next, rtol, atol);
            self.n_rhs += 6;
            if !(err.is_finite() && all_finite(&w.next)) {
                // Often an overflow from a far too large trial step: retry smaller first.
                nonfinite += 1;
                self.n_rejected += 1;
                self.last_rejected = true;
                let h_retry = hs * NONFINITE_SHRINK;
                if nonfinite > MAX_NONFINITE || h_retry < 16.0 * f64::EPSILON * tc.abs() {
                    return Err((tc, SolverError::NonFinite { t: t1 }));
                }
                self.h = h_retry;
                continue;
            }
            nonfinite = 0;
            if err > 1.0 {
                self.h = hs / (err.powf(EXPO1) / SAFE).min(1.0 / FAC_MIN);
                self.last_rejected = true;
                self.n_rejected += 1;
                continue;
            }
            if w.err_old_pow.0 != self.err_old {
                w.err_old_pow = (self.err_old, self.err_old.powf(BETA));
            }
            let err_old_pow = w.err_old_pow.1;
            if hs < h_prop {
                // Clipped to land on t_end: the short step says nothing about the
                // step the solution allows, so neither shrink the proposal nor
                // let its small error enter the controller memory.
                self.h = proposal_after_clipped_step(err, err_old_pow, hs, h_prop, self.last_rejected);
            } else {
                let mut h_new = hs / step_factor(err.powf(EXPO1), err_old_pow);
                if self.last_rejected {
                    h_new = h_new.min(hs);
                }
                self.h = h_new;
                self.err_old = err.max(ERR_OLD_INIT);
            }
            self.last_rejected = false;
            self.n_steps += 1;
            if self.n_ind > 0 {
                sys.event_indicators(t1, &w.next, &mut w.zn);
                if events::any_crossed(&self.z_left, &w.zn) {
                    w.za.copy_from_slice(&self.z_left);
                    w.zb.copy_from_slice(&w.zn);
                    let (x0, x1, k1, ks) = (&w.cur, &w.next, &self.k1, &w.k);
                    let xs = &mut w.xs;
                    let tb = events::locate(tc, t1, &self.z_left, &mut w.za, &mut w.zb, &mut w.zm, |tm, z| {
                        dense(tc, hs, tm, x0, x1, k1, ks, xs);
                        sys.event_indicators(tm, xs, z);
                    });
                    if tb == t1 {
                        std::mem::swap(&mut w.cur, &mut w.next);
                    } else {
                        dense(tc, hs, tb, &w.cur, &w.next, &self.k1, &w.k, &mut w.xs);
                        std::mem::swap(&mut w.cur, &mut w.xs);
                    }
                    let fired = events::fired(&self.z_left, &w.zb);
                    self.z_left.copy_from_slice(&w.zb);
                    // The derivative at the event point was never computed.
                    self.fsal_valid = false;
                    return Ok((tb, Advance::Event { fired }));
                }
                self.z_left.copy_from_slice(&w.zn);
            }
            std::mem::swap(&mut self.k1, &mut w.k[5]);
            std::mem::swap(&mut w.cur, &mut w.next);
            tc = t1;
            if lands {
                return Ok((t_end, Advance::Reached));
            }
        }
    }
}

/// The PI controller's divisor for the next step (h_next = h / factor), from err^EXPO1 of an
/// accepted step and err_old^BETA.
#[inline]
fn step_factor(err_pow: f64, err_old_pow: f64) -> f64 {
    (err_pow / err_old_pow / SAFE).clamp(1.0 / FAC_MAX, 1.0 / FAC_MIN)
}

/// The proposal after an accepted step of size `hs` clipped below the proposal `h_prop`: the
/// larger of h_prop and the controller's next step, which after a rejection is at most hs.
///
/// That next step only exceeds h_prop if err^EXPO1 < r = hs / h_prop * err_old_pow * SAFE. For
/// err <= 1, err^EXPO1 >= err^(3/16) (EXPO1 = 0.17 < 3/16), so when err^(3/16) >= r already
/// rules growth out, the powf (a tenth of a step's time) is skipped; so it is when h_prop is
/// beyond the largest growth, FAC_MAX hs. On the Ex. 4 sweep this leaves a powf in 1 of 9
/// clipped steps, and the proposal grows in 1 of 26.
///
/// The test compares err^3 with r^16: two products on err, whose latency counts, against four
/// square roots before (80 cycles, a tenth of a step: perf found the step waiting on them); r^16
/// is ready before err is. It cannot rule out a growth: where the proposal grows, err < 0.54 (r
/// < SAFE), so err^(3/16) < 0.99 r and err^3 < 0.85 r^16, far beyond the rounding of either side.
/// r >= 0.062 (hs > h_prop / FAC_MAX, err_old >= ERR_OLD_INIT), so r^16 does not underflow.
#[inline]
pub(super) fn proposal_after_clipped_step(err: f64, err_old_pow: f64, hs: f64, h_prop: f64, last_rejected: bool) -> f64 {
    let may_grow = !last_rejected && FAC_MAX * hs > h_prop && {
        let r2 = (hs / h_prop * err_old_pow * SAFE).powi(2);
        let r8 = (r2 * r2) * (r2 * r2);
        err * err * err < r8 * r8
    };
    if may_grow {
        h_prop.max(hs / step_factor(err.powf(EXPO1), err_old_pow))
    } else {
        h_prop
    }
}

/// One Dopri5 trial step of size `h` from (t, x0) with k1 = f(t, x0), writing
/// x1 and k2..k7 (k7 = f(t1, x1)); returns the scaled RMS error estimate
/// (non-finite if anything overflowed). `t1` is the exact step end time.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn step<S: OdeSystem>(
    sys: &S,
    t: f64,
    h: f64,
    t1: f64,
    x0: &[f64],
    k1: &[f64],
    k: &mut [Vec<f64>; 6],
    xs: &mut [f64],
    x1: &mut [f64],
    rtol: f64,
    atol: f64,
) -> f64 {
    // `dim()` is a constant once `step` is instantiated for a model, so every slice below has
    // a known length: the stage loops unroll, and neither they nor an inlined right-hand side
    // keep bounds checks (which also makes the right-hand side cheap enough to inline).
    let n = sys.dim();
    let [k2, k3, k4, k5, k6, k7] = k;
    let (x0, k1, xs, x1) = (&x0[..n], &k1[..n], &mut xs[..n], &mut x1[..n]);
    let (k2, k3, k4, k5, k6, k7) = (&mut k2[..n], &mut k3[..n], &mut k4[..n], &mut k5[..n], &mut k6[..n], &mut k7[..n]);
    for i in 0..n {
        xs[i] = x0[i] + h * (A21 * k1[i]);
    }
    sys.rhs(t + C2 * h, xs, k2);
    for i in 0..n {
        xs[i] = x0[i] + h * (A31 * k1[i] + A32 * k2[i]);
    }
    sys.rhs(t + C3 * h, xs, k3);
    for i in 0..n {
        xs[i] = x0[i] + h * (A41 * k1[i] + A42 * k2[i] + A43 * k3[i]);
    }
    sys.rhs(t + C4 * h, xs, k4);
    for i in 0..n {
        xs[i] = x0[i] + h * (A51 * k1[i] + A52 * k2[i] + A53 * k3[i] + A54 * k4[i]);
    }
    sys.rhs(t + C5 * h, xs, k5);
    for i in 0..n {
        xs[i] = x0[i] + h * (A61 * k1[i] + A62 * k2[i] + A63 * k3[i] + A64 * k4[i] + A65 * k5[i]);
    }
    sys.rhs(t1, xs, k6);
    for i in 0..n {
        x1[i] = x0[i] + h * (A71 * k1[i] + A73 * k3[i] + A74 * k4[i] + A75 * k5[i] + A76 * k6[i]);
    }
    sys.rhs(t1, x1, k7);
    let mut sum = 0.0;
    for i in 0..n {
        let e = h * (E1 * k1[i] + E3 * k3[i] + E4 * k4[i] + E5 * k5[i] + E6 * k6[i] + E7 * k7[i]);
        // MIN_POSITIVE keeps atol = 0 with a zero state from dividing 0 by 0.
        let sk = (atol + rtol * x0[i].abs().max(x1[i].abs())).max(f64::MIN_POSITIVE);
        let r = e / sk;
        sum += r * r;
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Dense output at time `t` inside the last step [t0, t0 + h] (4th order).
#[allow(clippy::too_many_arguments)]
#[inline]
pub(super) fn dense(t0: f64, h: f64, t: f64, x0: &[f64], x1: &[f64], k1: &[f64], k: &[Vec<f64>; 6], out: &mut [f64]) {
    let th = (t - t0) / h;
    let th1 = 1.0 - th;
    let n = out.len();
    let [_, k3, k4, k5, k6, k7] = k;
    let (x0, x1, k1) = (&x0[..n], &x1[..n], &k1[..n]);
    let (k3, k4, k5, k6, k7) = (&k3[..n], &k4[..n], &k5[..n], &k6[..n], &k7[..n]);
    for i in 0..n {
        let ydiff = x1[i] - x0[i];
        let bspl = h * k1[i] - ydiff;
        let r4 = ydiff - h * k7[i] - bspl;
        let r5 = h * (D1 * k1[i] + D3 * k3[i] + D4 * k4[i] + D5 * k5[i] + D6 * k6[i] + D7 * k7[i]);
        out[i] = x0[i] + th * (ydiff + th1 * (bspl + th * (r4 + th1 * r5)));
    }
}

/// Root mean square of `f(i)` over `n` components (0 for an empty state).
#[inline]
fn rms(n: usize, f: impl Fn(usize) -> f64) -> f64 {
    if n == 0 {
        return 0.0;
    }
    ((0..n).map(|i| f(i) * f(i)).sum::<f64>() / n as f64).sqrt()
}

/// Initial step guess (Hairer, Nørsett & Wanner, "Solving ODEs I", II.4): one
/// explicit Euler probe estimates the second derivative; costs one rhs call.
#[allow(clippy::too_many_arguments)]
pub(super) fn initial_step<S: OdeSystem>(
    sys: &S,
    t0: f64,
    x0: &[f64],
    f0: &[f64],
    hmax: f64,
    rtol: f64,
    atol: f64,
    x1: &mut [f64],
    f1: &mut [f64],
) -> f64 {
    let n = x0.len();
    let sk = |i: usize| (atol + rtol * x0[i].abs()).max(f64::MIN_POSITIVE);
    let dnf = rms(n, |i| f0[i] / sk(i));
    let dny = rms(n, |i| x0[i] / sk(i));
    let mut h = if dnf <= 1e-5 || dny <= 1e-5 { 1e-6 } else { 0.01 * dny / dnf };
    h = h.min(hmax);
    for i in 0..n {
        x1[i] = x0[i] + h * f0[i];
    }
    sys.rhs(t0 + h, x1, f1);
    let der2 = rms(n, |i| (f1[i] - f0[i]) / sk(i)) / h;
    // f64::max ignores a NaN probe, falling back on the first-derivative bound.
    let der12 = der2.max(dnf);
    let h1 = if der12 <= 1e-15 { (h * 1e-3).max(1e-6) } else { (0.01 / der12).powf(1.0 / 5.0) };
    h = (100.0 * h).min(h1).min(hmax);
    if h.is_finite() && h > 0.0 {
        h
    } else {
        hmax.min(1e-6)
    }
}
