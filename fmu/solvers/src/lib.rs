//! ODE integrators for co-simulation: forward Euler and classic RK4 with a fixed step, the
//! adaptive Dormand–Prince 5(4), Bogacki–Shampine 3(2) and Dormand–Prince 8(5,3), and for stiff
//! systems the implicit variable-order BDF and the L-stable ESDIRK 3(2) (Newton iterations with
//! a Jacobian from the system's directional derivatives or grouped finite differences), all
//! with dense output and event (zero-crossing) location. Used inside the exported FMUs and by
//! the runner to integrate Model Exchange FMUs.
//!
//! The adaptive methods take the steps their error control chooses, across the times `advance`
//! is asked to reach: the state there comes from the dense output of the step that covers it,
//! and the next `advance` goes on from that step's own end (the *pending step*). The pending
//! step is thrown away, and integration restarts from the caller's point, when the caller
//! changes that point (a state or time other than the one handed out), calls `invalidate`
//! (new inputs or parameters), or changes the settings. No step goes past an event, nor past
//! the stop time (`set_stop_time`).
//!
//! The integrator owns every buffer it needs, so `advance` never allocates (except the `fired`
//! vector of an `Advance::Event`, and error messages). Its whole continuation-relevant state,
//! the pending step included, is `Clone` + serde, so an FMU can roll back with
//! `fmi2GetFMUstate`/`fmi2SetFMUstate`, or restore a serialized state in a fresh instance, and
//! continue bit for bit.

use serde::{Deserialize, Serialize};

mod adaptive;
mod bdf;
mod bs23;
pub mod controls;
mod dop853;
mod dopri5;
mod esdirk;
mod events;
mod fixed;
pub mod implicit;
mod lanes;
mod root;
#[cfg(test)]
mod stiff_tests;
#[cfg(test)]
mod tests;

/// The system the integrator advances: dx/dt = f(t, x), plus event indicators.
pub trait OdeSystem {
    /// Number of continuous states.
    fn dim(&self) -> usize;
    /// Writes f(t, x) into `dx`.
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]);
    /// Number of event indicators (zero-crossing functions).
    fn n_event_indicators(&self) -> usize {
        0
    }
    /// Writes the event indicator values at (t, x) into `z`.
    fn event_indicators(&self, _t: f64, _x: &[f64], _z: &mut [f64]) {}
    /// For each derivative (row of the Jacobian df/dx), the states it depends on, when known
    /// (an FMU's ModelStructure): the implicit methods then evaluate columns that share no row
    /// together. `None` (the default): every derivative may depend on every state.
    fn jacobian_pattern(&self) -> Option<&[Vec<usize>]> {
        None
    }
    /// Whether `directional_derivative` gives exact Jacobian products (else the implicit
    /// methods take finite differences of `rhs`).
    fn provides_directional_derivative(&self) -> bool {
        false
    }
    /// Writes df/dx(t, x) · v into `out` (NaN where it cannot be evaluated).
    fn directional_derivative(&self, _t: f64, _x: &[f64], _v: &[f64], out: &mut [f64]) {
        out.fill(f64::NAN);
    }
    /// The implicit methods' Jacobian by directional derivatives: for each group of `groups`
    /// (states seeded together with 1, the others 0), in order, df/dx(t, x) · seed handed to
    /// `column(group, values)` (NaN where it cannot be evaluated). `seed` and `out` are
    /// scratch of `dim()` values. The default makes one `directional_derivative` per group; a
    /// system whose point is costly to place (an FMU) places it once for all the columns.
    ///
    /// Generic in the group's type so that the implicit methods' usual groups, one column each
    /// (`[usize; 1]`), compile to a loop with no general case in it.
    fn directional_columns<G: AsRef<[usize]>>(
        &self,
        t: f64,
        x: &[f64],
        groups: &[G],
        (seed, out): (&mut [f64], &mut [f64]),
        mut column: impl FnMut(&[usize], &[f64]),
    ) {
        for group in groups {
            let group = group.as_ref();
            seed.fill(0.0);
            for &j in group {
                seed[j] = 1.0;
            }
            self.directional_derivative(t, x, seed, out);
            column(group, out);
        }
    }
}

/// Integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Method {
    /// Forward Euler with a fixed step.
    Euler,
    /// Classic 4th-order Runge–Kutta with a fixed step.
    Rk4,
    /// Adaptive Dormand–Prince 5(4) with its 4th-order dense output (MATLAB's ode45).
    Dopri5,
    /// Adaptive Bogacki–Shampine 3(2) with its cubic Hermite dense output (MATLAB's ode23).
    Bs23,
    /// Adaptive Dormand–Prince 8(5,3) with its 7th-order dense output (Hairer's DOP853).
    Dop853,
    /// Implicit variable-order (1–5) variable-step BDF for stiff systems (CVODE's class).
    Bdf,
    /// Implicit L-stable ESDIRK 3(2) (Kennedy & Carpenter) for stiff systems.
    Esdirk,
}

impl Method {
    /// Every method, in the order of their codes.
    pub const ALL: [Method; 7] = [Method::Euler, Method::Rk4, Method::Dopri5, Method::Bs23, Method::Dop853, Method::Bdf, Method::Esdirk];

    /// Method for an integer code as exposed in the model description (0 Euler, 1 Rk4, 2 Dopri5,
    /// 3 Bs23, 4 Dop853, 5 Bdf, 6 Esdirk).
    pub fn from_code(code: i32) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.code() == code)
    }

    /// Integer code of this method (inverse of `from_code`).
    pub fn code(self) -> i32 {
        match self {
            Method::Euler => 0,
            Method::Rk4 => 1,
            Method::Dopri5 => 2,
            Method::Bs23 => 3,
            Method::Dop853 => 4,
            Method::Bdf => 5,
            Method::Esdirk => 6,
        }
    }

    /// Lower-case name: "euler", "rk4", "dopri5", "bs23", "dop853", "bdf" or "esdirk".
    pub fn name(self) -> &'static str {
        match self {
            Method::Euler => "euler",
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
            Method::Bs23 => "bs23",
            Method::Dop853 => "dop853",
            Method::Bdf => "bdf",
            Method::Esdirk => "esdirk",
        }
    }

    /// The method's full name, for messages: "forward Euler", "classical RK4", ...
    pub fn title(self) -> &'static str {
        match self {
            Method::Euler => "forward Euler",
            Method::Rk4 => "classical RK4",
            Method::Dopri5 => "Dormand-Prince 5(4)",
            Method::Bs23 => "Bogacki-Shampine 3(2)",
            Method::Dop853 => "Dormand-Prince 8(5,3)",
            Method::Bdf => "implicit BDF, orders 1-5",
            Method::Esdirk => "implicit ESDIRK 3(2)",
        }
    }

    /// Method for a name as returned by `name` (case-insensitive).
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(name.trim()))
    }

    /// True for the methods that use `fixed_step` (Euler, RK4).
    pub fn is_fixed_step(self) -> bool {
        matches!(self, Method::Euler | Method::Rk4)
    }

    /// True for the implicit methods for stiff systems (BDF, ESDIRK).
    pub fn is_implicit(self) -> bool {
        matches!(self, Method::Bdf | Method::Esdirk)
    }

    /// The order of the method's solution (1, 4, 5, 3, 8; BDF's highest, 5; ESDIRK 3).
    pub fn order(self) -> u32 {
        match self {
            Method::Euler => 1,
            Method::Rk4 => 4,
            Method::Dopri5 => 5,
            Method::Bs23 => 3,
            Method::Dop853 => 8,
            Method::Bdf => 5,
            Method::Esdirk => 3,
        }
    }
}

/// Solver settings; `fixed_step` is used by Euler/RK4, `rtol`/`atol`/`max_step` by the adaptive methods.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// Integration method.
    pub method: Method,
    /// Step size in seconds for Euler and RK4 (FMU parameter `fixed_step`).
    pub fixed_step: f64,
    /// Relative tolerance of the adaptive methods (FMU parameter `tolerance`).
    pub rtol: f64,
    /// Absolute tolerance of the adaptive methods (FMU parameter `abs_tol`).
    pub atol: f64,
    /// Largest step of the adaptive methods in seconds; 0 = unlimited (FMU parameter `max_step`).
    pub max_step: f64,
}

