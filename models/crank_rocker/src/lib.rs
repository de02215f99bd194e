#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu::{require_finite, require_positive, EventOutcome, Model, ModelError, ModelInfo, Variable};
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

/// Rows of this model's variable table.
type V = Variable<FourBar>;

/// Revolutions per minute in rad/s.
const RPM: f64 = std::f64::consts::PI / 30.0;
/// The run stops when |det A| / (l_AB l_BC) = |sin(theta4 - theta3)| falls below this.
pub const SINGULAR: f64 = 1e-3;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// Four-bar OABC: input link OA (angle theta), coupler AB (angle theta3 of A->B), output
/// link CB (angle theta4 of C->B), ground O->C of length l_CO at angle theta_CO.
/// Loop r2 + r3 = r1 + r4. State vector [theta, theta3, theta4, theta3', theta4'].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FourBar {
    pub l_oa: f64,
    pub l_ab: f64,
    pub l_bc: f64,
    pub l_co: f64,
    pub theta_co: f64,
    pub theta0: f64,
    pub omega: f64,
    pub branch: i32,
    // Outputs.
    pub theta3_ddot: f64,
    pub theta4_ddot: f64,
    pub a_x: f64,
    pub a_y: f64,
    pub b_x: f64,
    pub b_y: f64,
    pub v_a_x: f64,
    pub v_a_y: f64,
    pub v_b_x: f64,
    pub v_b_y: f64,
    pub loop_residual: f64,
}

impl Default for FourBar {
    fn default() -> Self {
        let mut m = FourBar {
            l_oa: 0.100,
            l_ab: 0.180,
            l_bc: 0.500,
            l_co: 0.560,
            theta_co: 0.0,
            theta0: 135f64.to_radians(),
            omega: 5.0 * RPM,
            branch: 1,
            theta3_ddot: 0.0,
            theta4_ddot: 0.0,
            a_x: 0.0,
            a_y: 0.0,
            b_x: 0.0,
            b_y: 0.0,
            v_a_x: 0.0,
            v_a_y: 0.0,
            v_b_x: 0.0,
            v_b_y: 0.0,
            loop_residual: 0.0,
        };
        // Start values of the outputs: the assembled initial configuration.
        let mut x = [0.0; 5];
        if m.assemble(&mut x).is_ok() {
            m.outputs(0.0, &x);
        }
        m
    }
}

impl FourBar {
    /// The ground pivot C.
    pub fn c(&self) -> Vector2<f64> {
        self.l_co * Vector2::new(self.theta_co.cos(), self.theta_co.sin())
    }

    /// Loop-closure gap e = r2 + r3 - r1 - r4 (E.14 to E.16 for this loop).
    pub fn gap(&self, theta: f64, th3: f64, th4: f64) -> Vector2<f64> {
        self.l_oa * Vector2::new(theta.cos(), theta.sin()) + self.l_ab * Vector2::new(th3.cos(), th3.sin())
            - self.c()
            - self.l_bc * Vector2::new(th4.cos(), th4.sin())
    }

    /// A of A x' = b and A x'' = b, for x = [theta3, theta4].
    pub fn a_matrix(&self, th3: f64, th4: f64) -> Matrix2<f64> {
        Matrix2::new(-self.l_ab * th3.sin(), self.l_bc * th4.sin(), self.l_ab * th3.cos(), -self.l_bc * th4.cos())
    }

    fn b_velocity(&self, theta: f64) -> Vector2<f64> {
        self.l_oa * self.omega * Vector2::new(theta.sin(), -theta.cos())
    }

    fn b_acceleration(&self, theta: f64, th3: f64, th4: f64, w3: f64, w4: f64) -> Vector2<f64> {
        self.l_oa * self.omega * self.omega * Vector2::new(theta.cos(), theta.sin()) + self.l_ab * w3 * w3 * Vector2::new(th3.cos(), th3.sin())
            - self.l_bc * w4 * w4 * Vector2::new(th4.cos(), th4.sin())
    }

    /// x'' = A^-1 b; a singular A (only past the stop at a limit position) gives zeros, not NaN.
    fn accelerations(&self, x: &[f64]) -> Vector2<f64> {
        let b = self.b_acceleration(x[0], x[1], x[2], x[3], x[4]);
        self.a_matrix(x[1], x[2]).lu().solve(&b).filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or_else(Vector2::zeros)
    }

