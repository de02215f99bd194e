//! Variable-order (1 to 5), variable-step BDF, CVODE's class of method for stiff systems, in
//! the quasi-constant-step form of Shampine & Reichelt's ode15s and scipy's `BDF` (the pure BDF
//! coefficients, not ode15s's NDF ones): the history is the array of modified divided
//! differences of the solution on an equally spaced grid, which a step-size change
//! re-interpolates. Each step predicts from the differences, solves the implicit formula by a
//! simplified Newton iteration with the shared iteration matrix (implicit.rs), estimates the
//! local error from the corrector's correction, and every `order + 1` steps at one step size
//! picks the order (k - 1, k or k + 1) whose estimated error allows the longest step, with
//! CVODE's biases towards shorter steps (and a further one against raising the order), and
//! after a failed attempt keeps step and order for one step, as CVODE does. The
//! dense output is the interpolating polynomial of the differences. A restart (the first
//! step, an event, new inputs) begins at order 1 with a fresh initial step and Jacobian.

use super::adaptive::initial_step;
use super::implicit::{scaled_rms, Dense};
use super::{all_finite, step_floor, Integrator, OdeSystem, SolverError, MAX_STEPS_PER_CALL};

/// Highest order.
pub(super) const MAX_ORDER: usize = 5;
/// Step-size control, CVODE's biases: the step that an error estimate e of local order p
/// allows is h / ((BIAS e)^(1/p) + 1e-6), with a larger bias for the estimate at order k + 1
/// (a difference of two corrections, so less certain). The bias keeps the steps well inside
/// the tolerance, which costs fewer rejected steps and Newton iterations than it costs steps
/// (measured in tests/bench/stiff).
const BIAS: f64 = 6.0;
const BIAS_HIGHER: f64 = 10.0;
/// Largest growth of the step at one change.
const MAX_FACTOR: f64 = 10.0;
/// After a failed error test the step shrinks to at least this fraction, and from the second
/// failure in a row to at most `SHRINK_REPEATED`.
const MIN_FACTOR: f64 = 0.1;
const SHRINK_REPEATED: f64 = 0.2;
/// The step after a Newton failure, as a fraction of the failed one (CVODE's etacf).
const NEWTON_FAILURE_FACTOR: f64 = 0.25;
/// Failed step attempts in a row (error tests, CVODE's mxnef1, or Newton iterations) after
/// which the history restarts at order 1.
const ORDER_ONE_AFTER: u32 = 3;

/// gamma_k = sum_{j<=k} 1/j: the BDF's coefficients in the difference form; alpha_k = gamma_k
/// for the pure BDF.
const GAMMA: [f64; MAX_ORDER + 1] = [
    0.0,
    1.0,
    1.0 + 1.0 / 2.0,
    1.0 + 1.0 / 2.0 + 1.0 / 3.0,
    1.0 + 1.0 / 2.0 + 1.0 / 3.0 + 1.0 / 4.0,
    1.0 + 1.0 / 2.0 + 1.0 / 3.0 + 1.0 / 4.0 + 1.0 / 5.0,
];

/// The local error constant of order k: 1 / (k + 1).
fn error_constant(k: usize) -> f64 {
    1.0 / (k as f64 + 1.0)
}

/// The matrix R(order, factor) of ode15s that re-interpolates the differences on a grid
/// `factor` times as wide (row-major, (order + 1)^2).
fn interpolation_matrix(order: usize, factor: f64, r: &mut [f64; (MAX_ORDER + 1) * (MAX_ORDER + 1)]) {
    let m = order + 1;
    r[..m].fill(1.0);
    for i in 1..m {
        for j in 0..m {
            let entry = if j == 0 { 0.0 } else { (i as f64 - 1.0 - factor * j as f64) / i as f64 };
            r[i * m + j] = r[(i - 1) * m + j] * entry;
        }
    }
}

