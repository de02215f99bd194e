//! Tests of the implicit methods on stiff systems, against independent references: closed-form
//! solutions, published values, asymptotic formulas and analytic Jacobians. Print-outs (run
//! with `--nocapture`) report the measured work and errors that the assertions bound.

use super::implicit::{column_groups, Implicit};
use super::*;

const IMPLICIT: [Method; 2] = [Method::Bdf, Method::Esdirk];

fn settings(method: Method, rtol: f64, atol: f64) -> Settings {
    Settings { method, fixed_step: 1e-3, rtol, atol, max_step: 0.0 }
}

/// The stiff mass-spring-damper of issue 33: m x'' + b x' + k x = 0 with m = 1 kg,
/// b = 1e6 N.s/m, k = 1e6 N/m, x(0) = 1 m, v(0) = 0: eigenvalues near -1 and -1e6 1/s.
struct StiffSpring;

const B_DAMP: f64 = 1e6;
const K_SPRING: f64 = 1e6;

impl StiffSpring {
    /// The two-exponential solution: x = (l2 e^(l1 t) - l1 e^(l2 t)) / (l2 - l1).
    fn exact(t: f64) -> [f64; 2] {
        let disc = (B_DAMP * B_DAMP - 4.0 * K_SPRING).sqrt();
        // The slow root without cancellation: l1 = -2k / (b + disc).
        let (l1, l2) = (-2.0 * K_SPRING / (B_DAMP + disc), -(B_DAMP + disc) / 2.0);
        let (e1, e2) = ((l1 * t).exp(), (l2 * t).exp());
        [(l2 * e1 - l1 * e2) / (l2 - l1), l1 * l2 * (e1 - e2) / (l2 - l1)]
    }
}

impl OdeSystem for StiffSpring {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = -K_SPRING * x[0] - B_DAMP * x[1];
    }
}

/// Robertson's chemical kinetics (the Reference FMUs' Roberts), with its analytic Jacobian as
/// directional derivatives when `exact` is set.
struct Robertson {
    exact: bool,
}

impl Robertson {
    fn jacobian(x: &[f64]) -> [[f64; 3]; 3] {
        [[-0.04, 1e4 * x[2], 1e4 * x[1]], [0.04, -1e4 * x[2] - 6e7 * x[1], -1e4 * x[1]], [0.0, 6e7 * x[1], 0.0]]
    }
}

impl OdeSystem for Robertson {
    fn dim(&self) -> usize {
        3
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = -0.04 * x[0] + 1e4 * x[1] * x[2];
        dx[2] = 3e7 * x[1] * x[1];
        dx[1] = -dx[0] - dx[2];
    }
    fn provides_directional_derivative(&self) -> bool {
        self.exact
    }
    fn directional_derivative(&self, _t: f64, x: &[f64], v: &[f64], out: &mut [f64]) {
        let j = Robertson::jacobian(x);
        for i in 0..3 {
            out[i] = (0..3).map(|k| j[i][k] * v[k]).sum();
        }
    }
}

/// Van der Pol's oscillator x1' = x2, x2' = mu (1 - x1^2) x2 - x1 (the Reference FMUs' form).
struct VanDerPol {
    mu: f64,
}

impl OdeSystem for VanDerPol {
    fn dim(&self) -> usize {
        2
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        dx[0] = x[1];
        dx[1] = self.mu * (1.0 - x[0] * x[0]) * x[1] - x[0];
    }
    fn n_event_indicators(&self) -> usize {
        1
    }
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = x[0];
    }
}

/// A chain of n reactions, x_i' = -x_i^2 + x_{i-1} x_{i+1} ... tridiagonal: each derivative
/// depends on its state and its two neighbours, so three groups of columns suffice.
struct Chain {
    n: usize,
    pattern: Vec<Vec<usize>>,
}

impl Chain {
    fn new(n: usize) -> Chain {
        let pattern = (0..n).map(|i| (i.saturating_sub(1)..(i + 2).min(n)).collect()).collect();
        Chain { n, pattern }
    }
}

impl OdeSystem for Chain {
    fn dim(&self) -> usize {
        self.n
    }
    fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        for i in 0..self.n {
            let left = if i > 0 { x[i - 1] } else { 1.0 };
            let right = if i + 1 < self.n { x[i + 1] } else { 0.5 };
            dx[i] = -1e3 * x[i] * x[i] + 10.0 * left * right - (i as f64 + 1.0) * x[i];
        }
    }
    fn jacobian_pattern(&self) -> Option<&[Vec<usize>]> {
        Some(&self.pattern)
    }
}

