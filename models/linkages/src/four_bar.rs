//! The four-bar OABC of Ex. 5A #3 and #4 (crank-rocker, double rocker).

use fmu_export::scalar::length;
use fmu_export::{Equations, EventOutcome, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};
use std::marker::PhantomData;

use crate::FourBarPreset;

/// The run stops when |det A| / (l_AB l_BC) = |sin(theta4 - theta3)| on the closed loop falls
/// to this: AB and BC 2.87 deg short of collinear, a margin before the limit position that an
/// implicit solver reaches at any tolerance (derivation.md, "Limit positions").
pub const SINGULAR: f64 = 0.05;
/// Newton iterations of the projection onto the loop closure.
const NEWTON_ITERS: usize = 20;

/// Four-bar OABC: input link OA (angle theta), coupler AB (angle theta3 of A->B), output
/// link CB (angle theta4 of C->B), ground O->C of length l_CO at angle theta_CO.
/// Loop r2 + r3 = r1 + r4.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[serde(bound(serialize = "T: Serialize + Scalar", deserialize = "T: Deserialize<'de> + Scalar"))]
#[variables(states = State, bound = "P: FourBarPreset")]
pub struct FourBar<P, T = f64> {
    /// Which FMU this is (defaults and identity); no data.
    #[serde(skip)]
    pub preset: PhantomData<fn() -> P>,
    /// Input link length OA
    #[parameter(name = "l_OA", unit = "m", display = "mm", positive)]
    pub l_oa: T,
    /// Coupler length AB
    #[parameter(name = "l_AB", unit = "m", display = "mm", positive)]
    pub l_ab: T,
    /// Output link length BC
    #[parameter(name = "l_BC", unit = "m", display = "mm", positive)]
    pub l_bc: T,
    /// Ground length OC
    #[parameter(name = "l_CO", unit = "m", display = "mm", positive)]
    pub l_co: T,
    /// Direction of the ground pivot C seen from O
    #[parameter(name = "theta_CO", unit = "rad", display = "deg", finite)]
    pub theta_co: T,
    /// Initial input angle (counter-clockwise from +x)
    #[parameter(unit = "rad", display = "deg", finite)]
    pub theta0: T,
    /// Input angular velocity (counter-clockwise, constant)
    #[parameter(unit = "rad/s", display = "rpm", finite)]
    pub omega: T,
    /// Assembly: +1 puts B to the left of the directed line A->C, -1 to the right
    #[parameter(one_of(1, -1))]
    pub branch: i32,
    /// Angular acceleration of the coupler
    #[output(unit = "rad/s2")]
    pub theta3_ddot: T,
    /// Angular acceleration of the output link
    #[output(unit = "rad/s2")]
    pub theta4_ddot: T,
    /// x and y of the joint A
    #[output(name = "A", unit = "m")]
    pub a: Vector2<T>,
    /// x and y of the joint B
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

/// The state vector: the input angle, the loop's unknowns x = [theta3, theta4] and their rates.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Input angle theta2 of O->A
    #[state(unit = "rad", display = "deg")]
    pub theta: T,
    /// Angle of the coupler A->B
    #[state(unit = "rad", display = "deg")]
    pub theta3: T,
    /// Angle of the output link C->B
    #[state(unit = "rad", display = "deg")]
    pub theta4: T,
    /// Angular velocity of the coupler
    #[state(unit = "rad/s")]
    pub theta3_dot: T,
    /// Angular velocity of the output link
    #[state(unit = "rad/s")]
    pub theta4_dot: T,
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

impl<P: FourBarPreset, T: Scalar> FourBar<P, T> {
    /// The ground pivot C.
    pub fn c(&self) -> Vector2<T> {
        direction(self.theta_co) * self.l_co
    }

    /// Loop-closure gap e = r2 + r3 - r1 - r4 (E.14 to E.16 for this loop).
    pub fn gap(&self, theta: T, th3: T, th4: T) -> Vector2<T> {
        direction(theta) * self.l_oa + direction(th3) * self.l_ab - self.c() - direction(th4) * self.l_bc
    }

    /// A of A x' = b and A x'' = b, for x = [theta3, theta4].
    pub fn a_matrix(&self, th3: T, th4: T) -> Matrix2<T> {
        Matrix2::new(-self.l_ab * th3.sin(), self.l_bc * th4.sin(), self.l_ab * th3.cos(), -self.l_bc * th4.cos())
    }

    fn b_velocity(&self, theta: T) -> Vector2<T> {
        Vector2::new(theta.sin(), -theta.cos()) * (self.l_oa * self.omega)
    }

