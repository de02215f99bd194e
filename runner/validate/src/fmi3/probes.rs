//! The dynamic checks of FMI 3.0, as probes the child process runs. Each probe is a list of
//! cells (one check each), reported to the parent as they start, so that after a crash the
//! parent knows what crashed and can resume after it.
//!
//! - `lifecycle`: the DefaultExperiment run through (Co-Simulation: fmi3DoStep, with Event
//!   Mode and early return where the FMU offers them; Model Exchange: integrated by the
//!   validator), then fmi3Reset and the same run again, which must give the same bits.
//! - `state-machine`: in each state the validator reaches, calls the standard does not allow
//!   there must return fmi3Error (FMI 3.0.2 section 2.2.3: "When detecting illegal arguments
//!   or a function call not allowed in the current state according to the respective state
//!   machine, the FMU must return fmi3Error"), and reading values must succeed where allowed.

use std::collections::HashSet;

use fmi_schema::fmi3::{self as s, Causality, Variability};

use super::capabilities;
use super::raw::{Code, CsOptions, Instance, Interface};
use super::Child;
use crate::isolation::Message;
use crate::report::{Finding, Severity};

/// The instance name of the runs.
const NAME: &str = "runner-validate";
/// The most communication steps one run takes.
const MAX_STEPS: usize = 100_000;
/// The most variables a run records.
const MAX_RECORDED: usize = 64;
/// The most fmi3UpdateDiscreteStates calls of one event before the iteration counts as stuck.
const MAX_ITERATIONS: usize = 100;
/// The most events (or early returns) within one communication step.
const MAX_EVENTS: usize = 10_000;

/// The probes there are.
pub(crate) fn known(probe: &str) -> bool {
    PROBES.contains(&probe)
}

/// Every probe, in the order they run (the first two are the lifecycle's and the state
/// machine's; the rest, of capabilities and robustness, are in capabilities.rs).
pub(crate) const PROBES: [&str; 7] = ["lifecycle", "state-machine", "fmu-state", "serialize", "arguments", "threads", "strings"];

/// Whether a probe repeats the DefaultExperiment's run (so fails alike when that run fails).
pub(crate) fn runs_the_experiment(probe: &str) -> bool {
    matches!(probe, "fmu-state" | "serialize" | "threads")
}

/// Whether a probe may resume after a crash in one of its cells (its cells are independent).
pub(crate) fn resumable(probe: &str) -> bool {
    probe == "state-machine" || probe == "arguments"
}

/// The check a crash before a probe's first cell counts against.
pub(crate) fn first_check(probe: &str) -> &'static str {
    match probe {
        "lifecycle" => "lifecycle.instantiate",
        "fmu-state" => "capability.fmu-state",
        "serialize" => "capability.serialize",
        "arguments" => "arguments.null-instance",
        "threads" => "capability.threads",
        "strings" => "variables.string",
        _ => "state-machine.illegal",
    }
}

/// The description as the probes use it.
pub(crate) struct Model {
    pub md: s::ModelDescription,
    pub start: f64,
    pub stop: f64,
    pub h: f64,
    pub steps: usize,
    pub tolerance: Option<f64>,
    /// Scalar Float64 variables a run records: the outputs, else the non-constant locals.
    pub recorded: Vec<(String, u32)>,
    /// The number of continuous states and event indicators the description declares (arrays
    /// counted by their start sizes); `None` where a size cannot be known.
    pub nx: Option<usize>,
    pub nz: Option<usize>,
}

impl Model {
    pub(crate) fn new(md: s::ModelDescription) -> Model {
        let experiment = md.default_experiment.unwrap_or_default();
        let finite = |v: Option<f64>| v.filter(|x| x.is_finite());
        let start = finite(experiment.start_time).unwrap_or(0.0);
        let stop = finite(experiment.stop_time).filter(|&s| s > start).unwrap_or(start + 1.0);
        let h = finite(experiment.step_size).filter(|&h| h > 0.0 && h <= stop - start).unwrap_or((stop - start) / 500.0);
        let steps = (((stop - start) / h - 1e-9).ceil() as usize).clamp(1, MAX_STEPS);
        let scalar_f64 =
            |v: &&s::Variable| v.dimensions.is_empty() && matches!(v.kind, s::VariableKind::Float { precision: s::FloatType::Float64, .. });
        let mut recorded: Vec<(String, u32)> = md
            .model_variables
            .iter()
            .filter(scalar_f64)
            .filter(|v| v.causality() == Causality::Output)
            .map(|v| (v.name.clone(), v.value_reference))
            .collect();
        if recorded.is_empty() {
            recorded = md
                .model_variables
                .iter()
                .filter(scalar_f64)
                .filter(|v| v.causality() == Causality::Local && v.variability() != Variability::Constant)
                .map(|v| (v.name.clone(), v.value_reference))
                .collect();
        }
        recorded.truncate(MAX_RECORDED);
        let count = |unknowns: &[s::Unknown]| -> Option<usize> {
            unknowns
                .iter()
                .map(|u| md.variable_by_reference(u.value_reference).and_then(|v| md.start_shape(v)))
                .try_fold(0usize, |n, shape| Some(n + shape?.iter().product::<u64>() as usize))
        };
        let nx = count(&md.model_structure.continuous_state_derivatives);
        let nz = count(&md.model_structure.event_indicators);
        Model { start, stop, h, steps, tolerance: finite(experiment.tolerance).filter(|t| *t > 0.0), recorded, nx, nz, md }
    }

