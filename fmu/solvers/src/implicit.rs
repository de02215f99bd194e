//! What the implicit methods (BDF, ESDIRK) share: the Newton iteration matrix I - c J, its LU
//! factors, the Jacobian J = df/dx, the counters, and the end of an accepted step (event
//! location on the method's own dense output).
//!
//! The Jacobian comes from the system's exact directional derivatives when it provides them
//! (an FMU's `GetDirectionalDerivative`), else from forward differences of the right-hand side.
//! Either way columns that share no row of the system's dependency pattern (an FMU's
//! ModelStructure `Derivatives`) are evaluated together, one evaluation per group. J is kept
//! across steps, as CVODE keeps it: it is evaluated again only when the Newton iteration fails
//! to converge with an old one, after `JACOBIAN_MAX_AGE` steps, or after a restart (an event
//! changes the right-hand side). The LU factors follow J and c = h / alpha (BDF) or h gamma
//! (ESDIRK); a step-size change within `C_CHANGE` keeps them (a simplified Newton matrix
//! still converges), as CVODE's `dgmax` does.

use serde::{Deserialize, Serialize};

use super::events;
use super::{Integrator, OdeSystem, EVENT_TOL};

/// Newton iterations per implicit solve (CVODE's maxcor).
pub(super) const NEWTON_MAX_ITER: usize = 3;
/// The convergence rate estimate decays at most this fast from one iteration to the next
/// (CVODE's crdown).
const RATE_DECAY: f64 = 0.3;
/// An iteration whose correction grows more than this is diverging (CVODE's rdiv).
const DIVERGENCE: f64 = 2.0;
/// A relative change of c beyond this factors the iteration matrix again (CVODE's dgmax).
const C_CHANGE: f64 = 0.3;
/// Steps after which the Jacobian is evaluated again even when Newton converges (CVODE's msbj).
pub(super) const JACOBIAN_MAX_AGE: u64 = 50;

/// The state the implicit methods carry between steps; serialized with the integrator, so an
/// FMU state restored elsewhere continues bit for bit (the LU factors are recomputed from J and
/// c, which gives the same bits).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub(super) struct Implicit {
    /// df/dx, row-major (`n * n`).
    pub(super) jac: Vec<f64>,
    /// `jac` holds a Jacobian (false after a restart or before the first step).
    pub(super) jac_valid: bool,
    /// `jac` was evaluated during the current step attempt: a Newton failure cannot be blamed on it.
    pub(super) jac_current: bool,
    /// Accepted steps since `jac` was evaluated.
    pub(super) jac_age: u64,
    /// The c of the factored iteration matrix (0: none).
    pub(super) c_lu: f64,
    /// The Newton iteration's convergence rate, carried from solve to solve (CVODE's crate):
    /// a first correction small enough for it ends the iteration.
    pub(super) rate: f64,
    /// BDF: the order of the next step (1..=5) and the steps taken at it since the step size
    /// or order last changed after an accepted step.
    pub(super) order: usize,
    pub(super) equal_steps: usize,
    /// BDF: the step after a failed attempt keeps its size and order (CVODE's etamax = 1).
    #[serde(default)]
    pub(super) hold: bool,
    /// BDF: the modified divided differences, `MAX_ORDER + 3` rows of `n` (scipy's `D`).
    pub(super) differences: Vec<f64>,
    /// BDF: the order of the pending step's dense output.
    pub(super) dense_order: usize,
    /// ESDIRK: the dense output holds the step just before, whose interpolant guesses the
    /// next step's stages.
    pub(super) extrapolate: bool,
    pub(super) n_jacobians: u64,
    pub(super) n_jacobian_columns: u64,
    pub(super) n_directional: u64,
    pub(super) n_newton_failures: u64,
    #[serde(skip)]
    pub(super) work: Work,
}