    fn velocities(&self, theta: f64, th3: f64, th4: f64) -> Option<Vector2<f64>> {
        self.a_matrix(th3, th4).lu().solve(&self.b_velocity(theta))
    }

    /// |det A| / (l_AB l_BC) signed by the branch: branch sin(theta4 - theta3) (positive on
    /// the chosen branch since sin(theta4 - theta3) l_AB l_BC = cross(C - A, B - A); zero when
    /// AB and BC are collinear).
    fn singularity_margin(&self, th3: f64, th4: f64) -> f64 {
        self.branch as f64 * (th4 - th3).sin()
    }

    fn describe_parameters(&self) -> String {
        format!(
            "l_OA = {} m, l_AB = {} m, l_BC = {} m, l_CO = {} m, theta_CO = {:.4} deg",
            self.l_oa,
            self.l_ab,
            self.l_bc,
            self.l_co,
            self.theta_co.to_degrees()
        )
    }

    /// Initial positions for `branch` (+1: B to the left of the directed line A->C) from the
    /// intersection of the circles about A (radius l_AB) and C (radius l_BC); velocities from
    /// A x' = b.
    fn assemble(&self, x: &mut [f64]) -> Result<(), ModelError> {
        let theta = self.theta0;
        let a = self.l_oa * Vector2::new(theta.cos(), theta.sin());
        let ac = self.c() - a;
        let d = ac.norm();
        let (l3, l4) = (self.l_ab, self.l_bc);
        if !(d <= l3 + l4 && d >= (l3 - l4).abs()) || d == 0.0 {
            return Err(ModelError(format!(
                "the four-bar cannot be assembled at theta0 = {:.4} deg: |AC| = {d:.6} m is outside [|l_AB - l_BC|, l_AB + l_BC] = [{:.6}, {:.6}] m ({})",
                theta.to_degrees(),
                (l3 - l4).abs(),
                l3 + l4,
                self.describe_parameters()
            )));
        }
        let u = ac / d;
        let p = (l3 * l3 - l4 * l4 + d * d) / (2.0 * d);
        let h = (l3 * l3 - p * p).max(0.0).sqrt();
        let b = a + p * u + self.branch as f64 * h * Vector2::new(-u[1], u[0]);
        let ab = b - a;
        let cb = b - self.c();
        let (th3, th4) = (ab[1].atan2(ab[0]), cb[1].atan2(cb[0]));
        if self.singularity_margin(th3, th4) < SINGULAR {
            return Err(ModelError(format!(
                "theta0 = {:.4} deg is at a limit position (AB and BC collinear, A singular): {}",
                theta.to_degrees(),
                self.describe_parameters()
            )));
        }
        let v = self.velocities(theta, th3, th4).ok_or_else(|| ModelError("A is singular at theta0".into()))?;
        x.copy_from_slice(&[theta, th3, th4, v[0], v[1]]);
        Ok(())
    }

    /// Projects the positions back onto the loop closure by Newton's method on e = 0 (the
    /// Jacobian of e with respect to the unknowns is A; the input angle is exact), then the
    /// velocities onto A x' = b. Leaves x unchanged and returns false when Newton does not
    /// converge on this branch with at least `min_margin` from the singularity.
    fn project(&self, x: &mut [f64], min_margin: f64) -> bool {
        let scale = self.l_oa + self.l_ab + self.l_bc + self.l_co;
        let mut q = Vector2::new(x[1], x[2]);
        for _ in 0..NEWTON_ITERS {
            let e = self.gap(x[0], q[0], q[1]);
            if e.norm() <= 1e-15 * scale {
                break;
            }
            match self.a_matrix(q[0], q[1]).lu().solve(&e) {
                // The Jacobian of e with respect to (theta3, theta4) is A itself.
                Some(dq) => q -= dq,
                None => break,
            }
        }
        let closed = self.singularity_margin(q[0], q[1]) >= min_margin && self.gap(x[0], q[0], q[1]).norm() < 1e-12 * scale;
        if !closed {
            return false;
        }
        let Some(v) = self.velocities(x[0], q[0], q[1]) else {
            return false;
        };
        x[1] = q[0];
        x[2] = q[1];
        x[3] = v[0];
        x[4] = v[1];
        true
    }
}