    /// Communication point `k` (0..=steps), the last one the stop time.
    fn point(&self, k: usize) -> f64 {
        if k == self.steps {
            self.stop.min(self.start + k as f64 * self.h)
        } else {
            self.start + k as f64 * self.h
        }
    }

    fn has_event_mode(&self) -> bool {
        self.md.co_simulation.as_ref().is_some_and(|c| c.has_event_mode)
    }

    fn might_return_early(&self) -> bool {
        self.md.co_simulation.as_ref().is_some_and(|c| c.might_return_early_from_do_step)
    }

    fn needs_completed_integrator_step(&self) -> bool {
        self.md.model_exchange.as_ref().is_some_and(|m| m.needs_completed_integrator_step)
    }

    /// A scalar Float64 variable that may not be set in the states after initialization
    /// (constant, or a fixed parameter): its name, value reference and start value.
    fn fixed_float64(&self, constant: bool) -> Option<(String, u32, f64)> {
        self.md.model_variables.iter().find_map(|v| match &v.kind {
            s::VariableKind::Float { precision: s::FloatType::Float64, start: Some(start), .. }
                if v.dimensions.is_empty()
                    && start.len() == 1
                    && if constant {
                        v.variability() == Variability::Constant
                    } else {
                        v.causality() == Causality::Parameter && v.variability() == Variability::Fixed
                    } =>
            {
                Some((v.name.clone(), v.value_reference, start[0]))
            }
            _ => None,
        })
    }
}

/// What a probe works with, and where its findings go.
pub(crate) struct Ctx<'a> {
    pub child: &'a Child<'a>,
    pub interface: Interface,
    resume: usize,
    next_cell: usize,
    troubled: HashSet<String>,
}

impl<'a> Ctx<'a> {
    pub(crate) fn new(child: &'a Child<'a>, interface: Interface, resume: usize) -> Ctx<'a> {
        Ctx { child, interface, resume, next_cell: 0, troubled: HashSet::new() }
    }

    /// Starts the next cell, of `check`: false when it lies before the resume point.
    pub(super) fn cell(&mut self, check: &str) -> bool {
        self.cell_with(check, Severity::Error)
    }

    /// Starts the next cell, of `check`, whose crash is a finding of severity `crash`.
    pub(super) fn cell_with(&mut self, check: &str, crash: Severity) -> bool {
        let index = self.next_cell;
        self.next_cell += 1;
        if index < self.resume {
            return false;
        }
        self.child.out.send(&Message::Cell { check: check.to_owned(), index, crash });
        eprintln!("{}{index}", crate::isolation::CELL_MARK);
        true
    }

    pub(super) fn report(&mut self, finding: Finding) {
        if finding.severity <= Severity::Warning {
            self.troubled.insert(finding.check.clone());
        }
        self.child.out.send(&Message::Finding(finding.interface(Some(self.interface.title()))));
    }

    pub(super) fn pass(&mut self, check: &str, message: impl Into<String>) {
        if !self.troubled.contains(check) {
            self.report(Finding::passed(check, message));
        }
    }

    /// A new instance of this interface with the FMU's own token.
    pub(super) fn instantiate(&self, cs: CsOptions) -> Result<Instance<'a>, Failure> {
        self.instantiate_in(cs, 0)
    }

    /// [`Ctx::instantiate`] for the thread of progress slot `slot`.
    pub(super) fn instantiate_in(&self, cs: CsOptions, slot: usize) -> Result<Instance<'a>, Failure> {
        let c = self.child;
        Instance::new(c.api, self.interface, NAME, &c.model.md.instantiation_token, &c.resources, cs, (c.progress, slot), c.timeout)
            .map_err(|(code, log)| {
                let what = if code == Code::MISSING { "is not exported" } else { "returned NULL with the FMU's own instantiationToken" };
                let call = match self.interface {
                    Interface::CoSimulation => "fmi3InstantiateCoSimulation",
                    Interface::ModelExchange => "fmi3InstantiateModelExchange",
                };
                Failure { message: format!("{call} {what}"), call: call.into(), state: "(no instance)".into(), log }
            })
    }

    /// The options the runs use: Event Mode and early return when the FMU offers them.
    pub(super) fn cs_options(&self) -> CsOptions {
        let m = &self.child.model;
        CsOptions { event_mode_used: m.has_event_mode(), early_return_allowed: m.might_return_early() }
    }
}

/// A call that went wrong.
pub(super) struct Failure {
    pub message: String,
    pub call: String,
    pub state: String,
    pub log: Option<String>,
}

impl Failure {
    pub(super) fn finding(self, check: &str) -> Finding {
        Finding::error(check, self.message).call(self.call).state(self.state).log(self.log)
    }
}

/// Fails unless `code` is fmi3OK or fmi3Warning.
pub(super) fn legal(inst: &Instance, call: &str, code: Code) -> Result<(), Failure> {
    if code.ok() {
        return Ok(());
    }
    Err(Failure {
        message: format!("{call} returned {} in {}, where the standard allows it", code.name(), inst.state),
        call: call.into(),
        state: inst.state.into(),
        log: inst.log.take(),
    })
}

/// A run's record: the recorded values at each communication point, where it ended and why.
#[derive(PartialEq)]
pub(super) struct Trajectory {
    values: Vec<u64>,
    pub end: f64,
    ended: Option<String>,
}