impl Default for Settings {
    /// The FMU controls' defaults: DOPRI5, rtol 1e-6 (the models' default experiment), atol
    /// 1e-9, steps unlimited; `fixed_step` 1e-3 for Euler and RK4.
    fn default() -> Self {
        Settings { method: Method::Dopri5, fixed_step: 1e-3, rtol: 1e-6, atol: 1e-9, max_step: 0.0 }
    }
}

/// The most step attempts (accepted and rejected) one `advance` call may take; the next one
/// fails with [`SolverError::TooManySteps`] (CVODE's `mxstep`, whose default is 500 per output
/// interval). Without it an extreme parameter (a pendulum 1e-20 m long: a period of 2e-10 s)
/// or a huge communication step has one `fmi2DoStep` integrate for hours.
///
/// Ours is far larger than CVODE's because one call may legitimately span a whole experiment
/// (an importer that takes one communication step to the stop time; our adaptive steps cross
/// communication points anyway). Measured (December 2026), every lab model's default experiment
/// taken in ONE call, each of the seven methods at its defaults: at most 28,040 attempts
/// (quarter_car with BS23; Euler and RK4 over crank_rocker's 24 s at 1 ms: 23,891), so the
/// bound is 35 times the worst; on the models' own output grids a call takes at most 13. At
/// rtol 1e-12, quarter_car in one call takes 188,394 with BS23 (5 times below). The solvers'
/// stiff tests take at most about 3,550 in a call, the whole solver suite about 10,000. A
/// refused call of the two-state pendulum takes 0.2 s (DOPRI5, BDF) to 0.5 s (ESDIRK) in the
/// release FMU, 0.6 s to 6 s in a debug build.
pub const MAX_STEPS_PER_CALL: u64 = 1_000_000;

/// A step smaller than this many units in the last place of |t| cannot change t reliably:
/// the adaptive methods then fail with [`SolverError::StepSizeTooSmall`], and so does a
/// `fixed_step` below it.
const STEP_FLOOR_ULPS: f64 = 16.0;

/// The smallest step that still moves time `t` (see [`STEP_FLOOR_ULPS`]).
#[inline(always)]
fn step_floor(t: f64) -> f64 {
    STEP_FLOOR_ULPS * f64::EPSILON * t.abs()
}

/// Smallest accepted relative tolerance: below this the error estimate is rounding noise.
pub const MIN_RTOL: f64 = 100.0 * f64::EPSILON;

impl Settings {
    /// Checks the settings, naming the offending control (`fixed_step`, `tolerance`, `abs_tol`).
    pub fn validate(&self) -> Result<(), SolverError> {
        if self.method.is_fixed_step() && !(self.fixed_step.is_finite() && self.fixed_step > 0.0) {
            return Err(SolverError::InvalidSettings(format!(
                "fixed_step must be a finite number greater than 0 for the {} method (got {})",
                self.method.name(),
                self.fixed_step
            )));
        }
        // Tolerances and max_step are checked for every method so that a bad value is
        // reported when it is set, not later when someone switches to an adaptive method.
        if !(self.rtol.is_finite() && self.rtol > 0.0) {
            return Err(SolverError::InvalidSettings(format!(
                "tolerance (relative tolerance) must be a finite number greater than 0 (got {})",
                self.rtol
            )));
        }
        if self.rtol < MIN_RTOL {
            return Err(SolverError::InvalidSettings(format!(
                "tolerance (relative tolerance) {:e} is below {:e}, which double precision cannot deliver; use a larger value",
                self.rtol, MIN_RTOL
            )));
        }
        if !(self.atol.is_finite() && self.atol >= 0.0) {
            return Err(SolverError::InvalidSettings(format!(
                "abs_tol (absolute tolerance) must be a finite number >= 0 (got {})",
                self.atol
            )));
        }
        if !(self.max_step.is_finite() && self.max_step >= 0.0) {
            return Err(SolverError::InvalidSettings(format!(
                "max_step (largest adaptive step) must be a finite number >= 0, 0 meaning unlimited (got {})",
                self.max_step
            )));
        }
        Ok(())
    }

    /// The largest step the adaptive methods may take (infinite when `max_step` is 0).
    pub fn step_limit(&self) -> f64 {
        if self.max_step > 0.0 {
            self.max_step
        } else {
            f64::INFINITY
        }
    }
}

