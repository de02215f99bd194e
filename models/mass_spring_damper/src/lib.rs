#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::{INCH, LBF};
use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// `m x'' + b x' + k x = F(t)`, F an input.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct MassSpringDamper<T = f64> {
    /// Mass (2 lbf.s2/in)
    #[parameter(unit = "kg", display = "lbf.s2/in", positive)]
    pub m: T,
    /// Damping coefficient (1 lbf.s/in)
    #[parameter(unit = "N.s/m", display = "lbf.s/in", non_negative)]
    pub b: T,
    /// Spring stiffness (10 lbf/in)
    #[parameter(unit = "N/m", display = "lbf/in", non_negative)]
    pub k: T,
    /// Initial displacement
    #[parameter(unit = "m", display = "in", finite)]
    pub x0: T,
    /// Initial velocity
    #[parameter(unit = "m/s", display = "in/s", finite)]
    pub v0: T,
    /// Applied force F(t)
    #[input(name = "F", unit = "N", display = "lbf")]
    pub force: T,
    /// Acceleration
    #[output(unit = "m/s2", display = "in/s2")]
    pub a: T,
    /// Force through spring and damper, k x + b v
    #[output(name = "F_total", unit = "N", display = "lbf")]
    pub f_total: T,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Displacement
    #[state(unit = "m", display = "in")]
    pub x: T,
    /// Velocity
    #[state(unit = "m/s", display = "in/s")]
    pub v: T,
}

impl Default for MassSpringDamper {
    fn default() -> Self {
        MassSpringDamper { m: 2.0 * LBF / INCH, b: LBF / INCH, k: 10.0 * LBF / INCH, x0: 0.0, v0: 0.0, force: 0.0, a: 0.0, f_total: 0.0 }
    }
}

impl<T: Scalar> MassSpringDamper<T> {
    /// Acceleration from Newton's second law.
    #[inline]
    fn acceleration(&self, x: T, v: T) -> T {
        (self.force - self.b * v - self.k * x) / self.m
    }
}

impl<T: Scalar> Equations<T> for MassSpringDamper<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        State { x: self.x0, v: self.v0 }.store(x);
        Ok(())
    }

    #[inline]
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        State { x: s.v, v: self.acceleration(s.x, s.v) }.store(dx);
    }

    /// The App. B output equation y = C x + D u.
    fn outputs(&mut self, _t: T, x: &[T]) {
        let s = State::load(x);
        self.a = self.acceleration(s.x, s.v);
        self.f_total = self.k * s.x + self.b * s.v;
    }
}

impl Model for MassSpringDamper {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "mass_spring_damper",
            description: "ME326 Ex. 4 prelab, App. A/B: m x'' + b x' + k x = F(t), F an input",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 0.01,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(MassSpringDamper);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use fmu_export::harness::{jacobian, Stage};
    use formulas::Formula;
    use formulas::References;

    /// The underdamped free vibration of experiment.toml's `[compare.reference]` (derivation.md),
    /// the closed form `runner compare` and tests/fmpy evaluate too, at `t` from (x0, v0).
    fn free(p: &MassSpringDamper, x0: f64, v0: f64, t: f64) -> (f64, f64) {
        let experiment: toml::Table = include_str!("../experiment.toml").parse().expect("experiment.toml is TOML");
        let value = |output: &str| {
            let formula = Formula::parse(experiment["compare"]["reference"][output].as_str().expect("a formula")).expect("valid");
            let values: Vec<f64> = formula
                .names
                .iter()
                .map(|name| match name.as_str() {
                    "t" => t,
                    "m" => p.m,
                    "b" => p.b,
                    "k" => p.k,
                    "x0" => x0,
                    "v0" => v0,
                    other => panic!("the reference reads {other}, which this test does not give"),
                })
                .collect();
            formula.evaluate(&values)
        };
        (value("x"), value("v"))
    }

    /// The response to a constant force `f0` from p's x0, v0: the free vibration about the
    /// shifted equilibrium f0/k (x - f0/k obeys the unforced equation).
    fn exact(p: &MassSpringDamper, f0: f64, t: f64) -> (f64, f64) {
        let (x, v) = free(p, p.x0 - f0 / p.k, p.v0, t);
        (f0 / p.k + x, v)
    }

    /// The reference itself, independent of the solver: it starts at (x0, v0), v is dx/dt,
    /// and m x'' + b x' + k x = 0 holds, x'' by a central difference of v (h = 1e-5: truncation
    /// ~1e-10 of |a| <= 0.2 m/s², rounding ~1e-11; bound 1e-7 N on forces of ~50 N).
    #[test]
    fn the_reference_solves_the_free_vibration() {
        let p = MassSpringDamper::default();
        let (x0, v0) = (0.0254, -0.1);
        assert_eq!(free(&p, x0, v0, 0.0), (x0, v0));
        let h = 1e-5;
        for t in [0.3, 1.0, 2.5, 7.0] {
            let ((x, v), (xp, vp), (xm, vm)) = (free(&p, x0, v0, t), free(&p, x0, v0, t + h), free(&p, x0, v0, t - h));
            assert!(((xp - xm) / (2.0 * h) - v).abs() < 1e-8, "t = {t}: v is not dx/dt");
            let residual = p.m * (vp - vm) / (2.0 * h) + p.b * v + p.k * x;
            assert!(residual.abs() < 1e-7, "t = {t}: residual {residual:e} N");
        }
    }