/// Runs `probe` for `ctx`'s interface.
pub(crate) fn run(probe: &str, ctx: &mut Ctx) -> Result<(), String> {
    match probe {
        "lifecycle" => lifecycle(ctx),
        "state-machine" => state_machine(ctx),
        "fmu-state" => capabilities::fmu_state(ctx, false),
        "serialize" => capabilities::fmu_state(ctx, true),
        "arguments" => capabilities::arguments(ctx),
        "threads" => capabilities::threads(ctx),
        "strings" => capabilities::string_variables(ctx),
        other => return Err(format!("unknown probe {other:?}")),
    }
    Ok(())
}

/// Instantiates (a wrong token refused, as a warning: the standard lets the FMU check it),
/// runs, resets and runs again.
fn lifecycle(ctx: &mut Ctx) {
    if ctx.cell("lifecycle.instantiate") {
        match ctx.instantiate(ctx.cs_options()) {
            Err(f) => {
                ctx.report(f.finding("lifecycle.instantiate"));
                return;
            }
            Ok(mut inst) => inst.free(),
        }
        let c = ctx.child;
        let token = wrong_token(&c.model.md.instantiation_token);
        if let Ok(mut inst) = Instance::new(c.api, ctx.interface, NAME, &token, &c.resources, ctx.cs_options(), (c.progress, 0), c.timeout)
        {
            inst.free();
            ctx.report(
                Finding::warning(
                    "lifecycle.instantiate",
                    "a wrong instantiationToken was accepted: the standard lets the FMU check it (\"can be used by the FMU to check that the modelDescription.xml file is compatible\"), and a binary that does not check it runs with any description",
                )
                .value(token),
            );
        }
        ctx.pass("lifecycle.instantiate", "instantiated with its own instantiationToken, a wrong one refused");
    }
    if !ctx.cell("lifecycle.run") {
        return;
    }
    let mut inst = match ctx.instantiate(ctx.cs_options()) {
        Ok(i) => i,
        Err(f) => return ctx.report(f.finding("lifecycle.run")),
    };
    let first = match simulate(ctx, &mut inst) {
        Ok(t) => t,
        Err(f) => return ctx.report(f.finding("lifecycle.run")),
    };
    let model = &ctx.child.model;
    let how = match ctx.interface {
        Interface::CoSimulation => {
            let o = ctx.cs_options();
            format!(
                "fmi3DoStep over the DefaultExperiment, {} steps of {} s{}{}",
                model.steps,
                model.h,
                if o.event_mode_used { ", with Event Mode" } else { "" },
                if o.early_return_allowed { ", early return allowed" } else { "" }
            )
        }
        Interface::ModelExchange => {
            format!("integrated by the validator (RK4, {} steps of {} s, events at step ends)", model.steps, model.h)
        }
    };
    let ended = first.ended.as_ref().map_or(String::new(), |why| format!(" (the model ended the run at t = {}: {why})", first.end));
    ctx.pass("lifecycle.run", format!("{how} from t = {} to t = {}, every recorded value finite{ended}", model.start, first.end));
    if !ctx.cell("lifecycle.reset") {
        return;
    }
    let terminated = legal(&inst, "fmi3Terminate", inst.plain("fmi3Terminate", inst.api.terminate));
    if let Err(f) = terminated {
        return ctx.report(f.finding("lifecycle.reset"));
    }
    inst.state = "Terminated";
    if let Err(f) = legal(&inst, "fmi3Reset", inst.plain("fmi3Reset", inst.api.reset)) {
        return ctx.report(f.finding("lifecycle.reset"));
    }
    inst.state = "Instantiated";
    match simulate(ctx, &mut inst) {
        Err(f) => {
            ctx.report(Failure { message: format!("after fmi3Reset, the same run failed: {}", f.message), ..f }.finding("lifecycle.reset"))
        }
        Ok(second) if second != first => ctx.report(Finding::error(
            "lifecycle.reset",
            format!(
                "after fmi3Reset the same run gave other results ({}): fmi3Reset must bring the instance back to the state after instantiation",
                difference(&ctx.child.model, &first, &second, "in the first run", "after fmi3Reset")
            ),
        )),
        Ok(_) => {
            let _ = inst.plain("fmi3Terminate", inst.api.terminate);
            ctx.pass("lifecycle.reset", "fmi3Terminate, fmi3Reset and the same run again: the same results to the bit");
        }
    }
}

/// Where two runs of the same grid first differ: the variable, time and both values (`mine`
/// and `theirs` say which run is which), or where they ended.
pub(super) fn difference(model: &Model, first: &Trajectory, second: &Trajectory, mine: &str, theirs: &str) -> String {
    let recorded = &model.recorded;
    match first.values.iter().zip(&second.values).position(|(a, b)| a != b) {
        Some(i) if !recorded.is_empty() => {
            let (name, point) = (&recorded[i % recorded.len()].0, i / recorded.len());
            let (a, b) = (f64::from_bits(first.values[i]), f64::from_bits(second.values[i]));
            format!("{name} at t = {} was {a} {mine} and {b} {theirs}", model.point(point))
        }
        _ => format!("the runs ended at t = {} and t = {}", first.end, second.end),
    }
}

/// A token surely not the FMU's: the same length, one character changed.
fn wrong_token(token: &str) -> String {
    let mut chars: Vec<char> = token.chars().collect();
    match chars.iter().rposition(|c| c.is_ascii_alphanumeric()) {
        Some(i) => {
            chars[i] = if chars[i] == '0' { '1' } else { '0' };
            chars.into_iter().collect()
        }
        None => format!("{token}-not-this-one"),
    }
}

