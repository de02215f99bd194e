//! Tests of the solver module. Print-outs (run with `--nocapture`) report the
//! measured orders and errors that the assertions bound.

use super::adaptive::Scheme;
use super::*;

// ---------------------------------------------------------------- systems

/// Damped oscillator x'' + 2 zeta x' + x = 0, x(0) = 1, x'(0) = 0 (known solution).
struct Osc {
    zeta: f64,
}

impl Osc {
    fn exact(&self, t: f64) -> [f64; 2] {
        let wd = (1.0 - self.zeta * self.zeta).sqrt();
        let e = (-self.zeta * t).exp();
        let (s, c) = (wd * t).sin_cos();
        [e * (c + self.zeta / wd * s), -e * s / wd]
    }
}

impl OdeSystem for Osc {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -x[0] - 2.0 * self.zeta * x[1];
    }
}

/// x' = slope with indicators z_i = sign_i * (x - level_i).
struct Ramp {
    slope: f64,
    levels: Vec<(f64, f64)>,
}

impl OdeSystem for Ramp {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, _t: f64, _x: &[f64], dx: &mut [f64]) {
        dx[0] = self.slope;
    }
    fn n_event_indicators(&self) -> usize {
        self.levels.len()
    }
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        for (zi, &(sign, level)) in z.iter_mut().zip(&self.levels) {
            *zi = sign * (x[0] - level);
        }
    }
}

/// x' = 1 - 2t (x = t - t^2 from x(0) = 0), indicator z = x: starts at exactly 0.
struct Arch;

impl OdeSystem for Arch {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, t: f64, _x: &[f64], dx: &mut [f64]) {
        dx[0] = 1.0 - 2.0 * t;
    }
    fn n_event_indicators(&self) -> usize {
        1
    }
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = x[0];
    }
}

const G: f64 = 9.81;

/// Falling ball [height, velocity], indicator = height.
struct Ball;

impl OdeSystem for Ball {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -G;
    }
    fn n_event_indicators(&self) -> usize {
        1
    }
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = x[0];
    }
}

/// x' = -lambda x.
struct Decay {
    lambda: f64,
}

impl OdeSystem for Decay {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = -self.lambda * x[0];
    }
}

/// A model whose derivative is always NaN.
struct Broken;

impl OdeSystem for Broken {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, _t: f64, _x: &[f64], dx: &mut [f64]) {
        dx[0] = f64::NAN;
    }
}

/// x' = cos(1e4 t): needs steps far below 16 eps t when t is around 1e12.
struct FastAtLargeTime;

impl OdeSystem for FastAtLargeTime {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, t: f64, _x: &[f64], dx: &mut [f64]) {
        dx[0] = (1e4 * t).cos();
    }
}

fn settings(method: Method, fixed_step: f64, rtol: f64, atol: f64) -> Settings {
    Settings { method, fixed_step, rtol, atol, max_step: 0.0 }
}

const ALL: [Method; 7] = Method::ALL;
/// The adaptive methods.
const ADAPTIVE: [Method; 5] = [Method::Dopri5, Method::Bs23, Method::Dop853, Method::Bdf, Method::Esdirk];

fn err_inf(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn sci(v: &[f64]) -> String {
    v.iter().map(|e| format!("{e:.3e}")).collect::<Vec<_>>().join(", ")
}

fn orders(errors: &[f64]) -> Vec<f64> {
    errors.windows(2).map(|w| (w[0] / w[1]).log2()).collect()
}

// ---------------------------------------------------------------- basics

#[test]
fn method_codes_and_names_round_trip() {
    for m in ALL {
        assert_eq!(Method::from_code(m.code()), Some(m));
        assert_eq!(Method::from_name(m.name()), Some(m));
    }
    assert_eq!(Method::Euler.code(), 0);
    assert_eq!(Method::Rk4.code(), 1);
    assert_eq!(Method::Dopri5.code(), 2);
    assert_eq!(Method::Bs23.code(), 3);
    assert_eq!(Method::Dop853.code(), 4);
    assert_eq!(Method::Dopri5.name(), "dopri5");
    assert_eq!(Method::from_name("BS23"), Some(Method::Bs23));
    assert_eq!(Method::from_name("dop853"), Some(Method::Dop853));
    assert_eq!(Method::Bdf.code(), 5);
    assert_eq!(Method::Esdirk.code(), 6);
    assert_eq!(Method::from_name("BDF"), Some(Method::Bdf));
    assert_eq!(Method::from_code(7), None);
    assert_eq!(Method::from_code(-1), None);
}

#[test]
fn invalid_settings_name_the_control() {
    let msg = |s: Settings| match s.validate() {
        Err(SolverError::InvalidSettings(m)) => m,
        other => panic!("expected InvalidSettings for {s:?}, got {other:?}"),
    };
    for bad in [0.0, -1e-3, f64::NAN, f64::INFINITY] {
        assert!(msg(settings(Method::Euler, bad, 1e-6, 1e-8)).contains("fixed_step"));
        assert!(msg(settings(Method::Rk4, bad, 1e-6, 1e-8)).contains("fixed_step"));
    }
    // Dopri5 does not use fixed_step.
    assert!(settings(Method::Dopri5, 0.0, 1e-6, 1e-8).validate().is_ok());
    for bad in [0.0, -1e-6, f64::NAN, f64::INFINITY, 1e-17] {
        assert!(msg(settings(Method::Dopri5, 1e-3, bad, 1e-8)).contains("tolerance"));
    }
    for bad in [-1e-9, f64::NAN, f64::INFINITY] {
        assert!(msg(settings(Method::Dopri5, 1e-3, 1e-6, bad)).contains("abs_tol"));
    }
    assert!(settings(Method::Dopri5, 1e-3, 1e-6, 0.0).validate().is_ok());
    for bad in [-1e-3, f64::NAN, f64::INFINITY] {
        let s = Settings { max_step: bad, ..settings(Method::Rk4, 1e-3, 1e-6, 1e-8) };
        assert!(msg(s).contains("max_step"), "{bad}");
    }

    // advance reports them too, without touching the state.
    let mut integ = Integrator::new(settings(Method::Euler, -1.0, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (0.0, [1.0]);
    let e = integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 1.0).unwrap_err();
    assert!(matches!(&e, SolverError::InvalidSettings(m) if m.contains("fixed_step")), "{e}");
    assert_eq!((t, x), (0.0, [1.0]));
    // Settings are checked once, on first use; a refused first call does not count as that.
    assert!(matches!(integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 1.0), Err(SolverError::InvalidSettings(_))));

    // A wrong state length or a t_end in the past is rejected, not a panic.
    let mut integ = Integrator::new(settings(Method::Rk4, 0.1, 1e-6, 1e-8), 2, 0);
    let mut x1 = [1.0];
    assert!(matches!(integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x1, 1.0), Err(SolverError::InvalidSettings(_))));
    let mut x2 = [1.0, 0.0];
    assert!(matches!(integ.advance(&Osc { zeta: 0.0 }, &mut t, &mut x2, -1.0), Err(SolverError::InvalidSettings(_))));
}

// ---------------------------------------------------------------- orders

/// Global error at t = 2 of a fixed-step method driven through `advance`.
fn fixed_step_error(method: Method, h: f64) -> f64 {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(method, h, 1e-6, 1e-8), 2, 0);
    let (mut t, mut x) = (0.0, [1.0, 0.0]);
    // Communication intervals that are not multiples of h exercise the short final steps too.
    for k in 1..=4 {
        assert_eq!(integ.advance(&sys, &mut t, &mut x, 0.5 * k as f64), Ok(Advance::Reached));
    }
    err_inf(&x, &sys.exact(2.0))
}

// Observed orders must be within +-0.3 of the theoretical one: the step
// sequences below are in the asymptotic range (the next term of the error
// expansion changes the ratio by a few percent) and far above rounding.
const ORDER_SLACK: f64 = 0.3;

