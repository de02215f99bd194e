//! The slider-crank of Ex. 5A #1 and #2 (slider on the x-axis, or offset to y = y_OC).

use fmu_export::{require_finite, require_positive, EventOutcome, Model, ModelError, ModelInfo, Variable};
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};
use std::marker::PhantomData;

use crate::SliderCrankPreset;

/// Rows of this model's variable table.
type V<P> = Variable<SliderCrank<P>>;

/// The run stops when |det A| / l_AB = |cos theta3| falls below this (a limit position).
pub const SINGULAR: f64 = 1e-3;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// Mechanisms #1 and #2: crank OA (input, angle theta) and connecting rod AB; the slider B moves
/// on the line y = y_OC. Loop r2 + r3 = r1 + r4, unknowns r1 (= x of B)
/// and theta3 (angle of A->B). State vector [theta, r1, theta3, r1', theta3'].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(bound = "")]
pub struct SliderCrank<P> {
    /// Which FMU this is (defaults and identity); no data.
    #[serde(skip)]
    pub preset: PhantomData<fn() -> P>,
    pub l_oa: f64,
    pub l_ab: f64,
    /// Height of the slider's line above O.
    pub y_oc: f64,
    pub theta0: f64,
    pub omega: f64,
    pub branch: i32,
    // Outputs.
    pub r1_ddot: f64,
    pub theta3_ddot: f64,
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

impl<P: SliderCrankPreset> Default for SliderCrank<P> {
    fn default() -> Self {
        let p = P::parameters();
        let mut m = SliderCrank {
            preset: PhantomData,
            l_oa: p.l_oa,
            l_ab: p.l_ab,
            y_oc: p.y_oc,
            theta0: p.theta0,
            omega: p.omega,
            branch: p.branch,
            r1_ddot: 0.0,
            theta3_ddot: 0.0,
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

impl<P: SliderCrankPreset> SliderCrank<P> {
    /// Loop-closure gap e = r2 + r3 - r1 - r4 (E.14, E.15).
    pub fn gap(&self, theta: f64, r1: f64, th3: f64) -> Vector2<f64> {
        Vector2::new(self.l_oa * theta.cos() + self.l_ab * th3.cos() - r1, self.l_oa * theta.sin() + self.l_ab * th3.sin() - self.y_oc)
    }

    /// A of A x' = b and A x'' = b, for x = [r1, theta3].
    pub fn a_matrix(&self, th3: f64) -> Matrix2<f64> {
        Matrix2::new(-1.0, -self.l_ab * th3.sin(), 0.0, self.l_ab * th3.cos())
    }

    /// b of the velocity equations (E.5, E.6 for this loop).
    fn b_velocity(&self, theta: f64) -> Vector2<f64> {
        Vector2::new(self.l_oa * self.omega * theta.sin(), -self.l_oa * self.omega * theta.cos())
    }

    /// b of the acceleration equations (E.10, E.11 for this loop; theta'' = 0).
    fn b_acceleration(&self, theta: f64, th3: f64, th3_dot: f64) -> Vector2<f64> {
        let w2 = self.omega * self.omega;
        let t2 = th3_dot * th3_dot;
        Vector2::new(self.l_oa * w2 * theta.cos() + self.l_ab * t2 * th3.cos(), self.l_oa * w2 * theta.sin() + self.l_ab * t2 * th3.sin())
    }

    /// x'' = A^-1 b; a singular A (only past the stop at a limit position) gives zeros, not NaN.
    fn accelerations(&self, x: &[f64]) -> Vector2<f64> {
        let b = self.b_acceleration(x[0], x[2], x[4]);
        self.a_matrix(x[2]).lu().solve(&b).filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or_else(Vector2::zeros)
    }

    /// Velocities consistent with the positions: A x' = b.
    fn velocities(&self, theta: f64, th3: f64) -> Option<Vector2<f64>> {
        self.a_matrix(th3).lu().solve(&self.b_velocity(theta))
    }

    /// Distance to the singularity of A, signed by the branch: |det A| / l_AB = branch cos theta3.
    fn singularity_margin(&self, th3: f64) -> f64 {
        self.branch as f64 * th3.cos()
    }

    /// Initial positions for `branch` (B at larger x than A for +1) and velocities from A x' = b.
    pub fn assemble(&self, x: &mut [f64]) -> Result<(), ModelError> {
        let (theta, l, b) = (self.theta0, self.l_ab, self.branch as f64);
        let (ax, ay) = (self.l_oa * theta.cos(), self.l_oa * theta.sin());
        let dy = self.y_oc - ay;
        if dy.abs() >= l {
            return Err(ModelError(format!(
                "the mechanism cannot be assembled at theta0 = {:.4} deg: the rod l_AB = {} m cannot reach the slider line y_OC = {} m from A (l_OA = {} m), which is {} m away",
                theta.to_degrees(),
                l,
                self.y_oc,
                self.l_oa,
                dy.abs()
            )));
        }
        // E.3.1: the zero of the gap e, here in closed form (circle about A meets the line).
        let dx = b * (l * l - dy * dy).sqrt();
        let th3 = dy.atan2(dx);
        if self.singularity_margin(th3) < SINGULAR {
            return Err(ModelError(format!(
                "theta0 = {:.4} deg is at a limit position of the mechanism (l_OA = {}, l_AB = {}, y_OC = {}): A is singular",
                theta.to_degrees(),
                self.l_oa,
                l,
                self.y_oc
            )));
        }
        let v = self.velocities(theta, th3).ok_or_else(|| ModelError("A is singular at theta0".into()))?;
        x.copy_from_slice(&[theta, ax + dx, th3, v[0], v[1]]);
        Ok(())
    }

    /// Projects the positions back onto the loop closure by Newton's method on e = 0 (the
    /// Jacobian of e with respect to the unknowns is A; the input angle is exact), then the
    /// velocities onto A x' = b. Leaves x unchanged and returns false when Newton does not
    /// converge on this branch with at least `min_margin` from the singularity.
    fn project(&self, x: &mut [f64], min_margin: f64) -> bool {
        let scale = self.l_oa + self.l_ab + self.y_oc.abs();
        let mut q = Vector2::new(x[1], x[2]);
        for _ in 0..NEWTON_ITERS {
            let e = self.gap(x[0], q[0], q[1]);
            if e.norm() <= 1e-15 * scale {
                break;
            }
            match self.a_matrix(q[1]).lu().solve(&e) {
                // The Jacobian of e with respect to (r1, theta3) is A itself.
                Some(dq) => q -= dq,
                None => break,
            }
        }
        let closed = self.singularity_margin(q[1]) >= min_margin && self.gap(x[0], q[0], q[1]).norm() < 1e-12 * scale;
        if !closed {
            return false;
        }
        let Some(v) = self.velocities(x[0], q[1]) else {
            return false;
        };
        x[1] = q[0];
        x[2] = q[1];
        x[3] = v[0];
        x[4] = v[1];
        true
    }
}

impl<P: SliderCrankPreset> Model for SliderCrank<P> {
    const N_STATES: usize = 5;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        P::info()
    }

    fn variables() -> Vec<Variable<Self>> {
        let mut rows = vec![
            V::<P>::parameter("l_OA", "Crank length OA", |s| s.l_oa, |s, v| s.l_oa = v).unit("m").display("mm"),
            V::<P>::parameter("l_AB", "Connecting rod length AB", |s| s.l_ab, |s, v| s.l_ab = v).unit("m").display("mm"),
            V::<P>::parameter("theta0", "Initial crank angle (counter-clockwise from +x)", |s| s.theta0, |s, v| s.theta0 = v)
                .unit("rad")
                .display("deg"),
            V::<P>::parameter("omega", "Crank angular velocity (counter-clockwise, constant)", |s| s.omega, |s, v| s.omega = v)
                .unit("rad/s")
                .display("rpm"),
            V::<P>::integer_parameter(
                "branch",
                "Assembly: +1 puts B at larger x than A, -1 at smaller x",
                |s| s.branch,
                |s, v| s.branch = v,
            ),
            V::<P>::state("theta", "Crank angle theta2", 0).unit("rad").display("deg"),
            V::<P>::state("r1", "Slider position: x of B (vector r1 along +x, r4 = y_OC up)", 1).unit("m"),
            V::<P>::state("theta3", "Angle of the connecting rod A->B", 2).unit("rad").display("deg"),
            V::<P>::state("r1_dot", "Slider velocity", 3).unit("m/s"),
            V::<P>::state("theta3_dot", "Angular velocity of the connecting rod", 4).unit("rad/s"),
            V::<P>::output("r1_ddot", "Slider acceleration", |s| s.r1_ddot).unit("m/s2"),
            V::<P>::output("theta3_ddot", "Angular acceleration of the connecting rod", |s| s.theta3_ddot).unit("rad/s2"),
            V::<P>::output("A_x", "x of the crank pin A", |s| s.a_x).unit("m"),
            V::<P>::output("A_y", "y of the crank pin A", |s| s.a_y).unit("m"),
            V::<P>::output("B_x", "x of the slider pin B", |s| s.b_x).unit("m"),
            V::<P>::output("B_y", "y of the slider pin B", |s| s.b_y).unit("m"),
            V::<P>::output("v_A_x", "x velocity of A", |s| s.v_a_x).unit("m/s"),
            V::<P>::output("v_A_y", "y velocity of A", |s| s.v_a_y).unit("m/s"),
            V::<P>::output("v_B_x", "x velocity of B", |s| s.v_b_x).unit("m/s"),
            V::<P>::output("v_B_y", "y velocity of B", |s| s.v_b_y).unit("m/s"),
            V::<P>::output("loop_residual", "Vector-loop gap |e| (E.16)", |s| s.loop_residual).unit("m"),
        ];
        // The centred crank-slider has no slider offset to set (MODELS.md).
        if P::HAS_OFFSET {
            rows.insert(
                2,
                V::<P>::parameter("y_OC", "Height of the slider's line above O (collar height)", |s| s.y_oc, |s, v| s.y_oc = v)
                    .unit("m")
                    .display("mm"),
            );
        }
        rows
    }

    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
        require_positive("l_OA", self.l_oa)?;
        require_positive("l_AB", self.l_ab)?;
        require_finite("y_OC", self.y_oc)?;
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
        self.r1_ddot = acc[0];
        self.theta3_ddot = acc[1];
        (self.a_x, self.a_y, self.v_a_x, self.v_a_y) = crate::crank_point(self.l_oa, x[0], self.omega);
        self.b_x = x[1];
        self.b_y = self.y_oc;
        self.v_b_x = x[3];
        self.v_b_y = 0.0;
        self.loop_residual = self.gap(x[0], x[1], x[2]).norm();
    }

    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = self.singularity_margin(x[2]) - SINGULAR;
    }

    fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        if fired[0] && self.singularity_margin(x[2]) <= 2.0 * SINGULAR {
            // Close the loop at the stop too (matters for the fixed-step solvers, whose last
            // step may have drifted); if that fails on this branch the state is left as is.
            self.project(x, 0.0);
            return Ok(EventOutcome::Stop {
                reason: format!(
                    "limit position at theta = {:.4} deg: the connecting rod AB is perpendicular to the slider line (A singular), the crank cannot turn further",
                    x[0].to_degrees()
                ),
            });
        }
        Ok(EventOutcome::Continue)
    }

    /// The loop-closure gap |e| over the sum of the lengths (Model Exchange projects with a
    /// step event when it exceeds the tolerance).
    fn constraint_drift(&self, x: &[f64]) -> f64 {
        self.gap(x[0], x[1], x[2]).norm() / (self.l_oa + self.l_ab + self.y_oc.abs())
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
