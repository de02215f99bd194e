//! ESDIRK3(2)4L[2]SA, the implicit part of Kennedy & Carpenter's additive Runge–Kutta method
//! ARK3(2)4L[2]SA (Appl. Numer. Math. 44, 2003): four stages, the first explicit and three
//! implicit with one diagonal coefficient gamma, so every stage solves with the same iteration
//! matrix I - h gamma J; L-stable and stiffly accurate (the solution is the last stage, so no
//! stiff component is amplified), third order with an embedded second-order solution for the
//! error estimate. The estimate is filtered through (I - h gamma J)^-1, as in Hairer & Wanner's
//! RADAU5, so that stiff components that the method damps do not inflate it. The dense output
//! is the cubic Hermite interpolant on the step's ends (third order, like the method).

use super::adaptive::initial_step;
use super::implicit::{scaled_rms, Dense, NEWTON_MAX_ITER};
use super::{all_finite, step_floor, Integrator, OdeSystem, SolverError, MAX_STEPS_PER_CALL};

/// The diagonal coefficient gamma.
pub(super) const GAMMA: f64 = 1767732205903.0 / 4055673282236.0;
/// Stage times c_i.
pub(super) const C: [f64; 4] = [0.0, 2.0 * GAMMA, 3.0 / 5.0, 1.0];
/// The strictly lower part of the Butcher matrix (the diagonal is gamma for stages 2 to 4).
pub(super) const A: [[f64; 3]; 4] =
    [[0.0, 0.0, 0.0], [GAMMA, 0.0, 0.0], [2746238789719.0 / 10658868560708.0, -640167445237.0 / 6845629431997.0, 0.0], [B[0], B[1], B[2]]];
/// Third-order weights: the last row of A (stiffly accurate).
pub(super) const B: [f64; 4] =
    [1471266399579.0 / 7840856788654.0, -4482444167858.0 / 7529755066697.0, 11266239266428.0 / 11593286722821.0, GAMMA];
/// The embedded second-order weights.
pub(super) const B_HAT: [f64; 4] = [
    2756255671327.0 / 12835298489170.0,
    -10771552573575.0 / 22201958757719.0,
    9247589265047.0 / 10645013368117.0,
    2193209047091.0 / 5459859503100.0,
];

/// Step-size controller: h_new = h SAFE err^(-1/3), between SHRINK and GROWTH times h.
const SAFE: f64 = 0.9;
const SHRINK: f64 = 0.2;
const GROWTH: f64 = 5.0;
/// The step after a Newton failure, as a fraction of the failed one.
const NEWTON_FAILURE_FACTOR: f64 = 0.25;

impl Integrator {
    /// ESDIRK steps from `t_int` until one reaches `t_end` or an event is located (the contract
    /// of `advance_adaptive`).
    pub(super) fn advance_esdirk<S: OdeSystem>(&mut self, sys: &S, t_end: f64) -> Result<(), SolverError> {
        let (rtol, atol) = (self.settings.rtol, self.settings.atol);
        let h_max = self.settings.step_limit();
        let limit = t_end.max(self.stop_time);
        let n = sys.dim();
        self.implicit.prepare(sys, n);
        let mut failures = 0u32;
        let (budget, accepted_before) = (self.attempts() + MAX_STEPS_PER_CALL, self.n_steps);
        loop {
            if self.attempts() >= budget {
                return Err(self.too_many_steps(self.t_int, accepted_before));
            }
            let tc = self.t_int;
            if !self.fsal_valid {
                sys.rhs(tc, &self.x_int, &mut self.k1);
                self.n_rhs += 1;
                if !(all_finite(&self.k1[..n]) && all_finite(&self.x_int[..n])) {
                    return Err(SolverError::NonFinite { t: tc });
                }
                self.fsal_valid = true;
                self.implicit.jac_valid = false;
                self.implicit.extrapolate = false;
                if self.h <= 0.0 {
                    let [xs, fs, ..] = &mut self.work.k;
                    self.h = initial_step(sys, tc, &self.x_int, &self.k1, (limit - tc).min(h_max), 3, rtol, atol, xs, fs);
                    self.n_rhs += 1;
                }
            }
            let h_prop = self.h.min(h_max);
            let remaining = limit - tc;
            let lands = (1.01 * h_prop).min(h_max) >= remaining;
            let h = if lands { remaining } else { h_prop };
            if !lands && h < step_floor(tc) {
                return Err(SolverError::StepSizeTooSmall { t: tc, h });
            }
            let t1 = if lands { limit } else { tc + h };
            self.implicit.jac_current = false;
            let Some(iterations) = self.esdirk_stages(sys, tc, h, t1, n) else {
                self.implicit.n_newton_failures += 1;
                self.n_rejected += 1;
                self.last_rejected = true;
                failures += 1;
                let h_next = h * NEWTON_FAILURE_FACTOR;
                if failures > 40 || h_next < step_floor(tc) {
                    return Err(SolverError::NonFinite { t: t1 });
                }
                self.h = h_next;
                continue;
            };
            failures = 0;
            // The error estimate h sum (b - b_hat) k, filtered by (I - h gamma J)^-1.
            let [k2, k3, k4, err, ..] = &mut self.work.k[6..] else { unreachable!("fifteen stage buffers") };
            for i in 0..n {
                err[i] = h
                    * ((B[0] - B_HAT[0]) * self.k1[i] + (B[1] - B_HAT[1]) * k2[i] + (B[2] - B_HAT[2]) * k3[i] + (B[3] - B_HAT[3]) * k4[i]);
            }
            self.implicit.solve(&mut err[..n]);
            let error = scaled_rms(&err[..n], &self.work.next[..n], rtol, atol);
            let safety = SAFE * (2 * NEWTON_MAX_ITER + 1) as f64 / (2 * NEWTON_MAX_ITER + iterations) as f64;
            if error.is_nan() || error > 1.0 {
                let factor = if error.is_finite() { (safety * error.powf(-1.0 / 3.0)).max(SHRINK) } else { SHRINK };
                self.h = h * factor;
                self.n_rejected += 1;
                self.last_rejected = true;
                continue;
            }
            let mut factor = (safety * error.powf(-1.0 / 3.0)).min(GROWTH);
            if self.last_rejected {
                factor = factor.min(1.0);
            }
            // A step clipped to land on the stop time does not shrink the proposal.
            self.h = if h < h_prop { self.h.max(h * factor) } else { h * factor };
            self.last_rejected = false;
            self.n_steps += 1;
            self.implicit.jac_age += 1;
            // Dense output: the cubic Hermite interpolant on x0, x1 and the slopes k1, k4.
            let (x0, x1, k4) = (&self.x_int, &self.work.next, &self.work.k[8]);
            let (r0, rest) = self.dense.split_at_mut(n);
            let (r1, rest) = rest.split_at_mut(n);
            let (r2, rest) = rest.split_at_mut(n);
            let r3 = &mut rest[..n];
            for i in 0..n {
                let dx = x1[i] - x0[i];
                r0[i] = x0[i];
                r1[i] = dx;
                r2[i] = h * self.k1[i] - dx;
                r3[i] = dx - h * k4[i] - (h * self.k1[i] - dx);
            }
            (self.dense_t0, self.dense_h) = (tc, h);
            self.implicit.extrapolate = true;
            // The last stage's slope is f(t1, x1): the next step's first stage.
            std::mem::swap(&mut self.k1, &mut self.work.k[8]);
            if self.end_implicit_step(sys, tc, t1, Dense::Hermite) || t1 >= t_end {
                return Ok(());
            }
        }
    }