#[test]
fn euler_converges_with_order_1() {
    let errors: Vec<f64> = (0..5).map(|k| fixed_step_error(Method::Euler, 0.01 / 2f64.powi(k))).collect();
    let p = orders(&errors);
    println!("euler errors {} orders {p:.3?}", sci(&errors));
    for q in p {
        assert!((q - 1.0).abs() < ORDER_SLACK, "euler order {q}");
    }
}

#[test]
fn rk4_converges_with_order_4() {
    // 0.5 / h is not an integer for every h here: each interval ends with a short step.
    let errors: Vec<f64> = (0..5).map(|k| fixed_step_error(Method::Rk4, 0.15 / 2f64.powi(k))).collect();
    let p = orders(&errors);
    println!("rk4 errors {} orders {p:.3?}", sci(&errors));
    for q in p {
        assert!((q - 4.0).abs() < ORDER_SLACK, "rk4 order {q}");
    }
}

/// Global error at `t_end` of scheme `M` on the oscillator with n equal steps (no error control:
/// the method's own order shows).
fn scheme_fixed_error<M: Scheme>(n: usize, t_end: f64) -> f64 {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-8), 2, 0);
    let w = &mut integ.work;
    let h = t_end / n as f64;
    integ.x_int.copy_from_slice(&[1.0, 0.0]);
    sys.rhs(0.0, &integ.x_int, &mut integ.k1);
    for i in 0..n {
        let t = i as f64 * h;
        M::step(&sys, t, h, t + h, &integ.x_int, &integ.k1, &mut w.k, &mut w.xs, &mut w.next, 1e-6, 1e-8);
        std::mem::swap(&mut integ.x_int, &mut w.next);
        std::mem::swap(&mut integ.k1, &mut w.k[M::LAST]);
    }
    err_inf(&integ.x_int, &sys.exact(t_end))
}

/// The observed orders of scheme `M` over four halvings of the step from t_end / n0.
fn observed_orders<M: Scheme>(name: &str, n0: usize, t_end: f64) -> Vec<f64> {
    let errors: Vec<f64> = (0..4).map(|k| scheme_fixed_error::<M>(n0 << k, t_end)).collect();
    let p = orders(&errors);
    println!("{name} fixed-step errors {} orders {p:.3?}", sci(&errors));
    assert!(errors[3] > 5e-15, "{name}: errors must stay above rounding for the order to mean anything");
    p
}

#[test]
fn dopri5_converges_with_order_5() {
    // h = 2/16 .. 2/128: h = 0.25 is still pre-asymptotic (observed 5.3).
    for q in observed_orders::<dopri5::Dopri5>("dopri5", 16, 2.0) {
        assert!((q - 5.0).abs() < ORDER_SLACK, "dopri5 order {q}");
    }
}

#[test]
fn bs23_converges_with_order_3() {
    // h = 2/16 .. 2/128, errors 1e-5 .. 1e-8.
    for q in observed_orders::<bs23::Bs23>("bs23", 16, 2.0) {
        assert!((q - 3.0).abs() < ORDER_SLACK, "bs23 order {q}");
    }
}

#[test]
fn dop853_converges_with_order_8() {
    // Over 20 s, h = 1 .. 1/8: errors from 1e-7 to 1e-14, the last still 50 ulps of x(20) and
    // far above the rounding of 160 steps (a few 1e-17 each on this decaying solution).
    for q in observed_orders::<dop853::Dop853>("dop853", 20, 20.0) {
        assert!((q - 8.0).abs() < ORDER_SLACK, "dop853 order {q}");
    }
}

/// One step of scheme `M` of size h from the exact state at t = 0.3: (local error of the dense
/// output at a third of the step, error estimate in units of the tolerance). Checks on the way
/// that the dense output interpolates both step ends.
fn one_step<M: Scheme>(h: f64) -> (f64, f64) {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-8), 2, 0);
    let w = &mut integ.work;
    let t0 = 0.3;
    integ.x_int.copy_from_slice(&sys.exact(t0));
    sys.rhs(t0, &integ.x_int, &mut integ.k1);
    let err = M::step(&sys, t0, h, t0 + h, &integ.x_int, &integ.k1, &mut w.k, &mut w.xs, &mut w.next, 1e-6, 0.0);
    M::fill_dense(&sys, t0, h, &integ.x_int, &w.next, &integ.k1, &mut w.k, &mut w.xs, &mut integ.dense);
    M::eval(0.0, 2, &integ.dense, &mut w.xs);
    assert_eq!(w.xs, integ.x_int);
    M::eval(1.0, 2, &integ.dense, &mut w.xs);
    assert!(err_inf(&w.xs, &w.next) < 1e-15);
    // Not mid-step: at 1/2 some continuous extensions are more accurate than at other points.
    M::eval(1.0 / 3.0, 2, &integ.dense, &mut w.xs);
    (err_inf(&w.xs, &sys.exact(t0 + h / 3.0)), err)
}

/// The local orders of scheme `M`'s dense output and error estimate over three halvings of h0.
fn local_orders<M: Scheme>(name: &str, h0: f64) -> (Vec<f64>, Vec<f64>) {
    let runs: Vec<(f64, f64)> = (0..4).map(|k| one_step::<M>(h0 / 2f64.powi(k))).collect();
    let dense: Vec<f64> = runs.iter().map(|r| r.0).collect();
    let est: Vec<f64> = runs.iter().map(|r| r.1).collect();
    let (pd, pe) = (orders(&dense), orders(&est));
    println!("{name}: dense errors at a third of the step {} local orders {pd:.3?}", sci(&dense));
    println!("{name}: error estimates {} local orders {pe:.3?}", sci(&est));
    assert!(dense[3] > 1e-14, "{name}: dense errors must stay above rounding");
    (pd, pe)
}

#[test]
fn dopri5_dense_output_and_error_estimate_have_local_order_5() {
    // Both the 4th-order continuous extension and the embedded 4th-order
    // solution have local error O(h^5): halving h divides them by ~32. A wrong
    // coefficient in either table drops this to O(h^k), k <= 4.
    let (pd, pe) = local_orders::<dopri5::Dopri5>("dopri5", 0.4);
    for q in pd.into_iter().chain(pe) {
        assert!((q - 5.0).abs() < ORDER_SLACK, "local order {q}");
    }
}

#[test]
fn bs23_dense_output_has_local_order_4_and_error_estimate_3() {
    // The Hermite interpolant on 3rd-order end values and slopes is a 3rd-order continuous
    // extension (local error O(h^4)); the 2nd-order embedded solution makes the estimate O(h^3).
    let (pd, _) = local_orders::<bs23::Bs23>("bs23", 0.4);
    for q in pd {
        assert!((q - 4.0).abs() < ORDER_SLACK, "bs23 dense local order {q}");
    }
    // The estimate's h^4 term is large on this problem: its asymptotic range starts lower.
    let (_, pe) = local_orders::<bs23::Bs23>("bs23", 0.05);
    for q in pe {
        assert!((q - 3.0).abs() < ORDER_SLACK, "bs23 estimate local order {q}");
    }
}

#[test]
fn dop853_dense_output_has_local_order_8() {
    // The 7th-order continuous extension has local error O(h^8): halving h divides it by ~256.
    // Leaving out any one of the three extra stages, or a wrong row of D, drops the order.
    // (The estimate's order is not a clean power: it blends the 5th- and 3rd-order errors.)
    let (pd, _) = local_orders::<dop853::Dop853>("dop853", 1.6);
    for q in pd {
        assert!((q - 8.0).abs() < ORDER_SLACK, "dop853 dense local order {q}");
    }
}

#[test]
fn hermite_is_exact_for_cubics() {
    // p(t) = 1 + 2t - t^2 + 0.5 t^3 on [0.2, 0.7].
    let p = |t: f64| 1.0 + 2.0 * t - t * t + 0.5 * t * t * t;
    let dp = |t: f64| 2.0 - 2.0 * t + 1.5 * t * t;
    let (t0, h) = (0.2, 0.5);
    let mut out = [0.0];
    for s in [0.0, 0.1, 0.5, 0.77, 1.0] {
        let t = t0 + s * h;
        fixed::hermite(t0, h, t, &[p(t0)], &[p(t0 + h)], &[dp(t0)], &[dp(t0 + h)], &mut out);
        assert!((out[0] - p(t)).abs() < 1e-14, "s = {s}: {} vs {}", out[0], p(t));
    }
}