/// Initializes `inst` (fmi3EnterInitializationMode with the experiment, fmi3ExitInitializationMode).
fn initialize(ctx: &Ctx, inst: &mut Instance) -> Result<(), Failure> {
    let m = &ctx.child.model;
    legal(inst, "fmi3EnterInitializationMode", inst.enter_initialization_mode(m.tolerance, m.start, m.stop))?;
    inst.state = "InitializationMode";
    legal(inst, "fmi3ExitInitializationMode", inst.plain("fmi3ExitInitializationMode", inst.api.exit_initialization_mode))?;
    inst.state = match (ctx.interface, ctx.cs_options().event_mode_used) {
        (Interface::CoSimulation, false) => "StepMode",
        _ => "EventMode",
    };
    Ok(())
}

/// fmi3UpdateDiscreteStates until no update is needed: `Some(reason)` when the model asks to
/// end the simulation, and the next time event.
fn event_iteration(inst: &Instance, t: f64) -> Result<(bool, Option<f64>), Failure> {
    for _ in 0..MAX_ITERATIONS {
        let (code, again, terminate, next) = inst.update_discrete_states();
        legal(inst, "fmi3UpdateDiscreteStates", code)?;
        if terminate {
            return Ok((true, None));
        }
        if !again {
            if let Some(te) = next {
                if !(te.is_finite() && te >= t) {
                    return Err(Failure {
                        message: format!(
                            "fmi3UpdateDiscreteStates at t = {t} gave nextEventTime = {te}, which is not a time at or after now"
                        ),
                        call: "fmi3UpdateDiscreteStates".into(),
                        state: inst.state.into(),
                        log: inst.log.take(),
                    });
                }
            }
            return Ok((false, next));
        }
    }
    Err(Failure {
        message: format!("the event iteration at t = {t} did not end: discreteStatesNeedUpdate stayed true for {MAX_ITERATIONS} calls"),
        call: "fmi3UpdateDiscreteStates".into(),
        state: inst.state.into(),
        log: inst.log.take(),
    })
}

/// Reads the recorded variables and checks them finite.
fn record(ctx: &Ctx, inst: &Instance, t: f64, into: &mut Vec<u64>) -> Result<(), Failure> {
    let recorded = &ctx.child.model.recorded;
    if recorded.is_empty() {
        return Ok(());
    }
    let vrs: Vec<u32> = recorded.iter().map(|(_, vr)| *vr).collect();
    let mut values = vec![0.0; vrs.len()];
    legal(inst, "fmi3GetFloat64", inst.get_float64(&vrs, &mut values))?;
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(Failure {
            message: format!("{} = {} at t = {t}", recorded[i].0, values[i]),
            call: "fmi3GetFloat64".into(),
            state: inst.state.into(),
            log: inst.log.take(),
        });
    }
    into.extend(values.iter().map(|v| v.to_bits()));
    Ok(())
}

/// One run of the DefaultExperiment grid.
pub(super) fn simulate(ctx: &Ctx, inst: &mut Instance) -> Result<Trajectory, Failure> {
    let mut run = begin(ctx, inst)?;
    advance(ctx, inst, &mut run, ctx.child.model.steps)?;
    Ok(run.trajectory())
}

/// Where a run is: the communication point it reached, what it recorded, and what the
/// validator's integrator keeps between steps (Model Exchange), so that a run can be taken
/// up again from a copy after an FMU state is restored.
#[derive(Clone)]
pub(super) struct Cursor {
    pub k: usize,
    pub t: f64,
    values: Vec<u64>,
    pub ended: bool,
    x: Vec<f64>,
    z: Vec<f64>,
    next_event: Option<f64>,
}

impl Cursor {
    pub(super) fn trajectory(self) -> Trajectory {
        Trajectory { values: self.values, end: self.t, ended: self.ended.then(|| "terminateSimulation".to_owned()) }
    }
}

/// Initializes `inst` and records the start of a run.
pub(super) fn begin(ctx: &Ctx, inst: &mut Instance) -> Result<Cursor, Failure> {
    initialize(ctx, inst)?;
    let t = ctx.child.model.start;
    let mut run = Cursor { k: 0, t, values: Vec::new(), ended: false, x: Vec::new(), z: Vec::new(), next_event: None };
    let stop = match ctx.interface {
        Interface::CoSimulation if ctx.cs_options().event_mode_used => {
            let stop = event_iteration(inst, t)?.0;
            if !stop {
                legal(inst, "fmi3EnterStepMode", inst.plain("fmi3EnterStepMode", inst.api.enter_step_mode))?;
                inst.state = "StepMode";
            }
            stop
        }
        Interface::CoSimulation => false,
        Interface::ModelExchange => {
            let (nx, nz) = sizes(ctx, inst)?;
            (run.x, run.z) = (vec![0.0; nx], vec![0.0; nz]);
            let (stop, next) = event_iteration(inst, t)?;
            run.next_event = next;
            if !stop {
                continuous_time(inst, &mut run.x, &mut run.z)?;
            }
            stop
        }
    };
    run.ended = stop;
    if !stop {
        record(ctx, inst, t, &mut run.values)?;
    }
    Ok(run)
}

/// Runs on to communication point `until` (or the model's end of the run).
pub(super) fn advance(ctx: &Ctx, inst: &mut Instance, run: &mut Cursor, until: usize) -> Result<(), Failure> {
    if run.ended {
        return Ok(());
    }
    match ctx.interface {
        Interface::CoSimulation => co_simulation(ctx, inst, run, until),
        Interface::ModelExchange => model_exchange(ctx, inst, run, until),
    }
}