    /// Solves the three implicit stages of the step [tc, t1] of size h: their slopes in k[6],
    /// k[7], k[8], the solution (the last stage) in `next`. The most Newton iterations a
    /// stage took, or `None` when a stage did not converge even with a fresh Jacobian.
    fn esdirk_stages<S: OdeSystem>(&mut self, sys: &S, tc: f64, h: f64, t1: f64, n: usize) -> Option<usize> {
        let (rtol, atol) = (self.settings.rtol, self.settings.atol);
        // The stages' iteration error within 3 % of the error weight: each stage's error
        // reaches the solution (CVODE's tenth of the local tolerance, spread over three
        // stages, gave 5x the global error at rtol 1e-9).
        let tol = 0.03;
        let c = h * GAMMA;
        let mut most = 0;
        for stage in 1..4 {
            let ts = if stage == 3 { t1 } else { tc + C[stage] * h };
            // base = x0 + h sum_{j<stage} a_sj k_j, into k[0]; the guess z = base + c k_prev.
            let (stages, rest) = self.work.k.split_at_mut(6);
            let [base, z, _, _, f_guess, _] = stages else { unreachable!("six buffers") };
            let slopes = &mut rest[..3];
            for i in 0..n {
                let mut sum = A[stage][0] * self.k1[i];
                for j in 1..stage {
                    sum += A[stage][j] * slopes[j - 1][i];
                }
                base[i] = self.x_int[i] + h * sum;
                let previous = if stage == 1 { self.k1[i] } else { slopes[stage - 2][i] };
                z[i] = base[i] + c * previous;
            }
            if self.implicit.extrapolate {
                // The previous step's interpolant carried on to the stage time: a guess that
                // follows a stiff solution, where the explicit one above does not.
                let th = (ts - self.dense_t0) / self.dense_h;
                super::adaptive::interpolate::<super::bs23::Bs23>(th, n, &self.dense, z);
            }
            sys.rhs(ts, z, f_guess);
            self.n_rhs += 1;
            if !all_finite(&f_guess[..n]) || !self.implicit.setup(sys, ts, z, f_guess, c, h, rtol, atol) {
                return None;
            }
            let iterations = loop {
                let [base, z, f, dz, f_guess, guess, ..] = &mut self.work.k;
                let scratch = (&mut f[..n], &mut dz[..n], &mut guess[..n]);
                let tolerances = (rtol, atol);
                if let Some(k) =
                    self.implicit.newton(sys, ts, c, &base[..n], &mut z[..n], &f_guess[..n], scratch, tol, tolerances, &mut self.n_rhs)
                {
                    break k;
                }
                if self.implicit.jac_current {
                    return None;
                }
                // The failed iteration left the guess in k[1] (f there in k[4]): the
                // Jacobian is evaluated again at it.
                let [_, z, _, _, f_guess, ..] = &self.work.k;
                if !self.implicit.refresh(sys, ts, z, f_guess, c, h, rtol, atol) {
                    return None;
                }
            };
            most = most.max(iterations);
            // The stage's slope from the converged stage equation, k = (z - base) / (h gamma):
            // exact for the formula, and free of the error of f at an unconverged iterate.
            let (stages, rest) = self.work.k.split_at_mut(6);
            let (base, z) = (&stages[0], &stages[1]);
            for i in 0..n {
                rest[stage - 1][i] = (z[i] - base[i]) / c;
            }
            if stage == 3 {
                self.work.next[..n].copy_from_slice(&z[..n]);
            }
        }
        Some(most)
    }
}
