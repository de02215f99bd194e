#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// Ex. 1: `a2 q'' + a1 q' + a0 q = exp(-3t)`.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct SecondOrder<T = f64> {
    /// Coefficient of q''
    #[parameter(finite)]
    pub a2: T,
    /// Coefficient of q'
    #[parameter(finite)]
    pub a1: T,
    /// Coefficient of q
    #[parameter(finite)]
    pub a0: T,
    /// Initial value q(0)
    #[parameter(finite)]
    pub q0: T,
    /// Initial rate q'(0)
    #[parameter(finite)]
    pub q_dot0: T,
    /// Input u(t) = exp(-3t)
    #[output]
    pub u: T,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Response q(t)
    pub q: T,
    /// Rate q'(t)
    pub q_dot: T,
}

impl Default for SecondOrder {
    fn default() -> Self {
        SecondOrder { a2: 2.0, a1: 10.0, a0: 12.0, q0: 2.0, q_dot0: 1.0, u: 1.0 }
    }
}

/// The forcing of Ex. 1.
fn forcing<T: Scalar>(t: T) -> T {
    (t * -3.0).exp()
}

impl<T: Scalar> Equations<T> for SecondOrder<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        if self.a2 == T::zero() {
            return Err(ModelError("parameter a2 = 0 makes the equation first order: a2 must not be zero".into()));
        }
        State { q: self.q0, q_dot: self.q_dot0 }.store(x);
        Ok(())
    }

    /// q' = q_dot, q'' = (u - a1 q' - a0 q) / a2.
    #[inline]
    fn derivatives(&self, t: T, x: &[T], dx: &mut [T]) {
        let State { q, q_dot } = State::load(x);
        State { q: q_dot, q_dot: (forcing(t) - self.a1 * q_dot - self.a0 * q) / self.a2 }.store(dx);
    }

    fn outputs(&mut self, t: T, _x: &[T]) {
        self.u = forcing(t);
    }
}

impl Model for SecondOrder {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "second_order",
            description: "ME326 Ex. 1: 2 q'' + 10 q' + 12 q = exp(-3t), q(0) = 2, q'(0) = 1",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 0.01,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(SecondOrder);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use fmu_export::harness::{jacobian, Stage};
    use formulas::Formula;
    use formulas::References;

    /// A closed form of experiment.toml's `[compare.reference]` (derived in derivation.md, for
    /// the default parameters): the one `runner compare` and tests/fmpy evaluate too.
    fn reference(output: &str) -> Formula {
        let experiment: toml::Table = include_str!("../experiment.toml").parse().expect("experiment.toml is TOML");
        let text = experiment["compare"]["reference"][output].as_str().expect("a formula");
        let formula = Formula::parse(text).expect("a valid formula");
        assert_eq!(formula.names, ["t"], "{output} = {text} should depend on t alone");
        formula
    }

    /// (q, q') of the closed form at `t`.
    fn exact(t: f64) -> (f64, f64) {
        (reference("q").evaluate(&[t]), reference("q_dot").evaluate(&[t]))
    }

