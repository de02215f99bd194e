//! The validator's Model Exchange integration, the same for both versions: classical RK4 on
//! the communication grid, each step cut at the next time event; a state event (an event
//! indicator changing domain over a step) located by bisection on the step's fraction until
//! the bracket is a few ulps of t wide, so that the FMU sees the event where it happens; time
//! events and step events handled; the event iteration bounded.
//!
//! Why not the importer's driver (`fmi_importer::exchange`): the validator calls the FMU
//! through its own instances, which record every call for the crash reports and take any
//! status the FMU returns; its failures name the check, call, state and value they concern;
//! the FMU-state probes save and restore the integration's own state with the FMU's; and a
//! fixed grid makes the runs it compares reproducible by construction.

use crate::failure::Failure;
use crate::fmi::{numbers, Op, State, Version};
use crate::instance::{EventUpdate, Instance};
use crate::model::Grid;

/// The most discrete updates one event may take before the iteration counts as not
/// converging: event iterations of real models take a handful.
pub(crate) const MAX_EVENT_ITERATIONS: usize = 100;
/// The most events at one time instant before the run counts as stuck in an event loop.
const MAX_EVENTS_AT_ONE_TIME: usize = 20;
/// The most events one run handles.
const MAX_EVENTS: usize = 100_000;
/// The most states or event indicators the validator takes an FMU's word for.
const MAX_SIZE: usize = 1 << 20;

/// What the integration keeps between steps.
#[derive(Debug, Clone, Default)]
pub(crate) struct Exchange {
    nx: usize,
    nz: usize,
    x: Vec<f64>,
    z: Vec<f64>,
    next_time_event: Option<f64>,
    /// Events handled: (time, which indicator for a state event).
    events: Vec<(f64, Option<usize>)>,
    /// The most discrete updates any event took.
    most_iterations: usize,
    /// Derivatives at the start (after the initial event iteration).
    start_derivatives: Vec<f64>,
    needs_completed_integrator_step: bool,
}

/// Where a saved integration stands (see [`Exchange::saved`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct SavedExchange {
    next_time_event: Option<f64>,
    events: usize,
}

/// Reads `n` values of a Model Exchange vector (nothing to call for none), which must be
/// finite.
pub(crate) fn read_vector(inst: &mut dyn Instance, op: Op, n: usize) -> Result<Vec<f64>, Failure> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let state = inst.core().state;
    let got = inst.get_vector(op, n);
    let name = inst.core().name(op);
    let values = inst.core().expect(got, op, state)?;
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        let what = match op {
            Op::GetDerivatives => "derivative",
            Op::GetEventIndicators => "event indicator",
            Op::GetContinuousStates => "state",
            _ => "value",
        };
        return Err(Failure::new(format!("{name} returned {what} {} = {} at this point, which is not finite", i + 1, values[i]))
            .at(name, state)
            .value(numbers(&values))
            .check("health.finite"));
    }
    Ok(values)
}

/// Discrete updates until no further one is needed: the last update and how many it took.
pub(crate) fn event_iteration(inst: &mut dyn Instance, t: f64) -> Result<(EventUpdate, usize), Failure> {
    let name = inst.core().name(Op::UpdateDiscreteStates);
    for calls in 1..=MAX_EVENT_ITERATIONS {
        let got = inst.update_discrete_states();
        let update = inst.core().expect(got, Op::UpdateDiscreteStates, State::EventMode)?;
        if update.terminate {
            return Ok((update, calls));
        }
        if !update.again {
            if let Some(te) = update.next_event_time.filter(|te| !(te.is_finite() && *te >= t)) {
                return Err(Failure::new(format!("{name} at t = {t} gave nextEventTime = {te}, which is not a time at or after now"))
                    .at(name, State::EventMode)
                    .with_log(inst.core().take_log()));
            }
            return Ok((update, calls));
        }
    }
    let flag = inst.core().fmi().again_flag();
    Err(Failure::new(format!(
        "the event iteration at t = {t} did not converge: {name} still set {flag} after {MAX_EVENT_ITERATIONS} calls"
    ))
    .at(name, State::EventMode)
    .value(format!("t = {t}"))
    .check("model-exchange.event-iteration"))
}

/// A call on the instance alone that must succeed in `state`, after which the instance is in
/// `next`.
pub(crate) fn enter(inst: &mut dyn Instance, op: Op, state: State, next: State) -> Result<(), Failure> {
    let got = inst.simple(op);
    inst.core().expect(got, op, state)?;
    inst.core_mut().state = next;
    Ok(())
}

