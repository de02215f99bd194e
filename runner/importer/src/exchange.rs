//! The runner's integration of a Model Exchange FMU, the same for FMI 2.0 and 3.0: the FMU
//! supplies derivatives and event indicators (and, for the implicit methods, directional
//! derivatives when it declares them, and the ModelStructure's dependencies of the
//! derivatives on the states, which group the Jacobian's columns), the runner's integrator (crate `solvers`) steps
//! through each communication interval and locates state events on its dense output by the sign
//! changes of the indicators, and the FMU's event machinery runs at every state event, time
//! event (`nextEventTime`) and step event (`CompletedIntegratorStep`): event mode, the discrete
//! update (`fmi2NewDiscreteStates`, `fmi3UpdateDiscreteStates`) until no further one is needed
//! (at most [`MAX_EVENT_ITERATIONS`] times), continuous-time mode, the states read back.
//! `terminateSimulation` ends the run as an early end.
//!
//! What differs between the versions (the functions' names and arguments, how the instance is
//! made and initialized, the sizes) is the [`Exchange`] trait, which each binding implements
//! over its raw calls.

mod linear;

pub use linear::{JacobianSource, Jacobians, Matrix, Ports};

use std::cell::{Cell, RefCell};
use std::ffi::c_int;

use solvers::{Advance, Integrator, OdeSystem, Settings};

use crate::logging::LogContext;
use crate::trace::{self, Call};
use crate::{Reader, Solver, Step, Value, Variable};

/// Most discrete-update calls one event may take before the run is stopped: an event iteration
/// that does not settle in this many super-dense steps will not settle at all.
pub const MAX_EVENT_ITERATIONS: usize = 1000;

/// Most events one communication step may have (the FMU is then chattering).
const MAX_EVENTS_PER_STEP: usize = 10_000;

/// The relative tolerance when neither the run nor the FMU's DefaultExperiment gives one.
const DEFAULT_TOLERANCE: f64 = 1e-6;

// The status codes, the same numbers in FMI 2.0 and 3.0.
const OK: c_int = 0;
const WARNING: c_int = 1;
const DISCARD: c_int = 2;
pub(crate) const ERROR: c_int = 3;
const FATAL: c_int = 4;

/// What one discrete update (`fmi2NewDiscreteStates`, `fmi3UpdateDiscreteStates`) returned.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EventUpdate {
    /// Another update is needed at the same time (`newDiscreteStatesNeeded`, `discreteStatesNeedUpdate`).
    pub again: bool,
    /// The model asks to end the simulation.
    pub terminate: bool,
    /// The next time event, when one is defined.
    pub next_event_time: Option<f64>,
}

/// A call's trace code and its C name, for the supervisor and the messages.
pub type Named = (Call, &'static str);

/// The continuous states as the ModelStructure declares them, for the implicit methods'
/// Jacobian: value references of the states and of their derivatives, in state order, and the
/// states each derivative depends on.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StateStructure {
    /// The states' value references.
    pub states: Vec<u32>,
    /// The derivatives' value references (the unknowns of a directional derivative).
    pub derivatives: Vec<u32>,
    /// Per derivative, the indices (into `states`) of the states it depends on; `None` when
    /// some derivative declares no dependencies (it may then depend on every state).
    pub pattern: Option<Vec<Vec<usize>>>,
}

/// The work of the runner's integrator in a Model Exchange run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Counters {
    /// Accepted steps.
    pub n_steps: u64,
    /// Derivative evaluations, those for finite-difference Jacobian columns included.
    pub n_rhs: u64,
    /// Jacobian evaluations of the implicit methods.
    pub n_jacobians: u64,
    /// Jacobian columns (or groups of columns sharing no row) evaluated, by differences or by
    /// directional derivatives.
    pub n_jacobian_columns: u64,
    /// Directional-derivative calls (not counted in `n_rhs`).
    pub n_directional: u64,
    /// Step attempts whose Newton iteration did not converge.
    pub n_newton_failures: u64,
}

/// The names of the calls the integration makes, in one FMI version.
pub struct Names {
    pub set_time: Named,
    pub set_continuous_states: Named,
    pub get_derivatives: Named,
    pub get_event_indicators: Named,
    pub get_continuous_states: Named,
    pub enter_event_mode: Named,
    pub update_discrete_states: Named,
    pub enter_continuous_time_mode: Named,
    pub completed_integrator_step: Named,
    pub get_directional_derivative: Named,
    /// The update's flag that asks for another iteration.
    pub again_flag: &'static str,
}

/// One Model Exchange instance as the integration drives it: the calls that differ between FMI
/// 2.0 and 3.0 (names, argument conventions, instantiation and initialization). The raw calls
/// return the FMU's status; the integration decides what a status means.
pub trait Exchange {
    /// The version's names of the calls.
    const NAMES: Names;

    /// The standard's name of a status (`fmi2Error`, `fmi3Error`).
    fn status_name(status: c_int) -> &'static str;
    /// The instance's name, for messages.
    fn name(&self) -> &str;
    /// What the FMU logged.
    fn log(&self) -> &LogContext;
    /// Ok for OK and Warning, else the failure of `call` with the FMU's logged reason.
    fn check(&mut self, call: &str, status: c_int) -> Result<(), String>;
    /// Records what a status other than OK or Warning means for the calls still allowed.
    fn note_status(&mut self, status: c_int);

    /// Sets the time.
    fn set_time(&self, t: f64) -> c_int;
    /// Sets the continuous states (all of them, in ModelStructure order).
    fn set_continuous_states(&self, x: &[f64]) -> c_int;
    /// The state derivatives.
    fn get_derivatives(&self, dx: &mut [f64]) -> c_int;
    /// The event indicators.
    fn get_event_indicators(&self, z: &mut [f64]) -> c_int;
    /// The continuous states.
    fn get_continuous_states(&self, x: &mut [f64]) -> c_int;
    /// Enters event mode.
    fn enter_event_mode(&self) -> c_int;
    /// One discrete update in event mode.
    fn update_discrete_states(&self) -> (c_int, EventUpdate);
    /// Enters continuous-time mode.
    fn enter_continuous_time_mode(&self) -> c_int;
    /// Whether the FMU needs `CompletedIntegratorStep` after every step (FMI 2.0 always; FMI
    /// 3.0 when it declares `needsCompletedIntegratorStep`).
    fn needs_completed_integrator_step(&self) -> bool;
    /// `CompletedIntegratorStep` (with noSetFMUStatePriorToCurrentPoint true): the status,
    /// enterEventMode and terminateSimulation.
    fn completed_integrator_step(&self) -> (c_int, bool, bool);

