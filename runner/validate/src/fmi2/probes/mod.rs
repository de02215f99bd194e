//! The dynamic checks of FMI 2.0, as probes the child process runs: each probe is a list of
//! cells (one check each), reported to the parent as they start, so that after a crash the
//! parent knows what crashed and can resume after it.

mod null_arguments;
mod state_machine;
mod strings;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use super::model::Grid;
use super::raw::Fmu;
use super::run::{Failure, Run, Trajectory};
use super::table::{Interface, State};
use crate::isolation::Message;
use crate::report::{Finding, Severity};

/// The instance name of the reference run and of the runs compared with it.
pub(crate) const NAME: &str = "runner-validate";
/// Another instance name: the results must not depend on it.
const OTHER_NAME: &str = "second instance, another name";

/// The probes there are, by name (`state-machine:<State>` takes the state's name).
pub(crate) fn known(probe: &str) -> bool {
    matches!(probe, "lifecycle" | "reproducible" | "arguments" | "strings" | "fmu-state" | "serialize" | "variable-step" | "threads")
        || probe.strip_prefix("state-machine:").and_then(State::from_name).is_some()
}

/// Whether a probe may resume after a crash in one of its cells (its cells are independent).
pub(crate) fn resumable(probe: &str) -> bool {
    probe == "arguments" || probe.starts_with("state-machine:")
}

/// The check a crash before a probe's first cell counts against.
pub(crate) fn first_check(probe: &str) -> &'static str {
    match probe {
        "lifecycle" => "lifecycle.guid",
        "reproducible" => "health.reproducible",
        "arguments" => "arguments.unknown-vr",
        "strings" => "variables.string",
        "fmu-state" => "capability.fmu-state",
        "serialize" => "capability.serialize",
        "variable-step" => "capability.variable-step",
        "threads" => "capability.threads",
        _ => "state-machine.legal",
    }
}

/// Where the messages to the parent go: one JSON line each, flushed at once (a crash right
/// after must not lose it).
pub(crate) struct Out {
    writer: Mutex<std::fs::File>,
}

impl Out {
    pub(crate) fn new(file: std::fs::File) -> Out {
        Out { writer: Mutex::new(file) }
    }

    pub(crate) fn send(&self, message: &Message) {
        let mut line = serde_json::to_string(message).expect("messages are plain data");
        line.push('\n');
        if let Ok(mut w) = self.writer.lock() {
            let _ = w.write_all(line.as_bytes());
        }
    }
}

/// What a probe works with, and where its findings go.
pub(crate) struct Ctx<'a> {
    pub fmu: &'a Fmu,
    out: &'a Out,
    runs: PathBuf,
    resume: usize,
    next_cell: usize,
    troubled: std::collections::HashSet<String>,
}

impl<'a> Ctx<'a> {
    pub(crate) fn new(fmu: &'a Fmu, out: &'a Out, runs: &Path, resume: usize) -> Ctx<'a> {
        Ctx { fmu, out, runs: runs.to_path_buf(), resume, next_cell: 0, troubled: Default::default() }
    }

    /// Starts the next cell, of `check`: false when it lies before the resume point and is to
    /// be skipped. A crash inside it becomes a finding of severity `crash`.
    pub(crate) fn cell(&mut self, check: &str, crash: Severity) -> bool {
        let index = self.next_cell;
        self.next_cell += 1;
        if index < self.resume {
            return false;
        }
        self.out.send(&Message::Cell { check: check.to_owned(), index, crash });
        eprintln!("{}{index}", crate::isolation::CELL_MARK);
        true
    }

    /// Reports a finding of this interface.
    pub(crate) fn report(&mut self, finding: Finding) {
        if finding.severity <= Severity::Warning {
            self.troubled.insert(finding.check.clone());
        }
        let finding = finding.interface(Some(self.fmu.interface.title()));
        self.out.send(&Message::Finding(finding));
    }

    /// Reports `failure` as an error of `check` (or of the failure's own check).
    pub(crate) fn fail(&mut self, check: &str, failure: Failure) {
        self.report(failure.finding(check, Severity::Error));
    }

    /// Reports `failure` as a warning.
    pub(crate) fn warn(&mut self, check: &str, failure: Failure) {
        self.report(failure.finding(check, Severity::Warning));
    }

    /// Reports `check` passed, unless it already has an error or warning.
    pub(crate) fn pass(&mut self, check: &str, message: impl Into<String>) {
        if !self.troubled.contains(check) {
            self.report(Finding::passed(check, message));
        }
    }

    /// Reports `check` skipped.
    pub(crate) fn skip(&mut self, check: &str, message: impl Into<String>) {
        self.report(Finding::skipped(check, message));
    }

    fn reference_path(&self) -> PathBuf {
        self.runs.join(format!("{}-reference.bin", self.fmu.interface.arg()))
    }

    /// The first run, which the lifecycle probe saved.
    fn reference(&self) -> Result<Trajectory, String> {
        Trajectory::load(&self.reference_path(), super::run::Recorder::new(&self.fmu.model).columns())
    }
}

