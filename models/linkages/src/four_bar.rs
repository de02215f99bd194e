//! The four-bar OABC of Ex. 5A #3 and #4 (crank-rocker, double rocker).

use fmu_export::{require_finite, require_positive, EventOutcome, Model, ModelError, ModelInfo, Variable};
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};
use std::marker::PhantomData;

use crate::FourBarPreset;

/// Rows of this model's variable table.
type V<P> = Variable<FourBar<P>>;

/// The run stops when |det A| / (l_AB l_BC) = |sin(theta4 - theta3)| falls below this.
pub const SINGULAR: f64 = 1e-3;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// Four-bar OABC: input link OA (angle theta), coupler AB (angle theta3 of A->B), output
/// link CB (angle theta4 of C->B), ground O->C of length l_CO at angle theta_CO.
/// Loop r2 + r3 = r1 + r4. State vector [theta, theta3, theta4, theta3', theta4'].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct FourBar<P> {
    /// Which FMU this is (defaults and identity); no data.
    #[serde(skip)]
    pub preset: PhantomData<fn() -> P>,
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

impl<P: FourBarPreset> Default for FourBar<P> {
    fn default() -> Self {
        let p = P::parameters();
        let mut m = FourBar {
            preset: PhantomData,
            l_oa: p.l_oa,
            l_ab: p.l_ab,
            l_bc: p.l_bc,
            l_co: p.l_co,
            theta_co: p.theta_co,
            theta0: p.theta0,
            omega: p.omega,
            branch: p.branch,
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

impl<P: FourBarPreset> FourBar<P> {
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
        self.l_oa * self.omega * self.omega * Vector2::new(theta.cos(), theta.sin())
            + self.l_ab * w3 * w3 * Vector2::new(th3.cos(), th3.sin())
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
    pub fn assemble(&self, x: &mut [f64]) -> Result<(), ModelError> {
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

impl<P: FourBarPreset> Model for FourBar<P> {
    const N_STATES: usize = 5;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        P::info()
    }

    fn variables() -> Vec<Variable<Self>> {
        vec![
            V::<P>::parameter("l_OA", "Input link length OA", |s| s.l_oa, |s, v| s.l_oa = v).unit("m").display("mm"),
            V::<P>::parameter("l_AB", "Coupler length AB", |s| s.l_ab, |s, v| s.l_ab = v).unit("m").display("mm"),
            V::<P>::parameter("l_BC", "Output link length BC", |s| s.l_bc, |s, v| s.l_bc = v).unit("m").display("mm"),
            V::<P>::parameter("l_CO", "Ground length OC", |s| s.l_co, |s, v| s.l_co = v).unit("m").display("mm"),
            V::<P>::parameter("theta_CO", "Direction of the ground pivot C seen from O", |s| s.theta_co, |s, v| s.theta_co = v)
                .unit("rad")
                .display("deg"),
            V::<P>::parameter("theta0", "Initial input angle (counter-clockwise from +x)", |s| s.theta0, |s, v| s.theta0 = v)
                .unit("rad")
                .display("deg"),
            V::<P>::parameter("omega", "Input angular velocity (counter-clockwise, constant)", |s| s.omega, |s, v| s.omega = v)
                .unit("rad/s")
                .display("rpm"),
            V::<P>::integer_parameter(
                "branch",
                "Assembly: +1 puts B to the left of the directed line A->C, -1 to the right",
                |s| s.branch,
                |s, v| s.branch = v,
            ),
            V::<P>::state("theta", "Input angle theta2 of O->A", 0).unit("rad").display("deg"),
            V::<P>::state("theta3", "Angle of the coupler A->B", 1).unit("rad").display("deg"),
            V::<P>::state("theta4", "Angle of the output link C->B", 2).unit("rad").display("deg"),
            V::<P>::state("theta3_dot", "Angular velocity of the coupler", 3).unit("rad/s"),
            V::<P>::state("theta4_dot", "Angular velocity of the output link", 4).unit("rad/s"),
            V::<P>::output("theta3_ddot", "Angular acceleration of the coupler", |s| s.theta3_ddot).unit("rad/s2"),
            V::<P>::output("theta4_ddot", "Angular acceleration of the output link", |s| s.theta4_ddot).unit("rad/s2"),
            V::<P>::output("A_x", "x of the joint A", |s| s.a_x).unit("m"),
            V::<P>::output("A_y", "y of the joint A", |s| s.a_y).unit("m"),
            V::<P>::output("B_x", "x of the joint B", |s| s.b_x).unit("m"),
            V::<P>::output("B_y", "y of the joint B", |s| s.b_y).unit("m"),
            V::<P>::output("v_A_x", "x velocity of A", |s| s.v_a_x).unit("m/s"),
            V::<P>::output("v_A_y", "y velocity of A", |s| s.v_a_y).unit("m/s"),
            V::<P>::output("v_B_x", "x velocity of B", |s| s.v_b_x).unit("m/s"),
            V::<P>::output("v_B_y", "y velocity of B", |s| s.v_b_y).unit("m/s"),
            V::<P>::output("loop_residual", "Vector-loop gap |e| (E.16)", |s| s.loop_residual).unit("m"),
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
        crate::check_branch(self.branch)?;
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
        (self.a_x, self.a_y, self.v_a_x, self.v_a_y) = crate::crank_point(self.l_oa, x[0], self.omega);
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

    /// The loop-closure gap |e| over the sum of the lengths (Model Exchange projects with a
    /// step event when it exceeds the tolerance).
    fn constraint_drift(&self, x: &[f64]) -> f64 {
        self.gap(x[0], x[1], x[2]).norm() / (self.l_oa + self.l_ab + self.l_bc + self.l_co)
    }

    /// At every communication point: project onto the constraints (see `project`); a point
    /// that cannot be projected on this branch is a limit position.
    fn communication_point(&mut self, _t: f64, x: &mut [f64]) -> Result<EventOutcome, ModelError> {
        if self.project(x, SINGULAR) {
            return Ok(EventOutcome::Continue);
        }
        Ok(EventOutcome::Stop {
            reason: format!(
                "the loop can no longer be closed on this branch at theta = {:.4} deg: a limit position, or a step too large for the solver (with euler or rk4, reduce fixed_step)",
                x[0].to_degrees()
            ),
        })
    }
}