pub(super) fn failure(inst: &Instance, call: &str, message: String) -> Failure {
    Failure { message, call: call.into(), state: inst.state.into(), log: inst.log.take() }
}

/// fmi3DoStep on the grid (with Event Mode and early returns where the FMU offers them).
fn co_simulation(ctx: &Ctx, inst: &mut Instance, run: &mut Cursor, until: usize) -> Result<(), Failure> {
    let m = &ctx.child.model;
    let options = ctx.cs_options();
    let mut t = run.t;
    let ended = |run: &mut Cursor, t: f64| {
        (run.t, run.ended) = (t, true);
        Ok(())
    };
    for k in run.k + 1..=until {
        let target = m.point(k);
        let mut events = 0;
        while t < target {
            let (code, event, terminate, early, last) = inst.do_step(t, target - t);
            legal(inst, "fmi3DoStep", code)?;
            let reached = if early {
                if !options.early_return_allowed {
                    return Err(failure(inst, "fmi3DoStep", format!("fmi3DoStep from t = {t} returned earlyReturn = true, but the instance was made with earlyReturnAllowed = false")));
                }
                if !(last > t && last <= target) {
                    return Err(failure(
                        inst,
                        "fmi3DoStep",
                        format!("fmi3DoStep from t = {t} to {target} returned early with lastSuccessfulTime = {last}, which is not within the step"),
                    ));
                }
                last
            } else {
                target
            };
            if terminate {
                return ended(run, reached);
            }
            t = reached;
            if event && options.event_mode_used {
                events += 1;
                if events > MAX_EVENTS {
                    return Err(failure(inst, "fmi3DoStep", format!("more than {MAX_EVENTS} events within the step to t = {target}")));
                }
                legal(inst, "fmi3EnterEventMode", inst.plain("fmi3EnterEventMode", inst.api.enter_event_mode))?;
                inst.state = "EventMode";
                if event_iteration(inst, t)?.0 {
                    return ended(run, t);
                }
                legal(inst, "fmi3EnterStepMode", inst.plain("fmi3EnterStepMode", inst.api.enter_step_mode))?;
                inst.state = "StepMode";
            } else if reached < target {
                events += 1;
                if events > MAX_EVENTS {
                    return Err(failure(
                        inst,
                        "fmi3DoStep",
                        format!("more than {MAX_EVENTS} early returns within the step to t = {target}"),
                    ));
                }
            }
        }
        record(ctx, inst, t, &mut run.values)?;
        (run.k, run.t) = (k, t);
    }
    Ok(())
}

/// The sizes the FMU reports, checked against the description.
fn sizes(ctx: &Ctx, inst: &Instance) -> Result<(usize, usize), Failure> {
    let m = &ctx.child.model;
    let (code, nx) = inst.number_of("fmi3GetNumberOfContinuousStates", inst.api.get_number_of_continuous_states);
    legal(inst, "fmi3GetNumberOfContinuousStates", code)?;
    let (code, nz) = inst.number_of("fmi3GetNumberOfEventIndicators", inst.api.get_number_of_event_indicators);
    legal(inst, "fmi3GetNumberOfEventIndicators", code)?;
    for (call, got, declared, what) in [
        ("fmi3GetNumberOfContinuousStates", nx, m.nx, "ContinuousStateDerivative"),
        ("fmi3GetNumberOfEventIndicators", nz, m.nz, "EventIndicator"),
    ] {
        if declared.is_some_and(|d| d != got) {
            return Err(failure(
                inst,
                call,
                format!(
                    "{call} reports {got}, but ModelStructure lists {} {what} elements (no structural parameter was changed)",
                    declared.unwrap_or(0)
                ),
            ));
        }
    }
    if nx > 1 << 20 || nz > 1 << 20 {
        return Err(failure(
            inst,
            "fmi3GetNumberOfContinuousStates",
            format!("{nx} states and {nz} event indicators: beyond any sane model"),
        ));
    }
    Ok((nx, nz))
}

/// Leaves Event Mode and reads the states and indicators.
fn continuous_time(inst: &mut Instance, x: &mut [f64], z: &mut [f64]) -> Result<(), Failure> {
    legal(inst, "fmi3EnterContinuousTimeMode", inst.plain("fmi3EnterContinuousTimeMode", inst.api.enter_continuous_time_mode))?;
    inst.state = "ContinuousTimeMode";
    legal(inst, "fmi3GetContinuousStates", inst.array("fmi3GetContinuousStates", inst.api.get_continuous_states, x))?;
    legal(inst, "fmi3GetEventIndicators", inst.array("fmi3GetEventIndicators", inst.api.get_event_indicators, z))?;
    Ok(())
}

/// The derivatives at (t, x), checked finite.
fn derivatives(inst: &Instance, t: f64, x: &[f64], dx: &mut [f64]) -> Result<(), Failure> {
    legal(inst, "fmi3SetTime", inst.set_time(t))?;
    if !x.is_empty() {
        legal(inst, "fmi3SetContinuousStates", inst.set_continuous_states(x))?;
    }
    legal(
        inst,
        "fmi3GetContinuousStateDerivatives",
        inst.array("fmi3GetContinuousStateDerivatives", inst.api.get_continuous_state_derivatives, dx),
    )?;
    if let Some(i) = dx.iter().position(|v| !v.is_finite()) {
        return Err(failure(inst, "fmi3GetContinuousStateDerivatives", format!("derivative {i} is {} at t = {t}", dx[i])));
    }
    Ok(())
}