/// Why an integration could not proceed.
#[derive(Debug, Clone, PartialEq)]
pub enum SolverError {
    /// A setting (or an argument of `advance`) is unusable; the message names it.
    InvalidSettings(String),
    /// A state or derivative became NaN or infinite at time `t`.
    NonFinite {
        /// Time at which the non-finite value appeared.
        t: f64,
    },
    /// An adaptive method needed a step `h` at time `t` too small for double precision (below
    /// 16 units in the last place of |t|), or `fixed_step` is that small.
    StepSizeTooSmall {
        /// Time of the failing step.
        t: f64,
        /// The rejected step size.
        h: f64,
    },
    /// One `advance` call took [`MAX_STEPS_PER_CALL`] step attempts without reaching its end.
    TooManySteps {
        /// The method that took them (for the hint).
        method: Method,
        /// Time integration had reached (the state there is handed out).
        t: f64,
        /// Step attempts this call took (accepted and rejected).
        steps: u64,
        /// Of which accepted.
        accepted: u64,
        /// The step size at the end (the adaptive methods' proposal, or `fixed_step`).
        h: f64,
    },
}

impl std::fmt::Display for SolverError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SolverError::InvalidSettings(msg) => write!(f, "invalid solver settings: {msg}"),
            SolverError::NonFinite { t } => write!(
                f,
                "the state or its derivative became NaN or infinite at t = {t} s \
                 (the model may be unstable, or the step too large: with euler or rk4 reduce \
                 fixed_step, with the adaptive methods reduce tolerance/abs_tol or set max_step)"
            ),
            SolverError::StepSizeTooSmall { t, h } => write!(
                f,
                "the step size fell to {h:e} s at t = {t} s, too small to make progress \
                 in double precision (the model may be stiff, or have a discontinuity that no \
                 event indicator signals; try a larger tolerance or a fixed-step method, or with \
                 euler or rk4 a larger fixed_step)"
            ),
            SolverError::TooManySteps { method, t, steps, accepted, h } => {
                // Times this close to the start read better in exponent notation.
                let t = if *t == 0.0 || t.abs() >= 1e-3 { format!("{t}") } else { format!("{t:e}") };
                write!(
                    f,
                    "gave up at t = {t} s after {steps} step attempts in one call ({accepted} accepted; \
                     the limit is {MAX_STEPS_PER_CALL}), with a step size of {h:e} s"
                )?;
                const EXTREME: &str = "a parameter extreme (a length, mass or time constant near zero, \
                                       a stiffness or gain near overflow), or an input's derivative huge";
                match method {
                    _ if method.is_fixed_step() => write!(
                        f,
                        " (fixed_step is far too small for this communication step: a larger fixed_step, \
                         shorter communication steps, or an adaptive method)"
                    ),
                    _ if method.is_implicit() => write!(f, " (the solution changes on that time scale: is {EXTREME}?)"),
                    _ => write!(f, " (is the model stiff (then try the implicit methods, bdf or esdirk), {EXTREME}?)"),
                }
            }
        }
    }
}

impl std::error::Error for SolverError {}

/// Outcome of a successful `Integrator::advance`.
#[derive(Debug, Clone, PartialEq)]
pub enum Advance {
    /// `t_end` was reached exactly.
    Reached,
    /// An event indicator changed sign; `fired[i]` marks each indicator that did.
    Event {
        /// One flag per event indicator.
        fired: Vec<bool>,
    },
}

/// Event location tolerance in seconds: the returned event time is at most this after the crossing.
pub const EVENT_TOL: f64 = 1e-10;

/// Number of stage-derivative buffers: DOP853's k2..k16 (the other methods use fewer).
const STAGE_BUFFERS: usize = 15;
/// Largest number of dense-output coefficient vectors (DOP853's 8).
const DENSE_COEFFICIENTS: usize = 8;

/// Work buffers: contents never carry information across `advance` calls,
/// so they are skipped by serde and rebuilt on first use.
#[derive(Debug, Clone, Default)]
struct Work {
    /// The buffers are sized (false after deserialization, which skips them).
    ready: bool,
    /// State at the end of the step being taken.
    next: Vec<f64>,
    /// Stage / interpolation scratch state.
    xs: Vec<f64>,
    /// Stage derivatives k2, k3, ... (k1 lives in the serialized `Integrator::k1`).
    k: [Vec<f64>; STAGE_BUFFERS],
    /// Indicator values at the step end, and the bracket ends/trial point of the root search.
    zn: Vec<f64>,
    za: Vec<f64>,
    zb: Vec<f64>,
    zm: Vec<f64>,
}

