//! The run through the DefaultExperiment, which the other probes build on: instantiate with
//! the FMU's own token and refuse a wrong one; initialize, run, terminate, reset and run again,
//! free (`lifecycle`, which writes the reference run); and the same run again in a new process
//! and under another instance name (`reproducible`). Each must equal the first bit for bit.

use crate::failure::Failure;
use crate::fmi::{numbers, Fmi, Interface, Op, State, Version};
use crate::model::MAX_STEPS;
use crate::probe::{instantiate_check, Ctx, NAME};
use crate::report::Severity;
use crate::run::{Run, Trajectory};

/// Another instance name: the results must not depend on it.
const OTHER_NAME: &str = "second instance, another name";

/// A token surely not the FMU's: the same length and form, one character changed.
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

/// How a run went, for the passed messages.
fn described(ctx: &Ctx, run: &Run) -> String {
    let grid = &run.grid;
    let how = match ctx.interface {
        Interface::CoSimulation => {
            let capabilities = ctx.model().capabilities(Interface::CoSimulation);
            format!(
                "{} {} calls of {} s{}{}",
                run.k,
                run.inst.core().name(Op::DoStep),
                grid.h,
                if capabilities.event_mode { ", with Event Mode" } else { "" },
                if capabilities.early_return { ", early return allowed" } else { "" }
            )
        }
        Interface::ModelExchange => format!("integrated by the validator (RK4) over {} steps of {} s", run.k, grid.h),
    };
    let mut text = format!("{how} from t = {} to t = {}", grid.start, run.t);
    if let Some(why) = &run.ended {
        text.push_str(&format!(" (the model ended the run: {why})"));
    }
    if grid.shortened {
        text.push_str(&format!(", the first {MAX_STEPS} steps of the DefaultExperiment"));
    }
    text
}

