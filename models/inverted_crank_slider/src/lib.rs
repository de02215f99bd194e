#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::scalar::length;
use fmu_export::{Equations, EventOutcome, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use nalgebra::{Matrix2, Matrix6, Matrix6x2, Vector2, Vector6};
use serde::{Deserialize, Serialize};

/// Revolutions per minute in rad/s.
const RPM: f64 = std::f64::consts::PI / 30.0;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// App. E: crank AB (pivot A, length r2, angle theta2) drives link BD (length L3) through a
/// collar pivoted at C. Loop r1 + r2 = r3 (r1 = C->A along +x, r3 = C->B).
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct InvertedCrankSlider<T = f64> {
    /// Ground distance from the collar pivot C to the crank pivot A
    #[parameter(unit = "m", display = "mm", positive)]
    pub r1: T,
    /// Crank length AB
    #[parameter(unit = "m", display = "mm", positive)]
    pub r2: T,
    /// Length of link BD (slides through the collar at C)
    #[parameter(name = "L3", unit = "m", display = "mm", positive)]
    pub l3: T,
    /// Crank angular velocity theta2' (counter-clockwise positive; the default turns
    /// clockwise as in Fig. E.1)
    #[parameter(unit = "rad/s", display = "rpm", finite)]
    pub omega: T,
    /// Initial crank angle theta2 (counter-clockwise from +x)
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta2_0: T,
    /// Mass of the crank AB (centre of mass at its middle)
    #[parameter(unit = "kg", non_negative)]
    pub m2: T,
    /// Mass of link BD (centre of mass at its middle)
    #[parameter(unit = "kg", non_negative)]
    pub m3: T,
    /// Moment of inertia of link BD about its centre of mass
    #[parameter(name = "I3", unit = "kg.m2", non_negative)]
    pub i3: T,
    /// Sliding acceleration r3''
    #[output(unit = "m/s2")]
    pub r3_ddot: T,
    /// Angular acceleration of link BD
    #[output(unit = "rad/s2")]
    pub theta3_ddot: T,
    // The kinetics' unknowns y = [F_Ax, F_Ay, F_Bx, F_By, F_C, T] (E.24):
    /// x force of the ground on the crank at A
    #[output(name = "F_Ax", unit = "N")]
    pub f_ax: T,
    /// y force of the ground on the crank at A
    #[output(name = "F_Ay", unit = "N")]
    pub f_ay: T,
    /// x force of link BD on the crank at B
    #[output(name = "F_Bx", unit = "N")]
    pub f_bx: T,
    /// y force of link BD on the crank at B
    #[output(name = "F_By", unit = "N")]
    pub f_by: T,
    /// Collar force on link BD, along (-sin theta3, cos theta3)
    #[output(name = "F_C", unit = "N")]
    pub f_c: T,
    /// Input torque on the crank (counter-clockwise positive)
    #[output(name = "T", unit = "N.m")]
    pub torque: T,
    /// Vector-loop gap |e| (E.16)
    #[output(unit = "m")]
    pub loop_residual: T,
}

/// The state vector: the crank angle, the loop's unknowns x = [r3, theta3] and their rates.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Crank angle
    #[state(unit = "rad", display = "deg")]
    pub theta2: T,
    /// Distance from the collar pivot C to B
    #[state(unit = "m")]
    pub r3: T,
    /// Angle of C->B (of link BD)
    #[state(unit = "rad", display = "deg")]
    pub theta3: T,
    /// Sliding velocity r3'
    #[state(unit = "m/s")]
    pub r3_dot: T,
    /// Angular velocity of link BD
    #[state(unit = "rad/s")]
    pub theta3_dot: T,
}