/// Re-interpolates the first `order + 1` differences (rows of `n`) for a step `factor` times
/// the current one: D <- (R U)^T D.
pub(super) fn change_differences(d: &mut [f64], n: usize, order: usize, factor: f64) {
    if factor == 1.0 {
        return;
    }
    let m = order + 1;
    let mut r = [0.0; (MAX_ORDER + 1) * (MAX_ORDER + 1)];
    let mut u = [0.0; (MAX_ORDER + 1) * (MAX_ORDER + 1)];
    interpolation_matrix(order, factor, &mut r);
    interpolation_matrix(order, 1.0, &mut u);
    let mut ru = [0.0; (MAX_ORDER + 1) * (MAX_ORDER + 1)];
    for i in 0..m {
        for j in 0..m {
            ru[i * m + j] = (0..m).map(|k| r[i * m + k] * u[k * m + j]).sum();
        }
    }
    let mut column = [0.0; MAX_ORDER + 1];
    for c in 0..n {
        for (j, out) in column.iter_mut().enumerate().take(m) {
            *out = (0..m).map(|i| ru[i * m + j] * d[i * n + c]).sum();
        }
        for j in 0..m {
            d[j * n + c] = column[j];
        }
    }
}

/// Re-interpolates the history for a step `factor` times the current one and scales the last
/// correction (row `order + 1`, of size h^(order+1)) with it, so the next step's difference of
/// corrections estimates the error at order + 1 even across a step change.
fn rescale(d: &mut [f64], n: usize, order: usize, factor: f64) {
    if factor == 1.0 {
        return;
    }
    change_differences(d, n, order, factor);
    let s = factor.powi(order as i32 + 1);
    d[(order + 1) * n..(order + 2) * n].iter_mut().for_each(|v| *v *= s);
}

/// The step factor that an error estimate `error` of local order `p` allows, with a bias.
fn allowed_factor(error: f64, bias: f64, p: usize) -> f64 {
    1.0 / ((bias * error).powf(1.0 / p as f64) + 1e-6)
}

/// The dense output of order `order` at fraction `th` of the last step: the polynomial through
/// the solution at the step's end and `order` points spaced by the step before it, from the
/// differences: D_0 + sum_j D_j prod_{m<j} (th - 1 + m) / (m + 1).
pub(super) fn eval(order: usize, th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
    out[..n].copy_from_slice(&dense[..n]);
    let mut p = 1.0;
    for j in 1..=order {
        p *= (th - 1.0 + (j - 1) as f64) / j as f64;
        let row = &dense[j * n..(j + 1) * n];
        for (o, dj) in out[..n].iter_mut().zip(row) {
            *o += p * dj;
        }
    }
}

/// How one attempt at a step ended.
enum Attempt {
    /// Newton converged.
    Converged,
    /// Newton did not converge, or met a non-finite value (the step shrinks).
    Failed,
}