    /// Sets up the experiment (FMI 3.0 keeps it for initialization).
    fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String>;
    /// Enters initialization mode.
    fn enter_initialization_mode(&mut self) -> Result<(), String>;
    /// Leaves initialization mode, into event mode.
    fn exit_initialization_mode(&mut self) -> Result<(), String>;
    /// Sets one variable.
    fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String>;
    /// Reads a String variable, each element of an array.
    fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String>;
    /// Reads the variables of `reader` into `out`.
    fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String>;
    /// Sets Real scalars, `values[k]` to `vrs[k]`, in one call.
    fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String>;
    /// Reset: back to the state right after instantiation.
    fn reset(&mut self) -> Result<(), String>;
    /// The FMU's state, serialized.
    fn get_state(&mut self) -> Result<Vec<u8>, String>;
    /// Sets the FMU's state from bytes of [`Exchange::get_state`].
    fn set_state(&mut self, bytes: &[u8]) -> Result<(), String>;
    /// The numbers of states and event indicators after initialization, given the
    /// description's (FMI 3.0 asks the FMU: structural parameters may change them).
    fn sizes(&mut self, nx: usize, nz: usize) -> Result<(usize, usize), String> {
        Ok((nx, nz))
    }
    /// Whether the FMU declares directional derivatives and exports the function.
    fn provides_directional_derivative(&self) -> bool;
    /// The directional derivative of `unknowns` with respect to `knowns` along `seed`, into
    /// `out` (only called when [`Exchange::provides_directional_derivative`]).
    fn directional_derivative(&self, unknowns: &[u32], knowns: &[u32], seed: &[f64], out: &mut [f64]) -> c_int;
}

/// What went wrong inside the integrator's calls of the FMU, for the error message.
#[derive(Debug, Clone)]
struct Trouble {
    /// The FMU's status (Discard, Error, ...) or OK for non-finite values.
    status: c_int,
    message: String,
}

/// What the implicit methods' Jacobian reuses from one group of columns to the next, kept by
/// the [`ModelExchange`] and lent to each [`System`] so that no call allocates: the knowns and
/// seed of a group.
#[derive(Debug, Default)]
struct JacobianScratch {
    knowns: Vec<u32>,
    seed: Vec<f64>,
}

/// The FMU seen as the integrator's ODE system: every right-hand side sets the time (when it
/// changed) and the states and asks for the derivatives; every indicator evaluation likewise.
/// The columns of one Jacobian by directional derivatives (`directional_columns`) set them once.
/// A failing call cannot return an error through `OdeSystem`: it records the trouble and
/// returns NaN, on which the integrator stops (an Error or Fatal poisons every later call, so
/// the FMU is not called again).
///
/// `N` is the number of states when it is one of the small sizes the runner is compiled for
/// (0 otherwise, and `nx` holds it): the integrator's stage loops then have a constant length,
/// which the compiler unrolls, as in an FMU's own solver.
struct System<'s, C, const N: usize> {
    calls: &'s C,
    nx: usize,
    nz: usize,
    /// The states and derivatives for the implicit methods' Jacobian (`None`: unknown, then
    /// differences column by column).
    structure: Option<&'s StateStructure>,
    /// Directional derivatives are used for the Jacobian.
    directional: bool,
    /// The time last set.
    time_set: Cell<f64>,
    /// Set with the first Error or Fatal, or a non-finite event indicator: no further call.
    /// Apart from `poisoned` so the hot path tests a flag.
    stopped: Cell<bool>,
    poisoned: RefCell<Option<Trouble>>,
    /// The last Discard or non-finite derivative (the integrator may retry a smaller step).
    last_discard: RefCell<Option<Trouble>>,
    /// The seed buffers of a group of columns.
    scratch: RefCell<&'s mut JacobianScratch>,
}

impl<'s, C: Exchange, const N: usize> System<'s, C, N> {
    /// The FMU's `nx` states and `nz` event indicators as a system, with the ModelStructure's
    /// states when they are as many.
    fn new(calls: &'s C, (nx, nz): (usize, usize), structure: Option<&'s StateStructure>, scratch: &'s mut JacobianScratch) -> Self {
        let structure = structure.filter(|s| s.states.len() == nx);
        System {
            calls,
            nx,
            nz,
            structure,
            directional: structure.is_some() && calls.provides_directional_derivative(),
            time_set: Cell::new(f64::NAN),
            stopped: Cell::new(false),
            poisoned: RefCell::new(None),
            last_discard: RefCell::new(None),
            scratch: RefCell::new(scratch),
        }
    }

    /// Sets time and states for an evaluation at (t, x); false once poisoned or on failure.
    #[inline(always)]
    fn place(&self, t: f64, x: &[f64]) -> bool {
        if self.stopped.get() {
            return false;
        }
        if t != self.time_set.get() {
            trace::enter(C::NAMES.set_time.0, t);
            let status = self.calls.set_time(t);
            if !accepted(status) {
                self.trouble(C::NAMES.set_time.1, t, status, false);
                return false;
            }
            self.time_set.set(t);
        }
        let nx = self.dim();
        if nx > 0 {
            trace::enter(C::NAMES.set_continuous_states.0, t);
            let status = self.calls.set_continuous_states(&x[..nx]);
            if !accepted(status) {
                self.trouble(C::NAMES.set_continuous_states.1, t, status, false);
                return false;
            }
        }
        true
    }

    /// Records a status other than OK and Warning: Discard as a refusal the integrator may
    /// retry with a smaller step, unless `discard_stops`; worse stops the run.
    #[cold]
    #[inline(never)]
    fn trouble(&self, call: &str, t: f64, status: c_int, discard_stops: bool) {
        let reason = self.calls.log().take_reason().unwrap_or_else(|| crate::logging::NO_REASON.to_owned());
        let trouble = Trouble { status, message: format!("{call} at t = {t} returned {}: {reason}", C::status_name(status)) };
        if status == DISCARD && !discard_stops {
            *self.last_discard.borrow_mut() = Some(trouble);
        } else {
            self.stopped.set(true);
            *self.poisoned.borrow_mut() = Some(trouble);
        }
    }