fn run<S: OdeSystem>(sys: &S, m: Method, rtol: f64, atol: f64, x0: &[f64], t_end: f64) -> (Vec<f64>, Integrator) {
    let mut integ = Integrator::new(settings(m, rtol, atol), x0.len(), sys.n_event_indicators());
    let (mut t, mut x) = (0.0, x0.to_vec());
    while t < t_end {
        integ.advance(sys, &mut t, &mut x, t_end).unwrap();
    }
    (x, integ)
}

/// The ESDIRK tableau: third-order conditions for the solution, second-order for the embedded
/// weights, row sums equal to the stage times, stiffly accurate. Exact rationals, so to rounding.
#[test]
fn esdirk_tableau_meets_its_order_conditions() {
    use super::esdirk::{A, B, B_HAT, C, GAMMA};
    // The full Butcher matrix, diagonal gamma from the second stage.
    let a = |i: usize, j: usize| {
        if j < i {
            A[i][j]
        } else if j == i && i > 0 {
            GAMMA
        } else {
            0.0
        }
    };
    for i in 0..4 {
        let row: f64 = (0..4).map(|j| a(i, j)).sum();
        assert!((row - C[i]).abs() < 1e-15, "row {i}: {row} vs c = {}", C[i]);
        assert_eq!(a(3, i), B[i], "stiffly accurate");
    }
    let dot = |w: &[f64; 4], f: &dyn Fn(usize) -> f64| (0..4).map(|i| w[i] * f(i)).sum::<f64>();
    let ac = |i: usize| (0..4).map(|j| a(i, j) * C[j]).sum::<f64>();
    for (value, want) in
        [(dot(&B, &|_| 1.0), 1.0), (dot(&B, &|i| C[i]), 0.5), (dot(&B, &|i| C[i] * C[i]), 1.0 / 3.0), (dot(&B, &ac), 1.0 / 6.0)]
    {
        assert!((value - want).abs() < 1e-14, "{value} vs {want}");
    }
    for (value, want) in [(dot(&B_HAT, &|_| 1.0), 1.0), (dot(&B_HAT, &|i| C[i]), 0.5)] {
        assert!((value - want).abs() < 1e-14, "embedded: {value} vs {want}");
    }
    // L-stability: the stability function R(z) = 1 + z b^T (I - z A)^-1 1 vanishes at infinity,
    // which for a stiffly accurate method with an explicit first stage means |R(-1e12)| small.
    let z = -1e12;
    // Solve (I - z A) y = 1 by forward substitution (A lower triangular).
    let mut y = [0.0; 4];
    for i in 0..4 {
        let s: f64 = (0..i).map(|j| a(i, j) * y[j]).sum();
        y[i] = (1.0 + z * s) / (1.0 - z * a(i, i));
    }
    let r = 1.0 + z * dot(&B, &|i| y[i]);
    assert!(r.abs() < 1e-6, "R(-1e12) = {r}");
}

/// ESDIRK's work-precision slope on a smooth problem is its order: the error falls as the
/// third power of the step count (least-squares slope of log error against log steps over four
/// decades of tolerance, within 0.4 of 3).
#[test]
fn esdirk_converges_with_order_3() {
    struct Osc;
    impl OdeSystem for Osc {
        fn dim(&self) -> usize {
            2
        }
        fn rhs(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = x[1];
            dx[1] = -x[0];
        }
    }
    let mut points = Vec::new();
    for rtol in [1e-4, 1e-5, 1e-6, 1e-7, 1e-8] {
        let (x, integ) = run(&Osc, Method::Esdirk, rtol, rtol * 1e-3, &[1.0, 0.0], 10.0);
        let err = ((x[0] - 10f64.cos()).powi(2) + (x[1] + 10f64.sin()).powi(2)).sqrt();
        points.push(((integ.n_steps() as f64).ln(), err.ln()));
        println!("ESDIRK rtol {rtol:e}: {} steps, error {err:.3e}", integ.n_steps());
    }
    let k = points.len() as f64;
    let (mx, my) = (points.iter().map(|p| p.0).sum::<f64>() / k, points.iter().map(|p| p.1).sum::<f64>() / k);
    let slope = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / points.iter().map(|p| (p.0 - mx).powi(2)).sum::<f64>();
    println!("slope {slope:.2}");
    assert!((-slope - 3.0).abs() < 0.4, "order {}", -slope);
}

