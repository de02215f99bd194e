//! Zero-crossing detection and location of event indicators on a dense output.

use super::EVENT_TOL;

/// Whether an indicator with reference value `r` (its sign at the last step end)
/// has changed sign at value `z`; a reference of exactly 0 never fires, so an
/// indicator that starts on its threshold must first leave it.
#[inline]
pub(super) fn crossed(r: f64, z: f64) -> bool {
    (r < 0.0 && z >= 0.0) || (r > 0.0 && z <= 0.0)
}

/// Whether any indicator changed sign relative to the reference values.
#[inline]
pub(super) fn any_crossed(z_ref: &[f64], z: &[f64]) -> bool {
    z_ref.iter().zip(z).any(|(&r, &v)| crossed(r, v))
}

/// The per-indicator `fired` flags (allocates: only called once per event).
pub(super) fn fired(z_ref: &[f64], z: &[f64]) -> Vec<bool> {
    z_ref.iter().zip(z).map(|(&r, &v)| crossed(r, v)).collect()
}

/// Cap on root-search iterations; with the bisection safeguard the bracket at
/// least halves every two iterations, so this covers any step size of interest.
const MAX_ITER: usize = 400;

/// Locates the earliest sign change in (ta, tb] and returns the right end of
/// the final bracket, which is at most `EVENT_TOL` (or a few ulps of t, if
/// larger) after the crossing.
///
/// `za` holds the indicators at `ta` (none crossed there), `zb` those at `tb`
/// (at least one crossed); on return `zb` holds the values at the returned
/// time. `eval(t, z)` evaluates the indicators on the dense output.
///
/// Method: Illinois-weighted regula falsi on every crossed indicator, taking
/// the earliest estimate (so the earliest crossing wins), with a bisection
/// whenever a secant step failed to halve the bracket.
pub(super) fn locate<F: FnMut(f64, &mut [f64])>(
    mut ta: f64,
    mut tb: f64,
    z_ref: &[f64],
    za: &mut [f64],
    zb: &mut [f64],
    zm: &mut [f64],
    mut eval: F,
) -> f64 {
    // Near large t an absolute 1e-10 s may be finer than the time grid itself.
    let tol = EVENT_TOL.max(4.0 * f64::EPSILON * ta.abs().max(tb.abs()));
    let (mut wa, mut wb) = (1.0f64, 1.0f64);
    let mut last_side = 0i8;
    let mut bisect = false;
    for _ in 0..MAX_ITER {
        let width = tb - ta;
        if width <= tol {
            break;
        }
        let mut tm = if bisect {
            ta + 0.5 * width
        } else {
            let mut frac = 1.0f64;
            for i in 0..z_ref.len() {
                if crossed(z_ref[i], zb[i]) {
                    // za[i] has the reference sign and zb[i] the other (or 0),
                    // so the ratio lies in (0, 1].
                    let fa = wa * za[i];
                    let fb = wb * zb[i];
                    let f = fa / (fa - fb);
                    if f < frac {
                        frac = f;
                    }
                }
            }
            ta + frac * width
        };
        // Keep the trial point at least tol/2 inside: every iteration shrinks
        // the bracket, and once the estimate is accurate the step past the
        // root closes the bracket to within tol.
        let d = 0.5 * tol;
        tm = tm.max(ta + d).min(tb - d);
        if !(tm > ta && tm < tb) {
            break;
        }
        eval(tm, zm);
        if any_crossed(z_ref, zm) {
            tb = tm;
            zb.copy_from_slice(zm);
            wb = 1.0;
            if last_side == 1 {
                wa *= 0.5;
            }
            last_side = 1;
        } else {
            ta = tm;
            za.copy_from_slice(zm);
            wa = 1.0;
            if last_side == -1 {
                wb *= 0.5;
            }
            last_side = -1;
        }
        bisect = !bisect && (tb - ta) > 0.5 * width;
    }
    tb
}