impl Work {
    fn new(dim: usize, n_ind: usize) -> Work {
        let v = || vec![0.0; dim];
        let z = || vec![0.0; n_ind];
        Work { ready: true, next: v(), xs: v(), k: std::array::from_fn(|_| v()), zn: z(), za: z(), zb: z(), zm: z() }
    }
}

/// Integrator state carried between communication steps; Clone/serde give bit-identical continuations.
///
/// Two points matter: where integration has got to (`t_int`, `x_int`: the end of the last
/// accepted step, or an event located inside it), and the point last handed to the caller
/// (`t_out`, `x_out`), at or before it. Between them lies the pending step, whose dense output
/// gives the state at any time in [`dense_t0`, `t_int`].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Integrator {
    settings: Settings,
    dim: usize,
    n_ind: usize,
    /// Step-size proposal of the adaptive methods, carried across `advance` calls (0 = not chosen yet).
    h: f64,
    /// A rejection happened since the last accepted step: the next step may not grow.
    last_rejected: bool,
    n_steps: u64,
    n_rhs: u64,
    n_rejected: u64,
    /// No step ends after this time unless the caller asks for a later one (infinite: no limit).
    stop_time: f64,
    /// False after `invalidate()` or a change of settings: the next `advance` restarts from
    /// the caller's point.
    resume: bool,
    /// The time and state last handed to the caller; a caller that comes back with others has
    /// moved time or changed the state, and integration restarts from there.
    t_out: f64,
    x_out: Vec<f64>,
    /// Where integration has got to.
    t_int: f64,
    x_int: Vec<f64>,
    /// Whether `k1` holds f(t_int, x_int) (first-same-as-last reuse of the adaptive methods).
    fsal_valid: bool,
    k1: Vec<f64>,
    /// Whether `z_left` holds the reference indicator values at `t_int`.
    signs_valid: bool,
    /// Indicator values at `t_int`; their signs are the reference signs (0 = wait until the
    /// indicator becomes nonzero).
    z_left: Vec<f64>,
    /// An event located at `t_int` and not yet handed out: one flag per indicator.
    event: Option<Vec<bool>>,
    /// Start and size of the step whose dense output `dense` holds (the pending step); it is
    /// filled whenever `t_out < t_int`.
    dense_t0: f64,
    dense_h: f64,
    /// The pending step's dense-output coefficient vectors, `dim` values each.
    dense: Vec<f64>,
    /// The settings were checked, by the first `advance` (again after deserialization: a
    /// serialized state may carry any settings), not on every call.
    #[serde(skip)]
    settings_checked: bool,
    /// The implicit methods' Jacobian, BDF history and counters (empty for the others).
    implicit: implicit::Implicit,
    #[serde(skip)]
    work: Work,
}

impl Integrator {
    /// Creates an integrator for a system with `dim` states and `n_event_indicators` indicators.
    pub fn new(settings: Settings, dim: usize, n_event_indicators: usize) -> Integrator {
        Integrator {
            settings,
            dim,
            n_ind: n_event_indicators,
            h: 0.0,
            last_rejected: false,
            n_steps: 0,
            n_rhs: 0,
            n_rejected: 0,
            stop_time: f64::INFINITY,
            resume: false,
            t_out: 0.0,
            x_out: vec![0.0; dim],
            t_int: 0.0,
            x_int: vec![0.0; dim],
            fsal_valid: false,
            k1: vec![0.0; dim],
            signs_valid: false,
            z_left: vec![0.0; n_event_indicators],
            event: None,
            dense_t0: 0.0,
            dense_h: 0.0,
            dense: vec![0.0; DENSE_COEFFICIENTS * dim],
            settings_checked: false,
            implicit: implicit::Implicit::default(),
            work: Work::new(dim, n_event_indicators),
        }
    }