/// The validator's integration: classical RK4 on the communication grid, each step cut at the
/// next time event; a sign change of an event indicator over a step, a time event or a step
/// event is handled at the step's end (the validator checks the calls, not the accuracy).
fn model_exchange(ctx: &Ctx, inst: &mut Instance, run: &mut Cursor, until: usize) -> Result<(), Failure> {
    let m = &ctx.child.model;
    let (nx, nz) = (run.x.len(), run.z.len());
    let (mut t, mut next_event) = (run.t, run.next_event);
    let (x, z) = (&mut run.x, &mut run.z);
    let mut z_new = vec![0.0; nz];
    let values = &mut run.values;
    let mut ended = false;
    let mut k = [vec![0.0; nx], vec![0.0; nx], vec![0.0; nx], vec![0.0; nx]];
    let mut probe = vec![0.0; nx];
    let mut reached = run.k;
    'steps: for step in run.k + 1..=until {
        let target = m.point(step);
        let mut events = 0;
        while t < target {
            let time_event = next_event.filter(|&te| te <= target);
            let t_next = time_event.map_or(target, |te| te.max(t));
            let dt = t_next - t;
            if dt > 0.0 {
                derivatives(inst, t, x, &mut k[0])?;
                for (stage, factor) in [(1, 0.5), (2, 0.5), (3, 1.0)] {
                    for i in 0..nx {
                        probe[i] = x[i] + factor * dt * k[stage - 1][i];
                    }
                    let (_, rest) = k.split_at_mut(stage);
                    derivatives(inst, t + factor * dt, &probe, &mut rest[0])?;
                }
                for i in 0..nx {
                    x[i] += dt / 6.0 * (k[0][i] + 2.0 * k[1][i] + 2.0 * k[2][i] + k[3][i]);
                }
            }
            t = t_next;
            legal(inst, "fmi3SetTime", inst.set_time(t))?;
            if nx > 0 {
                legal(inst, "fmi3SetContinuousStates", inst.set_continuous_states(x))?;
            }
            let mut step_event = false;
            if m.needs_completed_integrator_step() {
                let (code, enter, terminate) = inst.completed_integrator_step();
                legal(inst, "fmi3CompletedIntegratorStep", code)?;
                if terminate {
                    ended = true;
                    break 'steps;
                }
                step_event = enter;
            }
            legal(inst, "fmi3GetEventIndicators", inst.array("fmi3GetEventIndicators", inst.api.get_event_indicators, &mut z_new))?;
            let state_event = z.iter().zip(&z_new).any(|(a, b)| (*a > 0.0) != (*b > 0.0));
            z.copy_from_slice(&z_new);
            if state_event || step_event || time_event.is_some_and(|te| t >= te) {
                events += 1;
                if events > MAX_EVENTS {
                    return Err(failure(
                        inst,
                        "fmi3EnterEventMode",
                        format!("more than {MAX_EVENTS} events within the step to t = {target}"),
                    ));
                }
                legal(inst, "fmi3EnterEventMode", inst.plain("fmi3EnterEventMode", inst.api.enter_event_mode))?;
                inst.state = "EventMode";
                let (stop, next) = event_iteration(inst, t)?;
                if stop {
                    ended = true;
                    break 'steps;
                }
                next_event = next;
                continuous_time(inst, x, z)?;
            }
        }
        record(ctx, inst, t, values)?;
        reached = step;
    }
    (run.k, run.t, run.next_event, run.ended) = (reached, t, next_event, ended);
    Ok(())
}

/// The states the state-machine probe drives an instance into, in order.
fn states(ctx: &Ctx) -> Vec<&'static str> {
    match ctx.interface {
        Interface::CoSimulation if ctx.cs_options().event_mode_used => {
            vec!["Instantiated", "InitializationMode", "EventMode", "StepMode", "Terminated"]
        }
        Interface::CoSimulation => vec!["Instantiated", "InitializationMode", "StepMode", "Terminated"],
        Interface::ModelExchange => vec!["Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated"],
    }
}

/// A fresh instance driven into `state` by legal calls.
pub(super) fn drive<'a>(ctx: &Ctx<'a>, state: &str) -> Result<Instance<'a>, Failure> {
    let mut inst = ctx.instantiate(ctx.cs_options())?;
    if state == "Instantiated" {
        return Ok(inst);
    }
    let m = &ctx.child.model;
    legal(&inst, "fmi3EnterInitializationMode", inst.enter_initialization_mode(m.tolerance, m.start, m.stop))?;
    inst.state = "InitializationMode";
    if state == "InitializationMode" {
        return Ok(inst);
    }
    legal(&inst, "fmi3ExitInitializationMode", inst.plain("fmi3ExitInitializationMode", inst.api.exit_initialization_mode))?;
    let event_mode = ctx.interface == Interface::ModelExchange || ctx.cs_options().event_mode_used;
    inst.state = if event_mode { "EventMode" } else { "StepMode" };
    if state == "EventMode" {
        return Ok(inst);
    }
    if event_mode {
        let _ = event_iteration(&inst, m.start)?;
        if ctx.interface == Interface::ModelExchange {
            legal(&inst, "fmi3EnterContinuousTimeMode", inst.plain("fmi3EnterContinuousTimeMode", inst.api.enter_continuous_time_mode))?;
            inst.state = "ContinuousTimeMode";
        } else {
            legal(&inst, "fmi3EnterStepMode", inst.plain("fmi3EnterStepMode", inst.api.enter_step_mode))?;
            inst.state = "StepMode";
        }
    }
    if state == "Terminated" {
        legal(&inst, "fmi3Terminate", inst.plain("fmi3Terminate", inst.api.terminate))?;
        inst.state = "Terminated";
    }
    Ok(inst)
}