impl Default for InvertedCrankSlider {
    fn default() -> Self {
        let (m3, l3) = (0.5, 0.350);
        let mut m = InvertedCrankSlider {
            r1: 0.240,
            r2: 0.080,
            l3,
            // Fig. E.1: the crank turns clockwise; 60 rpm.
            omega: -60.0 * RPM,
            theta2_0: 0.0,
            m2: 0.2,
            m3,
            // A uniform slender bar: m3 L3^2 / 12.
            i3: m3 * l3 * l3 / 12.0,
            r3_ddot: 0.0,
            theta3_ddot: 0.0,
            f_ax: 0.0,
            f_ay: 0.0,
            f_bx: 0.0,
            f_by: 0.0,
            f_c: 0.0,
            torque: 0.0,
            loop_residual: 0.0,
        };
        let mut x = [0.0; State::LEN];
        if m.assemble(&mut x).is_ok() {
            m.outputs(0.0, &x);
        }
        m
    }
}

impl<T: Scalar> InvertedCrankSlider<T> {
    /// Loop gap e = r1 + r2 - r3 (E.14, E.15).
    pub fn gap(&self, th2: T, r3: T, th3: T) -> Vector2<T> {
        Vector2::new(self.r1 + self.r2 * th2.cos() - r3 * th3.cos(), self.r2 * th2.sin() - r3 * th3.sin())
    }

    /// A of E.7 and E.12 (A11 of E.23).
    pub fn a_matrix(r3: T, th3: T) -> Matrix2<T> {
        let (s3, c3) = th3.sin_cos();
        Matrix2::new(c3, -r3 * s3, s3, r3 * c3)
    }

    fn b_velocity(&self, th2: T) -> Vector2<T> {
        let (s2, c2) = th2.sin_cos();
        Vector2::new(-self.r2 * s2 * self.omega, self.r2 * c2 * self.omega)
    }

    /// b1 of E.12.
    fn b_acceleration(&self, s: &State<T>) -> Vector2<T> {
        let (s2, c2) = s.theta2.sin_cos();
        let (s3, c3) = s.theta3.sin_cos();
        let (r3, r3d, w3, w2) = (s.r3, s.r3_dot, s.theta3_dot, self.omega);
        Vector2::new(
            -self.r2 * c2 * w2 * w2 + s3 * 2.0 * r3d * w3 + r3 * c3 * w3 * w3,
            -self.r2 * s2 * w2 * w2 - c3 * 2.0 * r3d * w3 + r3 * s3 * w3 * w3,
        )
    }

    /// x'' = A^-1 b (A is regular: det A = r3 >= r1 - r2 > 0).
    fn accelerations(&self, s: &State<T>) -> Vector2<T> {
        Self::a_matrix(s.r3, s.theta3).lu().solve(&self.b_acceleration(s)).unwrap_or_else(Vector2::zeros)
    }

    /// The kinetics, E.17 to E.24: y = A22^-1 (b2 - A21 x''), y = [F_Ax, F_Ay, F_Bx, F_By, F_C, T].
    pub fn forces(&self, s: &State<T>, acc: &Vector2<T>) -> Vector6<T> {
        let (s2, c2) = s.theta2.sin_cos();
        let (s3, c3) = s.theta3.sin_cos();
        let (r2, l3, m2, m3) = (self.r2, self.l3, self.m2, self.m3);
        let (r3, r3d, w3, w2) = (s.r3, s.r3_dot, s.theta3_dot, self.omega);
        let g = r3 - l3 * 0.5;
        let (zero, one) = (T::zero(), T::one());
        #[rustfmt::skip]
        let a21 = Matrix6x2::new(
            zero, zero,
            zero, zero,
            zero, zero,
            -m3 * c3, m3 * g * s3,
            -m3 * s3, -m3 * g * c3,
            zero, -self.i3,
        );
        #[rustfmt::skip]
        let a22 = Matrix6::new(
            one, zero, one, zero, zero, zero,
            zero, one, zero, one, zero, zero,
            r2 * 0.5 * s2, -r2 * 0.5 * c2, -r2 * 0.5 * s2, r2 * 0.5 * c2, zero, one,
            zero, zero, -one, zero, -s3, zero,
            zero, zero, zero, -one, c3, zero,
            zero, zero, l3 * 0.5 * s3, -l3 * 0.5 * c3, -g, zero,
        );
        let b2 = Vector6::new(
            m2 * -0.5 * r2 * c2 * w2 * w2,
            m2 * -0.5 * r2 * s2 * w2 * w2,
            zero,
            m3 * -2.0 * s3 * r3d * w3 - m3 * g * c3 * w3 * w3,
            m3 * 2.0 * c3 * r3d * w3 - m3 * g * s3 * w3 * w3,
            zero,
        );
        a22.lu().solve(&(b2 - a21 * acc)).unwrap_or_else(Vector6::zeros)
    }