// ---------------------------------------------------------------- adaptive

/// Max error of adaptive method `m` on [0, 10] sampled every 0.5 s.
fn adaptive_error(m: Method, rtol: f64) -> (f64, u64) {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(m, 0.0, rtol, rtol * 1e-3), 2, 0);
    let (mut t, mut x) = (0.0, [1.0, 0.0]);
    let mut worst: f64 = 0.0;
    for k in 1..=20 {
        assert_eq!(integ.advance(&sys, &mut t, &mut x, 0.5 * k as f64), Ok(Advance::Reached));
        worst = worst.max(err_inf(&x, &sys.exact(t)));
    }
    (worst, integ.n_steps())
}

#[test]
fn adaptive_methods_meet_tolerance_and_error_falls_with_rtol() {
    for m in ADAPTIVE {
        let mut prev = f64::INFINITY;
        let mut prev_steps = 0;
        for rtol in [1e-3, 1e-5, 1e-7, 1e-9] {
            let (err, steps) = adaptive_error(m, rtol);
            println!("{m:?} rtol {rtol:e}: max global error {err:.3e} ({:.2} x rtol), {steps} steps", err / rtol);
            // Local control does not bound the global error, but on this non-stiff problem a
            // global error within a small multiple of rtol is what these controllers deliver;
            // the values between steps come from the dense output, which is as accurate. The
            // implicit methods' errors add up over more, lower-order steps, and their Newton
            // iteration stops at a tenth of the local tolerance (CVODE's rule): BDF's global
            // error here grows from 1.7x to 26x rtol over these tolerances, within 30x.
            let bound = if m.is_implicit() { 30.0 } else { 5.0 };
            assert!(err < bound * rtol, "{m:?} rtol {rtol}: error {err}");
            // Tightening by 100x must gain at least a factor 10, and cost more steps.
            assert!(err < prev / 10.0, "{m:?} rtol {rtol}: error {err} did not fall (previous {prev})");
            assert!(steps > prev_steps, "{m:?} rtol {rtol}: {steps} steps");
            (prev, prev_steps) = (err, steps);
        }
    }
}

#[test]
fn dopri5_uses_fsal_and_keeps_it_across_calls() {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-9), 2, 0);
    let (mut t, mut x) = (0.0, [1.0, 0.0]);
    for k in 1..=30 {
        integ.advance(&sys, &mut t, &mut x, 0.1 * k as f64).unwrap();
    }
    // 1 initial derivative + 1 initial-step probe + 6 per attempted step.
    assert_eq!(integ.n_rhs(), 2 + 6 * (integ.n_steps() + integ.n_rejected()));
    // invalidate() costs exactly one fresh derivative.
    integ.invalidate();
    let before = (integ.n_rhs(), integ.n_steps() + integ.n_rejected());
    integ.advance(&sys, &mut t, &mut x, 3.5).unwrap();
    assert_eq!(integ.n_rhs() - before.0, 1 + 6 * (integ.n_steps() + integ.n_rejected() - before.1));
}

#[test]
fn fixed_methods_count_one_and_four_rhs_per_step() {
    for (method, per) in [(Method::Euler, 1), (Method::Rk4, 4)] {
        let mut integ = Integrator::new(settings(method, 0.03, 1e-6, 1e-8), 1, 0);
        let (mut t, mut x) = (0.0, [1.0]);
        integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 1.0).unwrap();
        // 33 full steps of 0.03 and one short step of 0.01.
        assert_eq!(integ.n_steps(), 34);
        assert_eq!(integ.n_rhs(), per * 34);
    }
}

// ---------------------------------------------------------------- landing

#[test]
fn every_method_lands_exactly_on_t_end() {
    let sys = Osc { zeta: 0.05 };
    let mut stops = Vec::new();
    // An accumulated grid (not exactly representable), thirds, tiny and uneven gaps.
    let mut s = 0.0;
    for _ in 0..30 {
        s += 0.1;
        stops.push(s);
    }
    for k in 1..=9 {
        stops.push(3.0 + k as f64 / 3.0);
    }
    for gap in [1e-9, 1e-13, 0.123456789, 2.5e-7, 1.0 / 7.0, 0.3 + 1e-15] {
        let last = *stops.last().unwrap();
        stops.push(last + gap);
    }
    for m in ALL {
        let mut integ = Integrator::new(settings(m, 0.01, 1e-7, 1e-9), 2, 0);
        let (mut t, mut x) = (0.0, [1.0, 0.0]);
        for &stop in &stops {
            assert_eq!(integ.advance(&sys, &mut t, &mut x, stop), Ok(Advance::Reached));
            assert_eq!(t.to_bits(), stop.to_bits(), "{m:?}");
        }
        // Fixed-step grids restart at each call, but stay accurate.
        let tol = match m {
            // Euler's amplitude error grows like exp(h t / 2) on an oscillator.
            Method::Euler => 5e-2,
            Method::Rk4 => 1e-8,
            Method::Dopri5 | Method::Dop853 => 1e-5,
            Method::Bs23 => 1e-4,
            // Lower-order implicit methods, with the Newton iteration's error on top.
            Method::Bdf | Method::Esdirk => 1e-4,
        };
        let err = err_inf(&x, &sys.exact(t));
        assert!(err < tol, "{m:?}: error {err}");
    }
}

#[test]
fn fixed_step_merges_rounding_remainders() {
    // 0.3 / 0.1 is 2.9999999999999996 in floating point: still 3 steps, not 4.
    for m in [Method::Euler, Method::Rk4] {
        let mut integ = Integrator::new(settings(m, 0.1, 1e-6, 1e-8), 1, 0);
        let (mut t, mut x) = (0.0, [1.0]);
        integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 0.3).unwrap();
        assert_eq!(integ.n_steps(), 3);
        // 1.0 from 0.7 with step 0.1: 0.7 + 3*0.1 rounds just past 1.0.
        integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 0.7).unwrap();
        integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, 1.0).unwrap();
        assert_eq!(integ.n_steps(), 10);
        assert_eq!(t, 1.0);
    }
}

/// x' = -x, recording every time at which the rhs is evaluated.
struct Recording {
    times: std::cell::RefCell<Vec<f64>>,
}

impl OdeSystem for Recording {
    fn dim(&self) -> usize {
        1
    }
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        self.times.borrow_mut().push(t);
        dx[0] = -x[0];
    }
}