/// The BDF history: differences that represent a polynomial of degree <= order re-interpolated
/// for another step size still give that polynomial (to rounding) at every point of the new grid.
#[test]
fn bdf_differences_reinterpolate_polynomials_exactly() {
    let p = |t: f64| 1.0 + 2.0 * t - 3.0 * t * t + 0.5 * t * t * t;
    for order in 3..=5 {
        let h = 0.1;
        // Backward differences at t = 0, -h, -2h, ... (D_j = nabla^j y(0)).
        let values: Vec<f64> = (0..=order).map(|k| p(-(k as f64) * h)).collect();
        let mut d = vec![0.0; bdf::MAX_ORDER + 3];
        let mut row = values.clone();
        for dj in d.iter_mut().take(order + 1) {
            *dj = row[0];
            row = row.windows(2).map(|w| w[0] - w[1]).collect();
        }
        for factor in [0.3, 0.5, 2.0, 3.7] {
            let mut e = d.clone();
            bdf::change_differences(&mut e, 1, order, factor);
            // The new grid: 0, -factor h, ...: evaluate through the dense-output formula, where
            // th = 1 is the grid's end point and th = 1 - k the k-th point back.
            for k in 0..=order {
                let mut out = [0.0];
                bdf::eval(order, 1.0 - k as f64, 1, &e, &mut out);
                let want = p(-(k as f64) * factor * h);
                assert!(
                    (out[0] - want).abs() < 1e-12 * want.abs().max(1.0),
                    "order {order} factor {factor} point {k}: {} vs {want}",
                    out[0]
                );
            }
            // And between the points.
            let mut out = [0.0];
            bdf::eval(order, 0.5, 1, &e, &mut out);
            assert!((out[0] - p(-0.5 * factor * h)).abs() < 1e-12);
        }
    }
}

/// The stiff mass-spring-damper against its two-exponential solution: both implicit methods
/// stay within 10 rtol of it (relative to the 1 m amplitude) at every one of 100 output points
/// (the fast mode decays in microseconds, then the slow one sets the steps), in a few hundred
/// steps where DOPRI5 needs one per 3e-6 s for stability (checked on a short span).
#[test]
fn stiff_spring_meets_its_closed_form_in_few_steps() {
    let rtol = 1e-6;
    for m in IMPLICIT {
        let mut integ = Integrator::new(settings(m, rtol, 1e-9), 2, 0);
        integ.set_stop_time(Some(5.0));
        let (mut t, mut x) = (0.0, [1.0, 0.0]);
        let mut worst: f64 = 0.0;
        for k in 1..=100 {
            let stop = 0.05 * k as f64;
            integ.advance(&StiffSpring, &mut t, &mut x, stop).unwrap();
            worst = worst.max((x[0] - StiffSpring::exact(t)[0]).abs());
        }
        println!(
            "{m:?}: worst position error {worst:.2e} m, {} steps, {} rhs, {} Jacobians, {} Newton failures",
            integ.n_steps(),
            integ.n_rhs(),
            integ.n_jacobians(),
            integ.n_newton_failures()
        );
        assert!(worst < 10.0 * rtol, "{m:?}: {worst:e}");
        assert!(integ.n_steps() < 300, "{m:?}: {} steps", integ.n_steps());
        assert!(integ.n_jacobians() * 5 < integ.n_steps(), "{m:?}: the Jacobian is reused across steps");
    }
    // DOPRI5 over 0.01 s of the same system: stability bounds its step near 3.3 / 1e6 s.
    let (_, integ) = run(&StiffSpring, Method::Dopri5, rtol, 1e-9, &[1.0, 0.0], 0.01);
    println!("DOPRI5 over 0.01 s: {} steps", integ.n_steps());
    assert!(integ.n_steps() > 2000);
}