    /// Initial positions: the zero of the gap (E.3.1) in closed form, r3 = |r1 + r2|
    /// (r3 > 0); velocities from A x' = b (E.3.2).
    fn assemble(&self, x: &mut [T]) -> Result<(), ModelError> {
        let (s2, c2) = self.theta2_0.sin_cos();
        let (bx, by) = (self.r1 + self.r2 * c2, self.r2 * s2);
        let (r3, th3) = (bx.hypot(by), by.atan2(bx));
        let v = Self::a_matrix(r3, th3)
            .lu()
            .solve(&self.b_velocity(self.theta2_0))
            .ok_or_else(|| ModelError("A is singular at theta2_0".into()))?;
        State { theta2: self.theta2_0, r3, theta3: th3, r3_dot: v[0], theta3_dot: v[1] }.store(x);
        Ok(())
    }
}

impl<T: Scalar> Equations<T> for InvertedCrankSlider<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        if self.r2 >= self.r1 {
            return Err(ModelError(format!(
                "parameters r2 = {} m and r1 = {} m: the crank must be shorter than the ground distance (r2 < r1), otherwise B passes through the collar pivot C (r3 = 0, A singular)",
                self.r2.value(),
                self.r1.value()
            )));
        }
        // C-B at the start: where `assemble` puts B (r3 of the closed form).
        let r3_0 = (self.r1 + self.r2 * self.theta2_0.cos()).hypot(self.r2 * self.theta2_0.sin());
        if self.l3 <= r3_0 {
            return Err(ModelError(format!(
                "the mechanism cannot be assembled at theta2_0 = {:.4} deg: link BD (L3 = {} m) does not reach through the collar, \
                 C is {} m from B (r1 = {} m, r2 = {} m); L3 must exceed r1 + r2 for the crank to turn",
                self.theta2_0.value().to_degrees(),
                self.l3.value(),
                r3_0.value(),
                self.r1.value(),
                self.r2.value()
            )));
        }
        if self.r1 + self.r2 >= self.l3 {
            return Err(ModelError(format!(
                "parameters r1 = {} m, r2 = {} m, L3 = {} m: link BD would leave the collar during the crank's turn; \
                 it must be longer than the largest C-B distance r1 + r2 (at theta2 = 0)",
                self.r1.value(),
                self.r2.value(),
                self.l3.value()
            )));
        }
        self.assemble(x)
    }

    /// The crank turns at omega; the unknowns' accelerations from A x'' = b (E.12).
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        State { theta2: self.omega, r3: s.r3_dot, theta3: s.theta3_dot, r3_dot: acc[0], theta3_dot: acc[1] }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        self.r3_ddot = acc[0];
        self.theta3_ddot = acc[1];
        let y = self.forces(&s, &acc);
        [self.f_ax, self.f_ay, self.f_bx, self.f_by, self.f_c, self.torque] = [y[0], y[1], y[2], y[3], y[4], y[5]];
        // Zero but for the rounding of its terms (lengths up to r1 + r2) after a projection.
        let noise = 16.0 * f64::EPSILON * (self.r1 + self.r2).value();
        self.loop_residual = length(&self.gap(s.theta2, s.r3, s.theta3), noise);
    }
}