    /// The settings in use.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Replaces the settings. A change restarts integration from the caller's point at the next
    /// `advance`, with the step size chosen afresh (the counters go on); the same settings
    /// change nothing.
    pub fn set_settings(&mut self, settings: Settings) {
        if settings != self.settings {
            self.settings = settings;
            self.settings_checked = false;
            self.h = 0.0;
            self.last_rejected = false;
            self.invalidate();
        }
    }

    /// Steps of the adaptive methods end at `stop_time` at the latest (an `advance` to a later
    /// time still gets there), so the right-hand side is never evaluated past the end of the
    /// experiment; `None` (the default) sets no limit. A change restarts integration from the
    /// caller's point at the next `advance`.
    pub fn set_stop_time(&mut self, stop_time: Option<f64>) {
        let stop = stop_time.unwrap_or(f64::INFINITY);
        if stop.to_bits() != self.stop_time.to_bits() {
            self.stop_time = stop;
            self.invalidate();
        }
    }

    /// Number of continuous states.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of event indicators.
    pub fn n_event_indicators(&self) -> usize {
        self.n_ind
    }

    /// Accepted internal steps since construction (a step later thrown away by a restart counts:
    /// its work was done).
    pub fn n_steps(&self) -> u64 {
        self.n_steps
    }

    /// Right-hand-side evaluations since construction, the implicit methods' finite-difference
    /// Jacobian columns included (indicator evaluations not counted).
    pub fn n_rhs(&self) -> u64 {
        self.n_rhs + self.implicit.difference_rhs()
    }

    /// Jacobian evaluations of the implicit methods since construction.
    pub fn n_jacobians(&self) -> u64 {
        self.implicit.n_jacobians
    }

    /// Jacobian columns (or groups of columns sharing no row) evaluated, each one
    /// right-hand-side evaluation (counted in `n_rhs` too) or one directional derivative.
    pub fn n_jacobian_columns(&self) -> u64 {
        self.implicit.n_jacobian_columns
    }

    /// Directional-derivative evaluations (the system's exact Jacobian products).
    pub fn n_directional(&self) -> u64 {
        self.implicit.n_directional
    }

    /// Step attempts of the implicit methods whose Newton iteration did not converge.
    pub fn n_newton_failures(&self) -> u64 {
        self.implicit.n_newton_failures
    }

    /// Rejected step attempts of the adaptive methods since construction.
    pub fn n_rejected(&self) -> u64 {
        self.n_rejected
    }

    /// Step size proposed for the next internal step (adaptive methods: 0 before the first
    /// step, and not yet bounded by `max_step`; fixed methods: `fixed_step`).
    pub fn step_size(&self) -> f64 {
        if self.settings.method.is_fixed_step() {
            self.settings.fixed_step
        } else {
            self.h
        }
    }

    /// The right-hand side changed discontinuously (new inputs or parameters, a mode switch at an
    /// event): the pending step, the cached derivative and the event indicator signs are dropped,
    /// and the next `advance` restarts from the point it is given. A changed time or state needs
    /// no call: `advance` compares them with the point it handed out.
    pub fn invalidate(&mut self) {
        self.resume = false;
    }

    /// Step attempts since construction, accepted and rejected: each turn of a method's loop
    /// adds one, so one call's count is this minus its value at the call's start.
    #[inline(always)]
    fn attempts(&self) -> u64 {
        self.n_steps + self.n_rejected
    }

    /// The error of a call that started with `accepted_before` accepted steps and took
    /// [`MAX_STEPS_PER_CALL`] attempts, reaching `t`.
    #[cold]
    #[inline(never)]
    fn too_many_steps(&self, t: f64, accepted_before: u64) -> SolverError {
        SolverError::TooManySteps {
            method: self.settings.method,
            t,
            steps: MAX_STEPS_PER_CALL,
            accepted: self.n_steps - accepted_before,
            h: self.step_size(),
        }
    }

    /// Applies `advance`'s restart rule now: when (t, x) is not the point last handed out, the
    /// pending step is dropped and integration will restart from (t, x). `advance` does this
    /// itself, and serialization keeps everything the comparison needs, so callers need not;
    /// it is kept for those that want a copy to hold no pending step it will not use. A state of
    /// the wrong length is left to `advance` to refuse.
    pub fn settle(&mut self, t: f64, x: &[f64]) {
        if x.len() == self.dim && !self.resumes_at(t, x, self.dim) {
            self.restart(t, x, self.dim);
        }
    }