    /// The prelab's values in SI: the ratios k/m and b/m do not depend on the unit factors.
    #[test]
    fn handbook_values_in_si() {
        let p = MassSpringDamper::default();
        assert!((p.k - 1_751.268_352_464_76).abs() < 1e-8);
        assert!((p.k / p.m - 5.0).abs() < 1e-14 && (p.b / p.m - 0.5).abs() < 1e-14);
    }

    /// A step force from an initial displacement, against the closed form; at rtol 1e-10 the
    /// error stays below 1e-9 of the response's scale (F0/k ~ 0.057 m).
    #[test]
    fn step_response_matches_the_analytical_solution() {
        let mut h = Harness::<MassSpringDamper>::new();
        h.set("x0", 0.01).unwrap();
        h.set("v0", -0.02).unwrap();
        h.set("F", 100.0).unwrap();
        h.set("abs_tol", 1e-13).unwrap();
        h.initialize(Some(1e-10)).unwrap();
        let traj = h.run(10.0, 0.01, &["x", "v", "a", "F_total"]).unwrap();
        let p = MassSpringDamper { x0: 0.01, v0: -0.02, ..Default::default() };
        for (k, t) in traj.time.iter().enumerate() {
            let (x, v) = exact(&p, 100.0, *t);
            assert!((traj.get("x")[k] - x).abs() < 1e-10, "x at t={t}");
            assert!((traj.get("v")[k] - v).abs() < 1e-10, "v at t={t}");
            // Outputs are the App. B output equation y = C x + D u.
            let a = (100.0 - p.b * traj.get("v")[k] - p.k * traj.get("x")[k]) / p.m;
            assert!((traj.get("a")[k] - a).abs() < 1e-9);
            assert!((traj.get("F_total")[k] - (p.k * traj.get("x")[k] + p.b * traj.get("v")[k])).abs() < 1e-9);
        }
    }

    /// The input is held over a step: switching F mid-run gives the superposition of two steps.
    #[test]
    fn input_changes_between_steps_are_honoured() {
        let mut h = Harness::<MassSpringDamper>::new();
        h.set("abs_tol", 1e-13).unwrap();
        h.initialize(Some(1e-10)).unwrap();
        h.set("F", 50.0).unwrap();
        for _ in 0..100 {
            h.step(0.01).unwrap();
        }
        h.set("F", 0.0).unwrap();
        for _ in 0..100 {
            h.step(0.01).unwrap();
        }
        let p = MassSpringDamper::default();
        // F(t) = 50 (H(t) - H(t-1)): response is x50(t) - x50(t-1).
        let x = exact(&p, 50.0, 2.0).0 - exact(&p, 50.0, 1.0).0;
        assert!((h.get("x").unwrap() - x).abs() < 1e-10);
    }

    #[test]
    fn non_physical_parameters_are_refused_by_name() {
        for (name, value) in [("m", 0.0), ("m", -1.0), ("k", -5.0), ("b", -1.0)] {
            let mut h = Harness::<MassSpringDamper>::new();
            h.set(name, value).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(err.contains(&format!("parameter {name}")), "{err}");
        }
        let mut h = Harness::<MassSpringDamper>::new();
        assert!(h.set("m", f64::NAN).unwrap_err().contains("m = NaN"));
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<MassSpringDamper>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<MassSpringDamper>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }

    /// The exact Jacobians of the FMU's derivatives and outputs are A, B, C and D of
    /// references.toml (App. B's state-space form), to rounding (a few ulps of each matrix's
    /// largest entry), at a state away from rest and with a force applied.
    #[test]
    fn the_jacobians_are_the_state_space_matrices() {
        let p = MassSpringDamper { force: 3.0, ..Default::default() };
        let refs = References::from_toml(include_str!("../references.toml")).expect("valid references");
        let values = [("m", p.m), ("b", p.b), ("k", p.k)];
        let j = jacobian(&p, 0.0, &[0.02, -0.1], Stage::ContinuousTime);
        let (states, derivatives, outputs) = (["x", "v"], ["der(x)", "der(v)"], ["a", "F_total"]);
        for (name, got) in [
            ("A", j.block(&derivatives, &states)),
            ("B", j.block(&derivatives, &["F"])),
            ("C", j.block(&outputs, &states)),
            ("D", j.block(&outputs, &["F"])),
        ] {
            let want = refs.matrix(name, &values).unwrap();
            let scale = want.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
            for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
                assert!((g - w).abs() <= 4.0 * f64::EPSILON * scale, "{name}: {got:?} vs {want:?}");
            }
        }
    }
}