/// Robertson's problem against the published solution at t = 40 (Hairer & Wanner, Solving ODEs
/// II, IV.10: y1 = 0.7158271, y2 = 9.185535e-6, y3 = 0.2841637), within 1e-5 relative at
/// rtol 1e-8; and the conservation law y1 + y2 + y3 = 1 (the rates cancel), within 1e-9. With
/// the analytic Jacobian as directional derivatives the results agree with finite differences'.
#[test]
fn robertson_meets_the_published_values_and_conserves_mass() {
    let want = [0.7158270687, 9.185534765e-6, 0.2841637457];
    for m in IMPLICIT {
        for exact in [false, true] {
            let (x, integ) = run(&Robertson { exact }, m, 1e-8, 1e-14, &[1.0, 0.0, 0.0], 40.0);
            println!(
                "{m:?} (directional {exact}): {x:?}, {} steps, {} rhs, {} Jacobians ({} columns), {} Newton failures",
                integ.n_steps(),
                integ.n_rhs(),
                integ.n_jacobians(),
                integ.n_jacobian_columns(),
                integ.n_newton_failures()
            );
            for i in 0..3 {
                assert!(((x[i] - want[i]) / want[i]).abs() < 1e-5, "{m:?} y{}: {} vs {}", i + 1, x[i], want[i]);
            }
            assert!((x.iter().sum::<f64>() - 1.0).abs() < 1e-9, "{m:?}: sum {}", x.iter().sum::<f64>());
            assert_eq!(integ.n_directional() > 0, exact);
        }
    }
    // Far out, where the steps are long: y1 at 4e5 s (Hairer & Wanner's plot) is near 0.0049.
    let (x, integ) = run(&Robertson { exact: false }, Method::Bdf, 1e-6, 1e-10, &[1.0, 0.0, 0.0], 4e5);
    println!("BDF to 4e5 s: {x:?} in {} steps, {} rhs", integ.n_steps(), integ.n_rhs());
    assert!((x[0] - 0.00489).abs() < 2e-4 && integ.n_steps() < 1000, "{x:?}");
}

/// Van der Pol with mu = 1000: the relaxation period against its asymptotic formula
/// T = (3 - 2 ln 2) mu + 3 alpha mu^(-1/3), alpha = 2.338 (the first zero of Ai'): 1614.4 s,
/// with O(ln mu / mu) terms left out (within 0.1 %); measured between the state events where
/// x1 crosses zero downwards, located on the method's dense output.
#[test]
fn van_der_pol_period_matches_the_asymptotic_formula() {
    let mu: f64 = 1000.0;
    let period = (3.0 - 2.0 * 2f64.ln()) * mu + 3.0 * 2.338107 * mu.powf(-1.0 / 3.0);
    for m in IMPLICIT {
        let mut integ = Integrator::new(settings(m, 1e-6, 1e-9), 2, 1);
        let (mut t, mut x) = (0.0, [2.0, 0.0]);
        let mut crossings = Vec::new();
        while t < 5000.0 {
            if let Advance::Event { .. } = integ.advance(&VanDerPol { mu }, &mut t, &mut x, 5000.0).unwrap() {
                crossings.push(t);
            }
        }
        // Two crossings per period.
        let measured = crossings[crossings.len() - 1] - crossings[crossings.len() - 3];
        println!(
            "{m:?}: {} crossings, period {measured:.3} s (formula {period:.3}), {} steps, {} rhs, {} Jacobians",
            crossings.len(),
            integ.n_steps(),
            integ.n_rhs(),
            integ.n_jacobians()
        );
        assert!(((measured - period) / period).abs() < 1e-3, "{m:?}: {measured} vs {period}");
        // BDF needs about 7,000 evaluations here, the one-step ESDIRK three stages a step.
        let most = if m == Method::Bdf { 12_000 } else { 40_000 };
        assert!(integ.n_rhs() < most, "{m:?}: {} evaluations", integ.n_rhs());
    }
}

