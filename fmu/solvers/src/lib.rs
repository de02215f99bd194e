//! ODE integrators for co-simulation: forward Euler, classic RK4 and adaptive
//! Dormand–Prince 5(4), with dense output and event (zero-crossing) location.
//! Used inside the exported FMUs and by the runner to integrate Model Exchange FMUs.
//!
//! The integrator owns every buffer it needs, so `advance` never allocates
//! (except the `fired` vector of an `Advance::Event`, and error messages).
//! Its whole continuation-relevant state is `Clone` + serde, so an FMU can
//! roll back with `fmi2GetFMUstate`/`fmi2SetFMUstate` and replay bit-identically
//! (serde after `settle`, when the caller changed the state since the last advance).

use serde::{Deserialize, Serialize};

pub mod controls;
mod dopri5;
mod events;
mod fixed;
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
}

/// Integration method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Method {
    /// Forward Euler with a fixed step.
    Euler,
    /// Classic 4th-order Runge–Kutta with a fixed step.
    Rk4,
    /// Adaptive Dormand–Prince 5(4) with error control.
    Dopri5,
}

impl Method {
    /// Every method, in the order of their codes.
    pub const ALL: [Method; 3] = [Method::Euler, Method::Rk4, Method::Dopri5];

    /// Method for an integer code as exposed in the model description (0 Euler, 1 Rk4, 2 Dopri5).
    pub fn from_code(code: i32) -> Option<Method> {
        match code {
            0 => Some(Method::Euler),
            1 => Some(Method::Rk4),
            2 => Some(Method::Dopri5),
            _ => None,
        }
    }

    /// Integer code of this method (inverse of `from_code`).
    pub fn code(self) -> i32 {
        match self {
            Method::Euler => 0,
            Method::Rk4 => 1,
            Method::Dopri5 => 2,
        }
    }

    /// Lower-case name: "euler", "rk4" or "dopri5".
    pub fn name(self) -> &'static str {
        match self {
            Method::Euler => "euler",
            Method::Rk4 => "rk4",
            Method::Dopri5 => "dopri5",
        }
    }

    /// The method's full name, for messages: "forward Euler", "classical RK4", ...
    pub fn title(self) -> &'static str {
        match self {
            Method::Euler => "forward Euler",
            Method::Rk4 => "classical RK4",
            Method::Dopri5 => "Dormand-Prince 5(4)",
        }
    }

    /// Method for a name as returned by `name` (case-insensitive).
    pub fn from_name(name: &str) -> Option<Method> {
        Method::ALL.into_iter().find(|m| m.name().eq_ignore_ascii_case(name.trim()))
    }

    /// True for the methods that use `fixed_step` (Euler, RK4).
    pub fn is_fixed_step(self) -> bool {
        !matches!(self, Method::Dopri5)
    }
}

/// Solver settings; `fixed_step` is used by Euler/RK4, `rtol`/`atol` by Dopri5.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// Integration method.
    pub method: Method,
    /// Step size in seconds for Euler and RK4 (FMU parameter `fixed_step`).
    pub fixed_step: f64,
    /// Relative tolerance for Dopri5 (FMU parameter `tolerance`).
    pub rtol: f64,
    /// Absolute tolerance for Dopri5 (FMU parameter `abs_tol`).
    pub atol: f64,
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
        // Tolerances are checked for every method so that a bad value is
        // reported when it is set, not later when someone switches to Dopri5.
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
        Ok(())
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
    /// Dopri5 needed a step `h` at time `t` too small for double precision.
    StepSizeTooSmall {
        /// Time of the failing step.
        t: f64,
        /// The rejected step size.
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
                 fixed_step, with dopri5 reduce tolerance/abs_tol)"
            ),
            SolverError::StepSizeTooSmall { t, h } => write!(
                f,
                "the dopri5 step size fell to {h:e} s at t = {t} s, too small to make progress \
                 in double precision (the model may be stiff, or have a discontinuity that no \
                 event indicator signals; try a larger tolerance or a fixed-step method)"
            ),
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

/// Work buffers: contents never carry information across `advance` calls,
/// so they are skipped by serde and rebuilt on first use.
#[derive(Debug, Clone, Default)]
struct Work {
    /// The buffers are sized (false after deserialization, which skips them).
    ready: bool,
    /// State at the current time.
    cur: Vec<f64>,
    /// State at the end of the step being taken.
    next: Vec<f64>,
    /// Stage / interpolation scratch state.
    xs: Vec<f64>,
    /// Stage derivatives k2..k7 (k1 lives in the serialized `Integrator::k1`).
    k: [Vec<f64>; 6],
    /// Indicator values at the step end, and the bracket ends/trial point of the root search.
    zn: Vec<f64>,
    za: Vec<f64>,
    zb: Vec<f64>,
    zm: Vec<f64>,
    /// (err_old, err_old^BETA): while steps are clipped to communication points err_old does
    /// not change, so the controller's second `powf` per step is usually a lookup.
    err_old_pow: (f64, f64),
}

impl Work {
    fn new(dim: usize, n_ind: usize) -> Work {
        let v = || vec![0.0; dim];
        let z = || vec![0.0; n_ind];
        Work {
            ready: true,
            cur: v(),
            next: v(),
            xs: v(),
            k: [v(), v(), v(), v(), v(), v()],
            zn: z(),
            za: z(),
            zb: z(),
            zm: z(),
            err_old_pow: (f64::NAN, f64::NAN),
        }
    }
}