impl Model for InvertedCrankSlider {
    const N_STATES: usize = State::LEN;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "inverted_crank_slider",
            description:
                "ME326 App. E: crank AB drives link BD through a pivoted collar at C; vector-loop kinematics and the E.17-E.24 kinetics",
            // Two crank revolutions at 60 rpm.
            stop_time: 2.0,
            tolerance: 1e-6,
            output_interval: 1e-3,
            documentation: include_str!("../derivation.md"),
        }
    }

    /// The loop-closure gap |e| over r1 + r2 (Model Exchange projects with a step event when
    /// it exceeds the tolerance).
    fn constraint_drift(&self, x: &[f64]) -> f64 {
        self.gap(x[0], x[1], x[2]).norm() / (self.r1 + self.r2)
    }

    /// Projects (r3, theta3) back onto the loop closure by Newton's method (Jacobian A), then
    /// the velocities onto A x' = b. If Newton does not close the loop on the assembly
    /// r3 > 0 (only after a step far too large for the solver), the step fails saying so,
    /// rather than continuing on garbage or on the mirror solution r3 < 0.
    fn communication_point(&mut self, _t: f64, x: &mut [f64]) -> Result<EventOutcome, ModelError> {
        let State { theta2, r3, theta3, .. } = State::load(x);
        let mut q = Vector2::new(r3, theta3);
        for _ in 0..NEWTON_ITERS {
            let e = self.gap(theta2, q[0], q[1]);
            if e.norm() <= 1e-16 * (self.r1 + self.r2) {
                break;
            }
            // d e / d(r3, theta3) = -A.
            match Self::a_matrix(q[0], q[1]).lu().solve(&e) {
                Some(dq) => q += dq,
                None => break,
            }
        }
        let closed = q[0] > 0.0 && self.gap(theta2, q[0], q[1]).norm() <= 1e-12 * (self.r1 + self.r2);
        let v = Self::a_matrix(q[0], q[1])
            .lu()
            .solve(&self.b_velocity(theta2))
            .filter(|v| closed && v.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                ModelError(format!(
                    "the vector loop could not be closed at theta2 = {:.4} deg (Newton's method from r3 = {} m, theta3 = {} rad): \
                 the state drifted too far in one step; reduce fixed_step or the tolerance",
                    theta2.to_degrees(),
                    r3,
                    theta3
                ))
            })?;
        State { theta2, r3: q[0], theta3: q[1], r3_dot: v[0], theta3_dot: v[1] }.store(x);
        Ok(EventOutcome::Continue)
    }
}