/// The numbers of states and event indicators the FMU reports, where its version asks (FMI
/// 3.0: structural parameters may change them), checked against the description's.
fn sizes(inst: &mut dyn Instance) -> Result<(usize, usize), Failure> {
    let model = inst.core().model();
    if !inst.core().binary.table().has(Op::GetNumberOfContinuousStates) {
        return Ok((model.nx(), model.nz()));
    }
    let state = inst.core().state;
    let mut sizes = [0, 0];
    for (i, (op, declared, what)) in [
        (Op::GetNumberOfContinuousStates, model.nx, "ContinuousStateDerivative"),
        (Op::GetNumberOfEventIndicators, model.nz, "EventIndicator"),
    ]
    .into_iter()
    .enumerate()
    {
        let got = inst.number_of(op, false);
        let name = inst.core().name(op);
        let n = inst.core().expect(got, op, state)?;
        if declared.is_some_and(|d| d != n) || n > MAX_SIZE {
            let problem = match declared.filter(|d| *d != n) {
                Some(d) => {
                    format!("{name} reports {n}, but ModelStructure lists {d} {what} elements (no structural parameter was changed)")
                }
                None => format!("{name} reports {n}: beyond any sane model"),
            };
            return Err(Failure::new(problem).at(name, state).with_log(inst.core().take_log()));
        }
        sizes[i] = n;
    }
    Ok((sizes[0], sizes[1]))
}

impl Exchange {
    /// After initialization (the instance in Event Mode): the sizes, the event iteration,
    /// Continuous-Time Mode, and the states, indicators and derivatives at the start. Sets
    /// `ended` when the model ends the run.
    pub(crate) fn begin(inst: &mut dyn Instance, grid: &Grid, ended: &mut Option<String>) -> Result<Exchange, Failure> {
        let model = inst.core().model();
        let (nx, nz) = sizes(inst)?;
        let needs_completed_integrator_step = model.model_exchange.as_ref().is_some_and(|m| m.needs_completed_integrator_step);
        let mut me = Exchange { nx, nz, needs_completed_integrator_step, ..Exchange::default() };
        let (update, calls) = event_iteration(inst, grid.start)?;
        me.most_iterations = calls;
        if update.terminate {
            *ended = Some("the model asked to terminate during initialization".to_owned());
        }
        enter(inst, Op::EnterContinuousTimeMode, State::EventMode, State::ContinuousTimeMode)?;
        me.next_time_event = update.next_event_time;
        me.x = read_vector(inst, Op::GetContinuousStates, nx)?;
        me.z = read_vector(inst, Op::GetEventIndicators, nz)?;
        me.start_derivatives = read_vector(inst, Op::GetDerivatives, nx).map_err(|f| f.check("model-exchange.derivatives"))?;
        Ok(me)
    }

    /// Events handled: (time, indicator of a state event).
    pub(crate) fn events(&self) -> &[(f64, Option<usize>)] {
        &self.events
    }

    /// The most discrete updates an event took.
    pub(crate) fn most_iterations(&self) -> usize {
        self.most_iterations
    }

    /// The derivatives at the start.
    pub(crate) fn start_derivatives(&self) -> &[f64] {
        &self.start_derivatives
    }

    /// What [`Exchange::restore`] needs besides the FMU's own state.
    pub(crate) fn saved(&self) -> SavedExchange {
        SavedExchange { next_time_event: self.next_time_event, events: self.events.len() }
    }

    /// Takes the integration back to `saved`, the FMU having been set back to the state saved
    /// with it: the states and indicators are read from it.
    pub(crate) fn restore(&mut self, inst: &mut dyn Instance, saved: SavedExchange) -> Result<(), Failure> {
        self.next_time_event = saved.next_time_event;
        self.events.truncate(saved.events);
        self.x = read_vector(inst, Op::GetContinuousStates, self.nx)?;
        self.z = read_vector(inst, Op::GetEventIndicators, self.nz)?;
        Ok(())
    }