    #[cold]
    #[inline(never)]
    fn non_finite(&self, call: &str, t: f64, what: &str, values: &[f64], poison: bool) {
        let i = values.iter().position(|v| !v.is_finite()).unwrap_or(0);
        let trouble = Trouble { status: OK, message: format!("{call} at t = {t} returned {what}[{i}] = {}", values[i]) };
        if poison {
            self.stopped.set(true);
            *self.poisoned.borrow_mut() = Some(trouble);
        } else {
            *self.last_discard.borrow_mut() = Some(trouble);
        }
    }

    /// One `GetDirectionalDerivative` of every derivative along `seed` on `knowns` into
    /// `column`, at the point the FMU holds; false on a status other than OK and Warning
    /// (recorded; `column` is then not to be used). Non-finite values are recorded too.
    #[inline(always)]
    fn sensitivity(&self, t: f64, structure: &StateStructure, (knowns, seed): (&[u32], &[f64]), column: &mut [f64]) -> bool {
        trace::enter(C::NAMES.get_directional_derivative.0, t);
        let status = self.calls.directional_derivative(&structure.derivatives, knowns, seed, column);
        if !accepted(status) {
            self.trouble(C::NAMES.get_directional_derivative.1, t, status, false);
            return false;
        }
        if !all_finite(column) {
            self.non_finite(C::NAMES.get_directional_derivative.1, t, "sensitivity", column, false);
        }
        true
    }
}

/// OK or Warning.
#[inline(always)]
fn accepted(status: c_int) -> bool {
    status == OK || status == WARNING
}

/// Every value finite, tested without a branch per value (the hot path's check).
#[inline(always)]
fn all_finite(values: &[f64]) -> bool {
    values.iter().fold(true, |ok, v| ok & v.is_finite())
}

impl<C: Exchange, const N: usize> OdeSystem for System<'_, C, N> {
    #[inline(always)]
    fn dim(&self) -> usize {
        if N > 0 {
            N
        } else {
            self.nx
        }
    }

    #[inline(always)]
    fn rhs(&self, t: f64, x: &[f64], dx: &mut [f64]) {
        if !self.place(t, x) {
            dx.fill(f64::NAN);
            return;
        }
        let nx = self.dim();
        trace::enter(C::NAMES.get_derivatives.0, t);
        let status = self.calls.get_derivatives(&mut dx[..nx]);
        if !accepted(status) {
            self.trouble(C::NAMES.get_derivatives.1, t, status, false);
            dx.fill(f64::NAN);
        } else if !all_finite(&dx[..nx]) {
            self.non_finite(C::NAMES.get_derivatives.1, t, "derivatives", dx, false);
        }
    }

    fn n_event_indicators(&self) -> usize {
        self.nz
    }

    fn jacobian_pattern(&self) -> Option<&[Vec<usize>]> {
        self.structure.and_then(|s| s.pattern.as_deref())
    }

    fn provides_directional_derivative(&self) -> bool {
        self.directional
    }

    /// One `GetDirectionalDerivative` of every derivative with respect to the states seeded
    /// in `v` (any seed; the implicit methods call `directional_columns`) at (t, x), which it
    /// sets first; a failure is recorded as for the derivatives.
    fn directional_derivative(&self, t: f64, x: &[f64], v: &[f64], out: &mut [f64]) {
        let nx = self.dim();
        let structure = match self.structure {
            Some(s) if self.directional && x.len() >= nx && v.len() >= nx && out.len() >= nx => s,
            _ => {
                out.fill(f64::NAN);
                return;
            }
        };
        if !self.place(t, &x[..nx]) {
            out.fill(f64::NAN);
            return;
        }
        let mut scratch = self.scratch.borrow_mut();
        let JacobianScratch { knowns, seed } = &mut **scratch;
        knowns.clear();
        seed.clear();
        for (vr, s) in structure.states.iter().zip(&v[..nx]).filter(|(_, s)| **s != 0.0) {
            knowns.push(*vr);
            seed.push(*s);
        }
        if !self.sensitivity(t, structure, (knowns, seed), &mut out[..nx]) {
            out.fill(f64::NAN);
        }
    }

    /// The columns of one Jacobian at one point: the time and states set once (and again
    /// only after a refused call: the FMU that refused is not trusted to hold them), then one
    /// `GetDirectionalDerivative` per group. A single state's column passes that state's
    /// reference and a constant unit seed (no scan of a seed vector), a group its states
    /// through the kept buffers. Failures are recorded as for `directional_derivative`.
    fn directional_columns<G: AsRef<[usize]>>(
        &self,
        t: f64,
        x: &[f64],
        groups: &[G],
        (_, out): (&mut [f64], &mut [f64]),
        mut column: impl FnMut(&[usize], &[f64]),
    ) {
        let nx = self.dim();
        let structure = match self.structure {
            Some(s) if self.directional && x.len() >= nx && out.len() >= nx => s,
            _ => {
                out.fill(f64::NAN);
                groups.iter().for_each(|group| column(group.as_ref(), out));
                return;
            }
        };
        let (x, values) = (&x[..nx], &mut out[..nx]);
        let mut scratch = self.scratch.borrow_mut();
        let scratch = &mut **scratch;
        let mut placed = false;
        for group in groups {
            let group = group.as_ref();
            if !placed {
                placed = self.place(t, x);
            }
            let knowns = match group[..] {
                [j] => structure.states.get(j..=j),
                _ => {
                    scratch.knowns.clear();
                    scratch.knowns.extend(group.iter().filter_map(|&j| structure.states.get(j)));
                    scratch.seed.clear();
                    scratch.seed.resize(group.len(), 1.0);
                    (scratch.knowns.len() == group.len()).then_some(&scratch.knowns[..])
                }
            };
            let seed = if group.len() == 1 { &[1.0][..] } else { &scratch.seed[..] };
            match knowns {
                Some(knowns) if placed => {
                    if !self.sensitivity(t, structure, (knowns, seed), values) {
                        values.fill(f64::NAN);
                        placed = false;
                    }
                }
                _ => values.fill(f64::NAN),
            }
            column(group, values);
        }
    }

    fn event_indicators(&self, t: f64, x: &[f64], z: &mut [f64]) {
        if !self.place(t, x) {
            z.fill(f64::NAN);
            return;
        }
        trace::enter(C::NAMES.get_event_indicators.0, t);
        let status = self.calls.get_event_indicators(&mut z[..self.nz]);
        // A missed sign change would pass silently: indicators that cannot be evaluated stop
        // the run, even with a Discard.
        if !accepted(status) {
            self.trouble(C::NAMES.get_event_indicators.1, t, status, true);
            z.fill(f64::NAN);
        } else if !z.iter().all(|v| v.is_finite()) {
            self.non_finite(C::NAMES.get_event_indicators.1, t, "eventIndicators", z, true);
        }
    }
}

