#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::DEGREE;
use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// Ex. 2: `m L² theta'' = -m g L sin(theta) - c theta'`, theta from the downward vertical.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct Pendulum<T = f64> {
    /// Rod length, pivot to bob
    #[parameter(name = "L", unit = "m", positive)]
    pub l: T,
    /// Bob mass (point mass)
    #[parameter(unit = "kg", positive)]
    pub m: T,
    /// Gravitational acceleration
    // g > 0: without gravity there is no pendulum (and no restoring torque).
    #[parameter(unit = "m/s2", positive)]
    pub g: T,
    /// Initial angle from the downward vertical, counter-clockwise
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta0: T,
    /// Initial angular velocity
    #[parameter(unit = "rad/s", display = "deg/s", finite)]
    pub omega0: T,
    /// Viscous friction torque coefficient at the pivot
    #[parameter(unit = "N.m.s/rad", non_negative)]
    pub c: T,
    /// Kinetic plus potential energy, zero hanging at rest
    #[output(unit = "J")]
    pub energy: T,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Angle from the downward vertical, counter-clockwise
    #[state(unit = "rad", display = "deg")]
    pub theta: T,
    /// Angular velocity theta'
    #[state(unit = "rad/s", display = "deg/s")]
    pub omega: T,
}

impl Default for Pendulum {
    fn default() -> Self {
        let mut p = Pendulum { l: 0.75, m: 0.5, g: 9.81, theta0: 15.0 * DEGREE, omega0: 0.0, c: 0.0, energy: 0.0 };
        p.energy = p.energy_at(p.theta0, p.omega0);
        p
    }
}

impl<T: Scalar> Pendulum<T> {
    /// E = (1/2) m L² omega² + m g L (1 - cos theta).
    #[inline]
    pub fn energy_at(&self, theta: T, omega: T) -> T {
        self.m * 0.5 * self.l * self.l * omega * omega + self.m * self.g * self.l * (T::one() - theta.cos())
    }
}

impl<T: Scalar> Equations<T> for Pendulum<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        State { theta: self.theta0, omega: self.omega0 }.store(x);
        Ok(())
    }

    /// theta' = omega, omega' = -(g/L) sin(theta) - c omega / (m L²).
    #[inline]
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let State { theta, omega } = State::load(x);
        State { theta: omega, omega: -(self.g / self.l) * theta.sin() - self.c * omega / (self.m * self.l * self.l) }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let State { theta, omega } = State::load(x);
        self.energy = self.energy_at(theta, omega);
    }
}

impl Model for Pendulum {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "pendulum",
            description: "ME326 Ex. 2: nonlinear simple pendulum (point mass on a light rod) with optional viscous friction",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 0.01,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(Pendulum);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use formulas::References;
    use std::f64::consts::PI;
    use std::sync::OnceLock;

    /// Entry `name` of references.toml (derivation.md's closed forms, the ones `runner handbook`
    /// and tests/fmpy evaluate too) for the parameters of `p` released from rest at `theta0`.
    fn reference(p: &Pendulum, name: &str, theta0: f64) -> f64 {
        static REFERENCES: OnceLock<References> = OnceLock::new();
        let references = REFERENCES.get_or_init(|| References::from_toml(include_str!("../references.toml")).expect("valid references"));
        references.value(name, &[("L", p.l), ("g", p.g), ("m", p.m), ("theta0", theta0)]).expect("a reference of the parameters")
    }

    /// The exact period of the frictionless pendulum released from rest at `theta0`: 4 sqrt(L/g)
    /// K(sin²(theta0/2)), the complete elliptic integral evaluated by an AGM (metrics' `ellipk`).
    fn exact_period(p: &Pendulum, theta0: f64) -> f64 {
        reference(p, "period", theta0)
    }

    fn run(params: &[(&str, f64)], tolerance: Option<f64>, dt: f64) -> fmu_export::harness::Trajectory {
        let mut h = Harness::<Pendulum>::new();
        for (name, value) in params {
            h.set(name, *value).unwrap();
        }
        h.initialize(tolerance).unwrap();
        h.run(10.0, dt, &["theta", "omega", "energy"]).unwrap()
    }