impl Integrator {
    /// BDF steps from `t_int` until one reaches `t_end` or an event is located (the contract of
    /// `advance_adaptive`): afterwards the dense output of the last step is filled.
    pub(super) fn advance_bdf<S: OdeSystem>(&mut self, sys: &S, t_end: f64) -> Result<(), SolverError> {
        let (rtol, atol) = (self.settings.rtol, self.settings.atol);
        let h_max = self.settings.step_limit();
        let limit = t_end.max(self.stop_time);
        let n = sys.dim();
        self.implicit.prepare(sys, n);
        let mut failures = 0u32;
        let mut error_failures = 0u32;
        let (budget, accepted_before) = (self.attempts() + MAX_STEPS_PER_CALL, self.n_steps);
        loop {
            if self.attempts() >= budget {
                return Err(self.too_many_steps(self.t_int, accepted_before));
            }
            let tc = self.t_int;
            if !self.fsal_valid {
                self.restart_bdf(sys, tc, (limit - tc).min(h_max))?;
            }
            let mut h = self.h;
            let order = self.implicit.order;
            let d = &mut self.implicit.differences;
            if h > h_max {
                rescale(d, n, order, h_max / h);
                h = h_max;
                self.implicit.equal_steps = 0;
            }
            let remaining = limit - tc;
            let lands = 1.01 * h >= remaining;
            if lands {
                rescale(d, n, order, remaining / h);
                h = remaining;
                self.implicit.equal_steps = 0;
            } else if h < step_floor(tc) {
                return Err(SolverError::StepSizeTooSmall { t: tc, h });
            }
            self.h = h;
            let t1 = if lands { limit } else { tc + h };
            let c = h / GAMMA[order];
            let [y_pred, psi, f_pred, ..] = &mut self.work.k;
            for i in 0..n {
                y_pred[i] = (0..=order).map(|j| d[j * n + i]).sum();
                psi[i] = (1..=order).map(|j| GAMMA[j] * d[j * n + i]).sum::<f64>() / GAMMA[order];
            }
            self.implicit.jac_current = false;
            sys.rhs(t1, y_pred, f_pred);
            self.n_rhs += 1;
            let mut attempt = Attempt::Failed;
            if all_finite(&f_pred[..n]) && self.implicit.setup(sys, t1, y_pred, f_pred, c, h, rtol, atol) {
                loop {
                    attempt = self.bdf_newton(sys, t1, c, order, n);
                    if matches!(attempt, Attempt::Converged) || self.implicit.jac_current {
                        break;
                    }
                    // Slow convergence with an old Jacobian: evaluate it again and retry.
                    let [y_pred, _, f_pred, ..] = &self.work.k;
                    if !self.implicit.refresh(sys, t1, y_pred, f_pred, c, h, rtol, atol) {
                        break;
                    }
                }
            }
            let Attempt::Converged = attempt else {
                self.implicit.n_newton_failures += 1;
                self.n_rejected += 1;
                failures += 1;
                let h_next = h * NEWTON_FAILURE_FACTOR;
                if failures > 40 || h_next < step_floor(tc) {
                    return Err(if all_finite(&self.work.k[2][..n]) {
                        SolverError::StepSizeTooSmall { t: tc, h: h_next }
                    } else {
                        SolverError::NonFinite { t: t1 }
                    });
                }
                error_failures += 1;
                self.implicit.hold = true;
                if error_failures >= ORDER_ONE_AFTER && order > 1 {
                    self.restart_differences(sys, tc, h_next)?;
                    continue;
                }
                rescale(&mut self.implicit.differences, n, order, NEWTON_FAILURE_FACTOR);
                self.h = h_next;
                continue;
            };
            failures = 0;
            let y = &self.work.next;
            let corr = &self.work.k[5];
            let error = error_constant(order) * scaled_rms(&corr[..n], &y[..n], rtol, atol);
            // A NaN error fails the test too.
            if error.is_nan() || error > 1.0 {
                self.n_rejected += 1;
                error_failures += 1;
                self.implicit.hold = true;
                if error_failures >= ORDER_ONE_AFTER {
                    // The history no longer predicts the solution (CVODE's rule after three
                    // failed error tests): order 1 from the last point, a tenth of the step.
                    self.restart_differences(sys, tc, h * 0.1)?;
                    continue;
                }
                let mut factor = if error.is_finite() { allowed_factor(error, BIAS, order + 1).max(MIN_FACTOR) } else { MIN_FACTOR };
                if error_failures >= 2 {
                    factor = factor.min(SHRINK_REPEATED);
                }
                rescale(&mut self.implicit.differences, n, order, factor);
                self.h = h * factor;
                continue;
            }
            error_failures = 0;
            self.accept_bdf_step(n, order, h, error, h_max, rtol, atol);
            (self.dense_t0, self.dense_h) = (tc, h);
            if self.end_implicit_step(sys, tc, t1, Dense::Bdf(order)) || t1 >= t_end {
                return Ok(());
            }
        }
    }

    /// Starts the history at (t_int, x_int): order 1, the initial-step heuristic, no Jacobian
    /// (the right-hand side may have changed at an event).
    fn restart_bdf<S: OdeSystem>(&mut self, sys: &S, tc: f64, h_limit: f64) -> Result<(), SolverError> {
        let n = sys.dim();
        sys.rhs(tc, &self.x_int, &mut self.k1);
        self.n_rhs += 1;
        if !(all_finite(&self.k1[..n]) && all_finite(&self.x_int[..n])) {
            return Err(SolverError::NonFinite { t: tc });
        }
        let [xs, fs, ..] = &mut self.work.k;
        // The local error of BDF1 is of order 2.
        self.h = initial_step(sys, tc, &self.x_int, &self.k1, h_limit, 2, self.settings.rtol, self.settings.atol, xs, fs);
        self.n_rhs += 1;
        self.set_order_one(n);
        self.implicit.jac_valid = false;
        self.fsal_valid = true;
        Ok(())
    }

    /// The history from (t_int, x_int) at order 1 for a step `h` (f there evaluated again).
    fn restart_differences<S: OdeSystem>(&mut self, sys: &S, tc: f64, h: f64) -> Result<(), SolverError> {
        let n = sys.dim();
        sys.rhs(tc, &self.x_int, &mut self.k1);
        self.n_rhs += 1;
        if !all_finite(&self.k1[..n]) {
            return Err(SolverError::NonFinite { t: tc });
        }
        if h < step_floor(tc) {
            return Err(SolverError::StepSizeTooSmall { t: tc, h });
        }
        self.h = h;
        self.set_order_one(n);
        Ok(())
    }