#[test]
fn fixed_step_grid_does_not_drift() {
    // 10000 Euler steps of 0.1 in one call: step k starts at exactly k * 0.1
    // (repeated addition would be ~1e-10 off by the end).
    let sys = Recording { times: Default::default() };
    let mut integ = Integrator::new(settings(Method::Euler, 0.1, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (0.0, [1.0]);
    integ.advance(&sys, &mut t, &mut x, 1000.0).unwrap();
    let times = sys.times.borrow();
    assert_eq!(times.len(), 10000);
    for (k, &tk) in times.iter().enumerate() {
        assert_eq!(tk, k as f64 * 0.1, "step {k}");
    }
    assert_eq!(t, 1000.0);
}

// ---------------------------------------------------------------- carried step

#[test]
fn adaptive_steps_do_not_depend_on_the_communication_points() {
    // The adaptive methods step across the points `advance` is asked to reach and interpolate:
    // 10,000 calls of 1 ms take the very steps (same counters) of one call over 10 s, and both
    // land bit for bit on the same state at the stop time, where the steps end.
    let sys = Osc { zeta: 0.1 };
    for m in ADAPTIVE {
        let run = |points: usize| {
            let mut integ = Integrator::new(settings(m, 0.0, 1e-8, 1e-10), 2, 0);
            integ.set_stop_time(Some(10.0));
            let (mut t, mut x) = (0.0, [1.0, 0.0]);
            let mut worst: f64 = 0.0;
            for k in 1..=points {
                let stop = if k == points { 10.0 } else { k as f64 * 10.0 / points as f64 };
                assert_eq!(integ.advance(&sys, &mut t, &mut x, stop), Ok(Advance::Reached));
                assert_eq!(t, stop);
                worst = worst.max(err_inf(&x, &sys.exact(t)));
            }
            (x.map(f64::to_bits), integ.n_steps(), integ.n_rhs(), worst)
        };
        let (x1, steps1, rhs1, _) = run(1);
        let (x2, steps2, rhs2, worst) = run(10_000);
        println!("{m:?}: {steps1} steps over 10 s; every 1 ms from the dense output within {worst:.2e} of the exact solution");
        // Every step holds a sampled point: DOP853 pays its three dense-output stages in each.
        let dense_rhs = if m == Method::Dop853 { 3 * steps1 } else { 0 };
        assert_eq!((x1, steps1, rhs1 + dense_rhs), (x2, steps2, rhs2), "{m:?}");
        assert!(steps1 < 2000, "{m:?}: {steps1} steps for 10 s of a smooth solution at rtol 1e-8");
        // The dense output's error at the 10,000 points is of the order of the tolerance (the
        // global error of the steps themselves; see also the local-order tests).
        // The implicit methods' global error is a few times larger (see the test above).
        let bound = if m.is_implicit() { 1e-6 } else { 2e-7 };
        assert!(worst < bound, "{m:?}: dense output {worst:e} off");
    }
}

#[test]
fn no_step_ends_after_the_stop_time() {
    // x' = -x recording every rhs time: with a stop time the last step lands on it, and nothing
    // is evaluated after it; an advance past it is still honoured.
    for m in ADAPTIVE {
        let sys = Recording { times: Default::default() };
        let mut integ = Integrator::new(settings(m, 0.0, 1e-6, 1e-9), 1, 0);
        integ.set_stop_time(Some(2.5));
        let (mut t, mut x) = (0.0, [1.0]);
        for k in 1..=25 {
            integ.advance(&sys, &mut t, &mut x, 0.1 * k as f64).unwrap();
        }
        assert_eq!(t, 2.5);
        assert!(sys.times.borrow().iter().all(|&tr| tr <= 2.5), "{m:?}");
        assert!((x[0] - (-2.5f64).exp()).abs() < 1e-5, "{m:?}");
        integ.advance(&sys, &mut t, &mut x, 3.0).unwrap();
        assert_eq!(t, 3.0);
        assert!((x[0] - (-3.0f64).exp()).abs() < 1e-5, "{m:?}");
    }
}

#[test]
fn max_step_bounds_every_step() {
    // x' = -x sampled every 1 ms, shorter than any step here, so every step's end shows as a new
    // `t_int`: with max_step = 0.05 no step is longer, and without it they are.
    for m in ADAPTIVE {
        let run = |max_step: f64| {
            let sys = Decay { lambda: 1.0 };
            let mut integ = Integrator::new(Settings { max_step, ..settings(m, 0.0, 1e-3, 1e-6) }, 1, 0);
            let (mut t, mut x) = (0.0, [1.0]);
            let mut ends = vec![0.0];
            for k in 1..=4000 {
                integ.advance(&sys, &mut t, &mut x, k as f64 * 1e-3).unwrap();
                if integ.t_int != *ends.last().unwrap() {
                    ends.push(integ.t_int);
                }
            }
            let longest = ends.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
            (integ.n_steps(), longest, x[0])
        };
        let (free_steps, free_longest, _) = run(0.0);
        let (steps, longest, x) = run(0.05);
        println!("{m:?}: {free_steps} steps unbounded (longest {free_longest:.3}), {steps} with max_step 0.05 (longest {longest:.4})");
        assert!(free_longest > 0.1, "{m:?}: the unbounded steps must be longer for this test to mean anything");
        // (A difference of two step ends rounds: a few ulps of t.)
        assert!(longest <= 0.05 + 1e-15, "{m:?}: a step of {longest}");
        assert!(steps >= 80, "{m:?}: {steps} steps");
        assert!((x - (-4.0f64).exp()).abs() < 1e-4, "{m:?}");
    }
}

#[test]
fn settings_changes_restart_and_the_same_settings_change_nothing() {
    let sys = Osc { zeta: 0.1 };
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-8, 1e-10), 2, 0);
    let (mut t, mut x) = (0.0, [1.0, 0.0]);
    integ.advance(&sys, &mut t, &mut x, 1.0).unwrap();
    let same = *integ.settings();
    integ.set_settings(same);
    let rhs = integ.n_rhs();
    integ.advance(&sys, &mut t, &mut x, 1.001).unwrap();
    assert_eq!(integ.n_rhs(), rhs, "inside the pending step: interpolation only");
    // Another method: the pending step (a DOPRI5 step) is dropped, and DOP853 starts afresh at
    // the caller's point: a first derivative, an initial-step probe, then its own steps.
    integ.set_settings(settings(Method::Dop853, 0.0, 1e-8, 1e-10));
    assert_eq!(integ.step_size(), 0.0);
    let (t0, x0) = (t, x);
    integ.advance(&sys, &mut t, &mut x, 3.0).unwrap();
    let mut fresh = Integrator::new(settings(Method::Dop853, 0.0, 1e-8, 1e-10), 2, 0);
    let (mut tf, mut xf) = (t0, x0);
    fresh.advance(&sys, &mut tf, &mut xf, 3.0).unwrap();
    assert_eq!(x.map(f64::to_bits), xf.map(f64::to_bits), "the same as a new integrator from there");
    assert_eq!(integ.n_rhs() - rhs, fresh.n_rhs());
    assert!(err_inf(&x, &sys.exact(3.0)) < 1e-7);
}

#[test]
fn a_restart_is_an_integration_started_afresh_from_that_point() {
    // After invalidate() (an FMU's new input) the continuation is the integration restarted
    // from the communication point, bit for bit: the pending step is not used, only the
    // step-size proposal survives. Without invalidate the pending step is interpolated.
    let sys = Osc { zeta: 0.1 };
    for m in ADAPTIVE {
        let mut integ = Integrator::new(settings(m, 0.0, 1e-8, 1e-10), 2, 0);
        let (mut t, mut x) = (0.0, [1.0, 0.0]);
        integ.advance(&sys, &mut t, &mut x, 1.0).unwrap();
        let mut reference = integ.clone();
        integ.invalidate();
        let (mut t1, mut x1) = (t, x);
        integ.advance(&sys, &mut t1, &mut x1, 2.0).unwrap();
        // The same restart, made by handing the integrator a point it did not hand out.
        let (mut t2, mut x2) = (t, [x[0], x[1].next_up()]);
        reference.clone().advance(&sys, &mut t2, &mut x2, 2.0).unwrap();
        assert!(err_inf(&x1, &x2) < 1e-9 && x1 != x2, "{m:?}");
        let (mut t3, mut x3) = (t, x);
        let rhs = reference.n_rhs();
        reference.invalidate();
        reference.advance(&sys, &mut t3, &mut x3, 2.0).unwrap();
        assert_eq!(x3.map(f64::to_bits), x1.map(f64::to_bits), "{m:?}");
        assert!(reference.n_rhs() > rhs, "{m:?}: the restart integrates again");
    }
}

// ---------------------------------------------------------------- rollback

/// Drives `sys` through `stops`, handling ball bounces; returns a bitwise trace.
fn trace(integ: &mut Integrator, t: &mut f64, x: &mut [f64], stops: &[f64], ball: bool) -> Vec<u64> {
    let mut out = Vec::new();
    for &stop in stops {
        loop {
            let r = if ball { integ.advance(&Ball, t, x, stop) } else { integ.advance(&Osc { zeta: 0.2 }, t, x, stop) };
            out.push(t.to_bits());
            out.extend(x.iter().map(|v| v.to_bits()));
            match r.unwrap() {
                Advance::Reached => break,
                Advance::Event { .. } => {
                    x[0] = 0.0;
                    x[1] *= -0.8;
                    integ.invalidate();
                }
            }
        }
        if stop == 1.5 {
            // New inputs: the caller invalidates mid-run.
            integ.invalidate();
        }
    }
    out.push(integ.n_steps());
    out.push(integ.n_rhs());
    out.push(integ.step_size().to_bits());
    out
}