/// Buffers of the implicit methods; nothing in them carries over between `advance` calls
/// except the LU factors, which are factored again from `jac` and `c_lu` after
/// deserialization (the same bits).
#[derive(Debug, Clone, Default)]
pub(super) struct Work {
    pub(super) ready: bool,
    /// LU factors of I - c_lu J (row-major) and the row swaps.
    pub(super) lu: Vec<f64>,
    pub(super) pivots: Vec<usize>,
    /// Column groups (each evaluated by one call) and, per column, the rows that depend on it.
    pub(super) groups: Vec<Vec<usize>>,
    pub(super) column_rows: Vec<Vec<usize>>,
    /// The groups again when each is a single column (else empty): a system's directional
    /// derivatives are then called with groups whose length is known to be one.
    pub(super) unit_groups: Vec<[usize; 1]>,
    /// The Jacobian's scratch vectors (state, derivatives, increments), of length n.
    pub(super) v: [Vec<f64>; 3],
}

impl Implicit {
    /// Sizes every buffer for `n` states (after construction or deserialization).
    pub(super) fn prepare<S: OdeSystem>(&mut self, sys: &S, n: usize) {
        if self.work.ready && self.work.lu.len() == n * n {
            return;
        }
        if self.jac.len() != n * n {
            self.jac = vec![0.0; n * n];
            self.jac_valid = false;
        }
        if self.differences.len() != (super::bdf::MAX_ORDER + 3) * n {
            self.differences = vec![0.0; (super::bdf::MAX_ORDER + 3) * n];
        }
        let (groups, column_rows) = column_groups(n, sys.jacobian_pattern());
        let unit_groups = groups.iter().map(|g| g[..].try_into()).collect::<Result<Vec<[usize; 1]>, _>>().unwrap_or_default();
        self.work = Work {
            ready: true,
            lu: vec![0.0; n * n],
            pivots: vec![0; n],
            groups,
            column_rows,
            unit_groups,
            v: std::array::from_fn(|_| vec![0.0; n]),
        };
        if self.c_lu != 0.0 && self.jac_valid {
            let rate = self.rate;
            self.factor(self.c_lu);
            self.rate = rate;
        } else {
            self.c_lu = 0.0;
        }
    }