/// One Model Exchange instance with the runner's integrator, over either FMI version's calls.
pub struct ModelExchange<C> {
    component: C,
    nx: usize,
    nz: usize,
    /// The ModelStructure's states, when the description gives them (scalars, as many as the
    /// instance has).
    structure: Option<StateStructure>,
    solver: Solver,
    tolerance: Option<f64>,
    /// The experiment's stop time: no step of the integrator goes past it.
    stop: f64,
    integrator: Option<Integrator>,
    t: f64,
    x: Vec<f64>,
    next_event_time: Option<f64>,
    /// What the runner's implicit methods' Jacobians reuse between calls, lent to each
    /// [`System`].
    jacobian_scratch: JacobianScratch,
    /// tests/bench/jacobian's column groups, one per state, kept as the solver keeps its own.
    #[cfg(feature = "bench-hooks")]
    bench_groups: Vec<[usize; 1]>,
}

/// `f::<C, N>(args)` with `N` the number of states `nx`: the sizes of the lab's models and of
/// most small FMUs get a System (and solver) with loops of constant length, any other size the
/// general one (`N` = 0).
macro_rules! by_state_count {
    ($nx:expr, $f:ident::<$c:ty>($($arg:expr),* $(,)?)) => {
        match $nx {
            1 => $f::<$c, 1>($($arg),*),
            2 => $f::<$c, 2>($($arg),*),
            3 => $f::<$c, 3>($($arg),*),
            4 => $f::<$c, 4>($($arg),*),
            5 => $f::<$c, 5>($($arg),*),
            6 => $f::<$c, 6>($($arg),*),
            _ => $f::<$c, 0>($($arg),*),
        }
    };
}

// After `by_state_count`, which it uses.
#[cfg(feature = "bench-hooks")]
mod bench_hooks;

/// The integrator from `t` towards `target` on the FMU as a [`System`] of `N` states (0: any
/// number); the outcome and what went wrong in the FMU's calls, if anything.
fn integrate<C: Exchange, const N: usize>(
    integrator: &mut Integrator,
    calls: &C,
    (nz, structure, scratch): (usize, Option<&StateStructure>, &mut JacobianScratch),
    t: &mut f64,
    x: &mut [f64],
    target: f64,
) -> (Result<Advance, solvers::SolverError>, Option<Trouble>, Option<Trouble>) {
    let system = System::<C, N>::new(calls, (x.len(), nz), structure, scratch);
    let outcome = integrator.advance(&system, t, x, target);
    (outcome, system.poisoned.into_inner(), system.last_discard.into_inner())
}

/// A time within rounding of `t` (a time event at a communication point, given by the FMU
/// as a sum, may differ from the grid's product in the last bits).
fn near(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-12 * a.abs().max(b.abs()).max(1.0)
}

impl<C: Exchange> ModelExchange<C> {
    /// The integration of `component`, an instance with `nx` states and `nz` event indicators
    /// as its description declares them.
    pub(crate) fn new(component: C, nx: usize, nz: usize, structure: Option<StateStructure>) -> ModelExchange<C> {
        ModelExchange {
            component,
            nx,
            nz,
            structure,
            solver: Solver::default(),
            tolerance: None,
            stop: f64::INFINITY,
            integrator: None,
            t: 0.0,
            x: vec![0.0; nx],
            next_event_time: None,
            jacobian_scratch: JacobianScratch::default(),
            #[cfg(feature = "bench-hooks")]
            bench_groups: Vec::new(),
        }
    }

    /// The integrator for this run (before initialization ends).
    pub fn set_solver(&mut self, solver: Solver) {
        self.solver = solver;
    }

    /// Sets up the experiment; the tolerance is also the integrator's relative tolerance.
    pub fn setup_experiment(&mut self, tolerance: Option<f64>, start: f64, stop: f64) -> Result<(), String> {
        self.tolerance = tolerance;
        self.t = start;
        self.stop = stop;
        self.component.setup_experiment(tolerance, start, stop)
    }

    /// Enters initialization mode.
    pub fn enter_initialization_mode(&mut self) -> Result<(), String> {
        self.component.enter_initialization_mode()
    }

    /// The integrator's settings for this run.
    fn settings(&self) -> Settings {
        Settings {
            method: self.solver.method,
            fixed_step: self.solver.fixed_step,
            rtol: self.tolerance.unwrap_or(DEFAULT_TOLERANCE),
            atol: self.solver.abs_tol,
            max_step: 0.0,
        }
    }

    /// Leaves initialization mode, then the initial event iteration and continuous-time mode:
    /// the initial states are read and the integrator is started.
    pub fn exit_initialization_mode(&mut self) -> Result<(), String> {
        self.component.exit_initialization_mode()?;
        let settings = self.settings();
        settings.validate().map_err(|e| format!("{}: the runner's integrator: {e}", self.component.name()))?;
        let (nx, nz) = self.component.sizes(self.nx, self.nz)?;
        if nx != self.nx {
            self.x = vec![0.0; nx];
        }
        (self.nx, self.nz) = (nx, nz);
        if let Some(reason) = self.event_iteration()? {
            return Err(format!("{}: the model ended the simulation during its initial event iteration: {reason}", self.component.name()));
        }
        let mut integrator = Integrator::new(settings, self.nx, self.nz);
        // The adaptive methods step across communication points, never past the stop time.
        integrator.set_stop_time(Some(self.stop));
        self.integrator = Some(integrator);
        Ok(())
    }