#[test]
fn clone_and_serde_round_trip_continue_bit_identically() {
    for ball in [false, true] {
        for m in ALL {
            let (dim_ind, x0) = if ball { (1, [1.0, 0.0]) } else { (0, [1.0, 0.0]) };
            let mut integ = Integrator::new(settings(m, 0.013, 1e-6, 1e-9), 2, dim_ind);
            let (mut t, mut x) = (0.0, x0);
            let first: Vec<f64> = (1..=13).map(|k| 0.1 * k as f64).collect();
            trace(&mut integ, &mut t, &mut x, &first, ball);
            let rest: Vec<f64> = (14..=40).map(|k| 0.1 * k as f64).chain([1e-7 + 4.0, 4.5]).collect();

            let snapshot = integ.clone();
            let wire = wire::to_tokens(&integ);
            let (t_snap, x_snap) = (t, x);
            let reference = trace(&mut integ, &mut t, &mut x, &rest, ball);

            let mut cloned = snapshot;
            let (mut t2, mut x2) = (t_snap, x_snap);
            assert_eq!(trace(&mut cloned, &mut t2, &mut x2, &rest, ball), reference, "clone, {m:?}");

            let mut restored: Integrator = wire::from_tokens(wire);
            assert!(!restored.work.ready, "work buffers are rebuilt lazily");
            let (mut t3, mut x3) = (t_snap, x_snap);
            assert_eq!(trace(&mut restored, &mut t3, &mut x3, &rest, ball), reference, "serde, {m:?}");
        }
    }
}

// ---------------------------------------------------------------- events

fn ramp(levels: &[(f64, f64)]) -> Ramp {
    Ramp { slope: -1.0, levels: levels.to_vec() }
}

#[test]
fn crossing_is_located_within_1e_10_for_all_methods() {
    // x' = -1 from x = 1, z = x: crossing at exactly t = 1.
    let sys = ramp(&[(1.0, 0.0)]);
    for m in ALL {
        for h in [0.3, 0.07, 1.0 / 3.0] {
            let mut integ = Integrator::new(settings(m, h, 1e-6, 1e-9), 1, 1);
            let (mut t, mut x) = (0.0, [1.0]);
            let r = integ.advance(&sys, &mut t, &mut x, 2.5).unwrap();
            assert_eq!(r, Advance::Event { fired: vec![true] }, "{m:?}");
            println!("{m:?} h={h}: event at t - 1 = {:.3e}", t - 1.0);
            // The implicit methods' state carries the rounding of the Newton corrections: a
            // few ulps of x = 1 - t, so of t.
            let early = if m.is_implicit() { 1e-14 } else { 0.0 };
            assert!((-early..=EVENT_TOL).contains(&(t - 1.0)), "{m:?} h={h}: t = {t}");
            // The indicator has changed sign at the returned time.
            assert!(x[0] <= 0.0 && x[0] >= -EVENT_TOL, "{m:?}: x = {}", x[0]);
            // Continuing without a mode change does not re-fire.
            assert_eq!(integ.advance(&sys, &mut t, &mut x, 2.5), Ok(Advance::Reached));
            assert_eq!(t, 2.5);
            assert!((x[0] + 1.5).abs() < 1e-9);
        }
    }
}

#[test]
fn a_state_changed_between_advances_is_noticed_without_invalidate() {
    // A caller that moves x between calls (an FMU's projection onto constraints) must get the
    // same steps as one that calls invalidate(): a restart from the moved state; writing back
    // the very same bits is no change and keeps the pending step.
    for m in ALL {
        let run = |invalidate: bool, nudge: Option<f64>| {
            let mut integ = Integrator::new(settings(m, 0.01, 1e-8, 1e-10), 2, 0);
            let (mut t, mut x) = (0.0, [1.0, 0.0]);
            for k in 1..=20 {
                integ.advance(&Osc { zeta: 0.1 }, &mut t, &mut x, 0.25 * k as f64).unwrap();
                if let (10, Some(nudge)) = (k, nudge) {
                    x[1] *= 1.0 + nudge;
                    if invalidate {
                        integ.invalidate();
                    }
                }
            }
            (x, t, integ.n_rhs(), integ.n_steps())
        };
        assert_eq!(run(false, Some(1e-3)), run(true, Some(1e-3)), "{m:?}: a moved state");
        let untouched = run(false, None);
        assert_eq!(run(false, Some(0.0)), untouched, "{m:?}: the same bits written back");
        if m.is_implicit() {
            // A restart evaluates the Jacobian again, which may save later Newton iterations:
            // the work differs, not necessarily upwards.
            assert_ne!(run(true, Some(0.0)), untouched, "{m:?}: invalidate() restarts");
        } else if !m.is_fixed_step() {
            assert!(run(true, Some(0.0)).2 > untouched.2, "{m:?}: invalidate() restarts");
        }
        // Serialization keeps the point handed out: a copy made after the caller moved the state
        // restarts from the moved state as the original does, with or without settle().
        let resumed = |settle: bool| {
            let mut integ = Integrator::new(settings(m, 0.01, 1e-8, 1e-10), 2, 0);
            let (mut t, mut x) = (0.0, [1.0, 0.0]);
            integ.advance(&Osc { zeta: 0.1 }, &mut t, &mut x, 2.5).unwrap();
            x[1] *= 1.0 + 1e-3;
            if settle {
                integ.settle(t, &x);
            }
            let mut copy: Integrator = wire::from_tokens(wire::to_tokens(&integ));
            let finish = |integ: &mut Integrator| {
                let (mut t, mut x) = (t, x);
                integ.advance(&Osc { zeta: 0.1 }, &mut t, &mut x, 5.0).unwrap();
                (x.map(f64::to_bits), integ.n_rhs())
            };
            (finish(&mut integ), finish(&mut copy))
        };
        let (original, copy) = resumed(true);
        assert_eq!(original, copy, "{m:?}: settled, then serialized");
        assert_eq!(resumed(false), (original, copy), "{m:?}: serialized without settle()");
    }
}

#[test]
fn after_an_event_the_derivative_is_fresh_even_without_invalidate() {
    // Oscillator with z = x: the crossing is mid-step, so the cached step-start
    // derivative must not be reused from the event point. Skipping invalidate()
    // must give bit-identical results to calling it (nothing changed the state).
    struct OscZ;
    impl OdeSystem for OscZ {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
            Osc { zeta: 0.1 }.rhs(t, x, dx)
        }
        fn n_event_indicators(&self) -> usize {
            1
        }
        fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
            z[0] = x[0];
        }
    }
    for m in ALL {
        let run = |invalidate: bool| {
            let mut integ = Integrator::new(settings(m, 0.05, 1e-7, 1e-10), 2, 1);
            let (mut t, mut x) = (0.0, [1.0, 0.0]);
            let mut events = Vec::new();
            while t < 10.0 {
                if let Advance::Event { .. } = integ.advance(&OscZ, &mut t, &mut x, 10.0).unwrap() {
                    events.push(t);
                    if invalidate {
                        integ.invalidate();
                    }
                }
            }
            (events, x)
        };
        let (with, x_with) = run(true);
        let (without, x_without) = run(false);
        // x crosses zero every pi / omega_d = 3.157 s: at 1.67, 4.82 and 7.96.
        assert_eq!(with.len(), 3, "{m:?}: {with:?}");
        assert_eq!((with, x_with), (without, x_without), "{m:?}");
    }
}

