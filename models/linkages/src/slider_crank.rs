//! The slider-crank of Ex. 5A #1 and #2 (slider on the x-axis, or offset to y = y_OC).

use fmu_export::scalar::length;
use fmu_export::{Equations, EventOutcome, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};
use std::marker::PhantomData;

use crate::SliderCrankPreset;

/// The run stops when |det A| / l_AB = |cos theta3| on the closed loop falls to this: the rod
/// 2.87 deg short of perpendicular to the slider line, a margin before the limit position
/// that an implicit solver reaches at any tolerance (derivation.md, "Limit positions").
pub const SINGULAR: f64 = 0.05;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// Mechanisms #1 and #2: crank OA (input, angle theta) and connecting rod AB; the slider B moves
/// on the line y = y_OC. Loop r2 + r3 = r1 + r4, unknowns r1 (= x of B) and theta3 (angle of
/// A->B).
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[serde(bound(serialize = "T: Serialize + Scalar", deserialize = "T: Deserialize<'de> + Scalar"))]
#[variables(states = State, bound = "P: SliderCrankPreset")]
pub struct SliderCrank<P, T = f64> {
    /// Which FMU this is (defaults and identity); no data.
    #[serde(skip)]
    pub preset: PhantomData<fn() -> P>,
    /// Crank length OA
    #[parameter(name = "l_OA", unit = "m", display = "mm", positive)]
    pub l_oa: T,
    /// Connecting rod length AB
    #[parameter(name = "l_AB", unit = "m", display = "mm", positive)]
    pub l_ab: T,
    /// Height of the slider's line above O (collar height)
    // The centred crank-slider has no slider offset to set (MODELS.md).
    #[parameter(name = "y_OC", unit = "m", display = "mm", finite, when = P::HAS_OFFSET)]
    pub y_oc: T,
    /// Initial crank angle (counter-clockwise from +x)
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta0: T,
    /// Crank angular velocity (counter-clockwise, constant)
    #[parameter(unit = "rad/s", display = "rpm", finite)]
    pub omega: T,
    /// Assembly: +1 puts B at larger x than A, -1 at smaller x
    #[parameter(one_of(1, -1))]
    pub branch: i32,
    /// Slider acceleration
    #[output(unit = "m/s2")]
    pub r1_ddot: T,
    /// Angular acceleration of the connecting rod
    #[output(unit = "rad/s2")]
    pub theta3_ddot: T,
    /// x and y of the crank pin A
    #[output(name = "A", unit = "m")]
    pub a: Vector2<T>,
    /// x and y of the slider pin B
    #[output(name = "B", unit = "m")]
    pub b: Vector2<T>,
    /// x and y velocity of A
    #[output(name = "v_A", unit = "m/s")]
    pub v_a: Vector2<T>,
    /// x and y velocity of B
    #[output(name = "v_B", unit = "m/s")]
    pub v_b: Vector2<T>,
    /// Vector-loop gap |e| (E.16)
    #[output(unit = "m")]
    pub loop_residual: T,
}

/// The state vector: the crank angle, the loop's unknowns x = [r1, theta3] and their rates.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Crank angle theta2
    #[state(unit = "rad", display = "deg")]
    pub theta: T,
    /// Slider position: x of B (vector r1 along +x, r4 = y_OC up)
    #[state(unit = "m")]
    pub r1: T,
    /// Angle of the connecting rod A->B
    #[state(unit = "rad", display = "deg")]
    pub theta3: T,
    /// Slider velocity
    #[state(unit = "m/s")]
    pub r1_dot: T,
    /// Angular velocity of the connecting rod
    #[state(unit = "rad/s")]
    pub theta3_dot: T,
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
            a: Vector2::zeros(),
            b: Vector2::zeros(),
            v_a: Vector2::zeros(),
            v_b: Vector2::zeros(),
            loop_residual: 0.0,
        };
        // Start values of the outputs: the assembled initial configuration.
        let mut x = [0.0; State::LEN];
        if m.assemble(&mut x).is_ok() {
            m.outputs(0.0, &x);
        }
        m
    }
}