    /// Makes sure I - c J is factored with a Jacobian at (t, x) (f = f(t, x)) that is recent
    /// enough: evaluates J when it is missing or too old, factors again when c moved more than
    /// [`C_CHANGE`]. False when J or the factors are unusable (non-finite values, a singular
    /// matrix): the caller reduces the step.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn setup<S: OdeSystem>(&mut self, sys: &S, t: f64, x: &[f64], f: &[f64], c: f64, h: f64, rtol: f64, atol: f64) -> bool {
        if (!self.jac_valid || self.jac_age >= JACOBIAN_MAX_AGE) && !self.evaluate_jacobian(sys, t, x, f, h, rtol, atol) {
            return false;
        }
        if self.c_lu == 0.0 || ((c - self.c_lu) / self.c_lu).abs() > C_CHANGE {
            return self.factor(c);
        }
        true
    }

    /// Evaluates J again (after a Newton failure with an old one); false when it failed.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn refresh<S: OdeSystem>(&mut self, sys: &S, t: f64, x: &[f64], f: &[f64], c: f64, h: f64, rtol: f64, atol: f64) -> bool {
        self.evaluate_jacobian(sys, t, x, f, h, rtol, atol) && self.factor(c)
    }

    /// Factors I - c J; false when it is singular or not finite.
    pub(super) fn factor(&mut self, c: f64) -> bool {
        let n = self.work.pivots.len();
        let lu = &mut self.work.lu;
        for i in 0..n {
            for j in 0..n {
                lu[i * n + j] = -c * self.jac[i * n + j];
            }
            lu[i * n + i] += 1.0;
        }
        let ok = lu_factor(lu, &mut self.work.pivots, n);
        self.c_lu = if ok { c } else { 0.0 };
        self.rate = 1.0;
        ok
    }

    /// The simplified Newton iteration for z = base + c f(t, z) from the guess in `z` (f there
    /// in `f_guess`), with CVODE's convergence test: the correction dz, scaled by the carried
    /// rate estimate, below `tol` in the error-weighted norm (weights of the guess). On
    /// success `z` holds the solution and the iterations taken are returned; on failure `z`
    /// holds the guess again. A c that differs from the factored one scales the correction
    /// by 2 / (1 + c / c_lu), as CVODE does. `f` and `dz` are scratch.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn newton<S: OdeSystem>(
        &mut self,
        sys: &S,
        t: f64,
        c: f64,
        base: &[f64],
        z: &mut [f64],
        f_guess: &[f64],
        (f, dz, guess): (&mut [f64], &mut [f64], &mut [f64]),
        tol: f64,
        (rtol, atol): (f64, f64),
        n_rhs: &mut u64,
    ) -> Option<usize> {
        let n = z.len();
        guess[..n].copy_from_slice(z);
        let scale = if self.c_lu == c { 1.0 } else { 2.0 / (1.0 + c / self.c_lu) };
        let mut old = 0.0;
        for k in 0..NEWTON_MAX_ITER {
            if k > 0 {
                sys.rhs(t, z, f);
                *n_rhs += 1;
            }
            let fk: &[f64] = if k == 0 { f_guess } else { f };
            for i in 0..n {
                dz[i] = base[i] + c * fk[i] - z[i];
            }
            lu_solve(&self.work.lu, &self.work.pivots, &mut dz[..n]);
            if scale != 1.0 {
                dz[..n].iter_mut().for_each(|v| *v *= scale);
            }
            let norm = scaled_rms(&dz[..n], &guess[..n], rtol, atol);
            if !norm.is_finite() || (k > 0 && norm > DIVERGENCE * old) {
                break;
            }
            if k > 0 {
                self.rate = (RATE_DECAY * self.rate).max(norm / old);
            }
            for i in 0..n {
                z[i] += dz[i];
            }
            if norm * self.rate.min(1.0) <= tol {
                return Some(k + 1);
            }
            old = norm;
        }
        z.copy_from_slice(&guess[..n]);
        None
    }

    /// Solves (I - c_lu J) y = b in place.
    pub(super) fn solve(&self, b: &mut [f64]) {
        lu_solve(&self.work.lu, &self.work.pivots, b);
    }

    /// J at (t, x), f = f(t, x): exact directional derivatives when the system has them, else
    /// forward differences with CVODE's increments (sqrt(eps) |x_j|, at least a multiple of the
    /// error weight that keeps the difference above f's rounding); grouped columns.
    #[allow(clippy::too_many_arguments)]
    fn evaluate_jacobian<S: OdeSystem>(&mut self, sys: &S, t: f64, x: &[f64], f: &[f64], h: f64, rtol: f64, atol: f64) -> bool {
        let n = x.len();
        let directional = sys.provides_directional_derivative();
        let Work { groups, column_rows, unit_groups, v, .. } = &mut self.work;
        let [xs, fs, inc] = v;
        let weight = |j: usize| super::adaptive::weight(atol, rtol, x[j], x[j]);
        let min_inc = if directional {
            0.0
        } else {
            let fnorm = (f.iter().enumerate().map(|(j, fj)| (fj / weight(j)).powi(2)).sum::<f64>() / n.max(1) as f64).sqrt();
            if fnorm > 0.0 && fnorm.is_finite() {
                1000.0 * h.abs() * f64::EPSILON * n as f64 * fnorm
            } else {
                1.0
            }
        };
        self.jac.fill(0.0);
        if directional {
            // One call for all the columns, so the system places the point once.
            let jac = &mut self.jac;
            let store = |group: &[usize], column: &[f64]| {
                for &j in group {
                    for &i in &column_rows[j] {
                        jac[i * n + j] = column[i];
                    }
                }
            };
            let scratch = (&mut xs[..], &mut fs[..]);
            if unit_groups.len() == groups.len() {
                sys.directional_columns(t, x, unit_groups, scratch, store);
            } else {
                sys.directional_columns(t, x, groups, scratch, store);
            }
            self.n_directional += groups.len() as u64;
            self.n_jacobian_columns += groups.len() as u64;
        } else {
            for group in groups.iter() {
                xs.copy_from_slice(x);
                for &j in group {
                    inc[j] = (f64::EPSILON.sqrt() * x[j].abs()).max(min_inc * weight(j));
                    // The increment actually applied, after rounding.
                    xs[j] = x[j] + inc[j];
                    inc[j] = xs[j] - x[j];
                }
                sys.rhs(t, xs, fs);
                self.n_jacobian_columns += 1;
                for &j in group {
                    for &i in &column_rows[j] {
                        self.jac[i * n + j] = (fs[i] - f[i]) / inc[j];
                    }
                }
            }
        }
        self.n_jacobians += 1;
        self.jac_age = 0;
        self.jac_current = true;
        self.c_lu = 0.0;
        self.jac_valid = self.jac.iter().all(|v| v.is_finite());
        self.jac_valid
    }

    /// Forward-difference evaluations of the right-hand side so far (counted in `n_rhs` too).
    pub(super) fn difference_rhs(&self) -> u64 {
        self.n_jacobian_columns - self.n_directional
    }
}

