//! The adaptive methods' common loop: embedded Runge–Kutta pairs with error control (the
//! classical controller, h_new = h (0.9 / err)^(1/q)), FSAL, the initial-step heuristic, dense
//! output and event location on it.
//! Each method (dopri5.rs, bs23.rs, dop853.rs) supplies its tableau as a [`Scheme`].
//!
//! Steps go where the error control takes them, across the `t_end` of `advance`: a step that
//! ends past `t_end` becomes the pending step, and its dense output is built (for DOP853 that
//! costs three more right-hand-side evaluations), so later `advance` calls inside it only
//! interpolate. Steps end at the stop time at the latest, and at an event.

use super::events;
use super::{all_finite, step_floor, Integrator, OdeSystem, SolverError, EVENT_TOL, MAX_STEPS_PER_CALL, STAGE_BUFFERS};

/// Safety factor: aim a little below the tolerance so the next step is likely accepted.
const SAFE: f64 = 0.9;
/// After a NaN/inf trial, retry with this fraction of the step, at most `MAX_NONFINITE` times in a row.
const NONFINITE_SHRINK: f64 = 0.2;
const MAX_NONFINITE: u32 = 40;

/// The stage-derivative buffers k2, k3, ... of one step.
pub(super) type Stages = [Vec<f64>; STAGE_BUFFERS];

/// An embedded Runge–Kutta pair with a continuous extension.
pub(super) trait Scheme {
    /// Right-hand-side evaluations per step attempt (the first stage is the last step's last).
    const STAGES: u64;
    /// Index in [`Stages`] of f(t1, x1), which becomes the next step's first stage.
    const LAST: usize;
    /// The initial step is (0.01 / |x''|)^(1/ORDER): the local order of the error estimate.
    const ORDER: i32;
    /// Controller exponent: h_new = h / (err^EXPO1 / SAFE), clamped; 1/q for an error estimate
    /// of local order q.
    const EXPO1: f64;

    /// err^EXPO1.
    #[inline]
    fn power(err: f64) -> f64 {
        err.powf(Self::EXPO1)
    }
    /// Largest shrink (h_new >= SHRINK h) and growth (h_new <= GROWTH h) per step.
    const SHRINK: f64;
    const GROWTH: f64;
    /// The extra right-hand-side evaluations that building the dense output costs (its
    /// coefficient vectors number at most `DENSE_COEFFICIENTS`).
    const DENSE_RHS: u64;

    /// One trial step of size `h` from (t, x0) with k1 = f(t, x0), ending at the exact time
    /// `t1`: writes x1 and the stages (f(t1, x1) at `LAST`); returns the scaled RMS error
    /// estimate (non-finite if anything overflowed).
    #[allow(clippy::too_many_arguments)]
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
    ) -> f64;

    /// The dense-output coefficients of the accepted step [t, t + h] from x0 to x1.
    #[allow(clippy::too_many_arguments)]
    fn fill_dense<S: OdeSystem>(
        sys: &S,
        t: f64,
        h: f64,
        x0: &[f64],
        x1: &[f64],
        k1: &[f64],
        k: &mut Stages,
        xs: &mut [f64],
        dense: &mut [f64],
    );

    /// The dense output at the fraction `th` of the step, from `n`-long coefficient vectors.
    fn eval(th: f64, n: usize, dense: &[f64], out: &mut [f64]);
}

/// The dense output of scheme `M` at the fraction `th` of its step.
#[inline]
pub(super) fn interpolate<M: Scheme>(th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
    M::eval(th, n, dense, out)
}

/// The error weight of one component, atol + rtol max(|x0|, |x1|), at least MIN_POSITIVE (which
/// keeps atol = 0 with a zero state from dividing 0 by 0). Compares instead of `f64::max`, whose
/// NaN rule costs four instructions a call and keeps the loop scalar; the two agree for every
/// non-NaN value. A NaN in x1 (never in x0, which is checked) gives another weight than
/// `f64::max` would, but such a trial step is refused by the state check after it either way.
#[inline(always)]
pub(super) fn weight(atol: f64, rtol: f64, x0: f64, x1: f64) -> f64 {
    let (a, b) = (x0.abs(), x1.abs());
    let w = atol + rtol * if a > b { a } else { b };
    if w > f64::MIN_POSITIVE {
        w
    } else {
        f64::MIN_POSITIVE
    }
}