    /// Integrates from `t` to `target`, handling every event on the way; sets `ended` when
    /// the model ends the run.
    pub(crate) fn advance(&mut self, inst: &mut dyn Instance, mut t: f64, target: f64, ended: &mut Option<String>) -> Result<(), Failure> {
        let nz = self.nz;
        while t < target && ended.is_none() {
            let time_event = self.next_time_event.filter(|&te| te <= target);
            if let Some(te) = time_event.filter(|&te| te <= t) {
                self.handle_event(inst, te, None, ended)?;
                continue;
            }
            let t_end = time_event.unwrap_or(target);
            let h = t_end - t;
            let x_end = rk4(inst, t, &self.x, h)?;
            set_point(inst, t_end, &x_end)?;
            let z_end = read_vector(inst, Op::GetEventIndicators, nz)?;
            if crossing(&self.z, &z_end).is_some() {
                // Bisect on the step's fraction until the bracket is a few ulps of t wide.
                let (mut lo, mut hi) = (0.0f64, 1.0f64);
                let (mut x_hi, mut z_hi) = (x_end, z_end);
                for _ in 0..64 {
                    if (hi - lo) * h <= 4.0 * f64::EPSILON * t.abs().max(1.0) {
                        break;
                    }
                    let mid = 0.5 * (lo + hi);
                    let x_mid = rk4(inst, t, &self.x, mid * h)?;
                    set_point(inst, t + mid * h, &x_mid)?;
                    let z_mid = read_vector(inst, Op::GetEventIndicators, nz)?;
                    if crossing(&self.z, &z_mid).is_some() {
                        (hi, x_hi, z_hi) = (mid, x_mid, z_mid);
                    } else {
                        lo = mid;
                    }
                }
                let t_event = if hi == 1.0 { t_end } else { t + hi * h };
                set_point(inst, t_event, &x_hi)?;
                let which = crossing(&self.z, &z_hi);
                let (_, terminate) = self.completed_integrator_step(inst)?;
                (t, self.x, self.z) = (t_event, x_hi, z_hi);
                if terminate {
                    *ended = Some(format!("{} asked to terminate at t = {t}", inst.core().name(Op::CompletedIntegratorStep)));
                    break;
                }
                self.handle_event(inst, t, which, ended)?;
                continue;
            }
            let (enter, terminate) = self.completed_integrator_step(inst)?;
            (t, self.x, self.z) = (t_end, x_end, z_end);
            if terminate {
                *ended = Some(format!("{} asked to terminate at t = {t}", inst.core().name(Op::CompletedIntegratorStep)));
                break;
            }
            if enter || time_event == Some(t_end) {
                self.handle_event(inst, t, None, ended)?;
            }
        }
        Ok(())
    }

    /// CompletedIntegratorStep where the FMU needs it: (enterEventMode, terminateSimulation).
    fn completed_integrator_step(&self, inst: &mut dyn Instance) -> Result<(bool, bool), Failure> {
        if !self.needs_completed_integrator_step {
            return Ok((false, false));
        }
        let got = inst.completed_integrator_step();
        inst.core().expect(got, Op::CompletedIntegratorStep, State::ContinuousTimeMode)
    }

    /// Event Mode at `t`: enter, iterate, leave, and read back what the event changed.
    fn handle_event(
        &mut self,
        inst: &mut dyn Instance,
        t: f64,
        indicator: Option<usize>,
        ended: &mut Option<String>,
    ) -> Result<(), Failure> {
        let same_time = self.events.iter().rev().take_while(|(te, _)| (te - t).abs() <= 4.0 * f64::EPSILON * t.abs().max(1.0)).count();
        if same_time >= MAX_EVENTS_AT_ONE_TIME || self.events.len() >= MAX_EVENTS {
            let what = match indicator {
                Some(i) => format!("event indicator {} changes domain again", i + 1),
                None => "a time or step event is due again".to_owned(),
            };
            return Err(Failure::new(format!(
                "the events are not handled: {what} at t = {t} right after {same_time} events at the same time, so the integration cannot advance"
            ))
            .at(inst.core().name(Op::EnterEventMode), State::ContinuousTimeMode)
            .value(format!("t = {t}"))
            .check("model-exchange.state-events"));
        }
        enter(inst, Op::EnterEventMode, State::ContinuousTimeMode, State::EventMode)
            .map_err(|f| Failure { message: format!("{} at t = {t}", f.message), ..f }.check("model-exchange.state-events"))?;
        let (update, calls) = event_iteration(inst, t)?;
        self.most_iterations = self.most_iterations.max(calls);
        self.events.push((t, indicator));
        if update.terminate {
            *ended = Some(format!("the model asked to terminate at the event at t = {t}"));
            return Ok(());
        }
        enter(inst, Op::EnterContinuousTimeMode, State::EventMode, State::ContinuousTimeMode)?;
        if update.values_changed {
            self.x = read_vector(inst, Op::GetContinuousStates, self.nx)?;
        }
        self.z = read_vector(inst, Op::GetEventIndicators, self.nz)?;
        self.next_time_event = update.next_event_time;
        Ok(())
    }
}