/// Runs probe `probe` (see [`known`]).
pub(crate) fn run(probe: &str, ctx: &mut Ctx) -> Result<(), String> {
    match probe {
        "lifecycle" => lifecycle(ctx),
        "reproducible" => reproducible(ctx)?,
        "arguments" => state_machine::arguments(ctx),
        "strings" => strings::strings(ctx),
        "fmu-state" => fmu_state(ctx, false),
        "serialize" => fmu_state(ctx, true),
        "variable-step" => variable_step(ctx),
        "threads" => threads(ctx)?,
        other => {
            let state =
                other.strip_prefix("state-machine:").and_then(State::from_name).ok_or_else(|| format!("unknown probe {other:?}"))?;
            state_machine::state(ctx, state);
        }
    }
    Ok(())
}

/// A GUID surely not the FMU's: the same length and form, one digit changed.
fn wrong_guid(guid: &str) -> String {
    let mut chars: Vec<char> = guid.chars().collect();
    match chars.iter().rposition(|c| c.is_ascii_hexdigit()) {
        Some(i) => {
            chars[i] = if chars[i] == '0' { '1' } else { '0' };
            chars.into_iter().collect()
        }
        None => format!("{guid}-not-this-one"),
    }
}

/// How a run went, for the passed messages.
fn described(run: &Run) -> String {
    let grid = &run.grid;
    let how = match run.inst.interface() {
        Interface::CoSimulation => format!("{} fmi2DoStep calls of {} s", run.k, grid.h),
        Interface::ModelExchange => format!("integrated by the validator (RK4) over {} steps of {} s", run.k, grid.h),
    };
    let mut text = format!("{how} from t = {} to t = {}", grid.start, run.t);
    if let Some(why) = &run.ended {
        text.push_str(&format!(" (the model ended the run: {why})"));
    }
    if grid.shortened {
        text.push_str(&format!(", the first {} steps of the DefaultExperiment", super::model::MAX_STEPS));
    }
    text
}