/// The smaller and the larger of two times or step sizes of the loop below, by one compare
/// each: f64::min and max spend four instructions a call on their NaN rule, and no NaN gets
/// here (a non-finite trial step never reaches the controller; the stop time and `t_end` are
/// checked by `advance`). For every other value they give the same result.
#[inline(always)]
fn smaller(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn larger(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// The controller's divisor for the next step (h_next = h / factor) after an accepted step.
#[inline]
fn step_factor<M: Scheme>(err: f64) -> f64 {
    larger(smaller(M::power(err) / SAFE, 1.0 / M::SHRINK), 1.0 / M::GROWTH)
}

impl Integrator {
    /// Steps of scheme `M` from `t_int` until a step reaches `t_end` or an event is located.
    /// On return `t_int`/`x_int` is the end of the last step (or the event, recorded in
    /// `event`), and when `t_int > t_end` the dense output of that step is filled.
    pub(super) fn advance_adaptive<S: OdeSystem, M: Scheme>(&mut self, sys: &S, t_end: f64) -> Result<(), SolverError> {
        let (rtol, atol) = (self.settings.rtol, self.settings.atol);
        let h_max = self.settings.step_limit();
        // Steps end at the stop time, unless the caller asks for a later point.
        let limit = larger(self.stop_time, t_end);
        let n = sys.dim();
        let mut nonfinite = 0u32;
        let (budget, accepted_before) = (self.attempts() + MAX_STEPS_PER_CALL, self.n_steps);
        loop {
            if self.attempts() >= budget {
                return Err(self.too_many_steps(self.t_int, accepted_before));
            }
            let tc = self.t_int;
            if !self.fsal_valid {
                sys.rhs(tc, &self.x_int, &mut self.k1);
                self.n_rhs += 1;
                // No step size can repair a bad starting point.
                if !(all_finite(&self.k1) && all_finite(&self.x_int)) {
                    return Err(SolverError::NonFinite { t: tc });
                }
                self.fsal_valid = true;
            }
            if self.h <= 0.0 {
                let w = &mut self.work;
                let [k2, ..] = &mut w.k;
                self.h = initial_step(sys, tc, &self.x_int, &self.k1, (limit - tc).min(h_max), M::ORDER, rtol, atol, &mut w.xs, k2);
                self.n_rhs += 1;
            }
            let h_prop = smaller(self.h, h_max);
            let remaining = limit - tc;
            // Land exactly on the limit; stretching a step by up to 1% (within max_step) avoids
            // a sliver step afterwards.
            let lands = smaller(1.01 * h_prop, h_max) >= remaining;
            let hs = if lands { remaining } else { h_prop };
            if !lands && h_prop < step_floor(tc) {
                return Err(SolverError::StepSizeTooSmall { t: tc, h: h_prop });
            }
            let t1 = if lands { limit } else { tc + hs };
            let w = &mut self.work;
            let err = M::step(sys, tc, hs, t1, &self.x_int, &self.k1, &mut w.k, &mut w.xs, &mut w.next, rtol, atol);
            self.n_rhs += M::STAGES;
            if !(err.is_finite() && all_finite(&w.next[..n])) {
                // Often an overflow from a far too large trial step: retry smaller first.
                nonfinite += 1;
                self.n_rejected += 1;
                self.last_rejected = true;
                let h_retry = hs * NONFINITE_SHRINK;
                if nonfinite > MAX_NONFINITE || h_retry < step_floor(tc) {
                    return Err(SolverError::NonFinite { t: t1 });
                }
                self.h = h_retry;
                continue;
            }
            nonfinite = 0;
            if err > 1.0 {
                self.h = hs / (M::power(err) / SAFE).min(1.0 / M::SHRINK);
                self.last_rejected = true;
                self.n_rejected += 1;
                continue;
            }
            let mut h_new = hs / step_factor::<M>(err);
            if self.last_rejected {
                h_new = smaller(h_new, hs);
            }
            // A step clipped to land on the stop time says nothing about the step the solution
            // allows: it does not shrink the proposal.
            self.h = if hs < h_prop { larger(self.h, h_new) } else { h_new };
            self.last_rejected = false;
            self.n_steps += 1;
            // The crossing search runs from `ta`, where the indicators are `w.za`.
            let mut ta = tc;
            let mut filled = false;
            let mut crossed = false;
            if self.n_ind > 0 {
                sys.event_indicators(t1, &w.next, &mut w.zn);
                if self.z_left.contains(&0.0) {
                    // An indicator on its threshold at the step start (just after an event, a
                    // ball on the floor) waits until it leaves zero; a long step may take it off
                    // and back, so its reference is the sign it has just after the start, on the
                    // dense output (EVENT_TOL later: an event closer than that is not told apart).
                    M::fill_dense(sys, tc, hs, &self.x_int, &w.next, &self.k1, &mut w.k, &mut w.xs, &mut self.dense);
                    self.n_rhs += M::DENSE_RHS;
                    (self.dense_t0, self.dense_h, filled) = (tc, hs, true);
                    let tp = tc + EVENT_TOL.max(16.0 * f64::EPSILON * tc.abs()).min(0.5 * hs);
                    M::eval((tp - tc) / hs, n, &self.dense, &mut w.xs);
                    sys.event_indicators(tp, &w.xs, &mut w.za);
                    if events::any_crossed(&self.z_left, &w.za) {
                        // Another indicator crossed within EVENT_TOL of the start: the event is here.
                        std::mem::swap(&mut self.x_int, &mut w.xs);
                        self.event = Some(events::fired(&self.z_left, &w.za));
                        self.z_left.copy_from_slice(&w.za);
                        self.fsal_valid = false;
                        self.t_int = tp;
                        return Ok(());
                    }
                    for (r, z) in self.z_left.iter_mut().zip(&w.za) {
                        if *r == 0.0 {
                            *r = *z;
                        }
                    }
                    ta = tp;
                } else {
                    w.za.copy_from_slice(&self.z_left);
                }
                crossed = events::any_crossed(&self.z_left, &w.zn);
            }
            if (crossed || t1 > t_end) && !filled {
                // The caller will need values inside this step: build its dense output.
                M::fill_dense(sys, tc, hs, &self.x_int, &w.next, &self.k1, &mut w.k, &mut w.xs, &mut self.dense);
                self.n_rhs += M::DENSE_RHS;
                (self.dense_t0, self.dense_h) = (tc, hs);
            }
            if crossed {
                w.zb.copy_from_slice(&w.zn);
                let (dense, xs) = (&self.dense, &mut w.xs);
                let tb = events::locate(ta, t1, &self.z_left, &mut w.za, &mut w.zb, &mut w.zm, |tm, z| {
                    M::eval((tm - tc) / hs, n, dense, xs);
                    sys.event_indicators(tm, xs, z);
                });
                // No step goes past the event: integration has got to it, and the part of the
                // step after it is dropped (its dense output still serves times before it).
                if tb == t1 {
                    std::mem::swap(&mut self.x_int, &mut w.next);
                } else {
                    M::eval((tb - tc) / hs, n, &self.dense, &mut self.x_int);
                }
                self.event = Some(events::fired(&self.z_left, &w.zb));
                self.z_left.copy_from_slice(&w.zb);
                // The derivative at the event point was never computed.
                self.fsal_valid = false;
                self.t_int = tb;
                return Ok(());
            }
            if self.n_ind > 0 {
                self.z_left.copy_from_slice(&w.zn);
            }
            std::mem::swap(&mut self.k1, &mut w.k[M::LAST]);
            std::mem::swap(&mut self.x_int, &mut w.next);
            self.t_int = t1;
            if t1 >= t_end {
                return Ok(());
            }
        }
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

/// Initial step guess (Hairer, Nørsett & Wanner, "Solving ODEs I", II.4): one explicit Euler
/// probe estimates the second derivative; costs one rhs call. `order` is the local order of the
/// method's error estimate.
#[allow(clippy::too_many_arguments)]
pub(super) fn initial_step<S: OdeSystem>(
    sys: &S,
    t0: f64,
    x0: &[f64],
    f0: &[f64],
    hmax: f64,
    order: i32,
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
    let h1 = if der12 <= 1e-15 { (h * 1e-3).max(1e-6) } else { (0.01 / der12).powf(1.0 / order as f64) };
    h = (100.0 * h).min(h1).min(hmax);
    if h.is_finite() && h > 0.0 {
        h
    } else {
        hmax.min(1e-6)
    }
}