/// Groups the columns of a Jacobian with row pattern `pattern` (for each row the columns it
/// depends on; `None`: dense) so that no two columns of a group share a row (greedy colouring
/// in column order), and lists for each column the rows that depend on it. Out-of-range column
/// indices are ignored.
pub fn column_groups(n: usize, pattern: Option<&[Vec<usize>]>) -> (Vec<Vec<usize>>, Vec<Vec<usize>>) {
    let Some(rows) = pattern.filter(|p| p.len() == n) else {
        return ((0..n).map(|j| vec![j]).collect(), (0..n).map(|_| (0..n).collect()).collect());
    };
    let mut column_rows: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, cols) in rows.iter().enumerate() {
        for &j in cols {
            if j < n && column_rows[j].last() != Some(&i) {
                column_rows[j].push(i);
            }
        }
    }
    let mut groups: Vec<Vec<usize>> = Vec::new();
    // The rows each group already touches.
    let mut touched: Vec<Vec<bool>> = Vec::new();
    for (j, rows_of_j) in column_rows.iter().enumerate() {
        let fits = |t: &Vec<bool>| rows_of_j.iter().all(|&i| !t[i]);
        let g = match touched.iter().position(fits) {
            Some(g) => g,
            None => {
                groups.push(Vec::new());
                touched.push(vec![false; n]);
                groups.len() - 1
            }
        };
        groups[g].push(j);
        for &i in rows_of_j {
            touched[g][i] = true;
        }
    }
    (groups, column_rows)
}

/// LU factorization with partial pivoting of the row-major `n` x `n` matrix `a`, in place;
/// false when a pivot is zero or not finite.
pub(super) fn lu_factor(a: &mut [f64], pivots: &mut [usize], n: usize) -> bool {
    for k in 0..n {
        let mut p = k;
        let mut best = a[k * n + k].abs();
        for i in k + 1..n {
            let v = a[i * n + k].abs();
            if v > best {
                best = v;
                p = i;
            }
        }
        pivots[k] = p;
        if !(best > 0.0 && best.is_finite()) {
            return false;
        }
        if p != k {
            for j in 0..n {
                a.swap(k * n + j, p * n + j);
            }
        }
        let pivot = a[k * n + k];
        for i in k + 1..n {
            let m = a[i * n + k] / pivot;
            a[i * n + k] = m;
            if m != 0.0 {
                for j in k + 1..n {
                    a[i * n + j] -= m * a[k * n + j];
                }
            }
        }
    }
    true
}

/// Solves A y = b in place with the factors of [`lu_factor`].
pub(super) fn lu_solve(lu: &[f64], pivots: &[usize], b: &mut [f64]) {
    let n = pivots.len();
    for (k, &p) in pivots.iter().enumerate() {
        b.swap(k, p);
    }
    for i in 0..n {
        let mut s = b[i];
        for j in 0..i {
            s -= lu[i * n + j] * b[j];
        }
        b[i] = s;
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for j in i + 1..n {
            s -= lu[i * n + j] * b[j];
        }
        b[i] = s / lu[i * n + i];
    }
}