    /// Moves the states to `x` (one per continuous state) without calling the FMU: the next
    /// linearization or step sets them, as an implicit solver moves them between Jacobians.
    pub fn move_states(&mut self, x: &[f64]) -> Result<(), String> {
        if x.len() != self.nx {
            return Err(format!("{}: {} state values for {} continuous states", self.component.name(), x.len(), self.nx));
        }
        self.x.copy_from_slice(x);
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(())
    }

    /// Sets one variable.
    pub fn set(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        self.component.set(variable, value)
    }

    /// Reads a String variable, each element of an array.
    pub fn get_string(&mut self, variable: &Variable) -> Result<Vec<String>, String> {
        self.component.get_string(variable)
    }

    /// Reads the variables of `reader` into `out` (the FMU holds the time and states reached).
    #[inline]
    pub fn read(&mut self, reader: &mut Reader, out: &mut [f64]) -> Result<(), String> {
        self.component.read(reader, out)
    }

    /// Sets Real scalars, `values[k]` to `vrs[k]`, in one call.
    #[inline]
    pub fn set_reals(&mut self, vrs: &[u32], values: &[f64]) -> Result<(), String> {
        self.component.set_reals(vrs, values)
    }

    /// Sets a variable between steps (stepping from outside): a tunable parameter in event mode
    /// (entered, iterated and left again, as the standard wants), an input directly. The
    /// integrator restarts from the current point either way: the step it had taken ahead
    /// assumed the old value.
    pub fn set_between_steps(&mut self, variable: &Variable, value: &Value) -> Result<(), String> {
        if variable.causality == crate::Causality::Parameter {
            trace::enter(C::NAMES.enter_event_mode.0, self.t);
            let status = self.component.enter_event_mode();
            self.component.check(C::NAMES.enter_event_mode.1, status)?;
            self.component.set(variable, value)?;
            if let Some(reason) = self.event_iteration()? {
                return Err(format!(
                    "{}: the model ended the simulation at t = {} after {} was set: {reason}",
                    self.component.name(),
                    self.t,
                    variable.name
                ));
            }
        } else {
            self.component.set(variable, value)?;
        }
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(())
    }

    /// Reset: back to the state right after instantiation; the integrator is made again when
    /// initialization ends.
    pub fn reset(&mut self) -> Result<(), String> {
        self.component.reset()?;
        self.integrator = None;
        self.next_event_time = None;
        Ok(())
    }

    /// The FMU's state, serialized, with the time the integration reached and the next time
    /// event the FMU announced.
    pub fn get_state(&mut self) -> Result<(f64, Option<f64>, Vec<u8>), String> {
        Ok((self.t, self.next_event_time, self.component.get_state()?))
    }

    /// Sets the FMU's state from bytes of [`ModelExchange::get_state`] taken at `t` with the next
    /// time event `next_event_time`; the integration goes on from the states read back.
    pub fn set_state(&mut self, t: f64, next_event_time: Option<f64>, bytes: &[u8]) -> Result<(), String> {
        if self.integrator.is_none() {
            return Err(format!("{}: a state is set after initialization", self.component.name()));
        }
        self.component.set_state(bytes)?;
        self.t = t;
        self.next_event_time = next_event_time;
        if self.nx > 0 {
            let names = &C::NAMES;
            trace::enter(names.get_continuous_states.0, t);
            let status = self.component.get_continuous_states(&mut self.x);
            self.component.check(names.get_continuous_states.1, status)?;
        }
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(())
    }

    /// Accepted steps and right-hand-side evaluations of the runner's integrator so far.
    pub fn counters(&self) -> (u64, u64) {
        self.integrator.as_ref().map_or((0, 0), |i| (i.n_steps(), i.n_rhs()))
    }

    /// The work of the runner's integrator so far, the implicit methods' included.
    pub fn solver_counters(&self) -> Counters {
        self.integrator.as_ref().map_or(Counters::default(), |i| Counters {
            n_steps: i.n_steps(),
            n_rhs: i.n_rhs(),
            n_jacobians: i.n_jacobians(),
            n_jacobian_columns: i.n_jacobian_columns(),
            n_directional: i.n_directional(),
            n_newton_failures: i.n_newton_failures(),
        })
    }

    /// Gives the FMU the time and states the integrator reached.
    fn place(&mut self) -> Result<(), String> {
        trace::enter(C::NAMES.set_time.0, self.t);
        let status = self.component.set_time(self.t);
        self.component.check(C::NAMES.set_time.1, status)?;
        if self.nx > 0 {
            trace::enter(C::NAMES.set_continuous_states.0, self.t);
            let status = self.component.set_continuous_states(&self.x);
            self.component.check(C::NAMES.set_continuous_states.1, status)?;
        }
        Ok(())
    }