    /// Zero crossings of theta, each located inside its sample interval by the cubic Hermite
    /// interpolant of (theta, omega = theta') and Newton on it: error O(dt^4), ~1e-12 s at 1 ms.
    fn zero_crossings(traj: &fmu_export::harness::Trajectory) -> Vec<f64> {
        let (t, th, om) = (&traj.time, traj.get("theta"), traj.get("omega"));
        let mut out = Vec::new();
        for k in 0..t.len() - 1 {
            if th[k] == 0.0 || th[k].signum() == th[k + 1].signum() {
                continue;
            }
            let hk = t[k + 1] - t[k];
            let hermite = |s: f64| {
                let (s2, s3) = (s * s, s * s * s);
                let value = (2.0 * s3 - 3.0 * s2 + 1.0) * th[k]
                    + (s3 - 2.0 * s2 + s) * hk * om[k]
                    + (-2.0 * s3 + 3.0 * s2) * th[k + 1]
                    + (s3 - s2) * hk * om[k + 1];
                let slope = (6.0 * s2 - 6.0 * s) * th[k]
                    + (3.0 * s2 - 4.0 * s + 1.0) * hk * om[k]
                    + (-6.0 * s2 + 6.0 * s) * th[k + 1]
                    + (3.0 * s2 - 2.0 * s) * hk * om[k + 1];
                (value, slope)
            };
            let mut s = th[k] / (th[k] - th[k + 1]);
            for _ in 0..20 {
                let (value, slope) = hermite(s);
                s -= value / slope;
            }
            out.push(t[k] + s * hk);
        }
        out
    }

    /// The handbook's two release angles: every zero crossing at T/4 + n T/2 of the exact
    /// elliptic-integral period, to 1e-8 s. DOPRI5 at rtol 1e-11 keeps the phase error over
    /// 10 s (4 to 6 periods) near 1e-10 s; the interpolation adds ~1e-12 s.
    #[test]
    fn period_matches_the_complete_elliptic_integral() {
        let p = Pendulum::default();
        // The reference against a tabulated value: K(m = sin²60°) = 2.156515647499643 at 120 deg,
        // and against the small-angle period 2 pi sqrt(L/g) as theta0 -> 0.
        let scale = 4.0 * (p.l / p.g).sqrt();
        assert!((exact_period(&p, 120.0 * DEGREE) / scale - 2.156_515_647_499_643).abs() < 1e-14);
        let small = reference(&p, "period_small_angle", 0.0);
        assert!((small - 2.0 * PI * (p.l / p.g).sqrt()).abs() < 1e-15 && (exact_period(&p, 1e-4) / small - 1.0).abs() < 1e-9);
        for deg in [15.0, 120.0] {
            let theta0 = deg * DEGREE;
            let period = exact_period(&p, theta0);
            let traj = run(&[("theta0", theta0), ("abs_tol", 1e-13)], Some(1e-11), 1e-3);
            let crossings = zero_crossings(&traj);
            assert!(crossings.len() >= 8, "{deg} deg: only {} crossings", crossings.len());
            for (n, tc) in crossings.iter().enumerate() {
                let expected = period / 4.0 + n as f64 * period / 2.0;
                assert!((tc - expected).abs() < 1e-8, "{deg} deg crossing {n}: {tc} vs {expected}");
            }
            let measured = 2.0 * (crossings.last().unwrap() - crossings[0]) / (crossings.len() - 1) as f64;
            assert!((measured - period).abs() < 1e-9, "{deg} deg: period {measured} vs exact {period}");
        }
        // Discussion 1: the large swing is markedly slower than the small one (2.385 vs 1.745 s).
        assert!(exact_period(&p, 120.0 * DEGREE) / exact_period(&p, 15.0 * DEGREE) > 1.36);
    }

    /// c = 0: energy conserved over 10 s. DOPRI5 takes its own steps across the 10 ms
    /// communication points, so the drift is its global error over six periods, about 10 rtol
    /// (measured 9.0e-6 at the default rtol 1e-6, 9.1e-11 at 1e-11): bounds of 20 rtol.
    #[test]
    fn energy_is_conserved_without_friction() {
        for deg in [15.0, 120.0] {
            let theta0 = deg * DEGREE;
            let e0 = Pendulum::default().energy_at(theta0, 0.0);
            // The model's energy at rest against references.toml's m g L (1 - cos theta0).
            assert!((e0 / reference(&Pendulum::default(), "energy", theta0) - 1.0).abs() < 1e-15, "{deg} deg");
            for (tolerance, bound) in [(None, 2e-5), (Some(1e-11), 2e-10)] {
                let traj = run(&[("theta0", theta0), ("abs_tol", 1e-13)], tolerance, 0.01);
                let e = traj.get("energy");
                assert_eq!(e[0], e0);
                let drift = e.iter().map(|v| (v - e0).abs()).fold(0.0, f64::max) / e0;
                assert!(drift < bound, "{deg} deg, rtol {tolerance:?}: relative energy drift {drift:e}");
            }
        }
    }

