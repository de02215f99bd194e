#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::{Equations, EventOutcome, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// Ex. 3: a mass pushes a massless spring-damper plate until the contact force vanishes,
/// then coasts while the plate relaxes.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct Bumper<T = f64> {
    /// Mass of the moving body
    #[parameter(name = "M", unit = "kg", positive)]
    pub mass: T,
    /// Bumper spring stiffness
    #[parameter(name = "K", unit = "N/m", positive)]
    pub k: T,
    /// Bumper damping coefficient
    // B > 0: after release the massless plate's law B x' + K x = 0 needs a damper.
    #[parameter(name = "B", unit = "N.s/m", positive)]
    pub b: T,
    /// Speed of the mass at the collision (toward the bumper)
    // V0 > 0: the mass must be moving toward the bumper for a collision to happen.
    #[parameter(name = "V0", unit = "m/s", positive)]
    pub v0: T,
    /// True: the mass stays fastened to the plate (no release)
    #[parameter]
    pub attached: bool,
    /// Plate velocity
    #[output(unit = "m/s")]
    pub v: T,
    /// Plate acceleration
    #[output(unit = "m/s2")]
    pub a: T,
    /// Contact force between plate and mass, K x + B v (0 after release)
    #[output(name = "F_contact", unit = "N")]
    pub f_contact: T,
    /// True while the mass touches the plate
    #[output]
    pub in_contact: bool,
    /// Time the mass left the plate (-1 until it has)
    #[output(unit = "s", discrete)]
    pub t_release: T,
}

/// The state vector: the plate's displacement, then the mass's (listed with the plate's
/// velocity and acceleration, then the mass's, in the table).
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Plate displacement (compression of the bumper)
    #[state(unit = "m")]
    pub x: T,
    /// Mass displacement
    #[state(unit = "m", after = "a")]
    pub x_mass: T,
    /// Mass velocity
    #[state(unit = "m/s", after = "a")]
    pub v_mass: T,
}

impl Default for Bumper {
    fn default() -> Self {
        let (mass, k, b, v0) = (1000.0, 9850.0, 12500.0, 1.0);
        // Outputs at the collision: the plate moves at V0 and the damper alone pushes back.
        Bumper { mass, k, b, v0, attached: false, v: v0, a: -b * v0 / mass, f_contact: b * v0, in_contact: true, t_release: -1.0 }
    }
}

impl<T: Scalar> Bumper<T> {
    /// Plate velocity and acceleration in the current regime.
    #[inline]
    fn plate_motion(&self, s: &State<T>) -> (T, T) {
        if self.in_contact {
            (s.v_mass, -(self.k * s.x + self.b * s.v_mass) / self.mass)
        } else {
            // The massless plate obeys B x' + K x = 0: x' = -(K/B) x, x'' = (K/B)^2 x.
            let rate = self.k / self.b;
            (-rate * s.x, rate * rate * s.x)
        }
    }
}

impl<T: Scalar> Equations<T> for Bumper<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        self.in_contact = true;
        self.t_release = T::from(-1.0);
        State { x: T::zero(), x_mass: T::zero(), v_mass: self.v0 }.store(x);
        Ok(())
    }

    #[inline]
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        let (v, a) = self.plate_motion(&s);
        // In contact the mass shares the plate's acceleration; separated it coasts.
        State { x: v, x_mass: s.v_mass, v_mass: if self.in_contact { a } else { T::zero() } }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let s = State::load(x);
        (self.v, self.a) = self.plate_motion(&s);
        self.f_contact = if self.in_contact { self.k * s.x + self.b * self.v } else { T::zero() };
    }
}

impl Model for Bumper {
    const N_STATES: usize = State::LEN;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "bumper",
            description: "ME326 Ex. 3: a mass hits a massless spring-damper bumper and separates when the contact force vanishes",
            stop_time: 3.0,
            tolerance: 1e-6,
            output_interval: 1e-3,
            documentation: include_str!("../derivation.md"),
        }
    }

    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        let s = State::load(x);
        // The contact force; once separated (or fastened) nothing can switch, so a constant.
        z[0] = if self.in_contact && !self.attached { self.k * s.x + self.b * s.v_mass } else { 1.0 };
    }

    fn on_event(&mut self, t: f64, _x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        if fired[0] && self.in_contact && !self.attached {
            // x and v carry over: after release v = -(K/B) x, equal to v_mass since K x + B v = 0 here.
            self.in_contact = false;
            self.t_release = t;
        }
        Ok(EventOutcome::Continue)
    }
}