/// The calls the standard does not allow in `state` for `interface` (FMI 3.0.2 sections 2.3,
/// 3.2 and 4.2: each state's "Allowed Function Calls"; functions of the other interface are
/// not allowed at all). Each is made with arguments that would be valid in a state that
/// allows it, so the state is the only fault.
fn illegal(interface: Interface, state: &str, event_mode_used: bool) -> Vec<&'static str> {
    let me = interface == Interface::ModelExchange;
    let mut calls: Vec<&'static str> = match state {
        "Instantiated" => vec!["fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3UpdateDiscreteStates", "fmi3Terminate"],
        "InitializationMode" => vec!["fmi3EnterInitializationMode", "fmi3EnterEventMode", "fmi3UpdateDiscreteStates", "fmi3Terminate"],
        "EventMode" => vec!["fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3EnterEventMode"],
        "StepMode" => vec!["fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3UpdateDiscreteStates", "fmi3EnterStepMode"],
        "ContinuousTimeMode" => {
            vec!["fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3UpdateDiscreteStates", "fmi3EnterContinuousTimeMode"]
        }
        _ => vec!["fmi3EnterInitializationMode", "fmi3ExitInitializationMode", "fmi3EnterEventMode", "fmi3UpdateDiscreteStates"],
    };
    // The interface's own mode changes and steps, outside the states that allow them.
    if me {
        if state != "ContinuousTimeMode" {
            calls.extend(["fmi3SetTime", "fmi3SetContinuousStates", "fmi3CompletedIntegratorStep"]);
        }
        if state != "EventMode" && state != "ContinuousTimeMode" {
            calls.push("fmi3EnterContinuousTimeMode");
        }
        calls.extend(["fmi3DoStep", "fmi3EnterStepMode"]);
    } else {
        if state != "StepMode" {
            calls.push("fmi3DoStep");
        }
        if state != "EventMode" && state != "StepMode" {
            calls.push("fmi3EnterStepMode");
        }
        if state == "StepMode" && !event_mode_used {
            // Event Mode exists only for instances made with eventModeUsed.
            calls.push("fmi3EnterEventMode");
        }
        calls.extend(["fmi3SetTime", "fmi3EnterContinuousTimeMode", "fmi3GetContinuousStateDerivatives"]);
    }
    let mut seen = HashSet::new();
    calls.retain(|c| seen.insert(*c));
    calls
}

/// Makes `call` on `inst` with valid arguments.
fn make(ctx: &Ctx, inst: &Instance, call: &str) -> Code {
    let m = &ctx.child.model;
    let nx = m.nx.unwrap_or(0);
    match call {
        "fmi3EnterInitializationMode" => inst.enter_initialization_mode(m.tolerance, m.start, m.stop),
        "fmi3ExitInitializationMode" => inst.plain(call, inst.api.exit_initialization_mode),
        "fmi3EnterEventMode" => inst.plain(call, inst.api.enter_event_mode),
        "fmi3Terminate" => inst.plain(call, inst.api.terminate),
        "fmi3EnterStepMode" => inst.plain(call, inst.api.enter_step_mode),
        "fmi3EnterContinuousTimeMode" => inst.plain(call, inst.api.enter_continuous_time_mode),
        "fmi3UpdateDiscreteStates" => inst.update_discrete_states().0,
        "fmi3DoStep" => inst.do_step(m.start, m.h).0,
        "fmi3SetTime" => inst.set_time(m.start),
        "fmi3CompletedIntegratorStep" => inst.completed_integrator_step().0,
        "fmi3SetContinuousStates" => {
            let mut x = vec![0.0; nx];
            // The values the FMU holds, where it gives them (else zeros: the call is refused anyway).
            let _ = inst.array("fmi3GetContinuousStates", inst.api.get_continuous_states, &mut x);
            inst.set_continuous_states(&x)
        }
        "fmi3GetContinuousStateDerivatives" => {
            let mut dx = vec![0.0; nx];
            inst.array(call, inst.api.get_continuous_state_derivatives, &mut dx)
        }
        _ => Code::MISSING,
    }
}