    /// Forward Euler at the step sizes a student tries: the energy grows by the linearized
    /// factor (1 + h² g/L)^(10/h) = 3.696 (h = 0.01) and 1.140 (h = 0.001) of derivation.md.
    /// At 15 deg the nonlinearity softens the restoring torque by about theta²/8 (~1 %, more
    /// as the amplitude grows), so the growth exponent (1.31 and 0.131 linearized) comes out
    /// smaller, by 2.2 % and 1.1 % in a plain numpy Euler loop: it must be 0 to 5 % smaller.
    #[test]
    fn forward_euler_pumps_energy_in() {
        let p = Pendulum::default();
        let e0 = p.energy_at(p.theta0, 0.0);
        for step in [0.01, 0.001] {
            let traj = run(&[("solver", 0.0), ("fixed_step", step)], None, 0.01);
            let e = traj.get("energy");
            let growth = e.last().unwrap() / e0;
            let linear = (1.0 + step * step * p.g / p.l).powf(10.0 / step);
            assert!(growth > 1.0 + 0.5 * (linear - 1.0), "h = {step}: energy grew only by {growth}");
            let shortfall = 1.0 - growth.ln() / linear.ln();
            assert!((0.0..0.05).contains(&shortfall), "h = {step}: growth {growth} vs linearized {linear}");
            // The amplitude (largest |theta| in the last period) grows along with the energy.
            let late = traj.get("theta").iter().rev().take(200).fold(0.0f64, |a, v| a.max(v.abs()));
            assert!(late > p.theta0 * growth.sqrt() * 0.9, "h = {step}: late amplitude {late}");
        }
    }

    /// c > 0: the energy lost equals the friction work, E0 - E(t) = integral of c omega² dt
    /// (Simpson's rule on the 1 ms output: 3e-12 J on an exact solution). With E0 = 5.52 J and
    /// rtol 1e-11, the solver's share is ~1e-10 J: bound 1e-8 J, 2e-9 of E0.
    #[test]
    fn friction_dissipates_exactly_the_friction_work() {
        let c = 0.05;
        let traj = run(&[("theta0", 120.0 * DEGREE), ("c", c), ("abs_tol", 1e-13)], Some(1e-11), 1e-3);
        let (om, e) = (traj.get("omega"), traj.get("energy"));
        let dt = 1e-3;
        let mut work = 0.0;
        for k in (0..om.len() - 2).step_by(2) {
            work += c * dt / 3.0 * (om[k].powi(2) + 4.0 * om[k + 1].powi(2) + om[k + 2].powi(2));
            let balance = e[0] - e[k + 2] - work;
            assert!(balance.abs() < 1e-8, "energy balance off by {balance:e} J at t = {}", traj.time[k + 2]);
        }
        assert!(e.last().unwrap() < &(0.5 * e[0]), "friction c = {c} should remove over half the energy in 10 s");
    }

    #[test]
    fn hanging_at_rest_has_zero_energy_and_stays() {
        let traj = run(&[("theta0", 0.0)], None, 0.1);
        assert!(traj.get("energy").iter().chain(traj.get("theta")).all(|v| *v == 0.0));
    }

    /// Names, state indices, units and display units of the table are all known to the toolkit.
    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<Pendulum>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    #[test]
    fn non_physical_parameters_are_refused_by_name() {
        for (name, value) in [("L", 0.0), ("L", -0.75), ("m", 0.0), ("g", 0.0), ("c", -0.1)] {
            let mut h = Harness::<Pendulum>::new();
            h.set(name, value).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(err.contains(&format!("parameter {name}")), "{err}");
        }
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<Pendulum>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<Pendulum>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }

    /// The exact Jacobian at angles around the circle (with friction) equals references.toml's
    /// analytic one to rounding (a few ulps of its largest entry), and so does the energy's
    /// gradient; at theta = 0 without friction its eigenvalues are +-i sqrt(g/L), the
    /// small-angle angular frequency, to 1e-14 relative.
    #[test]
    fn the_jacobian_is_the_analytic_one_at_any_angle() {
        use fmu_export::harness::{jacobian, Stage};
        let refs = References::from_toml(include_str!("../references.toml")).expect("valid references");
        let p = Pendulum { c: 0.02, ..Default::default() };
        for k in 0..24 {
            let (theta, omega) = (-PI + k as f64 * PI / 12.0 + 0.1, 0.7 - 0.1 * k as f64);
            let values = [("L", p.l), ("g", p.g), ("m", p.m), ("c", p.c), ("theta", theta), ("omega", omega)];
            let j = jacobian(&p, 0.0, &[theta, omega], Stage::ContinuousTime);
            for (got, name) in [
                (j.block(&["der(theta)", "der(omega)"], &["theta", "omega"]), "jacobian"),
                (j.block(&["energy"], &["theta", "omega"]), "energy_gradient"),
            ] {
                let want = refs.matrix(name, &values).unwrap();
                let scale = want.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
                for (g, w) in got.iter().flatten().zip(want.iter().flatten()) {
                    assert!((g - w).abs() <= 4.0 * f64::EPSILON * scale, "{name} at theta = {theta}: {got:?} vs {want:?}");
                }
            }
        }
        let free = Pendulum::default();
        let a = jacobian(&free, 0.0, &[0.0, 0.0], Stage::ContinuousTime).block(&["der(theta)", "der(omega)"], &["theta", "omega"]);
        // Eigenvalues of [[0, 1], [-w^2, 0]]: +-i sqrt(-a10 a01) (zero trace).
        assert_eq!(a[0][0] + a[1][1], 0.0);
        let frequency = (-(a[1][0] * a[0][1])).sqrt();
        let want = refs.value("omega_small_angle", &[("g", free.g), ("L", free.l)]).unwrap();
        assert!((frequency - want).abs() <= 1e-14 * want, "{frequency} vs {want}");
    }

    /// Issue 37: a pendulum 1e-20 m long swings at sqrt(g/L) = 3.1e10 rad/s, so DOPRI5 needs
    /// some 1e10 steps for one 10 ms communication step (hours, before the bound). fmi2DoStep and
    /// fmi3DoStep now return fmiError once the step has taken MAX_STEPS_PER_CALL step attempts,
    /// with one logged Error line naming the time reached, the count, the step size and the
    /// hint; the states read afterwards are those at the step's start (the failed step is
    /// undone), and fmiReset and fmiFreeInstance still work. The time is a hang guard only: a
    /// million steps of this model take about a second in a debug build.
    #[test]
    fn an_extreme_length_ends_the_step_with_an_error_within_the_step_bound() {
        use fmu_export::harness::{c_api_step, FmiVersion};
        use fmu_export::solvers::MAX_STEPS_PER_CALL;
        for version in [FmiVersion::Fmi2, FmiVersion::Fmi3] {
            let step = c_api_step::<Pendulum>(version, &[("L", 1e-20)], 0.01).unwrap();
            println!("{version:?}: status {} in {:.2?}: {:?}", step.status, step.took, step.messages);
            assert_eq!(step.status, 3, "{version:?}: fmiError");
            let limit = format!("after {MAX_STEPS_PER_CALL} step attempts in one call");
            let line = step.messages.iter().find(|m| m.contains(&limit)).unwrap_or_else(|| panic!("{:?}", step.messages));
            assert!(line.starts_with("3: ") && line.contains("between t = 0 and t = 0.01"), "{line}");
            assert!(line.contains("gave up at t = ") && line.contains("with a step size of ") && line.contains("extreme"), "{line}");
            assert!(step.took < std::time::Duration::from_secs(120), "{version:?}: {:.2?}", step.took);
            assert_eq!(step.states, [Some(15.0 * fmu_export::units::DEGREE), Some(0.0)], "{version:?}: the state at the step's start");
            assert_eq!(step.reset_status, 0, "{version:?}: fmiReset after the error");
        }
    }
}