fmu_export::export_fmu!(InvertedCrankSlider);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::{Harness, Trajectory};
    use fmu_export::table::Table;
    use formulas::References;
    use std::f64::consts::PI;

    fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// The closed form's (r3, theta3) at the crank angle `th2` for the parameters of `p`:
    /// references.toml's, in the triangle CAB, independent of the vector loop; tests/fmpy
    /// evaluates it too.
    fn closed_form(p: &InvertedCrankSlider, th2: f64) -> (f64, f64) {
        let mut values = Table::<InvertedCrankSlider>::new().parameter_values(p);
        values.push(("theta2", th2));
        let references = References::of_model(env!("CARGO_MANIFEST_DIR")).expect("valid references");
        let at = |name| references.value(name, &values).expect("a reference of the parameters");
        (at("r3"), at("theta3"))
    }

    /// Time derivatives of the closed form by fourth-order central differences in theta2
    /// (step 1e-3 rad): truncation ~h^4 f(5)/30 ~ 1e-13, rounding ~eps/h ~ 1e-13 and
    /// eps/h^2 ~ 1e-10, each times omega or omega^2 (6.3, 39.5).
    fn fd(p: &InvertedCrankSlider, th2: f64) -> [f64; 4] {
        let h = 1e-3;
        let c = closed_form(p, th2);
        let at = |k: f64| closed_form(p, th2 + k * h);
        let (p1, p2, m1, m2) = (at(1.0), at(2.0), at(-1.0), at(-2.0));
        let w = p.omega;
        let der = |f: fn((f64, f64)) -> f64| {
            let r = |v: (f64, f64)| wrap(f(v) - f(c));
            (
                (-r(p2) + 8.0 * r(p1) - 8.0 * r(m1) + r(m2)) / (12.0 * h) * w,
                (-r(p2) + 16.0 * r(p1) + 16.0 * r(m1) - r(m2)) / (12.0 * h * h) * w * w,
            )
        };
        let (a1, a2) = der(|v| v.0);
        let (b1, b2) = der(|v| v.1);
        [a1, b1, a2, b2]
    }

    const NAMES: [&str; 16] = [
        "theta2",
        "r3",
        "theta3",
        "r3_dot",
        "theta3_dot",
        "r3_ddot",
        "theta3_ddot",
        "F_Ax",
        "F_Ay",
        "F_Bx",
        "F_By",
        "F_C",
        "T",
        "loop_residual",
        "n_steps",
        "n_rhs",
    ];

    fn run(params: &[(&str, f64)], dt: f64) -> Trajectory {
        let mut h = Harness::<InvertedCrankSlider>::new();
        for (n, v) in params {
            h.set(n, *v).unwrap();
        }
        h.initialize(None).unwrap();
        h.run(2.0, dt, &NAMES).unwrap()
    }

    fn with(params: &[(&str, f64)]) -> InvertedCrankSlider {
        let mut p = InvertedCrankSlider::default();
        for (n, v) in params {
            match *n {
                "omega" => p.omega = *v,
                "m3" => p.m3 = *v,
                "I3" => p.i3 = *v,
                "theta2_0" => p.theta2_0 = *v,
                _ => unreachable!(),
            }
        }
        p
    }

    /// Two revolutions (1 ms grid, default tolerance) against the closed form: positions to
    /// rounding (projected, bound 1e-12), rates and accelerations against the fourth-order
    /// differences (bounds 1e-8 m/s, rad/s and 1e-7 m/s2, rad/s2 on values up to ~0.8 and
    /// ~40), loop gap below 1e-9 m.
    #[test]
    fn kinematics_match_the_closed_form() {
        let p = InvertedCrankSlider::default();
        let tr = run(&[], 1e-3);
        assert_eq!(tr.time.len(), 2001);
        let mut err = [0.0f64; 4];
        for k in 0..tr.time.len() {
            let g = |n: &str| tr.get(n)[k];
            let th2 = p.theta2_0 + p.omega * tr.time[k];
            assert!((g("theta2") - th2).abs() < 1e-12);
            let (r3, t3) = closed_form(&p, th2);
            let d = fd(&p, th2);
            err[0] = err[0].max((g("r3") - r3).abs()).max(wrap(g("theta3") - t3).abs());
            err[1] = err[1].max((g("r3_dot") - d[0]).abs()).max((g("theta3_dot") - d[1]).abs());
            err[2] = err[2].max((g("r3_ddot") - d[2]).abs()).max((g("theta3_ddot") - d[3]).abs());
            err[3] = err[3].max(g("loop_residual"));
        }
        eprintln!("max errors: positions {:.2e}, rates {:.2e}, accelerations {:.2e}, loop gap {:.2e} m", err[0], err[1], err[2], err[3]);
        assert!(err[0] < 1e-12 && err[1] < 1e-8 && err[2] < 1e-7 && err[3] < 1e-9, "{err:?}");
    }

    /// Velocity and acceleration of link 3's centre of mass G3 = C + (r3 - L3/2) u3.
    fn g3_motion(p: &InvertedCrankSlider, g: impl Fn(&str) -> f64) -> ([f64; 2], [f64; 2]) {
        let (s3, c3) = g("theta3").sin_cos();
        let (d, d1, d2) = (g("r3") - 0.5 * p.l3, g("r3_dot"), g("r3_ddot"));
        let (w, al) = (g("theta3_dot"), g("theta3_ddot"));
        let (vu, vn) = (d1, d * w);
        let (au, an) = (d2 - d * w * w, 2.0 * d1 * w + d * al);
        ([vu * c3 - vn * s3, vu * s3 + vn * c3], [au * c3 - an * s3, au * s3 + an * c3])
    }

    /// Power balance: with no gravity and a frictionless collar and pins, the only work on
    /// the system is the input torque's, so T omega = d(KE)/dt. KE = 1/2 m3 |v_G3|^2 +
    /// 1/2 I3 theta3'^2 (the crank's KE is constant at constant omega) is computed from the
    /// kinematic outputs, and d/dt by a fourth-order difference over +-2 ms of the 1 ms
    /// samples (truncation dt^4 KE(5)/30 with KE(5) ~ 0.06 J omega^5 = 6e2 W/s^4: ~2e-11 W;
    /// measured error ~1e-9 W on powers up to ~1 W, from rates accurate to ~1e-10). Bound 1e-7 W.
    /// Also Newton for the whole system: the ground forces F_A and F_C (-sin3, cos3) equal
    /// m2 a_G2 + m3 a_G3 (bound 1e-9 N on forces of ~1 N: both sides come from the same
    /// accelerations, so only rounding and the conditioning of A22 enter).
    #[test]
    fn power_balance_and_whole_system_newton() {
        for th0 in [0.0, 1.0] {
            let p = with(&[("theta2_0", th0)]);
            let tr = run(&[("theta2_0", th0)], 1e-3);
            let n = tr.time.len();
            let ke: Vec<f64> = (0..n)
                .map(|k| {
                    let (v, _) = g3_motion(&p, |s| tr.get(s)[k]);
                    0.5 * p.m3 * (v[0] * v[0] + v[1] * v[1]) + 0.5 * p.i3 * tr.get("theta3_dot")[k].powi(2)
                })
                .collect();
            let (mut worst_p, mut worst_f, mut max_p) = (0.0f64, 0.0f64, 0.0f64);
            for k in 2..n - 2 {
                let dke = (-ke[k + 2] + 8.0 * ke[k + 1] - 8.0 * ke[k - 1] + ke[k - 2]) / (12.0 * 1e-3);
                let power = tr.get("T")[k] * p.omega;
                worst_p = worst_p.max((power - dke).abs());
                max_p = max_p.max(power.abs());
                let g = |s: &str| tr.get(s)[k];
                let (_, a3) = g3_motion(&p, g);
                let th2 = g("theta2");
                let a2 = [-0.5 * p.r2 * p.omega.powi(2) * th2.cos(), -0.5 * p.r2 * p.omega.powi(2) * th2.sin()];
                let (s3, c3) = g("theta3").sin_cos();
                let fx = g("F_Ax") - s3 * g("F_C") - p.m2 * a2[0] - p.m3 * a3[0];
                let fy = g("F_Ay") + c3 * g("F_C") - p.m2 * a2[1] - p.m3 * a3[1];
                worst_f = worst_f.max(fx.abs()).max(fy.abs());
            }
            eprintln!(
                "theta2_0 = {th0}: max |T omega - dKE/dt| = {worst_p:.2e} W (max |T omega| = {max_p:.3} W), whole-system Newton residual {worst_f:.2e} N"
            );
            assert!(max_p > 0.1, "the check must see real power flow");
            assert!(worst_p < 1e-7 && worst_f < 1e-9);
        }
    }

    /// omega = 0: nothing moves and, without gravity, there are no inertial loads: every force
    /// and the torque are exactly zero, the state stays put.
    #[test]
    fn at_rest_there_are_no_loads() {
        let tr = run(&[("omega", 0.0), ("theta2_0", 0.7)], 0.1);
        for name in ["r3_dot", "theta3_dot", "r3_ddot", "theta3_ddot", "F_Ax", "F_Ay", "F_Bx", "F_By", "F_C", "T"] {
            assert!(tr.get(name).iter().all(|v| *v == 0.0), "{name}: {:?}", &tr.get(name)[..3]);
        }
        let r3 = tr.get("r3");
        assert!(r3.iter().all(|v| *v == r3[0]));
    }

    /// A massless link BD (m3 = I3 = 0) transmits nothing: F_B = F_C = T = 0 and the ground
    /// carries the crank's centripetal force, F_A = -1/2 m2 r2 omega^2 (cos, sin)(theta2)
    /// (bound 1e-12 N: one linear solve).
    #[test]
    fn massless_link_leaves_only_the_crank_centripetal_force() {
        let p = with(&[("m3", 0.0), ("I3", 0.0)]);
        let tr = run(&[("m3", 0.0), ("I3", 0.0)], 1e-2);
        for k in 0..tr.time.len() {
            let g = |n: &str| tr.get(n)[k];
            let th2 = g("theta2");
            let c = -0.5 * p.m2 * p.r2 * p.omega * p.omega;
            assert!((g("F_Ax") - c * th2.cos()).abs() < 1e-12 && (g("F_Ay") - c * th2.sin()).abs() < 1e-12);
            for n in ["F_Bx", "F_By", "F_C", "T"] {
                assert!(g(n).abs() < 1e-12, "{n} = {}", g(n));
            }
        }
    }

    #[test]
    fn impossible_geometry_is_refused_naming_the_parameters() {
        for (name, v, expect) in
            [("r2", 0.3, "parameters r2"), ("L3", 0.3, "L3 = 0.3"), ("m3", -1.0, "parameter m3"), ("r1", 0.0, "parameter r1")]
        {
            let mut h = Harness::<InvertedCrankSlider>::new();
            h.set(name, v).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(err.contains(expect), "{err}");
        }
    }

    /// L3 = 0.3 m is shorter than C-B = r1 + r2 = 0.32 m at theta2_0 = 0: BD cannot even be
    /// put through the collar, and the refusal says so. At theta2_0 = 180 deg (C-B = 0.16 m)
    /// L3 = 0.2 m assembles but BD would leave the collar half a turn later: refused too,
    /// saying that instead.
    #[test]
    fn a_link_too_short_for_the_collar_is_refused_saying_why() {
        let err = Harness::<InvertedCrankSlider>::started(&[("L3", 0.3)], None).err().unwrap();
        assert!(err.contains("cannot be assembled at theta2_0 = 0.0000 deg") && err.contains("L3 = 0.3 m"), "{err}");
        let err = Harness::<InvertedCrankSlider>::started(&[("L3", 0.2), ("theta2_0", PI)], None).err().unwrap();
        assert!(err.contains("would leave the collar") && err.contains("L3 = 0.2 m"), "{err}");
    }

    /// Forward Euler with half a crank turn per step drifts so far that Newton cannot close
    /// the loop on r3 > 0: the step fails with fmi2Error saying so (it used to report only
    /// "A is singular"), and r3 never goes negative on the way.
    #[test]
    fn a_step_too_large_to_close_the_loop_fails_saying_so() {
        let mut h = Harness::<InvertedCrankSlider>::started(&[("solver", 0.0), ("fixed_step", 0.5)], None).unwrap();
        let err = loop {
            match h.step(1.0) {
                Ok(_) => assert!(h.get("r3").unwrap() > 0.0),
                Err(e) => break e,
            }
        };
        assert!(err.starts_with("Error") && err.contains("could not be closed"), "{err}");
        assert!(h.get("r3").unwrap() > 0.0);
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<InvertedCrankSlider>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<InvertedCrankSlider>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<InvertedCrankSlider>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