/// After an event the BDF starts its history again at order 1, with a new Jacobian (issue 33):
/// the event may have changed the right-hand side, so neither the differences of the solution
/// before it nor its Jacobian may carry over. Van der Pol's slow phase runs at higher orders,
/// so the first crossing of x1 = 0 interrupts a history of order above 1.
#[test]
fn bdf_restarts_at_order_one_with_a_new_jacobian_after_an_event() {
    let sys = VanDerPol { mu: 1000.0 };
    let mut integ = Integrator::new(settings(Method::Bdf, 1e-6, 1e-9), 2, 1);
    let (mut t, mut x) = (0.0f64, [2.0, 0.0]);
    let mut highest = 0;
    let event = loop {
        // Up to the crossing in pieces, to see the orders the history went through.
        let stop = (t + 10.0).min(3000.0);
        match integ.advance(&sys, &mut t, &mut x, stop).unwrap() {
            Advance::Event { .. } => break t,
            Advance::Reached if t >= 3000.0 => panic!("x1 crosses zero near t = 807 s"),
            Advance::Reached => highest = highest.max(integ.implicit.dense_order),
        }
    };
    let (order, jacobians, steps) = (integ.implicit.dense_order, integ.n_jacobians(), integ.n_steps());
    println!("event at {event:.3} s: highest order before {highest}, order of the step that crossed {order}");
    assert!(highest >= 3, "the slow phase ran at order {highest}");
    // Just past the event: one step, the first of the new history.
    integ.advance(&sys, &mut t, &mut x, event.next_up()).unwrap();
    assert_eq!(integ.n_steps(), steps + 1);
    assert_eq!(integ.implicit.dense_order, 1, "the first step after the event");
    assert_eq!(integ.n_jacobians(), jacobians + 1, "a new Jacobian at the event");
}

/// The Jacobian three ways at one point of Robertson's problem: analytic, forward differences
/// and directional derivatives agree (differences to about sqrt(eps) of the entry scale).
#[test]
fn jacobians_by_differences_and_directional_derivatives_agree_with_the_analytic_one() {
    let x = [0.9, 3e-5, 0.1];
    let want = Robertson::jacobian(&x);
    for exact in [false, true] {
        let sys = Robertson { exact };
        let mut im = Implicit::default();
        im.prepare(&sys, 3);
        let mut f = [0.0; 3];
        sys.rhs(0.0, &x, &mut f);
        assert!(im.setup(&sys, 0.0, &x, &f, 1e-3, 1e-3, 1e-6, 1e-10));
        for (i, row) in want.iter().enumerate() {
            // Differences: sqrt(eps) relative increments leave about 1e-8 of the row's scale.
            let scale = row.iter().map(|v| v.abs()).fold(0.0, f64::max);
            let tol = if exact { 1e-15 * scale } else { 1e-6 * scale };
            for (j, w) in row.iter().enumerate() {
                let got = im.jac[i * 3 + j];
                assert!((got - w).abs() <= tol, "directional {exact}: J[{i}][{j}] = {got} vs {w}");
            }
        }
        assert_eq!(im.n_jacobian_columns, 3);
    }
}

/// Directional derivatives by groups of columns (the tridiagonal chain's three, through
/// `directional_columns` with several states a group) give the Jacobian of the columns one at a
/// time (the unit groups, the pattern left out) to the bit, and both the analytic one: in a
/// group each row has one seeded state, so its product is that entry times one plus zeros.
#[test]
fn grouped_directional_columns_give_the_column_by_column_jacobian() {
    /// The chain with its exact Jacobian products, with or without its pattern.
    struct Exact<'a>(&'a Chain, bool);
    impl Exact<'_> {
        fn entry(&self, x: &[f64], i: usize, j: usize) -> f64 {
            let n = self.0.n;
            match j {
                _ if j == i => -2e3 * x[i] - (i as f64 + 1.0),
                _ if j + 1 == i => 10.0 * if i + 1 < n { x[i + 1] } else { 0.5 },
                _ if j == i + 1 => 10.0 * if i > 0 { x[i - 1] } else { 1.0 },
                _ => 0.0,
            }
        }
    }
    impl OdeSystem for Exact<'_> {
        fn dim(&self) -> usize {
            self.0.n
        }
        fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
            self.0.rhs(t, x, dx)
        }
        fn jacobian_pattern(&self) -> Option<&[Vec<usize>]> {
            self.1.then_some(&self.0.pattern[..])
        }
        fn provides_directional_derivative(&self) -> bool {
            true
        }
        fn directional_derivative(&self, _t: f64, x: &[f64], v: &[f64], out: &mut [f64]) {
            for (i, o) in out.iter_mut().enumerate() {
                *o = self.0.pattern[i].iter().map(|&j| self.entry(x, i, j) * v[j]).sum();
            }
        }
    }
    let chain = Chain::new(10);
    let x: Vec<f64> = (0..10).map(|i| 0.1 + 0.01 * i as f64).collect();
    let mut f = vec![0.0; 10];
    chain.rhs(0.0, &x, &mut f);
    let jacobian = |sys: &Exact| {
        let mut im = Implicit::default();
        im.prepare(sys, 10);
        assert!(im.setup(sys, 0.0, &x, &f, 1e-3, 1e-3, 1e-6, 1e-10));
        (im.jac, im.n_jacobian_columns, im.n_directional)
    };
    let (grouped, by_column) = (jacobian(&Exact(&chain, true)), jacobian(&Exact(&chain, false)));
    assert_eq!((grouped.1, grouped.2, by_column.1, by_column.2), (3, 3, 10, 10));
    assert_eq!(grouped.0, by_column.0);
    let exact = Exact(&chain, true);
    for (k, got) in grouped.0.iter().enumerate() {
        assert_eq!(*got, exact.entry(&x, k / 10, k % 10), "J[{}][{}]", k / 10, k % 10);
    }
}