    fn max_error(h: &mut Harness<SecondOrder>, dt: f64) -> f64 {
        let traj = h.run(10.0, dt, &["q", "q_dot"]).unwrap();
        traj.time
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let (q, qd) = exact(*t);
                (traj.get("q")[k] - q).abs().max((traj.get("q_dot")[k] - qd).abs())
            })
            .fold(0.0, f64::max)
    }

    /// DOPRI5 against the analytical solution: at rtol 1e-10 the global error over 10 s stays
    /// within a small multiple of the tolerance times the solution's scale (|q| <= 2.2).
    #[test]
    fn dopri5_matches_the_analytical_solution() {
        let mut h = Harness::<SecondOrder>::new();
        h.set("abs_tol", 1e-12).unwrap();
        h.initialize(Some(1e-10)).unwrap();
        let err = max_error(&mut h, 0.01);
        assert!(err < 1e-8, "max error {err}");
    }

    /// RK4 at h = 1e-3: its global error is O(h^4) ~ 1e-12 times the derivatives' scale, so 1e-9 holds with margin.
    #[test]
    fn rk4_matches_the_analytical_solution() {
        let mut h = Harness::<SecondOrder>::new();
        h.set("solver", 1.0).unwrap();
        h.initialize(None).unwrap();
        assert!(max_error(&mut h, 0.01) < 1e-9);
    }

    /// Forward Euler is first order: halving the step halves the error (ratio near 2).
    #[test]
    fn euler_converges_at_first_order() {
        let errs: Vec<f64> = [1e-3, 5e-4]
            .iter()
            .map(|step| {
                let mut h = Harness::<SecondOrder>::new();
                h.set("solver", 0.0).unwrap();
                h.set("fixed_step", *step).unwrap();
                h.initialize(None).unwrap();
                max_error(&mut h, 0.01)
            })
            .collect();
        let ratio = errs[0] / errs[1];
        assert!((ratio - 2.0).abs() < 0.1, "errors {errs:?}, ratio {ratio}");
    }

    /// The output u against experiment.toml's u = exp(-3*t) (and the formula against the
    /// handbook's value at t = 0.5), to rounding.
    #[test]
    fn outputs_the_input_signal() {
        let mut h = Harness::<SecondOrder>::new();
        h.initialize(None).unwrap();
        h.step(0.5).unwrap();
        let u = reference("u").evaluate(&[0.5]);
        assert!((u - (-1.5f64).exp()).abs() < 1e-16);
        assert!((h.get("u").unwrap() - u).abs() < 1e-15);
    }

    /// The closed form satisfies the initial conditions q(0) = 2, q'(0) = 1 and the equation
    /// 2 q'' + 10 q' + 12 q = exp(-3t), q'' by a central difference of q' (h = 1e-5: truncation
    /// ~1e-10, rounding ~1e-11): a check of the reference itself, independent of the solver.
    #[test]
    fn the_reference_solves_the_initial_value_problem() {
        let p = SecondOrder::default();
        assert_eq!(exact(0.0), (p.q0, p.q_dot0));
        let h = 1e-5;
        for t in [0.1, 0.5, 1.0, 2.0, 5.0] {
            let (q, q_dot) = exact(t);
            let q_ddot = (exact(t + h).1 - exact(t - h).1) / (2.0 * h);
            let residual = p.a2 * q_ddot + p.a1 * q_dot + p.a0 * q - forcing(t);
            assert!(residual.abs() < 1e-8, "t = {t}: residual {residual:e}");
            assert!(((exact(t + h).0 - exact(t - h).0) / (2.0 * h) - q_dot).abs() < 1e-8, "t = {t}: q' is not dq/dt");
        }
    }

    #[test]
    fn zero_leading_coefficient_is_refused_by_name() {
        let mut h = Harness::<SecondOrder>::new();
        h.set("a2", 0.0).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(err.contains("a2"), "{err}");
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<SecondOrder>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<SecondOrder>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }

    /// references.toml: the state-space form written from the equation (derivation.md).
    fn references() -> References {
        References::from_toml(include_str!("../references.toml")).expect("valid references")
    }

    /// The exact Jacobian of the FMU's derivatives with respect to its states is A of
    /// references.toml, and with respect to time b u'(t), to rounding (a few ulps of the
    /// largest entry: both sides evaluate the same quotients); its eigenvalues are the roots of
    /// the handbook's characteristic polynomial 2 s^2 + 10 s + 12, -2 and -3, to 1e-14.
    #[test]
    fn the_jacobian_is_the_state_matrix_and_its_eigenvalues_the_handbook_roots() {
        let p = SecondOrder::default();
        let values = [("a2", p.a2), ("a1", p.a1), ("a0", p.a0), ("t", 0.7)];
        let j = jacobian(&p, 0.7, &[0.3, -1.1], Stage::ContinuousTime);
        let a = references().matrix("A", &values).unwrap();
        let dfdt = references().matrix("dfdt", &values).unwrap();
        let exact = j.block(&["der(q)", "der(q_dot)"], &["q", "q_dot"]);
        let time = j.block(&["der(q)", "der(q_dot)"], &["time"]);
        for (got, want) in [(&exact, &a), (&time, &dfdt)] {
            let scale = want.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
                assert!((g - w).abs() <= 4.0 * f64::EPSILON * scale, "{got:?} vs {want:?}");
            }
        }
        // The eigenvalues of a 2x2 matrix: trace/2 ± sqrt((trace/2)^2 - det).
        let (tr, det) = (exact[0][0] + exact[1][1], exact[0][0] * exact[1][1] - exact[0][1] * exact[1][0]);
        let root = ((tr / 2.0).powi(2) - det).sqrt();
        let (fast, slow) = (tr / 2.0 - root, tr / 2.0 + root);
        let (want_fast, want_slow) = (references().value("s_fast", &values).unwrap(), references().value("s_slow", &values).unwrap());
        assert!((fast - want_fast).abs() < 1e-14 && (slow - want_slow).abs() < 1e-14, "{fast} {slow}");
        assert_eq!((want_fast, want_slow), (-3.0, -2.0));
    }

    /// Issue 37: a2 = 1e-30 makes the equation stiff, eigenvalues -a1/a2 = -1e31 and about
    /// -1.2: DOPRI5, stable only for steps under 3.3/1e31 s, would need 3e28 steps for one
    /// 10 ms communication step. fmi2DoStep and fmi3DoStep return fmiError after
    /// MAX_STEPS_PER_CALL attempts, the logged line suggesting the implicit methods, and with
    /// solver = 5 (BDF) the same step succeeds: the bound refuses the method, not the model.
    /// The time is a hang guard only (about a second in a debug build).
    #[test]
    fn a_stiff_extreme_is_refused_by_dopri5_within_the_step_bound_and_bdf_takes_it() {
        use fmu_export::harness::{c_api_step, FmiVersion};
        use fmu_export::solvers::MAX_STEPS_PER_CALL;
        for version in [FmiVersion::Fmi2, FmiVersion::Fmi3] {
            let step = c_api_step::<SecondOrder>(version, &[("a2", 1e-30)], 0.01).unwrap();
            println!("{version:?}: status {} in {:.2?}: {:?}", step.status, step.took, step.messages);
            assert_eq!(step.status, 3, "{version:?}: fmiError");
            let limit = format!("after {MAX_STEPS_PER_CALL} step attempts in one call");
            let line = step.messages.iter().find(|m| m.contains(&limit)).unwrap_or_else(|| panic!("{:?}", step.messages));
            assert!(line.starts_with("3: ") && line.contains("gave up at t = ") && line.contains("with a step size of "), "{line}");
            assert!(line.contains("is the model stiff (then try the implicit methods, bdf or esdirk)"), "{line}");
            assert!(step.took < std::time::Duration::from_secs(120), "{version:?}: {:.2?}", step.took);
            assert_eq!(step.states, [Some(2.0), Some(1.0)], "{version:?}: the state at the step's start");
            assert_eq!(step.reset_status, 0, "{version:?}: fmiReset after the error");
            let bdf = c_api_step::<SecondOrder>(version, &[("a2", 1e-30), ("solver", 5.0)], 0.01).unwrap();
            assert_eq!(bdf.status, 0, "{version:?}: BDF takes the step: {:?}", bdf.messages);
        }
    }
}