    /// From event mode: discrete updates until no further one is needed, then continuous-time
    /// mode and the states read back. `Some(reason)` when the model ended the simulation (the
    /// instance stays in event mode, where terminating is allowed).
    fn event_iteration(&mut self) -> Result<Option<String>, String> {
        let names = &C::NAMES;
        let mut update = EventUpdate::default();
        let mut settled = false;
        for _ in 0..MAX_EVENT_ITERATIONS {
            trace::enter(names.update_discrete_states.0, self.t);
            let (status, got) = self.component.update_discrete_states();
            self.component.check(names.update_discrete_states.1, status)?;
            update = got;
            if update.terminate {
                let reason = self.component.log().take_reason().unwrap_or_else(|| "terminateSimulation, no reason logged".to_owned());
                return Ok(Some(reason));
            }
            if !update.again {
                settled = true;
                break;
            }
        }
        if !settled {
            return Err(format!(
                "{}: the event iteration at t = {} did not converge: {} still asked for another iteration ({}) after {MAX_EVENT_ITERATIONS} calls",
                self.component.name(),
                self.t,
                names.update_discrete_states.1,
                names.again_flag
            ));
        }
        trace::enter(names.enter_continuous_time_mode.0, self.t);
        let status = self.component.enter_continuous_time_mode();
        self.component.check(names.enter_continuous_time_mode.1, status)?;
        // Read back whatever valuesOfContinuousStatesChanged says: one call per event, and an
        // FMU that forgets the flag still continues from its own states.
        if self.nx > 0 {
            trace::enter(names.get_continuous_states.0, self.t);
            let status = self.component.get_continuous_states(&mut self.x);
            self.component.check(names.get_continuous_states.1, status)?;
            if let Some(i) = self.x.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "{}: {} at t = {} returned x[{i}] = {}",
                    self.component.name(),
                    names.get_continuous_states.1,
                    self.t,
                    self.x[i]
                ));
            }
        }
        self.next_event_time = update.next_event_time;
        if let Some(te) = self.next_event_time {
            if !te.is_finite() {
                return Err(format!(
                    "{}: {} at t = {} gave nextEventTime = {te}",
                    self.component.name(),
                    names.update_discrete_states.1,
                    self.t
                ));
            }
        }
        if let Some(integrator) = self.integrator.as_mut() {
            integrator.invalidate();
        }
        Ok(None)
    }

    /// Enters event mode at the current time and iterates the event.
    fn event(&mut self) -> Result<Option<String>, String> {
        trace::enter(C::NAMES.enter_event_mode.0, self.t);
        let status = self.component.enter_event_mode();
        self.component.check(C::NAMES.enter_event_mode.1, status)?;
        self.event_iteration()
    }

    /// The early end of the run at the current time.
    fn ended(&self, reason: String) -> Step {
        Step::Ended { reason: crate::model_ended(&format!("t = {}", self.t), &reason), last_time: Some(self.t) }
    }

    /// Integrates from the communication point `t` over `h` with the runner's integrator,
    /// handling every event on the way.
    pub fn do_step(&mut self, t: f64, h: f64) -> Result<Step, String> {
        let t_end = t + h;
        let mut events = 0usize;
        while self.t < t_end {
            let time_event_due = self.next_event_time.filter(|&te| te < t_end || near(te, t_end));
            let target = match time_event_due {
                Some(te) if !near(te, t_end) => te.max(self.t),
                _ => t_end,
            };
            let outcome = self.advance(target)?;
            let (step_event, terminate) = self.completed_step()?;
            if terminate {
                let reason = self
                    .component
                    .log()
                    .take_reason()
                    .unwrap_or_else(|| format!("terminateSimulation from {}", C::NAMES.completed_integrator_step.1));
                return Ok(self.ended(reason));
            }
            let time_event = time_event_due.is_some_and(|te| self.t >= te || near(self.t, te));
            let state_event = matches!(outcome, Advance::Event { .. });
            if state_event || time_event || step_event {
                events += 1;
                if events > MAX_EVENTS_PER_STEP {
                    return Err(format!(
                        "{}: more than {MAX_EVENTS_PER_STEP} events between t = {t} and t = {t_end}: the model is chattering",
                        self.component.name()
                    ));
                }
                if let Some(reason) = self.event()? {
                    return Ok(self.ended(reason));
                }
            }
        }
        Ok(Step::Done)
    }

    /// The integrator from the current time towards `target`, which it reaches or stops
    /// short of at a state event; the FMU then holds the time and states reached.
    fn advance(&mut self, target: f64) -> Result<Advance, String> {
        let Some(integrator) = self.integrator.as_mut() else {
            return Err(format!("{}: the run was not initialized", self.component.name()));
        };
        let t0 = self.t;
        let (outcome, poisoned, discard) = if target > self.t {
            let (calls, t, x) = (&self.component, &mut self.t, &mut self.x[..]);
            let layout = (self.nz, self.structure.as_ref(), &mut self.jacobian_scratch);
            by_state_count!(self.nx, integrate::<C>(integrator, calls, layout, t, x, target))
        } else {
            (Ok(Advance::Reached), None, None)
        };
        if let Some(trouble) = poisoned {
            if trouble.status == ERROR || trouble.status == FATAL {
                self.component.note_status(trouble.status);
            }
            return Err(format!("{}: {}", self.component.name(), trouble.message));
        }
        let name = self.component.name();
        let outcome = outcome.map_err(|e| {
            let method = self.solver.method.name();
            let cause = discard.map_or(String::new(), |d| format!("; the cause: {}", d.message));
            format!("{name}: the runner's {method} integration from t = {t0} failed: {e}{cause}")
        })?;
        self.place()?;
        Ok(outcome)
    }

    /// `CompletedIntegratorStep`, where the FMU needs it: (enterEventMode, terminateSimulation).
    fn completed_step(&mut self) -> Result<(bool, bool), String> {
        if !self.component.needs_completed_integrator_step() {
            return Ok((false, false));
        }
        trace::enter(C::NAMES.completed_integrator_step.0, self.t);
        let (status, enter, terminate) = self.component.completed_integrator_step();
        self.component.check(C::NAMES.completed_integrator_step.1, status)?;
        Ok((enter, terminate))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A model f(x) = (x0 x1, x0^2), z = x0, with its Jacobian ((x1, x0), (2 x0, 0)) exact: the
    /// FMU answers from the time and states it was last given, and counts the calls that set
    /// them.
    #[derive(Default)]
    struct Quadratic {
        t: Cell<f64>,
        x: Cell<[f64; 2]>,
        times_set: Cell<usize>,
        states_set: Cell<usize>,
        /// The knowns of the last directional derivative.
        knowns: RefCell<Vec<u32>>,
        /// Directional derivatives return Discard.
        refuse: Cell<bool>,
        /// Directional derivatives return OK with a NaN for the second derivative.
        nan: Cell<bool>,
        log: LogContext,
    }

    /// The states' and derivatives' value references.
    const STATES: [u32; 2] = [10, 11];
    const DERIVATIVES: [u32; 2] = [20, 21];

    impl Exchange for Quadratic {
        const NAMES: Names = <crate::fmi2::Exchange2<'static> as Exchange>::NAMES;

        fn status_name(_: c_int) -> &'static str {
            "status"
        }
        fn name(&self) -> &str {
            "quadratic"
        }
        fn log(&self) -> &LogContext {
            &self.log
        }
        fn check(&mut self, _: &str, _: c_int) -> Result<(), String> {
            unreachable!("the System reports its trouble itself")
        }
        fn note_status(&mut self, _: c_int) {}
        fn set_time(&self, t: f64) -> c_int {
            self.t.set(t);
            self.times_set.set(self.times_set.get() + 1);
            OK
        }
        fn set_continuous_states(&self, x: &[f64]) -> c_int {
            self.x.set([x[0], x[1]]);
            self.states_set.set(self.states_set.get() + 1);
            OK
        }
        fn get_derivatives(&self, dx: &mut [f64]) -> c_int {
            let [x0, x1] = self.x.get();
            dx.copy_from_slice(&[x0 * x1, x0 * x0]);
            OK
        }
        fn get_event_indicators(&self, z: &mut [f64]) -> c_int {
            z[0] = self.x.get()[0];
            OK
        }
        fn get_continuous_states(&self, x: &mut [f64]) -> c_int {
            x.copy_from_slice(&self.x.get());
            OK
        }
        fn enter_event_mode(&self) -> c_int {
            unreachable!("the System never enters event mode")
        }
        fn update_discrete_states(&self) -> (c_int, EventUpdate) {
            unreachable!("the System never updates discrete states")
        }
        fn enter_continuous_time_mode(&self) -> c_int {
            unreachable!("the System never changes mode")
        }
        fn needs_completed_integrator_step(&self) -> bool {
            false
        }
        fn completed_integrator_step(&self) -> (c_int, bool, bool) {
            unreachable!("the System never completes a step")
        }
        fn setup_experiment(&mut self, _: Option<f64>, _: f64, _: f64) -> Result<(), String> {
            unreachable!("the System is made after initialization")
        }
        fn enter_initialization_mode(&mut self) -> Result<(), String> {
            unreachable!("the System is made after initialization")
        }
        fn exit_initialization_mode(&mut self) -> Result<(), String> {
            unreachable!("the System is made after initialization")
        }
        fn set(&mut self, _: &Variable, _: &Value) -> Result<(), String> {
            unreachable!("the System sets no variable")
        }
        fn get_string(&mut self, _: &Variable) -> Result<Vec<String>, String> {
            unreachable!("the System reads no string")
        }
        fn read(&mut self, _: &mut Reader, _: &mut [f64]) -> Result<(), String> {
            unreachable!("the System reads no output")
        }
        fn set_reals(&mut self, _: &[u32], _: &[f64]) -> Result<(), String> {
            unreachable!("the System sets no variable")
        }
        fn reset(&mut self) -> Result<(), String> {
            unreachable!("the System never resets")
        }
        fn get_state(&mut self) -> Result<Vec<u8>, String> {
            unreachable!("the System keeps no state")
        }
        fn set_state(&mut self, _: &[u8]) -> Result<(), String> {
            unreachable!("the System keeps no state")
        }
        fn provides_directional_derivative(&self) -> bool {
            true
        }
        fn directional_derivative(&self, unknowns: &[u32], knowns: &[u32], seed: &[f64], out: &mut [f64]) -> c_int {
            assert_eq!(unknowns, DERIVATIVES);
            *self.knowns.borrow_mut() = knowns.to_vec();
            if self.refuse.get() {
                return DISCARD;
            }
            let [x0, x1] = self.x.get();
            let jacobian = [[x1, x0], [2.0 * x0, 0.0]];
            for (row, o) in jacobian.iter().zip(out.iter_mut()) {
                *o = knowns.iter().zip(seed).map(|(vr, s)| row[STATES.iter().position(|k| k == vr).unwrap()] * s).sum();
            }
            if self.nan.get() {
                out[1] = f64::NAN;
            }
            OK
        }
    }

    /// A directional derivative on its own (any seed) sets the time and states and is taken
    /// there, whatever was called before, compared exactly with the analytic Jacobian (the
    /// products are exact in binary); its knowns are the seeded states, in order.
    #[test]
    fn a_directional_derivative_is_taken_where_it_is_asked_for() {
        let fmu = Quadratic::default();
        let structure = StateStructure { states: STATES.to_vec(), derivatives: DERIVATIVES.to_vec(), pattern: None };
        let mut scratch = JacobianScratch::default();
        let sys = System::<Quadratic, 2>::new(&fmu, (2, 1), Some(&structure), &mut scratch);
        assert!(sys.provides_directional_derivative());
        let (a, b) = ([2.0, 3.0], [5.0, 7.0]);
        let (mut column, mut f) = ([0.0; 2], [0.0; 2]);
        let mut jacobian_column = |t: f64, x: &[f64; 2], seed: [f64; 2], states_set: usize, expected: [f64; 2]| {
            sys.directional_derivative(t, x, &seed, &mut column);
            assert_eq!(column, expected, "at t = {t}, x = {x:?}, seed {seed:?}");
            assert_eq!((fmu.t.get(), fmu.x.get(), fmu.states_set.get()), (t, *x, states_set), "at t = {t}, x = {x:?}, seed {seed:?}");
        };
        jacobian_column(0.0, &a, [1.0, 0.0], 1, [3.0, 4.0]);
        assert_eq!(*fmu.knowns.borrow(), [10]);
        jacobian_column(0.0, &b, [0.0, 1.0], 2, [5.0, 0.0]);
        assert_eq!(*fmu.knowns.borrow(), [11]);
        // The derivatives at a in between: b again, not the FMU's a.
        sys.rhs(0.0, &a, &mut f);
        assert_eq!((f, fmu.states_set.get()), ([6.0, 4.0], 3));
        // Another time; two states seeded, one seeded by 2.
        jacobian_column(1.0, &b, [1.0, 1.0], 4, [12.0, 10.0]);
        assert_eq!((fmu.knowns.borrow().clone(), fmu.times_set.get()), (vec![10, 11], 2));
        jacobian_column(1.0, &b, [0.0, 2.0], 5, [10.0, 0.0]);
        assert_eq!(*fmu.knowns.borrow(), [11]);
    }

    /// A refused directional derivative is recorded as before (the Discard the integrator may
    /// retry, NaN out), and the next sets the states again.
    #[test]
    fn a_refused_column_is_recorded_and_the_next_sets_the_states_again() {
        let fmu = Quadratic::default();
        let structure = StateStructure { states: STATES.to_vec(), derivatives: DERIVATIVES.to_vec(), pattern: None };
        let mut scratch = JacobianScratch::default();
        let sys = System::<Quadratic, 2>::new(&fmu, (2, 1), Some(&structure), &mut scratch);
        let mut column = [0.0; 2];
        sys.directional_derivative(0.0, &[2.0, 3.0], &[1.0, 0.0], &mut column);
        fmu.refuse.set(true);
        sys.directional_derivative(0.0, &[2.0, 3.0], &[0.0, 1.0], &mut column);
        assert!(column.iter().all(|v| v.is_nan()), "{column:?}");
        let discard = sys.last_discard.borrow().clone().expect("the Discard is recorded");
        assert_eq!(discard.status, DISCARD);
        assert!(discard.message.starts_with("fmi2GetDirectionalDerivative at t = 0 returned status"), "{}", discard.message);
        assert!(sys.poisoned.borrow().is_none());
        fmu.refuse.set(false);
        sys.directional_derivative(0.0, &[2.0, 3.0], &[0.0, 1.0], &mut column);
        assert_eq!((column, fmu.states_set.get()), ([2.0, 0.0], 3));
    }

    /// A directional derivative that is not finite is recorded naming the value (the
    /// integrator may retry a smaller step, as for derivatives), and does not stop the run.
    #[test]
    fn a_non_finite_sensitivity_is_named() {
        let fmu = Quadratic::default();
        let structure = StateStructure { states: STATES.to_vec(), derivatives: DERIVATIVES.to_vec(), pattern: None };
        let mut scratch = JacobianScratch::default();
        let sys = System::<Quadratic, 2>::new(&fmu, (2, 1), Some(&structure), &mut scratch);
        let mut column = [0.0; 2];
        fmu.nan.set(true);
        sys.directional_derivative(0.5, &[2.0, 3.0], &[0.0, 1.0], &mut column);
        assert!(column[0] == 2.0 && column[1].is_nan(), "{column:?}");
        let discard = sys.last_discard.borrow().clone().expect("the value is recorded");
        assert_eq!(discard.message, "fmi2GetDirectionalDerivative at t = 0.5 returned sensitivity[1] = NaN");
        assert!(sys.poisoned.borrow().is_none());
    }

    /// The implicit solver's Jacobian (`directional_columns`): the time and states set once
    /// for all its columns, a single state's column with that state alone as the known, a
    /// group with its states in order, each column compared exactly with the analytic
    /// Jacobian (the products are exact in binary).
    #[test]
    fn the_columns_of_a_jacobian_set_the_point_once() {
        let fmu = Quadratic::default();
        let structure = StateStructure { states: STATES.to_vec(), derivatives: DERIVATIVES.to_vec(), pattern: None };
        let mut scratch = JacobianScratch::default();
        let sys = System::<Quadratic, 2>::new(&fmu, (2, 1), Some(&structure), &mut scratch);
        let (mut seed, mut out) = ([0.0; 2], [0.0; 2]);
        let mut columns = Vec::new();
        let groups = [vec![0], vec![1], vec![0, 1]];
        sys.directional_columns(0.5, &[2.0, 3.0], &groups, (&mut seed, &mut out), |group, column| {
            columns.push((group.to_vec(), fmu.knowns.borrow().clone(), column.to_vec()));
        });
        assert_eq!(
            columns,
            [(vec![0], vec![10], vec![3.0, 4.0]), (vec![1], vec![11], vec![2.0, 0.0]), (vec![0, 1], vec![10, 11], vec![5.0, 4.0])]
        );
        assert_eq!((fmu.t.get(), fmu.x.get(), fmu.times_set.get(), fmu.states_set.get()), (0.5, [2.0, 3.0], 1, 1));
        assert!(sys.last_discard.borrow().is_none() && sys.poisoned.borrow().is_none());
    }

    /// A refused column of the solver's Jacobian is NaN and recorded as a Discard (the
    /// integrator may retry), and the next column sets the states again rather than trust the
    /// FMU that refused; a non-finite value is named and keeps the point.
    #[test]
    fn a_refused_column_of_a_jacobian_is_nan_and_the_next_places_again() {
        let fmu = Quadratic::default();
        let structure = StateStructure { states: STATES.to_vec(), derivatives: DERIVATIVES.to_vec(), pattern: None };
        let mut scratch = JacobianScratch::default();
        let sys = System::<Quadratic, 2>::new(&fmu, (2, 1), Some(&structure), &mut scratch);
        let (mut seed, mut out) = ([0.0; 2], [0.0; 2]);
        let mut columns = Vec::new();
        fmu.refuse.set(true);
        sys.directional_columns(0.0, &[2.0, 3.0], &[vec![0], vec![1]], (&mut seed, &mut out), |_, column| {
            columns.push((column.to_vec(), fmu.states_set.get()));
            fmu.refuse.set(false);
        });
        assert!(columns[0].0.iter().all(|v| v.is_nan()) && columns[0].1 == 1, "{columns:?}");
        assert_eq!(columns[1], (vec![2.0, 0.0], 2));
        let discard = sys.last_discard.borrow_mut().take().expect("the Discard is recorded");
        assert_eq!(discard.status, DISCARD);
        assert!(discard.message.starts_with("fmi2GetDirectionalDerivative at t = 0 returned status"), "{}", discard.message);
        assert!(sys.poisoned.borrow().is_none());

        fmu.nan.set(true);
        columns.clear();
        sys.directional_columns(1.0, &[2.0, 3.0], &[vec![0], vec![1]], (&mut seed, &mut out), |_, column| {
            columns.push((column.to_vec(), fmu.states_set.get()));
        });
        assert!(columns[0].0[0] == 3.0 && columns[0].0[1].is_nan() && columns[1].0[0] == 2.0 && columns[1].1 == 3, "{columns:?}");
        let discard = sys.last_discard.borrow().clone().expect("the value is recorded");
        assert_eq!(discard.message, "fmi2GetDirectionalDerivative at t = 1 returned sensitivity[1] = NaN");
        assert!(sys.poisoned.borrow().is_none());
    }
}