/// Integrator state carried between communication steps; Clone/serde give bit-identical continuations.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Integrator {
    settings: Settings,
    dim: usize,
    n_ind: usize,
    /// Dopri5 step-size proposal carried across `advance` calls (0 = not chosen yet).
    h: f64,
    /// Previous accepted error norm, the memory of the PI step-size controller.
    err_old: f64,
    /// A rejection happened since the last accepted step: the next step may not grow.
    last_rejected: bool,
    n_steps: u64,
    n_rhs: u64,
    n_rejected: u64,
    /// Time at which the last `advance` left the state (`work.cur`): a caller that moves time
    /// or changes the state without `invalidate()` must not get a stale derivative or stale signs.
    t_cur: f64,
    /// Whether `k1` holds f(t_cur, x) (first-same-as-last reuse for Dopri5).
    fsal_valid: bool,
    k1: Vec<f64>,
    /// Whether `z_left` holds the reference indicator values at `t_cur`.
    signs_valid: bool,
    /// Indicator values at the current time; their signs are the reference
    /// signs (0 = wait until the indicator becomes nonzero).
    z_left: Vec<f64>,
    /// The settings were checked, by the first `advance` (again after deserialization: a
    /// serialized state may carry any settings), not on every call.
    #[serde(skip)]
    settings_checked: bool,
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
            err_old: dopri5::ERR_OLD_INIT,
            last_rejected: false,
            n_steps: 0,
            n_rhs: 0,
            n_rejected: 0,
            t_cur: 0.0,
            fsal_valid: false,
            k1: vec![0.0; dim],
            signs_valid: false,
            z_left: vec![0.0; n_event_indicators],
            settings_checked: false,
            work: Work::new(dim, n_event_indicators),
        }
    }

    /// The settings this integrator was built with.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Number of continuous states.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Number of event indicators.
    pub fn n_event_indicators(&self) -> usize {
        self.n_ind
    }

    /// Accepted internal steps since construction.
    pub fn n_steps(&self) -> u64 {
        self.n_steps
    }

    /// Right-hand-side evaluations since construction (indicator evaluations not counted).
    pub fn n_rhs(&self) -> u64 {
        self.n_rhs
    }

    /// Rejected Dopri5 step attempts since construction.
    pub fn n_rejected(&self) -> u64 {
        self.n_rejected
    }

    /// Dopri5 step size proposed for the next internal step (0 before the first step; fixed methods: `fixed_step`).
    pub fn step_size(&self) -> f64 {
        if self.settings.method.is_fixed_step() {
            self.settings.fixed_step
        } else {
            self.h
        }
    }

    /// The right-hand side changed discontinuously (new inputs, a mode switch at an event): drop any cached derivative (FSAL) and re-read the event indicator signs on the next advance. A changed time or state needs no call: `advance` compares them with where it left off.
    pub fn invalidate(&mut self) {
        self.fsal_valid = false;
        self.signs_valid = false;
    }

    /// Makes the cached derivative and indicator signs agree with (t, x): they are dropped when
    /// time moved or the caller changed the state (a projection onto constraints, an event's
    /// jump) since the last advance left off, compared bit for bit. `advance` does this itself;
    /// a copy about to be serialized must have it done first, because serialization keeps
    /// neither the work buffers nor the state they would be compared with.
    pub fn settle(&mut self, t: f64, x: &[f64]) {
        // The rule `advance` applies: buffers not built yet (deserialized and not advanced
        // since) mean the serialized flags still describe (t, x). A state of the wrong length
        // is left to `advance` to refuse.
        if self.work.ready && x.len() == self.dim {
            self.settle_at(t, x, self.dim);
        }
    }

    /// [`Integrator::settle`] for a state of `n` = `dim` values (a constant in `advance`).
    #[inline]
    fn settle_at(&mut self, t: f64, x: &[f64], n: usize) {
        if (self.fsal_valid || self.signs_valid) && (t != self.t_cur || !same_bits(&x[..n], &self.work.cur[..n])) {
            self.invalidate();
        }
    }

    /// Advance from *t towards t_end (> *t). Returns Reached with *t == t_end exactly and x the state there, or Event with *t the located event time and x the state there.
    ///
    /// `t_end == *t` returns `Reached` at once; a `t_end` before `*t` is `InvalidSettings`.
    /// On error, `*t` and `x` are the last time and state that were reached with finite values.
    pub fn advance<S: OdeSystem>(&mut self, sys: &S, t: &mut f64, x: &mut [f64], t_end: f64) -> Result<Advance, SolverError> {
        self.check_call(sys, *t, x, t_end)?;
        if !self.settings_checked {
            self.settings.validate()?;
            self.settings_checked = true;
        }
        // `check_call` made sure x has `sys.dim()` elements, a constant for a given model: the
        // comparison and the copies become a few moves instead of loops and calls to memcpy.
        let n = sys.dim();
        if !self.work.ready {
            // First use after deserialization: the serialized flags describe (t, x) (see `settle`).
            self.work = Work::new(self.dim, self.n_ind);
        } else {
            self.settle_at(*t, &x[..n], n);
        }
        self.work.cur[..n].copy_from_slice(&x[..n]);
        if t_end == *t {
            return Ok(Advance::Reached);
        }
        if self.n_ind > 0 && !self.signs_valid {
            sys.event_indicators(*t, &self.work.cur, &mut self.z_left);
            self.signs_valid = true;
        }
        let result =
            if self.settings.method.is_fixed_step() { self.advance_fixed(sys, *t, t_end) } else { self.advance_dopri5(sys, *t, t_end) };
        let (t_reached, outcome) = match result {
            Ok((tr, adv)) => (tr, Ok(adv)),
            Err((tr, e)) => (tr, Err(e)),
        };
        x[..n].copy_from_slice(&self.work.cur[..n]);
        *t = t_reached;
        self.t_cur = t_reached;
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