/// Every illegal call in every state the validator reaches, each on a fresh instance; reading
/// the recorded values where the standard allows it; setting a constant, or a fixed parameter
/// after initialization, refused.
fn state_machine(ctx: &mut Ctx) {
    let options = ctx.cs_options();
    let constant = ctx.child.model.fixed_float64(true);
    let fixed = ctx.child.model.fixed_float64(false);
    let (mut illegal_calls, mut legal_calls) = (0, 0);
    for state in states(ctx) {
        let mut cells: Vec<(&str, String)> =
            illegal(ctx.interface, state, options.event_mode_used).into_iter().map(|c| (c, String::new())).collect();
        if let Some((name, ..)) = &constant {
            cells.push(("fmi3SetFloat64", name.clone()));
        }
        if let Some((name, ..)) = fixed.as_ref().filter(|_| !matches!(state, "Instantiated" | "InitializationMode")) {
            cells.push(("fmi3SetFloat64", name.clone()));
        }
        for (call, variable) in cells {
            if !ctx.cell("state-machine.illegal") {
                continue;
            }
            let mut inst = match drive(ctx, state) {
                Ok(i) => i,
                Err(f) => {
                    ctx.report(f.finding("state-machine.legal"));
                    continue;
                }
            };
            let code = if variable.is_empty() {
                make(ctx, &inst, call)
            } else {
                let (_, vr, start) = [&constant, &fixed].into_iter().flatten().find(|(n, ..)| *n == variable).cloned().expect("listed");
                inst.set_float64(vr, start)
            };
            illegal_calls += 1;
            let what = if variable.is_empty() { call.to_owned() } else { format!("{call} of '{variable}'") };
            let finding = if code.ok() {
                Some(Finding::error(
                    "state-machine.illegal",
                    format!("{what} in {state} returned {}, but the standard does not allow it there and requires fmi3Error", code.name()),
                ))
            } else if code == Code::MISSING {
                None
            } else if code != Code::ERROR {
                Some(Finding::warning(
                    "state-machine.illegal",
                    format!("{what} in {state} was refused with {}, where the standard requires fmi3Error", code.name()),
                ))
            } else {
                None
            };
            if let Some(f) = finding {
                let f = f.call(call).state(state).log(inst.log.take());
                ctx.report(if variable.is_empty() { f } else { f.variable(variable.clone()) });
            }
            inst.free();
        }
        if state != "Instantiated" && !ctx.child.model.recorded.is_empty() && ctx.cell("state-machine.legal") {
            match drive(ctx, state) {
                Err(f) => ctx.report(f.finding("state-machine.legal")),
                Ok(inst) => {
                    let vrs: Vec<u32> = ctx.child.model.recorded.iter().map(|(_, vr)| *vr).collect();
                    let mut values = vec![0.0; vrs.len()];
                    legal_calls += 1;
                    if let Err(f) = legal(&inst, "fmi3GetFloat64", inst.get_float64(&vrs, &mut values)) {
                        ctx.report(f.finding("state-machine.legal"));
                    }
                }
            }
        }
    }
    ctx.pass(
        "state-machine.illegal",
        format!("{illegal_calls} calls the standard does not allow, each in a fresh instance, refused with fmi3Error"),
    );
    ctx.pass(
        "state-machine.legal",
        format!("every state reached by legal calls; fmi3GetFloat64 of the recorded variables succeeded in {legal_calls} states"),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The calls that move an instance on are never listed as illegal in the state they leave
    /// (the table would then flag every correct FMU), and are listed everywhere else.
    #[test]
    fn the_table_allows_each_transition_exactly_where_the_standard_does() {
        let cs = Interface::CoSimulation;
        let me = Interface::ModelExchange;
        let allowed_in = |interface, call: &str, event_mode| -> Vec<&str> {
            let all: &[&str] = match (interface, event_mode) {
                (Interface::ModelExchange, _) => &["Instantiated", "InitializationMode", "EventMode", "ContinuousTimeMode", "Terminated"],
                (_, true) => &["Instantiated", "InitializationMode", "EventMode", "StepMode", "Terminated"],
                (_, false) => &["Instantiated", "InitializationMode", "StepMode", "Terminated"],
            };
            all.iter().copied().filter(|s| !illegal(interface, s, event_mode).contains(&call)).collect()
        };
        assert_eq!(allowed_in(cs, "fmi3DoStep", false), ["StepMode"]);
        assert_eq!(allowed_in(cs, "fmi3EnterStepMode", true), ["EventMode"]);
        assert_eq!(allowed_in(cs, "fmi3EnterEventMode", true), ["StepMode"]);
        assert_eq!(allowed_in(cs, "fmi3EnterEventMode", false), Vec::<&str>::new());
        assert_eq!(allowed_in(me, "fmi3EnterEventMode", false), ["ContinuousTimeMode"]);
        assert_eq!(allowed_in(me, "fmi3EnterContinuousTimeMode", false), ["EventMode"]);
        assert_eq!(allowed_in(me, "fmi3SetTime", false), ["ContinuousTimeMode"]);
        assert_eq!(allowed_in(me, "fmi3CompletedIntegratorStep", false), ["ContinuousTimeMode"]);
        assert_eq!(allowed_in(me, "fmi3UpdateDiscreteStates", false), ["EventMode"]);
        assert_eq!(allowed_in(cs, "fmi3UpdateDiscreteStates", true), ["EventMode"]);
        assert_eq!(allowed_in(me, "fmi3ExitInitializationMode", false), ["InitializationMode"]);
        assert_eq!(allowed_in(cs, "fmi3EnterInitializationMode", false), ["Instantiated"]);
        // fmi3Terminate is probed before initialization only (Terminated is left unprobed for it).
        assert_eq!(&allowed_in(me, "fmi3Terminate", false)[..2], ["EventMode", "ContinuousTimeMode"]);
        // The other interface's functions nowhere.
        assert!(allowed_in(me, "fmi3DoStep", false).is_empty() && allowed_in(me, "fmi3EnterStepMode", false).is_empty());
        assert!(allowed_in(cs, "fmi3GetContinuousStateDerivatives", true).is_empty());
    }

    #[test]
    fn a_wrong_token_differs_from_the_right_one() {
        for token in ["{7d1c2f40-5b8e-4c3a-9f61-0e2d4b6a8c13}", "0", "{}", "abc"] {
            let wrong = wrong_token(token);
            assert_ne!(wrong, token);
        }
    }
}