#[test]
fn bouncing_ball_bounce_times_match_the_analytic_ones() {
    let e = 0.8;
    let t1 = (2.0 / G).sqrt();
    let mut exact = vec![t1];
    let mut v = G * t1;
    for _ in 0..4 {
        v *= e;
        exact.push(exact.last().unwrap() + 2.0 * v / G);
    }
    for m in ALL {
        let h = if m == Method::Euler { 1e-4 } else { 1e-3 };
        let mut integ = Integrator::new(settings(m, h, 1e-8, 1e-10), 2, 1);
        let (mut t, mut x) = (0.0, [1.0, 0.0]);
        let mut bounces = Vec::new();
        let mut k = 0;
        while bounces.len() < exact.len() {
            k += 1;
            assert!(k < 10_000, "{m:?}: bounces {bounces:?} by t = {t}");
            let stop = 0.01 * k as f64;
            while t < stop {
                if let Advance::Event { fired } = integ.advance(&Ball, &mut t, &mut x, stop).unwrap() {
                    assert_eq!(fired, vec![true]);
                    bounces.push(t);
                    x[0] = 0.0;
                    x[1] *= -e;
                    integ.invalidate();
                }
            }
        }
        println!("{m:?}: bounce time errors {}", sci(&bounces.iter().zip(&exact).map(|(a, b)| a - b).collect::<Vec<_>>()));
        for (k, (got, want)) in bounces.iter().zip(&exact).enumerate() {
            // RK4 and Dopri5 (and their interpolants) are exact on this
            // quadratic motion; what remains is the event lag (<= EVENT_TOL per
            // bounce), which also speeds up the ball by g*lag, lengthening every
            // later arc: a lag at bounce j delays bounce k by lag*(1 + 2 sum e^i).
            // Euler lengthens each arc by about h, compounding similarly.
            // The implicit methods' positions are within their tolerance (1e-8 m at speeds near
            // 4 m/s), a few 1e-9 s per bounce, compounded like the lag.
            let bound = if m == Method::Euler {
                30.0 * h
            } else if m.is_implicit() {
                1e-8 * (k + 1) as f64
            } else {
                (0..=k).map(|j| EVENT_TOL * (1.0 + 2.0 * (1..=k - j).map(|i| e.powi(i as i32)).sum::<f64>())).sum()
            };
            assert!((got - want).abs() <= bound, "{m:?}: bounce {k} at {got}, expected {want} +- {bound:e}");
            assert!(got >= want || m == Method::Euler || m.is_implicit(), "events are never reported early");
        }
    }
}

#[test]
fn earliest_of_two_crossings_in_one_step_wins() {
    // Levels crossed at t = 0.7 (z0), 0.5 (z1) and 0.5 in the other direction (z2).
    let sys = ramp(&[(1.0, 0.3), (1.0, 0.5), (-1.0, 0.5)]);
    for m in ALL {
        // A single fixed step of 2 covers both crossings.
        let mut integ = Integrator::new(settings(m, 2.0, 1e-6, 1e-9), 1, 3);
        let (mut t, mut x) = (0.0, [1.0]);
        let r = integ.advance(&sys, &mut t, &mut x, 2.0).unwrap();
        assert_eq!(r, Advance::Event { fired: vec![false, true, true] }, "{m:?}");
        // The implicit methods' rounding, as in the test above.
        let early = if m.is_implicit() { 1e-14 } else { 0.0 };
        assert!((-early..=EVENT_TOL).contains(&(t - 0.5)), "{m:?}: t = {t}");
        if m.is_fixed_step() {
            assert_eq!(integ.n_steps(), 1);
        }
        integ.invalidate();
        let r = integ.advance(&sys, &mut t, &mut x, 2.0).unwrap();
        assert_eq!(r, Advance::Event { fired: vec![true, false, false] }, "{m:?}");
        assert!((-early..=EVENT_TOL).contains(&(t - 0.7)), "{m:?}: t = {t}");
        integ.invalidate();
        assert_eq!(integ.advance(&sys, &mut t, &mut x, 2.0), Ok(Advance::Reached));
    }
}

#[test]
fn indicator_starting_at_zero_does_not_fire_until_it_left_zero() {
    // z = x with x' = +1 from x = 0: starts on the threshold and moves away.
    let away = Ramp { slope: 1.0, levels: vec![(1.0, 0.0)] };
    // z = t - t^2: starts at 0, positive, back to 0 at t = 1 (a real crossing).
    for m in ALL {
        let mut integ = Integrator::new(settings(m, 0.01, 1e-8, 1e-10), 1, 1);
        let (mut t, mut x) = (0.0, [0.0]);
        assert_eq!(integ.advance(&away, &mut t, &mut x, 1.0), Ok(Advance::Reached), "{m:?}");

        let mut integ = Integrator::new(settings(m, 0.01, 1e-8, 1e-10), 1, 1);
        let (mut t, mut x) = (0.0, [0.0]);
        for k in 1..=9 {
            assert_eq!(integ.advance(&Arch, &mut t, &mut x, 0.1 * k as f64), Ok(Advance::Reached), "{m:?}");
        }
        assert_eq!(integ.advance(&Arch, &mut t, &mut x, 1.5), Ok(Advance::Event { fired: vec![true] }));
        // Euler's state is O(h) off the true x = t - t^2; the implicit methods' within their
        // tolerance (1e-8 of a slope of -1), on either side.
        let slack = match m {
            Method::Euler => 0.02,
            m if m.is_implicit() => 1e-8,
            _ => EVENT_TOL,
        };
        let early = if m == Method::Euler || m.is_implicit() { -slack } else { 0.0 };
        assert!(t - 1.0 <= slack && t - 1.0 >= early, "{m:?}: t = {t}");
    }
}

/// No states at all, one time event at t = 0.5.
struct Clock;

impl OdeSystem for Clock {
    fn dim(&self) -> usize {
        0
    }
    fn rhs(&self, _t: f64, _x: &[f64], _dx: &mut [f64]) {}
    fn n_event_indicators(&self) -> usize {
        1
    }
    fn event_indicators(&self, t: f64, _x: &[f64], z: &mut [f64]) {
        z[0] = t - 0.5;
    }
}

#[test]
fn time_events_work_without_states() {
    for m in ALL {
        let mut integ = Integrator::new(settings(m, 0.1, 1e-6, 1e-9), 0, 1);
        let mut t = 0.0;
        assert_eq!(integ.advance(&Clock, &mut t, &mut [], 2.0), Ok(Advance::Event { fired: vec![true] }));
        assert!((0.0..=EVENT_TOL).contains(&(t - 0.5)), "{m:?}: t = {t}");
        assert_eq!(integ.advance(&Clock, &mut t, &mut [], 2.0), Ok(Advance::Reached));
        assert_eq!(t, 2.0);
    }
}

// ---------------------------------------------------------------- failures

#[test]
fn forward_euler_blow_up_is_reported_not_panicked() {
    let sys = Decay { lambda: 1000.0 };
    let mut integ = Integrator::new(settings(Method::Euler, 1.0, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (0.0, [1.0]);
    let err = integ.advance(&sys, &mut t, &mut x, 1e4).unwrap_err();
    let SolverError::NonFinite { t: t_bad } = err else { panic!("expected NonFinite, got {err:?}") };
    // |x| grows by 999 per step and overflows after ~103 steps.
    assert!((100.0..=110.0).contains(&t_bad), "t = {t_bad}");
    // The last finite state is handed back.
    assert_eq!(t, t_bad - 1.0);
    assert!(x[0].is_finite());
    let msg = err.to_string();
    assert!(msg.contains("NaN or infinite") && msg.contains("fixed_step"), "{msg}");
}

#[test]
fn dopri5_reports_nan_model_and_too_small_steps() {
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (0.0, [1.0]);
    assert_eq!(integ.advance(&Broken, &mut t, &mut x, 1.0), Err(SolverError::NonFinite { t: 0.0 }));

    // x' = x^2 from x = 1 blows up at t = 1: must end in an error, not hang or panic.
    struct Blow;
    impl OdeSystem for Blow {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[0] * x[0];
        }
    }
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (0.0, [1.0]);
    let err = integ.advance(&Blow, &mut t, &mut x, 2.0).unwrap_err();
    println!("x' = x^2: {err} (t = {t}, x = {})", x[0]);
    // The numerical solution lags the exact one, so it may blow up a little after t = 1.
    assert!(t > 0.99 && t < 1.001 && x[0].is_finite(), "t = {t}");

    let t0 = 1e12;
    let mut integ = Integrator::new(settings(Method::Dopri5, 0.0, 1e-6, 1e-8), 1, 0);
    let (mut t, mut x) = (t0, [0.0]);
    let err = integ.advance(&FastAtLargeTime, &mut t, &mut x, t0 + 10.0).unwrap_err();
    assert!(matches!(err, SolverError::StepSizeTooSmall { .. }), "{err:?}");
    assert!(err.to_string().contains("step size"));
}

/// x0' = omega x1, x1' = -omega x0: a unit circle traversed at `omega` rad/s (a pendulum a
/// hair long): every method needs steps of about 1/omega, so a call over 1 s at omega = 1e8
/// needs some 1e8 steps, a hundred times [`MAX_STEPS_PER_CALL`].
struct FastCircle {
    omega: f64,
}

impl OdeSystem for FastCircle {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = self.omega * x[1];
        dx[1] = -self.omega * x[0];
    }
}