/// Instantiate with the right token and refuse a wrong one; initialize, run through the
/// DefaultExperiment, terminate, reset and run again, free. Writes the reference run.
pub(super) fn lifecycle(ctx: &mut Ctx) {
    if ctx.cell(instantiate_check(ctx.fmi()), Severity::Error) && !instantiation(ctx) {
        return;
    }
    if !ctx.cell("lifecycle.run", Severity::Error) {
        return;
    }
    let mut run = match Run::start(ctx, NAME, 0) {
        Ok(run) => run,
        Err(f) => return ctx.fail("lifecycle.run", f),
    };
    if let Err(f) = run.run_to_end().and_then(|()| run.terminate()) {
        return ctx.fail("lifecycle.run", f);
    }
    let first = run.trajectory.clone();
    let first_ended = run.ended.clone();
    match first.first_non_finite() {
        Some((t, column, value)) => {
            let call = run.inst.core().name(Op::Get(crate::fmi::Type::Real));
            let step = ctx.binary.table().between_steps;
            ctx.fail(
                "health.finite",
                Failure::new(format!("output {column} is {value} at t = {t}: outputs must be finite"))
                    .variable(column.to_owned())
                    .value(value.to_string())
                    .at(call, step),
            )
        }
        None => {
            let all = ctx.model().recordable_count();
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
    let how = described(ctx, &run);
    ctx.pass("lifecycle.run", format!("instantiated, initialized, {how}, terminated"));
    if ctx.interface == Interface::ModelExchange {
        model_exchange_findings(ctx, &run);
    }
    if !ctx.cell("lifecycle.reset", Severity::Error) {
        return;
    }
    let reset = run.inst.core().name(Op::Reset);
    let again = run.reset().and_then(|()| run.run_to_end()).and_then(|()| run.terminate());
    match again {
        Err(f) => ctx.fail("lifecycle.reset", f),
        Ok(()) => match first.difference(&run.trajectory, "the first run", &format!("the run after {reset}")) {
            Some(f) => {
                let why = match (&run.ended, &first_ended) {
                    (Some(now), None) => format!("; the model ended the second run: {now}"),
                    (Some(now), Some(then)) if now != then => format!("; the model ended the second run: {now}"),
                    _ => String::new(),
                };
                let instantiate = ctx.binary.table().name(Op::Instantiate, ctx.interface);
                let message = format!("{reset} did not bring back the instance {instantiate} gave: {}{why}", f.message);
                ctx.fail("lifecycle.reset", Failure { message, ..f }.at(reset, State::Terminated));
            }
            None => {
                run.inst.free();
                let free = run.inst.core().name(Op::FreeInstance);
                ctx.pass("lifecycle.reset", format!("after {reset} a second run equals the first bit for bit; {free} returned"));
            }
        },
    }
}

/// The instantiation cell: the FMU's own token accepted, a wrong one and an undeclared
/// interface refused. False when nothing can run.
fn instantiation(ctx: &mut Ctx) -> bool {
    let check = instantiate_check(ctx.fmi());
    let (fmi, interface, model) = (ctx.fmi(), ctx.interface, ctx.model());
    let token = fmi.token();
    match ctx.instantiate(NAME, 0) {
        Err(f) => {
            let message = format!("{}, so nothing can run", f.message);
            ctx.fail(check, Failure { message, value: Some(model.token.clone()), ..f });
            return false;
        }
        Ok(mut inst) => inst.free(),
    }
    let call = ctx.binary.table().name(Op::Instantiate, interface);
    let wrong = wrong_token(&model.token);
    if let Ok(mut inst) = ctx.binary.instantiate(NAME, interface, &wrong, 0) {
        inst.free();
        let failure = match fmi {
            // FMI 2.0: the GUID "is used to check that the modelDescription.xml file is
            // compatible with the C code", which a binary that accepts any GUID does not.
            Fmi::Fmi2 | Fmi::Fmi1 => (Severity::Error, format!("{call} accepted a wrong GUID: it must refuse a modelDescription.xml that does not belong to its binary")),
            // FMI 3.0 lets the FMU check it: a warning.
            Fmi::Fmi3 => (
                Severity::Warning,
                "a wrong instantiationToken was accepted: the standard lets the FMU check it (\"can be used by the FMU to check that the modelDescription.xml file is compatible\"), and a binary that does not check it runs with any description".to_owned(),
            ),
        };
        let found = Failure::new(failure.1).at_instantiate(call).value(wrong);
        ctx.report(found.finding(check, failure.0));
    }
    let other = match interface {
        Interface::CoSimulation => Interface::ModelExchange,
        Interface::ModelExchange => Interface::CoSimulation,
    };
    if model.interface(other).is_none() && ctx.binary.table().functions(other).next().is_some() {
        if let Ok(mut inst) = ctx.binary.instantiate(NAME, other, &model.token, 0) {
            inst.free();
            let other_call = ctx.binary.table().name(Op::Instantiate, other);
            ctx.warn(
                check,
                Failure::new(format!("{other_call} created a {} instance, an interface the FMU does not declare", other.title()))
                    .at_instantiate(other_call)
                    .value(format!("fmuType {}", other.title())),
            );
        }
    }
    ctx.pass(check, format!("{call} accepts the FMU's {token} and refuses a wrong one"));
    true
}

/// What the Model Exchange reference run showed about derivatives and events.
fn model_exchange_findings(ctx: &mut Ctx, run: &Run) {
    let Some(me) = run.exchange() else { return };
    let derivatives = me.start_derivatives();
    if ctx.model().nx() == 0 {
        ctx.skip("model-exchange.derivatives", "the FMU has no continuous states");
    } else {
        let call = run.inst.core().name(Op::GetDerivatives);
        let message = format!("{call} at t = {}: all {} finite ({})", run.grid.start, derivatives.len(), numbers(derivatives));
        ctx.pass("model-exchange.derivatives", message);
    }
    let events = me.events();
    let update = run.inst.core().name(Op::UpdateDiscreteStates);
    ctx.pass(
        "model-exchange.event-iteration",
        format!(
            "the event iteration converged at the start and at each of {} events, in at most {} {update} calls",
            events.len(),
            me.most_iterations().max(1)
        ),
    );
    let state_events: Vec<&(f64, Option<usize>)> = events.iter().filter(|(_, i)| i.is_some()).collect();
    if ctx.model().nz() == 0 {
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
pub(super) fn reproducible(ctx: &mut Ctx) -> Result<(), String> {
    let reference = Trajectory::reference(ctx)?;
    for (check, name, what) in [
        ("health.reproducible", NAME, "a second, identical run in a new process"),
        ("health.instance-name", OTHER_NAME, "a run of an instance named \"second instance, another name\""),
    ] {
        if !ctx.cell(check, Severity::Error) {
            continue;
        }
        let mut run = match Run::start(ctx, name, 0) {
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

#[cfg(test)]
mod tests {
    use super::*;

    use crate::fmi::Fmi;
    use crate::report::Severity;
    use crate::testing::{Fake, Fault, Probed};

    /// A correct FMU runs clean on both interfaces of both versions, and leaves the reference
    /// run the other probes compare with; the runs in a new process and under another name
    /// equal it.
    #[test]
    fn a_correct_fmu_runs_clean_and_reproducibly() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            for interface in [Interface::CoSimulation, Interface::ModelExchange] {
                let probed = Probed::new();
                let fake = Fake::new(fmi, &[]);
                lifecycle(&mut probed.ctx(fake, interface));
                reproducible(&mut probed.ctx(fake, interface)).unwrap();
                assert_eq!(probed.troubles(), Vec::<(String, String, String)>::new(), "{fmi:?} {interface:?}");
                let passed: Vec<String> =
                    probed.findings().into_iter().filter(|f| f.severity == Severity::Passed).map(|f| f.check).collect();
                for check in [
                    instantiate_check(fmi),
                    "lifecycle.run",
                    "lifecycle.reset",
                    "health.finite",
                    "health.reproducible",
                    "health.instance-name",
                ] {
                    assert!(passed.iter().any(|c| c == check), "{fmi:?} {interface:?}: {check} in {passed:?}");
                }
                assert!(probed.ctx(fake, interface).reference_path().is_file());
            }
        }
    }

    /// A reset that keeps where the run got to: the second run differs at its start, and the
    /// error names fmi2Reset (fmi3Reset) and the variable.
    #[test]
    fn a_reset_that_keeps_the_run_is_caught() {
        for (fmi, call) in [(Fmi::Fmi2, "fmi2Reset"), (Fmi::Fmi3, "fmi3Reset")] {
            let probed = Probed::new();
            lifecycle(&mut probed.ctx(Fake::new(fmi, &[Fault::Reset]), Interface::CoSimulation));
            assert_eq!(probed.troubles(), [("lifecycle.reset".to_owned(), call.to_owned(), "Terminated".to_owned())]);
            let error = probed.findings().into_iter().find(|f| f.severity == Severity::Error).unwrap();
            assert_eq!(error.variable.as_deref(), Some("x"));
        }
    }

    #[test]
    fn a_wrong_token_differs_from_the_right_one_in_one_character() {
        assert_eq!(wrong_token("{5a0b6c1e-2f47-4d8e-9b3a-71c2d4e6f801}"), "{5a0b6c1e-2f47-4d8e-9b3a-71c2d4e6f800}");
        for token in ["{7d1c2f40-5b8e-4c3a-9f61-0e2d4b6a8c13}", "0", "{}", "abc"] {
            let wrong = wrong_token(token);
            assert_ne!(wrong, token);
        }
        assert_eq!(wrong_token("{}"), "{}-not-this-one");
    }
}