/// Instantiate with the right GUID and refuse a wrong one; initialize, run through the
/// DefaultExperiment, terminate, reset and run again, free. Writes the reference run.
fn lifecycle(ctx: &mut Ctx) {
    let fmu = ctx.fmu;
    let interface = fmu.interface;
    if ctx.cell("lifecycle.guid", Severity::Error) {
        match fmu.instantiate(NAME, 0) {
            Err((code, log)) => {
                let what = if code == super::raw::Code::MISSING { "is not exported" } else { "returned NULL with the FMU's own GUID" };
                let failure = Failure { log, ..Failure::new(format!("fmi2Instantiate {what}, so nothing can run")) }
                    .at_instantiate()
                    .value(fmu.model.md.guid.clone());
                ctx.fail("lifecycle.guid", failure);
                return;
            }
            Ok(mut inst) => inst.free(),
        }
        let wrong = wrong_guid(&fmu.model.md.guid);
        let c_wrong = std::ffi::CString::new(wrong.clone()).expect("a GUID without NUL");
        if let Ok(mut inst) = fmu.instantiate_as(NAME, interface, &c_wrong, 0) {
            inst.free();
            ctx.fail(
                "lifecycle.guid",
                Failure::new(
                    "fmi2Instantiate accepted a wrong GUID: it must refuse a modelDescription.xml that does not belong to its binary",
                )
                .at_instantiate()
                .value(wrong),
            );
        }
        let other = interface.other();
        let declared = match other {
            Interface::CoSimulation => fmu.model.md.co_simulation.is_some(),
            Interface::ModelExchange => fmu.model.md.model_exchange.is_some(),
        };
        if !declared {
            if let Ok(mut inst) = fmu.instantiate_as(NAME, other, &fmu.guid, 0) {
                inst.free();
                ctx.warn(
                    "lifecycle.guid",
                    Failure::new(format!("fmi2Instantiate created a {} instance, an interface the FMU does not declare", other.title()))
                        .at_instantiate()
                        .value(format!("fmuType {}", other.title())),
                );
            }
        }
        ctx.pass("lifecycle.guid", "fmi2Instantiate accepts the FMU's GUID and refuses a wrong one");
    }
    if !ctx.cell("lifecycle.run", Severity::Error) {
        return;
    }
    let mut run = match Run::start(fmu, NAME, 0) {
        Ok(run) => run,
        Err(f) => return ctx.fail("lifecycle.run", f),
    };
    if let Err(f) = run.run_to_end() {
        return ctx.fail("lifecycle.run", f);
    }
    if let Err(f) = run.terminate() {
        return ctx.fail("lifecycle.run", f);
    }
    let first = run.trajectory.clone();
    let first_ended = run.ended.clone();
    match first.first_non_finite() {
        Some((t, column, value)) => ctx.fail(
            "health.finite",
            Failure::new(format!("output {column} is {value} at t = {t}: outputs must be finite"))
                .variable(column.to_owned())
                .value(value.to_string())
                .at(super::run::got_function(super::model::Base::Real), State::StepComplete),
        ),
        None => {
            let all = fmu.model.recordable_count();
            let of = if all > first.columns.len() { format!(" (the first {} of {all})", first.columns.len()) } else { String::new() };
            ctx.pass(
                "health.finite",
                format!("all {} recorded outputs{of} finite at all {} communication points", first.columns.len(), first.rows()),
            )
        }
    }
    if let Err(e) = first.save(&ctx.reference_path()) {
        ctx.fail("lifecycle.run", Failure::new(format!("the validator could not keep the run: {e}")));
    }
    ctx.pass("lifecycle.run", format!("instantiated, initialized, {}, terminated", described(&run)));
    if interface == Interface::ModelExchange {
        model_exchange_findings(ctx, &run);
    }
    if !ctx.cell("lifecycle.reset", Severity::Error) {
        return;
    }
    let again = run.reset().and_then(|()| run.run_to_end()).and_then(|()| run.terminate());
    match again {
        Err(f) => ctx.fail("lifecycle.reset", f),
        Ok(()) => match first.difference(&run.trajectory, "the first run", "the run after fmi2Reset") {
            Some(f) => {
                let why = match (&run.ended, &first_ended) {
                    (Some(now), None) => format!("; the model ended the second run: {now}"),
                    (Some(now), Some(then)) if now != then => format!("; the model ended the second run: {now}"),
                    _ => String::new(),
                };
                let message = format!("fmi2Reset did not bring back the instance fmi2Instantiate gave: {}{why}", f.message);
                ctx.fail("lifecycle.reset", Failure { message, ..f }.at(super::table::Function::Reset, State::Terminated));
            }
            None => {
                run.inst.free();
                ctx.pass("lifecycle.reset", "after fmi2Reset a second run equals the first bit for bit; fmi2FreeInstance returned");
            }
        },
    }
}

/// What the Model Exchange reference run showed about derivatives and events.
fn model_exchange_findings(ctx: &mut Ctx, run: &Run) {
    let derivatives = run.start_derivatives();
    if ctx.fmu.model.nx() == 0 {
        ctx.skip("model-exchange.derivatives", "the FMU has no continuous states");
    } else {
        ctx.pass(
            "model-exchange.derivatives",
            format!(
                "fmi2GetDerivatives at t = {}: all {} finite ({})",
                run.grid.start,
                derivatives.len(),
                super::raw::numbers(derivatives)
            ),
        );
    }
    let events = run.events();
    ctx.pass(
        "model-exchange.event-iteration",
        format!(
            "the event iteration converged at the start and at each of {} events, in at most {} fmi2NewDiscreteStates calls",
            events.len(),
            run.most_iterations().max(1)
        ),
    );
    let state_events: Vec<&(f64, Option<usize>)> = events.iter().filter(|(_, i)| i.is_some()).collect();
    if ctx.fmu.model.event_indicators == 0 {
        ctx.skip("model-exchange.state-events", "the FMU has no event indicators");
    } else if let Some((t, Some(i))) = state_events.first() {
        ctx.pass(
            "model-exchange.state-events",
            format!(
                "{} state event(s) located by bisection and handled (the first at t = {t}, event indicator {}); the integration continued past each",
                state_events.len(),
                i + 1
            ),
        );
    } else {
        ctx.skip("model-exchange.state-events", "no event indicator changed domain during the DefaultExperiment");
    }
}