/// The derivatives at (t, x): SetTime, SetContinuousStates, GetDerivatives.
fn derivatives(inst: &mut dyn Instance, t: f64, x: &[f64]) -> Result<Vec<f64>, Failure> {
    set_point(inst, t, x)?;
    read_vector(inst, Op::GetDerivatives, x.len())
}

/// Gives the FMU the time and the states.
fn set_point(inst: &mut dyn Instance, t: f64, x: &[f64]) -> Result<(), Failure> {
    let time = inst.set_time(t);
    inst.core().expect(time, Op::SetTime, State::ContinuousTimeMode)?;
    if !x.is_empty() {
        let states = inst.set_continuous_states(x);
        inst.core().expect(states, Op::SetContinuousStates, State::ContinuousTimeMode)?;
    }
    Ok(())
}

/// One classical Runge-Kutta step from (t, x) over h.
fn rk4(inst: &mut dyn Instance, t: f64, x: &[f64], h: f64) -> Result<Vec<f64>, Failure> {
    if x.is_empty() {
        return Ok(Vec::new());
    }
    let along = |x: &[f64], k: &[f64], f: f64| x.iter().zip(k).map(|(a, b)| a + f * b).collect::<Vec<f64>>();
    let k1 = derivatives(inst, t, x)?;
    let k2 = derivatives(inst, t + h / 2.0, &along(x, &k1, h / 2.0))?;
    let k3 = derivatives(inst, t + h / 2.0, &along(x, &k2, h / 2.0))?;
    let k4 = derivatives(inst, t + h, &along(x, &k3, h))?;
    Ok((0..x.len()).map(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])).collect())
}

/// The index of the first indicator that changed domain (z > 0 against z <= 0, as FMI 2.0
/// defines a state event; FMI 3.0's sign change is the same test).
fn crossing(before: &[f64], after: &[f64]) -> Option<usize> {
    before.iter().zip(after).position(|(a, b)| (*a > 0.0) != (*b > 0.0))
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::fmi::{Fmi, Interface};
    use crate::probe::NAME;
    use crate::run::Run;
    use crate::testing::{Fake, Fault, Probed};

    /// x' = -x from x(0) = 1 reaches the indicator's 0.5 at t = ln 2; classical RK4 with
    /// h = 0.01 is within 1e-10 of the exact solution there, and the bisection puts the event
    /// within a few ulps of where the integration crosses, for both versions alike.
    #[test]
    fn a_state_event_is_located_where_it_happens() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            let probed = Probed::new();
            let ctx = probed.ctx(Fake::new(fmi, &[]), Interface::ModelExchange);
            let mut run = Run::start(&ctx, NAME, 0).unwrap();
            run.run_to_end().unwrap();
            let me = run.exchange().unwrap();
            assert_eq!(me.events().len(), 1, "{fmi:?}");
            let (t, indicator) = me.events()[0];
            assert_eq!(indicator, Some(0));
            assert!((t - 2f64.ln()).abs() < 1e-10, "{fmi:?}: the event at t = {t}");
            assert_eq!(run.trajectory.rows(), 101);
        }
    }

    /// An event iteration that never settles stops the run at the start, under the check
    /// that names it, with the version's own words for the flag.
    #[test]
    fn an_endless_event_iteration_is_its_own_finding() {
        for (fmi, words) in [
            (Fmi::Fmi2, "fmi2NewDiscreteStates still set newDiscreteStatesNeeded"),
            (Fmi::Fmi3, "fmi3UpdateDiscreteStates still set discreteStatesNeedUpdate"),
        ] {
            let probed = Probed::new();
            let ctx = probed.ctx(Fake::new(fmi, &[Fault::EventLoop]), Interface::ModelExchange);
            let failure = Run::start(&ctx, NAME, 0).err().expect("the run fails");
            assert_eq!(failure.check, Some("model-exchange.event-iteration"));
            assert!(failure.message.contains(words), "{}", failure.message);
        }
    }

    #[test]
    fn a_state_event_is_a_change_of_domain() {
        assert_eq!(crossing(&[1.0, 1.0], &[0.5, 0.0]), Some(1), "z > 0 to z <= 0");
        assert_eq!(crossing(&[0.0], &[-1.0]), None, "z <= 0 throughout");
        assert_eq!(crossing(&[-1.0], &[1e-300]), Some(0));
    }
}