/// Column grouping from the dependency pattern: a tridiagonal Jacobian of 10 columns takes 3
/// evaluations, and the grouped differences equal the column-by-column ones.
#[test]
fn grouped_columns_cost_fewer_evaluations_and_give_the_same_jacobian() {
    let chain = Chain::new(10);
    let (groups, rows) = column_groups(10, chain.jacobian_pattern());
    assert_eq!(groups.len(), 3, "{groups:?}");
    assert_eq!(rows[4], vec![3, 4, 5]);
    let x: Vec<f64> = (0..10).map(|i| 0.1 + 0.01 * i as f64).collect();
    let mut f = vec![0.0; 10];
    chain.rhs(0.0, &x, &mut f);
    let mut grouped = Implicit::default();
    grouped.prepare(&chain, 10);
    assert!(grouped.setup(&chain, 0.0, &x, &f, 1e-3, 1e-3, 1e-6, 1e-10));
    assert_eq!(grouped.n_jacobian_columns, 3);
    struct Dense<'a>(&'a Chain);
    impl OdeSystem for Dense<'_> {
        fn dim(&self) -> usize {
            self.0.n
        }
        fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
            self.0.rhs(t, x, dx)
        }
    }
    let mut dense = Implicit::default();
    dense.prepare(&Dense(&chain), 10);
    assert!(dense.setup(&Dense(&chain), 0.0, &x, &f, 1e-3, 1e-3, 1e-6, 1e-10));
    assert_eq!(dense.n_jacobian_columns, 10);
    assert_eq!(grouped.jac, dense.jac, "the same increments give the same quotients");
    // And the whole integration with the pattern costs fewer evaluations.
    let x0 = vec![0.5; 10];
    let (xa, a) = run(&chain, Method::Bdf, 1e-6, 1e-10, &x0, 10.0);
    let (xb, b) = run(&Dense(&chain), Method::Bdf, 1e-6, 1e-10, &x0, 10.0);
    println!("grouped: {} rhs, column by column: {} rhs", a.n_rhs(), b.n_rhs());
    assert!(a.n_rhs() < b.n_rhs());
    assert!(xa.iter().zip(&xb).all(|(p, q)| (p - q).abs() < 1e-5));
}

/// A right-hand side that cannot be evaluated (NaN, as an FMU's Discard arrives) in part of the
/// state space: the step shrinks and integration goes on; everywhere NaN is an error.
#[test]
fn a_failing_right_hand_side_shrinks_the_step_or_stops_with_an_error() {
    /// x' = -1000 (x - 1), refused below x = 0.5 (a trial step overshooting from x0 = 0 is not).
    struct Touchy;
    impl OdeSystem for Touchy {
        fn dim(&self) -> usize {
            1
        }
        fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
            dx[0] = if x[0] > 1.5 || t > 2.5 { f64::NAN } else { -1000.0 * (x[0] - 1.0) };
        }
    }
    for m in IMPLICIT {
        let (x, integ) = run(&Touchy, m, 1e-6, 1e-9, &[0.0], 2.0);
        assert!((x[0] - 1.0).abs() < 1e-6, "{m:?}: {x:?}");
        println!("{m:?}: {} Newton failures", integ.n_newton_failures());
        let mut integ = Integrator::new(settings(m, 1e-6, 1e-9), 1, 0);
        let (mut t, mut x) = (0.0, [0.0]);
        let err = integ.advance(&Touchy, &mut t, &mut x, 5.0).unwrap_err();
        assert!(matches!(err, SolverError::NonFinite { .. } | SolverError::StepSizeTooSmall { .. }), "{m:?}: {err}");
        assert!(t <= 2.5 && (x[0] - 1.0).abs() < 1e-5, "{m:?}: stopped at {t} with {x:?}");
    }
}