    fn b_acceleration(&self, theta: T, th3: T, th4: T, w3: T, w4: T) -> Vector2<T> {
        direction(theta) * (self.l_oa * self.omega * self.omega) + direction(th3) * (self.l_ab * w3 * w3)
            - direction(th4) * (self.l_bc * w4 * w4)
    }

    /// x'' = A^-1 b; a singular A (only past the stop at a limit position) gives zeros, not NaN.
    fn accelerations(&self, s: &State<T>) -> Vector2<T> {
        let b = self.b_acceleration(s.theta, s.theta3, s.theta4, s.theta3_dot, s.theta4_dot);
        self.a_matrix(s.theta3, s.theta4).lu().solve(&b).filter(|v| v.iter().all(|c| c.is_finite())).unwrap_or_else(Vector2::zeros)
    }

    fn velocities(&self, theta: T, th3: T, th4: T) -> Option<Vector2<T>> {
        self.a_matrix(th3, th4).lu().solve(&self.b_velocity(theta))
    }

    /// |det A| / (l_AB l_BC) signed by the branch: branch sin(theta4 - theta3) (positive on
    /// the chosen branch since sin(theta4 - theta3) l_AB l_BC = cross(C - A, B - A); zero when
    /// AB and BC are collinear).
    fn singularity_margin(&self, th3: T, th4: T) -> T {
        (th4 - th3).sin() * f64::from(self.branch)
    }

    /// The same distance where the loop is closed, from the input angle alone (derivation.md,
    /// "Limit positions"): |sin(theta4 - theta3)| is the sine of the angle at B of the
    /// triangle ABC, sqrt(1 - cos^2 B) with cos B = (l_AB^2 + l_BC^2 - |AC|^2) / (2 l_AB l_BC)
    /// and A at theta; zero at a limit position. theta is exact (theta' is constant), so an
    /// importer's solver finds the stop at the same input angle at any tolerance, whatever
    /// the drift of theta3 and theta4.
    fn closed_loop_margin(&self, theta: T) -> T {
        let ac = self.c() - direction(theta) * self.l_oa;
        let cos_b = (self.l_ab * self.l_ab + self.l_bc * self.l_bc - ac.dot(&ac)) / (self.l_ab * self.l_bc * 2.0);
        (T::one() - cos_b * cos_b).max(T::zero()).sqrt()
    }

    fn describe_parameters(&self) -> String {
        format!(
            "l_OA = {} m, l_AB = {} m, l_BC = {} m, l_CO = {} m, theta_CO = {:.4} deg",
            self.l_oa.value(),
            self.l_ab.value(),
            self.l_bc.value(),
            self.l_co.value(),
            self.theta_co.value().to_degrees()
        )
    }