impl<P: SliderCrankPreset, T: Scalar> SliderCrank<P, T> {
    /// Loop-closure gap e = r2 + r3 - r1 - r4 (E.14, E.15).
    pub fn gap(&self, theta: T, r1: T, th3: T) -> Vector2<T> {
        Vector2::new(self.l_oa * theta.cos() + self.l_ab * th3.cos() - r1, self.l_oa * theta.sin() + self.l_ab * th3.sin() - self.y_oc)
    }

    /// A of A x' = b and A x'' = b, for x = [r1, theta3].
    pub fn a_matrix(&self, th3: T) -> Matrix2<T> {
        Matrix2::new(-T::one(), -self.l_ab * th3.sin(), T::zero(), self.l_ab * th3.cos())
    }

    /// b of the velocity equations (E.5, E.6 for this loop).
    fn b_velocity(&self, theta: T) -> Vector2<T> {
        Vector2::new(self.l_oa * self.omega * theta.sin(), -self.l_oa * self.omega * theta.cos())
    }

    /// b of the acceleration equations (E.10, E.11 for this loop; theta'' = 0).
    fn b_acceleration(&self, theta: T, th3: T, th3_dot: T) -> Vector2<T> {
        let w2 = self.omega * self.omega;
        let t2 = th3_dot * th3_dot;
        Vector2::new(self.l_oa * w2 * theta.cos() + self.l_ab * t2 * th3.cos(), self.l_oa * w2 * theta.sin() + self.l_ab * t2 * th3.sin())
    }

    /// x'' = A^-1 b; a singular A (only past the stop at a limit position) gives zeros, not NaN.
    fn accelerations(&self, s: &State<T>) -> Vector2<T> {
        let b = self.b_acceleration(s.theta, s.theta3, s.theta3_dot);
        self.a_matrix(s.theta3).lu().solve(&b).filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or_else(Vector2::zeros)
    }

    /// Velocities consistent with the positions: A x' = b.
    fn velocities(&self, theta: T, th3: T) -> Option<Vector2<T>> {
        self.a_matrix(th3).lu().solve(&self.b_velocity(theta))
    }

    /// Distance to the singularity of A, signed by the branch: |det A| / l_AB = branch cos theta3.
    fn singularity_margin(&self, th3: T) -> T {
        th3.cos() * f64::from(self.branch)
    }

    /// The same distance where the loop is closed, from the crank angle alone (derivation.md,
    /// "Limit positions"): |cos theta3| = sqrt(1 - ((y_OC - l_OA sin theta) / l_AB)^2), zero
    /// at a limit position. theta is exact (theta' is constant), so an importer's solver
    /// finds the stop at the same crank angle at any tolerance, whatever the drift of theta3.
    fn closed_loop_margin(&self, theta: T) -> T {
        let s = (self.y_oc - self.l_oa * theta.sin()) / self.l_ab;
        (T::one() - s * s).max(T::zero()).sqrt()
    }

    /// Initial positions for `branch` (B at larger x than A for +1) and velocities from A x' = b.
    pub fn assemble(&self, x: &mut [T]) -> Result<(), ModelError> {
        let (theta, l, b) = (self.theta0, self.l_ab, f64::from(self.branch));
        let (ax, ay) = (self.l_oa * theta.cos(), self.l_oa * theta.sin());
        let dy = self.y_oc - ay;
        if dy.abs() >= l {
            return Err(ModelError(format!(
                "the mechanism cannot be assembled at theta0 = {:.4} deg: the rod l_AB = {} m cannot reach the slider line y_OC = {} m from A (l_OA = {} m), which is {} m away",
                theta.value().to_degrees(),
                l.value(),
                self.y_oc.value(),
                self.l_oa.value(),
                dy.abs().value()
            )));
        }
        // E.3.1: the zero of the gap e, here in closed form (circle about A meets the line).
        let dx = (l * l - dy * dy).sqrt() * b;
        let th3 = dy.atan2(dx);
        if self.closed_loop_margin(theta) <= T::from(SINGULAR) {
            return Err(ModelError(format!(
                "theta0 = {:.4} deg is at (or within the stop margin |cos theta3| = {SINGULAR} of) a limit position of the mechanism (l_OA = {}, l_AB = {}, y_OC = {}): A is singular there",
                theta.value().to_degrees(),
                self.l_oa.value(),
                l.value(),
                self.y_oc.value()
            )));
        }
        let v = self.velocities(theta, th3).ok_or_else(|| ModelError("A is singular at theta0".into()))?;
        State { theta, r1: ax + dx, theta3: th3, r1_dot: v[0], theta3_dot: v[1] }.store(x);
        Ok(())
    }
}