/// Each method's loop (the explicit pairs', BDF's, ESDIRK's, the fixed steps') stops after
/// exactly MAX_STEPS_PER_CALL attempts with `TooManySteps`, hands out the finite state it
/// reached (t between the start and the end), names the time, the count and the step size,
/// and a second call gets a budget of its own (the bound is per call, not per run). Before the
/// bound, each of these calls ran for hours.
#[test]
fn one_call_takes_at_most_max_steps_per_call() {
    let fast = FastCircle { omega: 1e8 };
    for m in [Method::Dopri5, Method::Bdf, Method::Esdirk, Method::Euler] {
        // Euler at 1e-9 s: 1e9 steps to t = 1 (its state grows by (1 + 1e-2)^(1/2) a step
        // at omega 1e8, so it runs on a slow system instead: x' = -x).
        let mut integ = Integrator::new(settings(m, 1e-9, 1e-6, 1e-9), if m == Method::Euler { 1 } else { 2 }, 0);
        let started = std::time::Instant::now();
        let (mut t, mut x) = (0.0, [1.0, 0.0]);
        let n = integ.dim();
        let err = if m == Method::Euler {
            integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x[..n], 1.0)
        } else {
            integ.advance(&fast, &mut t, &mut x[..n], 1.0)
        }
        .unwrap_err();
        let took = started.elapsed();
        println!("{m:?}: {err} ({took:.2?})");
        let SolverError::TooManySteps { t: t_reached, steps, accepted, h, .. } = err else { panic!("{m:?}: {err:?}") };
        assert_eq!(steps, MAX_STEPS_PER_CALL, "{m:?}");
        assert_eq!(integ.n_steps() + integ.n_rejected(), MAX_STEPS_PER_CALL, "{m:?}: every attempt counted");
        assert_eq!(integ.n_steps(), accepted, "{m:?}");
        assert!(t == t_reached && t > 0.0 && t < 1.0 && x[..n].iter().all(|v| v.is_finite()), "{m:?}: t = {t}, x = {x:?}");
        assert!(h > 0.0 && h < 1e-6, "{m:?}: the step size {h:e}");
        let msg = err.to_string();
        // Times under 1 ms in exponent notation.
        let shown = if t >= 1e-3 { format!("{t}") } else { format!("{t:e}") };
        assert!(
            msg.contains(&format!("gave up at t = {shown} s")) && msg.contains(&format!("{MAX_STEPS_PER_CALL} step attempts")),
            "{msg}"
        );
        if m == Method::Euler {
            // Fixed steps land on the grid: a million of 1e-9 s.
            assert!((t - 1e-3).abs() < 1e-15, "t = {t}");
            assert!(msg.contains("fixed_step is far too small for this communication step"), "{msg}");
        } else if m == Method::Dopri5 {
            assert!(msg.contains("stiff") && msg.contains("extreme"), "{msg}");
            // The next call starts a budget of its own, from where the last one stopped.
            let t_first = t;
            let err = integ.advance(&fast, &mut t, &mut x[..n], 1.0).unwrap_err();
            assert!(matches!(err, SolverError::TooManySteps { steps: MAX_STEPS_PER_CALL, .. }) && t > t_first, "{err:?}");
            assert_eq!(integ.n_steps() + integ.n_rejected(), 2 * MAX_STEPS_PER_CALL);
        }
    }
}

/// A `fixed_step` below 16 ulps of |t| cannot move time: refused at once, where the grid loop
/// used to count grid points that all rounded to the same time, without end.
#[test]
fn a_fixed_step_that_cannot_move_time_is_refused() {
    for m in [Method::Euler, Method::Rk4] {
        for (t0, h) in [(1.0, 1e-300), (0.0, 1e-16), (1e9, 1e-8)] {
            let mut integ = Integrator::new(settings(m, h, 1e-6, 1e-9), 1, 0);
            let (mut t, mut x) = (t0, [1.0]);
            let err = integ.advance(&Decay { lambda: 1.0 }, &mut t, &mut x, t0 + 1.0).unwrap_err();
            assert_eq!(err, SolverError::StepSizeTooSmall { t: t0, h }, "{m:?} from {t0}");
            assert_eq!((t, x[0]), (t0, 1.0), "nothing was integrated");
        }
    }
}

// ---------------------------------------------------------------- wire format

/// A minimal non-self-describing serde format (like postcard) for the round-trip test.
mod wire {
    use serde::de::{self, DeserializeSeed, IntoDeserializer, Visitor};
    use serde::ser::{self, Serialize};

    #[derive(Debug, Clone, PartialEq)]
    pub enum Tok {
        Bool(bool),
        U64(u64),
        F64(u64),
        Len(usize),
        Variant(u32),
        None,
        Some,
    }

    #[derive(Debug)]
    pub struct Error(String);