    /// Initial positions for `branch` (+1: B to the left of the directed line A->C) from the
    /// intersection of the circles about A (radius l_AB) and C (radius l_BC); velocities from
    /// A x' = b.
    pub fn assemble(&self, x: &mut [T]) -> Result<(), ModelError> {
        let theta = self.theta0;
        let a = direction(theta) * self.l_oa;
        let ac = self.c() - a;
        let d = ac.norm();
        let (l3, l4) = (self.l_ab, self.l_bc);
        if !(d <= l3 + l4 && d >= (l3 - l4).abs()) || d == T::zero() {
            return Err(ModelError(format!(
                "the four-bar cannot be assembled at theta0 = {:.4} deg: |AC| = {:.6} m is outside [|l_AB - l_BC|, l_AB + l_BC] = [{:.6}, {:.6}] m ({})",
                theta.value().to_degrees(),
                d.value(),
                (l3 - l4).abs().value(),
                (l3 + l4).value(),
                self.describe_parameters()
            )));
        }
        let u = ac / d;
        let p = (l3 * l3 - l4 * l4 + d * d) / (d * 2.0);
        let h = (l3 * l3 - p * p).max(T::zero()).sqrt();
        let b = a + u * p + Vector2::new(-u[1], u[0]) * (h * f64::from(self.branch));
        let ab = b - a;
        let cb = b - self.c();
        let (th3, th4) = (ab[1].atan2(ab[0]), cb[1].atan2(cb[0]));
        if self.closed_loop_margin(theta) <= T::from(SINGULAR) {
            return Err(ModelError(format!(
                "theta0 = {:.4} deg is at (or within the stop margin |sin(theta4 - theta3)| = {SINGULAR} of) a limit position (AB and BC collinear, A singular): {}",
                theta.value().to_degrees(),
                self.describe_parameters()
            )));
        }
        let v = self.velocities(theta, th3, th4).ok_or_else(|| ModelError("A is singular at theta0".into()))?;
        State { theta, theta3: th3, theta4: th4, theta3_dot: v[0], theta4_dot: v[1] }.store(x);
        Ok(())
    }
}

/// The unit vector at angle `angle` from +x.
fn direction<T: Scalar>(angle: T) -> Vector2<T> {
    Vector2::new(angle.cos(), angle.sin())
}

impl<P: FourBarPreset> FourBar<P> {
    /// Projects the positions back onto the loop closure by Newton's method on e = 0 (the
    /// Jacobian of e with respect to the unknowns is A; the input angle is exact), then the
    /// velocities onto A x' = b. Leaves x unchanged and returns false when Newton does not
    /// converge on this branch with at least `min_margin` from the singularity.
    fn project(&self, x: &mut [f64], min_margin: f64) -> bool {
        let scale = self.l_oa + self.l_ab + self.l_bc + self.l_co;
        let State { theta, theta3, theta4, .. } = State::load(x);
        let mut q = Vector2::new(theta3, theta4);
        for _ in 0..NEWTON_ITERS {
            let e = self.gap(theta, q[0], q[1]);
            if e.norm() <= 1e-15 * scale {
                break;
            }
            match self.a_matrix(q[0], q[1]).lu().solve(&e) {
                // The Jacobian of e with respect to (theta3, theta4) is A itself.
                Some(dq) => q -= dq,
                None => break,
            }
        }
        let closed = self.singularity_margin(q[0], q[1]) >= min_margin && self.gap(theta, q[0], q[1]).norm() < 1e-12 * scale;
        if !closed {
            return false;
        }
        let Some(v) = self.velocities(theta, q[0], q[1]) else {
            return false;
        };
        State { theta, theta3: q[0], theta4: q[1], theta3_dot: v[0], theta4_dot: v[1] }.store(x);
        true
    }
}

impl<P: FourBarPreset, T: Scalar> Equations<T> for FourBar<P, T> {
    /// The assembly for theta0 (the lengths and the branch are checked by their ranges).
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        self.assemble(x)
    }

    /// The input turns at omega; the unknowns' accelerations from A x'' = b.
    fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        State { theta: self.omega, theta3: s.theta3_dot, theta4: s.theta4_dot, theta3_dot: acc[0], theta4_dot: acc[1] }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let s = State::load(x);
        let acc = self.accelerations(&s);
        self.theta3_ddot = acc[0];
        self.theta4_ddot = acc[1];
        (self.a, self.v_a) = crate::crank_point(self.l_oa, s.theta, self.omega);
        let (s4, c4) = s.theta4.sin_cos();
        let pc = self.c();
        self.b = Vector2::new(pc[0] + self.l_bc * c4, pc[1] + self.l_bc * s4);
        self.v_b = Vector2::new(-self.l_bc * s.theta4_dot * s4, self.l_bc * s.theta4_dot * c4);
        // Zero but for the rounding of its terms (the lengths) after a projection.
        let noise = 16.0 * f64::EPSILON * (self.l_oa + self.l_ab + self.l_bc + self.l_co).value();
        self.loop_residual = length(&self.gap(s.theta, s.theta3, s.theta4), noise);
    }
}

impl<P: FourBarPreset> Model for FourBar<P> {
    const N_STATES: usize = State::LEN;
    const N_EVENT_INDICATORS: usize = 1;

    fn info() -> ModelInfo {
        P::info()
    }

    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        let s = State::load(x);
        z[0] = self.closed_loop_margin(s.theta) - SINGULAR;
    }

    fn on_event(&mut self, _t: f64, x: &mut [f64], fired: &[bool]) -> Result<EventOutcome, ModelError> {
        let s = State::load(x);
        if fired[0] && self.closed_loop_margin(s.theta) <= 2.0 * SINGULAR {
            // Close the loop at the stop too (matters for the fixed-step solvers, whose last
            // step may have drifted); if that fails on this branch the state is left as is.
            self.project(x, 0.0);
            return Ok(EventOutcome::Stop {
                reason: format!(
                    "limit position at theta = {:.4} deg: the coupler AB and the link BC are within the margin |sin(theta4 - theta3)| = {SINGULAR} of collinear (where A is singular), the input link cannot turn further",
                    s.theta.to_degrees()
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
                State::load(x).theta.to_degrees()
            ),
        })
    }
}