/// Two identical runs (this one in a new process) and a run under another instance name must
/// equal the reference run bit for bit.
fn reproducible(ctx: &mut Ctx) -> Result<(), String> {
    let reference = ctx.reference()?;
    for (check, name, what) in [
        ("health.reproducible", NAME, "a second, identical run in a new process"),
        ("health.instance-name", OTHER_NAME, "a run of an instance named \"second instance, another name\""),
    ] {
        if !ctx.cell(check, Severity::Error) {
            continue;
        }
        let mut run = match Run::start(ctx.fmu, name, 0) {
            Ok(run) => run,
            Err(f) => {
                ctx.fail(check, f);
                continue;
            }
        };
        match run.run_to_end().and_then(|()| run.terminate()) {
            Err(f) => ctx.fail(check, f),
            Ok(()) => match reference.difference(&run.trajectory, "the first run", what) {
                Some(f) => ctx.fail(check, f),
                None => ctx.pass(check, format!("{what} equals the first bit for bit ({} points)", reference.rows())),
            },
        }
    }
    Ok(())
}

/// Get/set (or serialized) FMU state: a state saved halfway and restored must reproduce the
/// continuation bit for bit.
fn fmu_state(ctx: &mut Ctx, serialized: bool) {
    let check = if serialized { "capability.serialize" } else { "capability.fmu-state" };
    if !ctx.cell(check, Severity::Error) {
        return;
    }
    let caps = capabilities(ctx.fmu);
    let declared = if serialized { caps.1 } else { caps.0 };
    if !declared {
        let flag = if serialized { "canSerializeFMUstate" } else { "canGetAndSetFMUstate" };
        return ctx.skip(check, format!("the FMU declares {flag}=false"));
    }
    // Ok(None): not exercised.
    let result = (|| -> Result<Option<String>, Failure> {
        let mut run = Run::start(ctx.fmu, NAME, 0)?;
        let half = (run.grid.steps / 2).max(1);
        while run.k < half && !run.done() {
            run.step()?;
        }
        if run.done() {
            return Ok(None);
        }
        let t_saved = run.t;
        let mut saved = run.save()?;
        let mut bytes = Vec::new();
        if serialized {
            let state = run.inst.state;
            let got = run.inst.serialize(saved.fmu_state);
            bytes = super::run::expect_ok(got, super::table::Function::SerializeFmuState, state)?;
            let freed = run.inst.free_fmu_state(&mut saved.fmu_state);
            super::run::expect_ok(freed, super::table::Function::FreeFmuState, state)?;
        }
        run.run_to_end()?;
        let first = run.trajectory.clone();
        let mut restored = saved;
        if serialized {
            let state = run.inst.state;
            let got = run.inst.deserialize(&bytes);
            restored.fmu_state = super::run::expect_ok(got, super::table::Function::DeSerializeFmuState, state)?;
        }
        run.restore(&restored)?;
        run.run_to_end()?;
        let state = run.inst.state;
        let freed = run.inst.free_fmu_state(&mut restored.fmu_state);
        super::run::expect_ok(freed, super::table::Function::FreeFmuState, state)?;
        let how = if serialized { "serialized (fmi2SerializeFMUstate), deserialized and set" } else { "restored with fmi2SetFMUstate" };
        match first.difference(&run.trajectory, "the first continuation", "the continuation after the restore") {
            Some(f) => Err(Failure {
                message: format!("the state saved at t = {t_saved} and {how} does not reproduce the continuation: {}", f.message),
                ..f
            }),
            None => {
                Ok(Some(format!("the state saved at t = {t_saved} and {how} reproduces the continuation to t = {} bit for bit", run.t)))
            }
        }
    })();
    match result {
        Ok(Some(message)) => ctx.pass(check, message),
        Ok(None) => ctx.skip(check, "not exercised: the model ended the run before its half-way point"),
        Err(f) => ctx.fail(check, f),
    }
}