/// Root mean square of v_i / w_i, the weights atol + rtol |x_i| (the error norm of both methods).
pub(super) fn scaled_rms(v: &[f64], x: &[f64], rtol: f64, atol: f64) -> f64 {
    let n = v.len();
    if n == 0 {
        return 0.0;
    }
    let sum: f64 = v.iter().zip(x).map(|(e, xi)| (e / super::adaptive::weight(atol, rtol, *xi, *xi)).powi(2)).sum();
    (sum / n as f64).sqrt()
}

/// The dense output of an implicit method over its last step.
#[derive(Debug, Clone, Copy)]
pub(super) enum Dense {
    /// BDF: the interpolating polynomial of the differences, of this order.
    Bdf(usize),
    /// ESDIRK: the cubic Hermite interpolant (in BS23's form).
    Hermite,
}

impl Dense {
    /// The dense output at fraction `th` of the step.
    #[inline]
    pub(super) fn eval(self, th: f64, n: usize, dense: &[f64], out: &mut [f64]) {
        match self {
            Dense::Bdf(order) => super::bdf::eval(order, th, n, dense, out),
            Dense::Hermite => super::adaptive::interpolate::<super::bs23::Bs23>(th, n, dense, out),
        }
    }
}

impl Integrator {
    /// After an accepted implicit step [tc, t1] (the state at t1 in `work.next`, its dense
    /// output in `dense`/`dense_t0`/`dense_h`): looks for sign changes of the indicators and
    /// locates the earliest on the dense output, as the explicit methods do. True when
    /// integration stopped at an event (`t_int`, `x_int`, `event` set); else `x_int` and `t_int`
    /// move to the step's end.
    pub(super) fn end_implicit_step<S: OdeSystem>(&mut self, sys: &S, tc: f64, t1: f64, dense: Dense) -> bool {
        let n = sys.dim();
        let hs = t1 - tc;
        let w = &mut self.work;
        if self.n_ind > 0 {
            sys.event_indicators(t1, &w.next, &mut w.zn);
            let mut ta = tc;
            if self.z_left.contains(&0.0) {
                // An indicator on its threshold at the start waits until it leaves it: its
                // reference is its sign just after the start (as in the explicit methods).
                let tp = tc + EVENT_TOL.max(16.0 * f64::EPSILON * tc.abs()).min(0.5 * hs);
                dense.eval((tp - self.dense_t0) / self.dense_h, n, &self.dense, &mut w.xs);
                sys.event_indicators(tp, &w.xs, &mut w.za);
                if events::any_crossed(&self.z_left, &w.za) {
                    std::mem::swap(&mut self.x_int, &mut w.xs);
                    self.event = Some(events::fired(&self.z_left, &w.za));
                    self.z_left.copy_from_slice(&w.za);
                    self.fsal_valid = false;
                    self.t_int = tp;
                    return true;
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
            if events::any_crossed(&self.z_left, &w.zn) {
                w.zb.copy_from_slice(&w.zn);
                let (d, t0, h, xs) = (&self.dense, self.dense_t0, self.dense_h, &mut w.xs);
                let tb = events::locate(ta, t1, &self.z_left, &mut w.za, &mut w.zb, &mut w.zm, |tm, z| {
                    dense.eval((tm - t0) / h, n, d, xs);
                    sys.event_indicators(tm, xs, z);
                });
                if tb == t1 {
                    std::mem::swap(&mut self.x_int, &mut w.next);
                } else {
                    dense.eval((tb - t0) / h, n, &self.dense, &mut self.x_int);
                }
                self.event = Some(events::fired(&self.z_left, &w.zb));
                self.z_left.copy_from_slice(&w.zb);
                // The history ends at the event: the method restarts there.
                self.fsal_valid = false;
                self.t_int = tb;
                return true;
            }
            self.z_left.copy_from_slice(&w.zn);
        }
        std::mem::swap(&mut self.x_int, &mut w.next);
        self.t_int = t1;
        false
    }
}