fmu_export::export_fmu!(Bumper);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use formulas::References;
    use std::sync::OnceLock;

    /// Entry `name` of references.toml (derivation.md's closed forms, the ones `runner handbook`
    /// and tests/fmpy evaluate too) at time `t` for the parameters of `p`.
    fn reference(p: &Bumper, name: &str, t: f64) -> f64 {
        static REFERENCES: OnceLock<References> = OnceLock::new();
        let references = REFERENCES.get_or_init(|| References::from_toml(include_str!("../references.toml")).expect("valid references"));
        references
            .value(name, &[("t", t), ("M", p.mass), ("K", p.k), ("B", p.b), ("V0", p.v0)])
            .expect("a reference of t and the parameters")
    }

    /// Regime 1 in closed form (derivation.md): plate (x, x'). The overdamped case (the
    /// handbook's) is references.toml's; the underdamped one is only tested here.
    fn contact(p: &Bumper, t: f64) -> (f64, f64) {
        let sigma = p.b / (2.0 * p.mass);
        let disc = sigma * sigma - p.k / p.mass;
        if disc > 0.0 {
            (reference(p, "x_contact", t), reference(p, "v_contact", t))
        } else {
            let wd = (-disc).sqrt();
            let e = (-sigma * t).exp();
            (p.v0 / wd * e * (wd * t).sin(), p.v0 / wd * e * (wd * (wd * t).cos() - sigma * (wd * t).sin()))
        }
    }

    /// The first zero of the contact force K x + B x' of the closed form, by a scan for the
    /// sign change and bisection to machine precision (independent of the release formula).
    fn release_time(p: &Bumper) -> f64 {
        let force = |t: f64| {
            let (x, v) = contact(p, t);
            p.k * x + p.b * v
        };
        let (mut lo, mut hi) = (0.0, 1e-3);
        while force(hi) > 0.0 {
            lo = hi;
            hi += 1e-3;
        }
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if force(mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    fn tight(params: &[(&str, f64)]) -> Harness<Bumper> {
        let mut all = params.to_vec();
        all.push(("abs_tol", 1e-13));
        Harness::started(&all, Some(1e-11)).unwrap()
    }

    /// derivation.md's numbers: zeta = 1.99 (overdamped) and references.toml's release time
    /// t_r = ln((K + B s2)/(K + B s1))/(s1 - s2) = 2 ln(s2/s1)/(s1 - s2) = 0.485484 s agree
    /// with the bisection on its contact force; the contact closed form starts at (0, V0).
    #[test]
    fn handbook_case_is_overdamped_and_the_release_formula_holds() {
        let p = Bumper::default();
        assert!((p.b / (2.0 * (p.k * p.mass).sqrt()) - 1.991_415_587).abs() < 1e-9);
        let formula = reference(&p, "t_release", 0.0);
        assert!((formula - release_time(&p)).abs() < 1e-13, "{formula} vs {}", release_time(&p));
        assert!((formula - 0.485_484_434_9).abs() < 1e-10);
        let (s1, s2) = (reference(&p, "s1", 0.0), reference(&p, "s2", 0.0));
        assert!((formula - 2.0 * (s2 / s1).ln() / (s1 - s2)).abs() < 1e-15);
        assert_eq!(contact(&p, 0.0), (0.0, p.v0));
        let (x_r, v_r) = contact(&p, formula);
        assert_eq!((reference(&p, "x_release", 0.0), reference(&p, "v_release", 0.0)), (x_r, v_r));
    }

    /// The FMU's located event against the closed-form release time: the toolkit locates it
    /// to 1e-10 s on a dense output accurate to ~rtol, so 1e-8 s has a wide margin. x and v at
    /// t_r (continuous there) against the closed form to 1e-10 m, m/s (rtol 1e-11, scale 1).
    #[test]
    fn release_time_and_state_match_the_closed_form() {
        let p = Bumper::default();
        let t_r = release_time(&p);
        let mut h = tight(&[]);
        h.step(t_r).unwrap();
        let (x_r, v_r) = contact(&p, t_r);
        assert!((h.get("x").unwrap() - x_r).abs() < 1e-10);
        assert!((h.get("v").unwrap() - v_r).abs() < 1e-10);
        assert!((h.get("x_mass").unwrap() - x_r).abs() < 1e-10);
        assert!((h.get("v_mass").unwrap() - v_r).abs() < 1e-10);
        h.step(3.0 - t_r).unwrap();
        let fmu_t_r = h.get("t_release").unwrap();
        assert!((fmu_t_r - t_r).abs() < 1e-8, "t_release {fmu_t_r} vs {t_r}");
        assert_eq!(h.get("in_contact").unwrap(), 0.0);
    }

    /// The whole run on a 1 ms grid: before release the plate and mass follow the closed form
    /// together (x_mass == x bit for bit, same equations); after it the plate follows
    /// x_r exp(-K (t - t_r)/B) and the mass coasts at v_r. Errors bounded by 1e-10 (rtol 1e-11
    /// on values of order 0.06 m and 1 m/s, plus the event's 1e-10 s location error times |v|).
    #[test]
    fn both_regimes_match_the_closed_form() {
        let p = Bumper::default();
        let t_r = release_time(&p);
        let v_r = contact(&p, t_r).1;
        let rate = p.k / p.b;
        let mut h = tight(&[]);
        let names = ["x", "v", "a", "x_mass", "v_mass", "in_contact", "t_release", "F_contact"];
        let traj = h.run(3.0, 1e-3, &names).unwrap();
        let mut after = 0;
        for (k, &t) in traj.time.iter().enumerate() {
            let g = |n: &str| traj.get(n)[k];
            if t < t_r {
                let (x, v) = contact(&p, t);
                assert!((g("x") - x).abs() < 1e-10 && (g("v") - v).abs() < 1e-10, "contact at t={t}");
                assert!((g("a") + (p.k * x + p.b * v) / p.mass).abs() < 1e-9, "a at t={t}");
                assert_eq!(g("x_mass"), g("x"));
                assert_eq!((g("in_contact"), g("t_release")), (1.0, -1.0));
                assert!(g("F_contact") > 0.0);
            } else {
                after += 1;
                let x = reference(&p, "x_separated", t);
                assert!((g("x") - x).abs() < 1e-10, "plate at t={t}: {} vs {x}", g("x"));
                assert!((g("v") + rate * x).abs() < 1e-10 && (g("a") - rate * rate * x).abs() < 1e-10);
                assert!((g("x_mass") - reference(&p, "x_mass_separated", t)).abs() < 1e-10, "mass at t={t}");
                assert!((g("v_mass") - v_r).abs() < 1e-10);
                assert_eq!((g("in_contact"), g("F_contact")), (0.0, 0.0));
            }
        }
        assert!(after > 2000, "the run must cover the separated regime");
    }

    /// Ex. 3 discussion 3: across the release x and v are continuous while a jumps from 0 to
    /// (K/B)² x_r = 0.0379 m/s². Over 2 us around t_r a continuous x moves by at most
    /// |v_r| 2e-6 = 9.6e-8 m and a continuous v by at most max|a| 2e-6 = 7.6e-8 m/s (bounds
    /// 1.1e-7 and 1e-7); a continuous a would move by ~1e-7 m/s², not by 0.038.
    #[test]
    fn position_and_velocity_are_continuous_but_acceleration_jumps() {
        let p = Bumper::default();
        let t_r = release_time(&p);
        let delta = 1e-6;
        let mut h = tight(&[]);
        h.step(t_r - delta).unwrap();
        let before = ["x", "v", "a"].map(|n| h.get(n).unwrap());
        assert_eq!(h.get("in_contact").unwrap(), 1.0);
        h.step(2.0 * delta).unwrap();
        let after = ["x", "v", "a"].map(|n| h.get(n).unwrap());
        assert_eq!(h.get("in_contact").unwrap(), 0.0);
        assert!((after[0] - before[0]).abs() < 1.1e-7, "x jumps: {before:?} -> {after:?}");
        assert!((after[1] - before[1]).abs() < 1e-7, "v jumps: {before:?} -> {after:?}");
        assert!(before[2].abs() < 1e-6, "a just before release {}", before[2]);
        let jump = (p.k / p.b).powi(2) * contact(&p, t_r).0;
        assert!((after[2] - before[2] - jump).abs() < 1e-6, "a: {before:?} -> {after:?}, expected jump {jump}");
    }

    /// `attached`: no event, the mass is pulled back by the plate (F_contact < 0 late in the
    /// run), and regime 1's closed form holds for all 3 s.
    #[test]
    fn attached_mass_never_separates() {
        let p = Bumper::default();
        let mut h = tight(&[("attached", 1.0)]);
        let traj = h.run(3.0, 1e-2, &["x", "v", "x_mass", "in_contact", "t_release", "F_contact"]).unwrap();
        for (k, &t) in traj.time.iter().enumerate() {
            let (x, v) = contact(&p, t);
            assert!((traj.get("x")[k] - x).abs() < 1e-10 && (traj.get("v")[k] - v).abs() < 1e-10, "t={t}");
            assert_eq!((traj.get("in_contact")[k], traj.get("t_release")[k]), (1.0, -1.0));
        }
        assert!(*traj.get("F_contact").last().unwrap() < 0.0, "the plate should be pulling the fastened mass");
    }

    /// An underdamped bumper (B = 2000, zeta = 0.32) releases at t_r = 2 atan2(wd, sigma)/wd
    /// = 0.838 s: the event is found for the other branch of the closed form too.
    #[test]
    fn underdamped_bumper_releases_at_the_closed_form_time() {
        let p = Bumper { b: 2000.0, ..Default::default() };
        let t_r = release_time(&p);
        let sigma = p.b / (2.0 * p.mass);
        let wd = (p.k / p.mass - sigma * sigma).sqrt();
        assert!((t_r - 2.0 * wd.atan2(sigma) / wd).abs() < 1e-12);
        let mut h = tight(&[("B", 2000.0)]);
        h.run(3.0, 1e-2, &["x"]).unwrap();
        assert!((h.get("t_release").unwrap() - t_r).abs() < 1e-8);
    }

    /// Names, state indices, units and display units of the table are all known to the toolkit.
    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<Bumper>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    #[test]
    fn non_physical_parameters_are_refused_by_name() {
        for (name, value) in [("M", 0.0), ("K", -9850.0), ("B", 0.0), ("V0", 0.0), ("V0", -1.0)] {
            let mut h = Harness::<Bumper>::new();
            h.set(name, value).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(err.contains(&format!("parameter {name}")), "{err}");
        }
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<Bumper>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<Bumper>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