    impl std::fmt::Display for Error {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str(&self.0)
        }
    }
    impl std::error::Error for Error {}
    impl ser::Error for Error {
        fn custom<T: std::fmt::Display>(msg: T) -> Self {
            Error(msg.to_string())
        }
    }
    impl de::Error for Error {
        fn custom<T: std::fmt::Display>(msg: T) -> Self {
            Error(msg.to_string())
        }
    }

    fn unsupported<T>(what: &str) -> Result<T, Error> {
        Err(Error(format!("wire: {what} unsupported")))
    }

    pub fn to_tokens<T: Serialize>(v: &T) -> Vec<Tok> {
        let mut s = Ser(Vec::new());
        v.serialize(&mut s).unwrap();
        s.0
    }

    pub fn from_tokens<T: de::DeserializeOwned>(toks: Vec<Tok>) -> T {
        let mut d = De { toks, pos: 0 };
        let v = T::deserialize(&mut d).unwrap();
        assert_eq!(d.pos, d.toks.len(), "trailing tokens");
        v
    }

    pub struct Ser(Vec<Tok>);

    impl ser::Serializer for &mut Ser {
        type Ok = ();
        type Error = Error;
        type SerializeSeq = Self;
        type SerializeTuple = Self;
        type SerializeTupleStruct = Self;
        type SerializeTupleVariant = Self;
        type SerializeMap = Self;
        type SerializeStruct = Self;
        type SerializeStructVariant = Self;
        fn serialize_bool(self, v: bool) -> Result<(), Error> {
            self.0.push(Tok::Bool(v));
            Ok(())
        }
        fn serialize_i8(self, _: i8) -> Result<(), Error> {
            unsupported("i8")
        }
        fn serialize_i16(self, _: i16) -> Result<(), Error> {
            unsupported("i16")
        }
        fn serialize_i32(self, _: i32) -> Result<(), Error> {
            unsupported("i32")
        }
        fn serialize_i64(self, _: i64) -> Result<(), Error> {
            unsupported("i64")
        }
        fn serialize_u8(self, v: u8) -> Result<(), Error> {
            self.serialize_u64(v.into())
        }
        fn serialize_u16(self, v: u16) -> Result<(), Error> {
            self.serialize_u64(v.into())
        }
        fn serialize_u32(self, v: u32) -> Result<(), Error> {
            self.serialize_u64(v.into())
        }
        fn serialize_u64(self, v: u64) -> Result<(), Error> {
            self.0.push(Tok::U64(v));
            Ok(())
        }
        fn serialize_f32(self, _: f32) -> Result<(), Error> {
            unsupported("f32")
        }
        fn serialize_f64(self, v: f64) -> Result<(), Error> {
            self.0.push(Tok::F64(v.to_bits()));
            Ok(())
        }
        fn serialize_char(self, _: char) -> Result<(), Error> {
            unsupported("char")
        }
        fn serialize_str(self, _: &str) -> Result<(), Error> {
            unsupported("str")
        }
        fn serialize_bytes(self, _: &[u8]) -> Result<(), Error> {
            unsupported("bytes")
        }
        fn serialize_none(self) -> Result<(), Error> {
            self.0.push(Tok::None);
            Ok(())
        }
        fn serialize_some<T: ?Sized + Serialize>(self, v: &T) -> Result<(), Error> {
            self.0.push(Tok::Some);
            v.serialize(self)
        }
        fn serialize_unit(self) -> Result<(), Error> {
            Ok(())
        }
        fn serialize_unit_struct(self, _: &'static str) -> Result<(), Error> {
            Ok(())
        }
        fn serialize_unit_variant(self, _: &'static str, idx: u32, _: &'static str) -> Result<(), Error> {
            self.0.push(Tok::Variant(idx));
            Ok(())
        }
        fn serialize_newtype_struct<T: ?Sized + Serialize>(self, _: &'static str, v: &T) -> Result<(), Error> {
            v.serialize(self)
        }
        fn serialize_newtype_variant<T: ?Sized + Serialize>(self, _: &'static str, _: u32, _: &'static str, _: &T) -> Result<(), Error> {
            unsupported("newtype variant")
        }
        fn serialize_seq(self, len: Option<usize>) -> Result<Self, Error> {
            self.0.push(Tok::Len(len.expect("sized sequences only")));
            Ok(self)
        }
        fn serialize_tuple(self, _: usize) -> Result<Self, Error> {
            Ok(self)
        }
        fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Self, Error> {
            Ok(self)
        }
        fn serialize_tuple_variant(self, _: &'static str, _: u32, _: &'static str, _: usize) -> Result<Self, Error> {
            unsupported("tuple variant")
        }
        fn serialize_map(self, _: Option<usize>) -> Result<Self, Error> {
            unsupported("map")
        }
        fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, Error> {
            Ok(self)
        }
        fn serialize_struct_variant(self, _: &'static str, _: u32, _: &'static str, _: usize) -> Result<Self, Error> {
            unsupported("struct variant")
        }
    }

    macro_rules! compound {
        ($tr:ident, $method:ident) => {
            impl ser::$tr for &mut Ser {
                type Ok = ();
                type Error = Error;
                fn $method<T: ?Sized + Serialize>(&mut self, v: &T) -> Result<(), Error> {
                    v.serialize(&mut **self)
                }
                fn end(self) -> Result<(), Error> {
                    Ok(())
                }
            }
        };
    }
    compound!(SerializeSeq, serialize_element);
    compound!(SerializeTuple, serialize_element);
    compound!(SerializeTupleStruct, serialize_field);
    compound!(SerializeTupleVariant, serialize_field);

    impl ser::SerializeMap for &mut Ser {
        type Ok = ();
        type Error = Error;
        fn serialize_key<T: ?Sized + Serialize>(&mut self, _: &T) -> Result<(), Error> {
            unsupported("map")
        }
        fn serialize_value<T: ?Sized + Serialize>(&mut self, _: &T) -> Result<(), Error> {
            unsupported("map")
        }
        fn end(self) -> Result<(), Error> {
            Ok(())
        }
    }

    impl ser::SerializeStruct for &mut Ser {
        type Ok = ();
        type Error = Error;
        fn serialize_field<T: ?Sized + Serialize>(&mut self, _: &'static str, v: &T) -> Result<(), Error> {
            v.serialize(&mut **self)
        }
        fn end(self) -> Result<(), Error> {
            Ok(())
        }
    }

    impl ser::SerializeStructVariant for &mut Ser {
        type Ok = ();
        type Error = Error;
        fn serialize_field<T: ?Sized + Serialize>(&mut self, _: &'static str, v: &T) -> Result<(), Error> {
            v.serialize(&mut **self)
        }
        fn end(self) -> Result<(), Error> {
            Ok(())
        }
    }

    pub struct De {
        toks: Vec<Tok>,
        pos: usize,
    }

    impl De {
        fn next(&mut self) -> Result<Tok, Error> {
            let t = self.toks.get(self.pos).cloned().ok_or_else(|| Error("wire: end of input".into()))?;
            self.pos += 1;
            Ok(t)
        }
    }

    struct Elements<'a> {
        de: &'a mut De,
        left: usize,
    }

    impl<'de> de::SeqAccess<'de> for Elements<'_> {
        type Error = Error;
        fn next_element_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<Option<T::Value>, Error> {
            if self.left == 0 {
                return Ok(None);
            }
            self.left -= 1;
            seed.deserialize(&mut *self.de).map(Some)
        }
        fn size_hint(&self) -> Option<usize> {
            Some(self.left)
        }
    }

    impl<'de> de::Deserializer<'de> for &mut De {
        type Error = Error;
        fn deserialize_any<V: Visitor<'de>>(self, _: V) -> Result<V::Value, Error> {
            unsupported("self-describing input")
        }
        fn deserialize_bool<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
            match self.next()? {
                Tok::Bool(b) => v.visit_bool(b),
                t => Err(Error(format!("wire: expected bool, got {t:?}"))),
            }
        }
        fn deserialize_u64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
            match self.next()? {
                Tok::U64(n) => v.visit_u64(n),
                t => Err(Error(format!("wire: expected u64, got {t:?}"))),
            }
        }
        fn deserialize_f64<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
            match self.next()? {
                Tok::F64(bits) => v.visit_f64(f64::from_bits(bits)),
                t => Err(Error(format!("wire: expected f64, got {t:?}"))),
            }
        }
        fn deserialize_option<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
            match self.next()? {
                Tok::None => v.visit_none(),
                Tok::Some => v.visit_some(self),
                t => Err(Error(format!("wire: expected an option, got {t:?}"))),
            }
        }
        fn deserialize_seq<V: Visitor<'de>>(self, v: V) -> Result<V::Value, Error> {
            match self.next()? {
                Tok::Len(n) => v.visit_seq(Elements { de: self, left: n }),
                t => Err(Error(format!("wire: expected length, got {t:?}"))),
            }
        }
        fn deserialize_struct<V: Visitor<'de>>(self, _: &'static str, fields: &'static [&'static str], v: V) -> Result<V::Value, Error> {
            v.visit_seq(Elements { de: self, left: fields.len() })
        }
        fn deserialize_enum<V: Visitor<'de>>(self, _: &'static str, _: &'static [&'static str], v: V) -> Result<V::Value, Error> {
            v.visit_enum(self)
        }
        serde::forward_to_deserialize_any! {
            i8 i16 i32 i64 i128 u8 u16 u32 u128 f32 char str string bytes byte_buf
            unit unit_struct newtype_struct tuple tuple_struct map identifier ignored_any
        }
    }

    impl<'de> de::EnumAccess<'de> for &mut De {
        type Error = Error;
        type Variant = Self;
        fn variant_seed<V: DeserializeSeed<'de>>(self, seed: V) -> Result<(V::Value, Self), Error> {
            match self.next()? {
                Tok::Variant(idx) => {
                    let d: de::value::U32Deserializer<Error> = idx.into_deserializer();
                    Ok((seed.deserialize(d)?, self))
                }
                t => Err(Error(format!("wire: expected variant, got {t:?}"))),
            }
        }
    }

    impl<'de> de::VariantAccess<'de> for &mut De {
        type Error = Error;
        fn unit_variant(self) -> Result<(), Error> {
            Ok(())
        }
        fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, _: T) -> Result<T::Value, Error> {
            unsupported("newtype variant")
        }
        fn tuple_variant<V: Visitor<'de>>(self, _: usize, _: V) -> Result<V::Value, Error> {
            unsupported("tuple variant")
        }
        fn struct_variant<V: Visitor<'de>>(self, _: &'static [&'static str], _: V) -> Result<V::Value, Error> {
            unsupported("struct variant")
        }
    }
}