impl Model for FourBar {
    const N_STATES: usize = 5;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "crank_rocker",
            description: "ME326 Ex. 5 mechanism #3: crank-rocker four-bar driven at constant speed, vector-loop kinematics",
            // Two revolutions at 5 rpm.
            stop_time: 24.0,
            tolerance: 1e-6,
            output_interval: 1e-2,
            documentation: include_str!("../derivation.md"),
        }
    }

    fn variables() -> Vec<Variable<Self>> {
        vec![
            V::parameter("l_OA", "Input link length OA", |s| s.l_oa, |s, v| s.l_oa = v).unit("m").display("mm"),
            V::parameter("l_AB", "Coupler length AB", |s| s.l_ab, |s, v| s.l_ab = v).unit("m").display("mm"),
            V::parameter("l_BC", "Output link length BC", |s| s.l_bc, |s, v| s.l_bc = v).unit("m").display("mm"),
            V::parameter("l_CO", "Ground length OC", |s| s.l_co, |s, v| s.l_co = v).unit("m").display("mm"),
            V::parameter("theta_CO", "Direction of the ground pivot C seen from O", |s| s.theta_co, |s, v| s.theta_co = v).unit("rad").display("deg"),
            V::parameter("theta0", "Initial input angle (counter-clockwise from +x)", |s| s.theta0, |s, v| s.theta0 = v).unit("rad").display("deg"),
            V::parameter("omega", "Input angular velocity (counter-clockwise, constant)", |s| s.omega, |s, v| s.omega = v).unit("rad/s").display("rpm"),
            V::integer_parameter("branch", "Assembly: +1 puts B to the left of the directed line A->C, -1 to the right", |s| s.branch, |s, v| s.branch = v),
            V::state("theta", "Input angle theta2 of O->A", 0).unit("rad").display("deg"),
            V::state("theta3", "Angle of the coupler A->B", 1).unit("rad").display("deg"),
            V::state("theta4", "Angle of the output link C->B", 2).unit("rad").display("deg"),
            V::state("theta3_dot", "Angular velocity of the coupler", 3).unit("rad/s"),
            V::state("theta4_dot", "Angular velocity of the output link", 4).unit("rad/s"),
            V::output("theta3_ddot", "Angular acceleration of the coupler", |s| s.theta3_ddot).unit("rad/s2"),
            V::output("theta4_ddot", "Angular acceleration of the output link", |s| s.theta4_ddot).unit("rad/s2"),
            V::output("A_x", "x of the joint A", |s| s.a_x).unit("m"),
            V::output("A_y", "y of the joint A", |s| s.a_y).unit("m"),
            V::output("B_x", "x of the joint B", |s| s.b_x).unit("m"),
            V::output("B_y", "y of the joint B", |s| s.b_y).unit("m"),
            V::output("v_A_x", "x velocity of A", |s| s.v_a_x).unit("m/s"),
            V::output("v_A_y", "y velocity of A", |s| s.v_a_y).unit("m/s"),
            V::output("v_B_x", "x velocity of B", |s| s.v_b_x).unit("m/s"),
            V::output("v_B_y", "y velocity of B", |s| s.v_b_y).unit("m/s"),
            V::output("loop_residual", "Vector-loop gap |e| (E.16)", |s| s.loop_residual).unit("m"),
        ]
    }

    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
        require_positive("l_OA", self.l_oa)?;
        require_positive("l_AB", self.l_ab)?;
        require_positive("l_BC", self.l_bc)?;
        require_positive("l_CO", self.l_co)?;
        require_finite("theta_CO", self.theta_co)?;
        require_finite("theta0", self.theta0)?;
        require_finite("omega", self.omega)?;
        if self.branch != 1 && self.branch != -1 {
            return Err(ModelError(format!("parameter branch = {} must be +1 or -1", self.branch)));
        }
        self.assemble(x)
    }

    fn derivatives(&self, _t: f64, x: &[f64], dx: &mut [f64]) {
        let acc = self.accelerations(x);
        dx[0] = self.omega;
        dx[1] = x[3];
        dx[2] = x[4];
        dx[3] = acc[0];
        dx[4] = acc[1];
    }

    fn outputs(&mut self, _t: f64, x: &[f64]) {
        let acc = self.accelerations(x);
        self.theta3_ddot = acc[0];
        self.theta4_ddot = acc[1];
        let (s, c) = x[0].sin_cos();
        self.a_x = self.l_oa * c;
        self.a_y = self.l_oa * s;
        self.v_a_x = -self.l_oa * self.omega * s;
        self.v_a_y = self.l_oa * self.omega * c;
        let (s4, c4) = x[2].sin_cos();
        let pc = self.c();
        self.b_x = pc[0] + self.l_bc * c4;
        self.b_y = pc[1] + self.l_bc * s4;
        self.v_b_x = -self.l_bc * x[4] * s4;
        self.v_b_y = self.l_bc * x[4] * c4;
        self.loop_residual = self.gap(x[0], x[1], x[2]).norm();
    }

    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = self.singularity_margin(x[1], x[2]) - SINGULAR;
    }

    fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        if fired[0] && self.singularity_margin(x[1], x[2]) <= 2.0 * SINGULAR {
            // Close the loop at the stop too (matters for the fixed-step solvers, whose last
            // step may have drifted); if that fails on this branch the state is left as is.
            self.project(x, 0.0);
            return Ok(EventOutcome::Stop {
                reason: format!(
                    "limit position at theta = {:.4} deg: the coupler AB and the link BC are collinear (A singular), the input link cannot turn further",
                    x[0].to_degrees()
                ),
            });
        }
        Ok(EventOutcome::Continue)
    }

    /// At every communication point: project onto the constraints (see `project`); a point
    /// that cannot be projected on this branch is a limit position.
    fn communication_point(&mut self, _t: f64, x: &mut [f64]) -> Result<EventOutcome, ModelError> {
        if self.project(x, SINGULAR) {
            return Ok(EventOutcome::Continue);
        }
        Ok(EventOutcome::Stop { reason: format!("limit position at theta = {:.4} deg: the loop can no longer be closed on this branch", x[0].to_degrees()) })
    }
}