    /// Whether (t, x) is the point last handed out and nothing invalidated the pending step.
    #[inline]
    fn resumes_at(&self, t: f64, x: &[f64], n: usize) -> bool {
        self.resume && t == self.t_out && same_bits(&x[..n], &self.x_out[..n])
    }

    /// Integration starts again from (t, x): no pending step, no cached derivative or signs.
    /// The step-size proposal is kept (the solution's scale has not changed).
    fn restart(&mut self, t: f64, x: &[f64], n: usize) {
        self.t_int = t;
        self.t_out = t;
        self.x_int[..n].copy_from_slice(&x[..n]);
        self.x_out[..n].copy_from_slice(&x[..n]);
        self.dense_t0 = t;
        self.dense_h = 0.0;
        self.fsal_valid = false;
        self.signs_valid = false;
        self.event = None;
        self.resume = true;
    }

    /// Advance from *t towards t_end (> *t). Returns Reached with *t == t_end exactly and x the state there, or Event with *t the located event time and x the state there.
    ///
    /// `t_end == *t` returns `Reached` at once; a `t_end` before `*t` is `InvalidSettings`.
    /// On error, `*t` and `x` are the last time and state that were reached with finite values.
    /// The adaptive methods may evaluate the right-hand side past `t_end` (up to the stop time),
    /// inside the step that covers it.
    // Always inlined: into the FMUs' DoStep (one frame fewer per communication step: 14
    // instructions of the Ex. 4 sweep's 1,520 per point); the bare loop inlined it already.
    #[inline(always)]
    pub fn advance<S: OdeSystem>(&mut self, sys: &S, t: &mut f64, x: &mut [f64], t_end: f64) -> Result<Advance, SolverError> {
        // The usual call when steps are longer than communication intervals: the caller comes
        // back with the point handed out and asks for one inside the pending step, which only
        // interpolates. The tests below are the slow path's, in the order that rules out most
        // (t_end < t_int is false for fixed-step methods, whose t_int is always t_out).
        let n = sys.dim();
        if t_end < self.t_int
            && t_end > *t
            && self.resume
            && *t == self.t_out
            && x.len() == n
            && n == self.dim
            && sys.n_event_indicators() == self.n_ind
            && self.settings_checked
            && self.work.ready
            && same_bits(&x[..n], &self.x_out[..n])
        {
            self.interpolate_at(t_end, n);
            x[..n].copy_from_slice(&self.x_out[..n]);
            *t = t_end;
            return Ok(Advance::Reached);
        }
        self.check_call(sys, *t, x, t_end)?;
        if !self.settings_checked {
            self.settings.validate()?;
            self.settings_checked = true;
        }
        // `check_call` made sure x has `sys.dim()` elements (n), a constant for a given model: the
        // comparison and the copies become a few moves instead of loops and calls to memcpy.
        if !self.work.ready {
            // First use after deserialization: everything else was serialized.
            self.work = Work::new(self.dim, self.n_ind);
        }
        if !self.resumes_at(*t, x, n) {
            self.restart(*t, x, n);
        }
        if t_end == *t {
            return Ok(Advance::Reached);
        }
        if self.settings.method.is_fixed_step() {
            return self.advance_fixed_step(sys, t, x, t_end);
        }
        if self.n_ind > 0 && !self.signs_valid {
            sys.event_indicators(self.t_int, &self.x_int, &mut self.z_left);
            self.signs_valid = true;
        }
        if self.event.is_none() && self.t_int < t_end {
            let stepped = match self.settings.method {
                Method::Dopri5 => self.advance_adaptive::<S, dopri5::Dopri5>(sys, t_end),
                Method::Bs23 => self.advance_adaptive::<S, bs23::Bs23>(sys, t_end),
                Method::Dop853 => self.advance_adaptive::<S, dop853::Dop853>(sys, t_end),
                Method::Bdf => self.advance_bdf(sys, t_end),
                Method::Esdirk => self.advance_esdirk(sys, t_end),
                Method::Euler | Method::Rk4 => unreachable!("fixed-step methods returned above"),
            };
            if let Err(e) = stepped {
                self.hand_out_end(t, x, n);
                return Err(e);
            }
        }
        if self.t_int <= t_end {
            if let Some(fired) = self.event.take() {
                self.hand_out_end(t, x, n);
                return Ok(Advance::Event { fired });
            }
        }
        if self.t_int == t_end {
            self.hand_out_end(t, x, n);
        } else {
            self.interpolate_at(t_end, n);
            x[..n].copy_from_slice(&self.x_out[..n]);
            *t = t_end;
        }
        Ok(Advance::Reached)
    }