    /// D_0 = x_int, D_1 = h f(t_int, x_int) (in `k1`), order 1.
    fn set_order_one(&mut self, n: usize) {
        let d = &mut self.implicit.differences;
        d.fill(0.0);
        d[..n].copy_from_slice(&self.x_int[..n]);
        for i in 0..n {
            d[n + i] = self.h * self.k1[i];
        }
        self.implicit.order = 1;
        self.implicit.equal_steps = 0;
        self.implicit.hold = false;
    }

    /// The corrector of one BDF step: y = (y_pred - psi) + c f(t1, y) by the shared Newton
    /// iteration from the prediction `k[0]` (f there in `k[2]`); y in `next`, the correction
    /// y - y_pred in `k[5]`. CVODE's test: the iteration's error within a tenth of what the
    /// local error test allows at this order.
    fn bdf_newton<S: OdeSystem>(&mut self, sys: &S, t1: f64, c: f64, order: usize, n: usize) -> Attempt {
        let [y_pred, psi, f_pred, f, dy, corr, guess, ..] = &mut self.work.k;
        let y = &mut self.work.next;
        for i in 0..n {
            corr[i] = y_pred[i] - psi[i];
        }
        y[..n].copy_from_slice(&y_pred[..n]);
        let tol = 0.1 / error_constant(order);
        let tolerances = (self.settings.rtol, self.settings.atol);
        let scratch = (&mut f[..n], &mut dy[..n], &mut guess[..n]);
        match self.implicit.newton(sys, t1, c, &corr[..n], &mut y[..n], &f_pred[..n], scratch, tol, tolerances, &mut self.n_rhs) {
            Some(_) => {
                for i in 0..n {
                    corr[i] = y[i] - y_pred[i];
                }
                Attempt::Converged
            }
            None => Attempt::Failed,
        }
    }

    /// Takes the accepted step into the differences and, after `order + 1` steps at one step
    /// size and order, chooses the next order (k - 1, k or k + 1, whichever allows the longest
    /// step, ties kept at k) and step size (scipy's timing, CVODE's biases). The step after a
    /// failed attempt keeps the step and order (CVODE's rule: the failure showed the estimates
    /// too optimistic).
    #[allow(clippy::too_many_arguments)]
    fn accept_bdf_step(&mut self, n: usize, order: usize, h: f64, error: f64, h_max: f64, rtol: f64, atol: f64) {
        self.n_steps += 1;
        let im = &mut self.implicit;
        im.jac_age += 1;
        im.equal_steps += 1;
        let d = &mut im.differences;
        let corr = &self.work.k[5];
        for i in 0..n {
            d[(order + 2) * n + i] = corr[i] - d[(order + 1) * n + i];
            d[(order + 1) * n + i] = corr[i];
        }
        for j in (0..=order).rev() {
            for i in 0..n {
                d[j * n + i] += d[(j + 1) * n + i];
            }
        }
        // The dense output of this step: the differences of its order, on its grid (before
        // they are re-interpolated for the next step).
        self.dense[..(order + 1) * n].copy_from_slice(&d[..(order + 1) * n]);
        im.dense_order = order;
        self.h = h;
        if std::mem::take(&mut im.hold) || im.equal_steps <= order {
            return;
        }
        let y = &self.work.next;
        let norm_of = |row: usize, k: usize| error_constant(k) * scaled_rms(&d[row * n..(row + 1) * n], &y[..n], rtol, atol);
        let here = allowed_factor(error, BIAS, order + 1);
        let lower = if order > 1 { allowed_factor(norm_of(order, order - 1), BIAS, order) } else { 0.0 };
        let higher = if order < MAX_ORDER { allowed_factor(norm_of(order + 2, order + 1), BIAS_HIGHER, order + 2) } else { 0.0 };
        let (factor, new_order) = if lower > here && lower >= higher {
            (lower, order - 1)
        } else if higher > here {
            (higher, order + 1)
        } else {
            (here, order)
        };
        let factor = factor.min(MAX_FACTOR).min(h_max / h);
        rescale(d, n, new_order, factor);
        im.order = new_order;
        im.equal_steps = 0;
        self.h = h * factor;
    }
}