fmu::export_fmu!(FourBar);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu::harness::Harness;
    use std::f64::consts::PI;

    /// Closed form by the law of cosines, independent of the vector loop: with d = |AC| and
    /// phi the direction of A->C, the coupler makes the angle alpha with AC where
    /// cos(alpha) = (l_AB^2 + d^2 - l_BC^2) / (2 l_AB d); branch +1 (B left of A->C) turns
    /// counter-clockwise from AC. Returns (theta3, theta4).
    pub(crate) fn closed_form(p: &FourBar, th: f64, br: f64) -> (f64, f64) {
        let (ax, ay) = (p.l_oa * th.cos(), p.l_oa * th.sin());
        let (cx, cy) = (p.l_co * p.theta_co.cos(), p.l_co * p.theta_co.sin());
        let d = ((cx - ax).powi(2) + (cy - ay).powi(2)).sqrt();
        let phi = (cy - ay).atan2(cx - ax);
        let alpha = ((p.l_ab * p.l_ab + d * d - p.l_bc * p.l_bc) / (2.0 * p.l_ab * d)).acos();
        let th3 = phi + br * alpha;
        let (bx, by) = (ax + p.l_ab * th3.cos(), ay + p.l_ab * th3.sin());
        (th3, (by - cy).atan2(bx - cx))
    }

    pub(crate) fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Time derivatives of the closed form by central differences in theta (step 3e-4 rad):
    /// truncation h^2 f(3)/6 and h^2 f(4)/12 ~ 1e-8, rounding 4 eps pi / h^2 ~ 2e-8 for the
    /// second derivative; bounds 5e-8 (first) and 2e-7 (second) rad/s, rad/s2.
    pub(crate) fn fd(p: &FourBar, th: f64, br: f64) -> [f64; 4] {
        let h = 3e-4;
        let (p0, m, c) = (closed_form(p, th + h, br), closed_form(p, th - h, br), closed_form(p, th, br));
        let w = p.omega;
        let d1 = |a: f64, b: f64| wrap(a - b) / (2.0 * h) * w;
        let d2 = |a: f64, b: f64, c: f64| (wrap(a - c) - wrap(c - b)) / (h * h) * w * w;
        [d1(p0.0, m.0), d1(p0.1, m.1), d2(p0.0, m.0, c.0), d2(p0.1, m.1, c.1)]
    }

    pub(crate) const NAMES: [&str; 17] = [
        "theta",
        "theta3",
        "theta4",
        "theta3_dot",
        "theta4_dot",
        "theta3_ddot",
        "theta4_ddot",
        "A_x",
        "A_y",
        "B_x",
        "B_y",
        "v_A_x",
        "v_A_y",
        "v_B_x",
        "v_B_y",
        "loop_residual",
        "n_steps",
    ];

    fn harness(params: &[(&str, f64)]) -> Harness<FourBar> {
        let mut h = Harness::<FourBar>::new();
        for (n, v) in params {
            h.set(n, *v).unwrap();
        }
        h.initialize(None).unwrap();
        h
    }

    /// Both branches over two revolutions (2401 points, default tolerance) against the law-of-
    /// cosines closed form: angles projected at every point agree to rounding (bound 1e-12
    /// rad); rates and accelerations within the finite-difference bounds of `fd`. B from C and
    /// theta4, and its velocity, checked against the closed form too (bounds 1e-12 m, and
    /// l_BC times the rate bound). The loop gap stays below 1e-9 m.
    #[test]
    fn motion_matches_the_closed_form_on_both_branches() {
        for br in [1.0, -1.0] {
            let p = FourBar { branch: br as i32, ..FourBar::default() };
            let mut h = harness(&[("branch", br)]);
            let tr = h.run(24.0, 0.01, &NAMES).unwrap();
            assert_eq!(tr.time.len(), 2401);
            let mut err = [0.0f64; 4];
            for k in 0..tr.time.len() {
                let g = |n: &str| tr.get(n)[k];
                let th = p.theta0 + p.omega * tr.time[k];
                assert!((g("theta") - th).abs() < 1e-12);
                let (t3, t4) = closed_form(&p, th, br);
                let d = fd(&p, th, br);
                err[0] = err[0].max(wrap(g("theta3") - t3).abs()).max(wrap(g("theta4") - t4).abs());
                err[1] = err[1].max((g("theta3_dot") - d[0]).abs()).max((g("theta4_dot") - d[1]).abs());
                err[2] = err[2].max((g("theta3_ddot") - d[2]).abs()).max((g("theta4_ddot") - d[3]).abs());
                err[3] = err[3].max(g("loop_residual"));
                let (bx, by) = (p.l_co + p.l_bc * t4.cos(), p.l_bc * t4.sin());
                assert!((g("B_x") - bx).abs() < 1e-12 && (g("B_y") - by).abs() < 1e-12);
                assert!((g("v_B_x") + p.l_bc * d[1] * t4.sin()).abs() < 3e-8 && (g("v_B_y") - p.l_bc * d[1] * t4.cos()).abs() < 3e-8);
                assert!((g("A_x") - p.l_oa * th.cos()).abs() < 1e-12 && (g("v_A_y") - p.l_oa * p.omega * th.cos()).abs() < 1e-12);
                // The branch: B stays left (+1) or right (-1) of A->C.
                let cross = (p.l_co - g("A_x")) * (g("B_y") - g("A_y")) + g("A_y") * (g("B_x") - g("A_x"));
                assert!(br * cross > 0.0);
            }
            eprintln!(
                "branch {br}: max |angle err| {:.2e} rad, rates {:.2e} rad/s, accelerations {:.2e} rad/s2, loop_residual {:.2e} m",
                err[0], err[1], err[2], err[3]
            );
            assert!(err[0] < 1e-12 && err[1] < 5e-8 && err[2] < 2e-7 && err[3] < 1e-9, "{err:?}");
        }
    }

    /// A crank-rocker is periodic in the input angle: after one revolution (12 s at 5 rpm) the
    /// whole state is back at its start (positions and rates projected, so to rounding: 1e-12).
    #[test]
    fn returns_to_the_start_after_one_revolution() {
        let mut h = harness(&[]);
        let names = ["theta3", "theta4", "theta3_dot", "theta4_dot", "theta3_ddot", "theta4_ddot", "B_x", "B_y"];
        let start: Vec<f64> = names.iter().map(|n| h.get(n).unwrap()).collect();
        h.run(12.0, 0.05, &names).unwrap();
        for (n, s) in names.iter().zip(&start) {
            let v = h.get(n).unwrap();
            let diff = if n.ends_with("3") || n.ends_with("4") { wrap(v - s) } else { v - s };
            eprintln!("{n}: start {s:.15} after one revolution {v:.15}");
            assert!(diff.abs() < 1e-12, "{n}: {s} -> {v}");
        }
    }

    #[test]
    fn impossible_assembly_is_refused_naming_the_parameters() {
        let mut h = Harness::<FourBar>::new();
        h.set("l_CO", 1.0).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(err.contains("theta0 = 135.0000 deg") && err.contains("l_CO = 1 m") && err.contains("l_BC") && err.contains("theta_CO"), "{err}");
        let mut h = Harness::<FourBar>::new();
        h.set("branch", 2.0).unwrap();
        assert!(h.initialize(None).unwrap_err().contains("parameter branch"));
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu::table::Table::<FourBar>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }
}