    /// Hands out the pending step's dense output at `t_end` (inside it): into `x_out`. Inlined
    /// into `advance`, where `n` is the model's constant (the loops unroll).
    #[inline(always)]
    fn interpolate_at(&mut self, t_end: f64, n: usize) {
        let th = (t_end - self.dense_t0) / self.dense_h;
        match self.settings.method {
            Method::Dopri5 => adaptive::interpolate::<dopri5::Dopri5>(th, n, &self.dense, &mut self.x_out),
            Method::Bs23 => adaptive::interpolate::<bs23::Bs23>(th, n, &self.dense, &mut self.x_out),
            Method::Dop853 => adaptive::interpolate::<dop853::Dop853>(th, n, &self.dense, &mut self.x_out),
            Method::Bdf => bdf::eval(self.implicit.dense_order, th, n, &self.dense, &mut self.x_out),
            Method::Esdirk => adaptive::interpolate::<bs23::Bs23>(th, n, &self.dense, &mut self.x_out),
            // Never pending: they land on every point they are asked for.
            Method::Euler | Method::Rk4 => unreachable!("a fixed-step method has no pending step"),
        }
        self.t_out = t_end;
    }

    /// Hands out the point integration has got to (no pending step is left).
    #[inline]
    fn hand_out_end(&mut self, t: &mut f64, x: &mut [f64], n: usize) {
        self.t_out = self.t_int;
        self.x_out[..n].copy_from_slice(&self.x_int[..n]);
        x[..n].copy_from_slice(&self.x_int[..n]);
        *t = self.t_int;
    }

    /// Euler and RK4: they land on `t_end` (or stop at an event), so nothing is ever pending.
    fn advance_fixed_step<S: OdeSystem>(&mut self, sys: &S, t: &mut f64, x: &mut [f64], t_end: f64) -> Result<Advance, SolverError> {
        let n = sys.dim();
        if self.n_ind > 0 && !self.signs_valid {
            sys.event_indicators(self.t_int, &self.x_int, &mut self.z_left);
            self.signs_valid = true;
        }
        let result = self.advance_fixed(sys, self.t_int, t_end);
        let (t_reached, outcome) = match result {
            Ok((tr, adv)) => (tr, Ok(adv)),
            Err((tr, e)) => (tr, Err(e)),
        };
        self.t_int = t_reached;
        self.hand_out_end(t, x, n);
        outcome
    }

    fn check_call<S: OdeSystem>(&self, sys: &S, t: f64, x: &[f64], t_end: f64) -> Result<(), SolverError> {
        if x.len() != self.dim || sys.dim() != self.dim || sys.n_event_indicators() != self.n_ind {
            return Err(SolverError::InvalidSettings(format!(
                "the integrator was built for {} states and {} event indicators, but the system has {} states \
                 and {} event indicators and the state vector has length {}",
                self.dim,
                self.n_ind,
                sys.dim(),
                sys.n_event_indicators(),
                x.len()
            )));
        }
        if !(t.is_finite() && t_end.is_finite() && t_end >= t) {
            return Err(SolverError::InvalidSettings(format!(
                "cannot advance from t = {t} s to t_end = {t_end} s: both must be finite and t_end must not be before t"
            )));
        }
        Ok(())
    }
}

/// True when `a` and `b` hold the same bits (so -0.0 differs from 0.0, and a NaN equals itself);
/// xor/or over the elements, which vectorizes.
#[inline]
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u64, |acc, (x, y)| acc | (x.to_bits() ^ y.to_bits())) == 0
}

/// True when every element is finite; written as a branch-free fold so it vectorizes.
#[inline]
fn all_finite(v: &[f64]) -> bool {
    v.iter().fold(true, |ok, x| ok & x.is_finite())
}