/// (canGetAndSetFMUstate, canSerializeFMUstate, canBeInstantiatedOnlyOncePerProcess) of the
/// probed interface.
pub(crate) fn capabilities(fmu: &Fmu) -> (bool, bool, bool) {
    let md = &fmu.model.md;
    let common = match fmu.interface {
        Interface::CoSimulation => md.co_simulation.as_ref().map(|c| &c.common),
        Interface::ModelExchange => md.model_exchange.as_ref().map(|m| &m.common),
    };
    common.map_or((false, false, true), |c| {
        (c.can_get_and_set_fmu_state, c.can_serialize_fmu_state, c.can_be_instantiated_only_once_per_process)
    })
}

/// With canHandleVariableCommunicationStepSize, steps of varying size (0.25 to 1.75 times the
/// step size) must all succeed and give finite outputs.
fn variable_step(ctx: &mut Ctx) {
    const CHECK: &str = "capability.variable-step";
    if !ctx.cell(CHECK, Severity::Error) {
        return;
    }
    let declared = ctx.fmu.model.md.co_simulation.as_ref().is_some_and(|c| c.can_handle_variable_communication_step_size);
    if !declared {
        return ctx.skip(CHECK, "the FMU declares canHandleVariableCommunicationStepSize=false: every run used the constant step size");
    }
    let result = (|| -> Result<String, Failure> {
        let mut run = Run::start(ctx.fmu, NAME, 0)?;
        let grid: Grid = run.grid;
        let end = grid.end();
        let factors = [0.5, 1.5, 1.0, 0.25, 1.75];
        let mut steps = 0;
        while run.t < end && run.ended.is_none() {
            let mut next = run.t + factors[steps % factors.len()] * grid.h;
            if next > end || end - next < 1e-9 * grid.h {
                next = end;
            }
            run.step_to(next)?;
            steps += 1;
        }
        run.terminate()?;
        if let Some((t, column, value)) = run.trajectory.first_non_finite() {
            return Err(Failure::new(format!("with varying step sizes, output {column} is {value} at t = {t}")).variable(column.to_owned()));
        }
        Ok(format!("{steps} fmi2DoStep calls of 0.25 to 1.75 times {} s reached t = {} with finite outputs", grid.h, run.t))
    })();
    match result {
        Ok(message) => ctx.pass(CHECK, message),
        Err(f) => ctx.fail(CHECK, f),
    }
}

/// Instances running at once on threads must give what the sequential reference run gave.
fn threads(ctx: &mut Ctx) -> Result<(), String> {
    const CHECK: &str = "capability.threads";
    const INSTANCES: usize = 3;
    if !ctx.cell(CHECK, Severity::Error) {
        return Ok(());
    }
    if capabilities(ctx.fmu).2 {
        ctx.skip(CHECK, "the FMU declares canBeInstantiatedOnlyOncePerProcess=true");
        return Ok(());
    }
    let reference = ctx.reference()?;
    let fmu = ctx.fmu;
    let results = crate::concurrent::concurrently(
        INSTANCES,
        |i| -> Result<Trajectory, Failure> {
            let mut run = Run::start(fmu, NAME, i + 1)?;
            run.run_to_end()?;
            run.terminate()?;
            Ok(run.trajectory.clone())
        },
        || Failure::new("the validator's thread panicked"),
    );
    for (i, result) in results.into_iter().enumerate() {
        let what = format!("instance {} of {INSTANCES} running at once on threads", i + 1);
        match result {
            Err(f) => ctx.fail(CHECK, Failure { message: format!("{what}: {}", f.message), ..f }),
            Ok(t) => {
                if let Some(f) = reference.difference(&t, "the sequential run", &what) {
                    ctx.fail(CHECK, f);
                }
            }
        }
    }
    ctx.pass(CHECK, format!("{INSTANCES} instances running at once on {INSTANCES} threads each equal the sequential run bit for bit"));
    Ok(())
}