impl<P: SliderCrankPreset> SliderCrank<P> {
    /// Projects the positions back onto the loop closure by Newton's method on e = 0 (the
    /// Jacobian of e with respect to the unknowns is A; the input angle is exact), then the
    /// velocities onto A x' = b. Leaves x unchanged and returns false when Newton does not
    /// converge on this branch with at least `min_margin` from the singularity.
    fn project(&self, x: &mut [f64], min_margin: f64) -> bool {
        let scale = self.l_oa + self.l_ab + self.y_oc.abs();
        let State { theta, r1, theta3, .. } = State::load(x);
        let mut q = Vector2::new(r1, theta3);
        for _ in 0..NEWTON_ITERS {
            let e = self.gap(theta, q[0], q[1]);
            if e.norm() <= 1e-15 * scale {
                break;
            }
            match self.a_matrix(q[1]).lu().solve(&e) {
                // The Jacobian of e with respect to (r1, theta3) is A itself.
                Some(dq) => q -= dq,
                None => break,
            }
        }
        let closed = self.singularity_margin(q[1]) >= min_margin && self.gap(theta, q[0], q[1]).norm() < 1e-12 * scale;
        if !closed {
            return false;
        }
        let Some(v) = self.velocities(theta, q[1]) else {
            return false;
        };
        State { theta, r1: q[0], theta3: q[1], r1_dot: v[0], theta3_dot: v[1] }.store(x);
        true
    }
}

impl<P: SliderCrankPreset, T: Scalar> Equations<T> for SliderCrank<P, T> {
    /// The assembly for theta0 (the lengths and the branch are checked by their ranges).
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        self.assemble(x)
    }

    /// The crank turns at omega; the unknowns' accelerations from A x'' = b.
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        State { theta: self.omega, r1: s.r1_dot, theta3: s.theta3_dot, r1_dot: acc[0], theta3_dot: acc[1] }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        self.r1_ddot = acc[0];
        self.theta3_ddot = acc[1];
        (self.a, self.v_a) = crate::crank_point(self.l_oa, s.theta, self.omega);
        self.b = Vector2::new(s.r1, self.y_oc);
        self.v_b = Vector2::new(s.r1_dot, T::zero());
        // Zero but for the rounding of its terms (the lengths) after a projection.
        let noise = 16.0 * f64::EPSILON * (self.l_oa + self.l_ab + self.y_oc.abs()).value();
        self.loop_residual = length(&self.gap(s.theta, s.r1, s.theta3), noise);
    }
}

impl<P: SliderCrankPreset> Model for SliderCrank<P> {
    const N_STATES: usize = State::LEN;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        P::info()
    }

    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        z[0] = self.closed_loop_margin(State::load(x).theta) - SINGULAR;
    }

    fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        let s = State::load(x);
        if fired[0] && self.closed_loop_margin(s.theta) <= 2.0 * SINGULAR {
            // Close the loop at the stop too (matters for the fixed-step solvers, whose last
            // step may have drifted); if that fails on this branch the state is left as is.
            self.project(x, 0.0);
            return Ok(EventOutcome::Stop {
                reason: format!(
                    "limit position at theta = {:.4} deg: the connecting rod AB is within the margin |cos theta3| = {SINGULAR} of perpendicular to the slider line (where A is singular), the crank cannot turn further",
                    s.theta.to_degrees()
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
                State::load(x).theta.to_degrees()
            ),
        })
    }
}
