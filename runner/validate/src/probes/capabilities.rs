//! The probes of what an FMU declares it can do, each run only where it declares it:
//!
//! - `fmu-state` / `serialize`: with canGetAndSetFMUstate (canSerializeFMUstate), a state saved
//!   half-way (serialized, the original freed, and deserialized) and restored must continue bit
//!   for bit as the run did, and FreeFMUState must give back NULL (FMI 2.0 and 3.0: "The
//!   function returns a null pointer in argument FMUstate").
//! - `variable-step`: with canHandleVariableCommunicationStepSize, steps of varying size must
//!   all succeed and give finite outputs.
//! - `threads`: unless canBeInstantiatedOnlyOncePerProcess, instances running at once on
//!   threads must each give the sequential run's bits.

use crate::failure::Failure;
use crate::fmi::{Interface, Op, Version};
use crate::instance::{FmuState, Instance};
use crate::probe::{Ctx, NAME};
use crate::report::Severity;
use crate::run::{Run, Trajectory};

/// The largest serialized FMU state the validator allocates (1 GiB): a larger size is taken
/// for garbage.
const MAX_SERIALIZED: usize = 1 << 30;

/// Instances the threads probe runs at once.
const INSTANCES: usize = 3;

/// SerializedFMUStateSize then SerializeFMUState: the bytes of `state`.
pub(crate) fn serialize(inst: &mut dyn Instance, state: FmuState) -> Result<Vec<u8>, Failure> {
    let now = inst.core().state;
    let size = inst.serialized_fmu_state_size(state);
    let n = inst.core().expect(size, Op::SerializedFmuStateSize, now)?;
    if n > MAX_SERIALIZED {
        let name = inst.core().name(Op::SerializedFmuStateSize);
        return Err(Failure::new(format!("{name} reported {n} bytes, more than the validator's limit of {MAX_SERIALIZED}")).at(name, now));
    }
    let mut bytes = vec![0u8; n];
    let got = inst.serialize_fmu_state(state, &mut bytes);
    inst.core().expect(got, Op::SerializeFmuState, now)?;
    Ok(bytes)
}

/// FreeFMUState, which must succeed and give back NULL.
pub(crate) fn free(inst: &mut dyn Instance, state: &mut FmuState) -> Result<(), Failure> {
    let now = inst.core().state;
    let freed = inst.free_fmu_state(state);
    inst.core().expect(freed, Op::FreeFmuState, now)?;
    if !state.is_null() {
        let name = inst.core().name(Op::FreeFmuState);
        return Err(Failure::new(format!(
            "{name} returned without setting the FMU state argument to NULL (\"The function returns a null pointer in argument FMUstate\")"
        ))
        .at(name, now));
    }
    Ok(())
}

/// Get/set (or serialized) FMU state: a state saved halfway and restored must reproduce the
/// continuation bit for bit.
pub(super) fn fmu_state(ctx: &mut Ctx, serialized: bool) {
    let check = if serialized { "capability.serialize" } else { "capability.fmu-state" };
    if !ctx.cell(check, Severity::Error) {
        return;
    }
    let capabilities = ctx.model().capabilities(ctx.interface);
    let declared = if serialized { capabilities.can_serialize_fmu_state } else { capabilities.can_get_and_set_fmu_state };
    if !declared {
        return ctx.skip(check, format!("the FMU declares {}=false", ctx.fmi().fmu_state_flag(serialized)));
    }
    match round_trip(ctx, serialized) {
        Ok(Some(message)) => ctx.pass(check, message),
        Ok(None) => ctx.skip(check, "not exercised: the model ended the run before its half-way point"),
        Err(f) => ctx.fail(check, f),
    }
}

/// The round trip of [`fmu_state`]: `Ok(None)` when the run ended before the half-way point.
fn round_trip(ctx: &Ctx, serialized: bool) -> Result<Option<String>, Failure> {
    let mut run = Run::start(ctx, NAME, 0)?;
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
        bytes = serialize(run.inst.as_mut(), saved.fmu_state)?;
        free(run.inst.as_mut(), &mut saved.fmu_state)?;
    }
    run.run_to_end()?;
    let first = run.trajectory.clone();
    let mut restored = saved;
    if serialized {
        let state = run.inst.core().state;
        let got = run.inst.deserialize_fmu_state(&bytes);
        restored.fmu_state = run.inst.core().expect(got, Op::DeserializeFmuState, state)?;
        if restored.fmu_state.is_null() {
            let name = run.inst.core().name(Op::DeserializeFmuState);
            return Err(Failure::new(format!("{name} returned OK but no FMU state (NULL)")).at(name, state));
        }
    }
    run.restore(&restored)?;
    run.run_to_end()?;
    free(run.inst.as_mut(), &mut restored.fmu_state)?;
    let (core, set) = (run.inst.core(), run.inst.core().name(Op::SetFmuState));
    let how = if serialized {
        format!("serialized ({}), deserialized and set", core.name(Op::SerializeFmuState))
    } else {
        format!("restored with {set}")
    };
    match first.difference(&run.trajectory, "the first continuation", "the continuation after the restore") {
        Some(f) => Err(Failure {
            message: format!("the state saved at t = {t_saved} and {how} does not reproduce the continuation: {}", f.message),
            ..f
        }),
        None => Ok(Some(format!("the state saved at t = {t_saved} and {how} reproduces the continuation to t = {} bit for bit", run.t))),
    }
}

/// With canHandleVariableCommunicationStepSize, steps of varying size (0.25 to 1.75 times the
/// step size) must all succeed and give finite outputs.
pub(super) fn variable_step(ctx: &mut Ctx) {
    const CHECK: &str = "capability.variable-step";
    if !ctx.cell(CHECK, Severity::Error) {
        return;
    }
    if !ctx.model().capabilities(Interface::CoSimulation).can_handle_variable_communication_step_size {
        return ctx.skip(CHECK, "the FMU declares canHandleVariableCommunicationStepSize=false: every run used the constant step size");
    }
    let result = (|| -> Result<String, Failure> {
        let mut run = Run::start(ctx, NAME, 0)?;
        let grid = run.grid;
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
        let call = run.inst.core().name(Op::DoStep);
        Ok(format!("{steps} {call} calls of 0.25 to 1.75 times {} s reached t = {} with finite outputs", grid.h, run.t))
    })();
    match result {
        Ok(message) => ctx.pass(CHECK, message),
        Err(f) => ctx.fail(CHECK, f),
    }
}

/// Instances running at once on threads must give what the sequential reference run gave.
pub(super) fn threads(ctx: &mut Ctx) -> Result<(), String> {
    const CHECK: &str = "capability.threads";
    if !ctx.cell(CHECK, Severity::Error) {
        return Ok(());
    }
    if ctx.model().capabilities(ctx.interface).can_be_instantiated_only_once_per_process {
        ctx.skip(CHECK, "the FMU declares canBeInstantiatedOnlyOncePerProcess=true");
        return Ok(());
    }
    let reference = Trajectory::reference(ctx)?;
    let shared: &Ctx = ctx;
    let results = concurrently(
        INSTANCES,
        |i| -> Result<Trajectory, Failure> {
            let mut run = Run::start(shared, NAME, i + 1)?;
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

/// Runs `work(0)` .. `work(n - 1)` each on its own thread, all at once, and gives their
/// results in order; a thread that panicked gives `panicked()` instead.
fn concurrently<T: Send, E: Send>(n: usize, work: impl Fn(usize) -> Result<T, E> + Sync, panicked: impl Fn() -> E) -> Vec<Result<T, E>> {
    let work = &work;
    std::thread::scope(|scope| {
        let handles: Vec<_> = (0..n).map(|i| scope.spawn(move || work(i))).collect();
        handles.into_iter().map(|h| h.join().unwrap_or_else(|_| Err(panicked()))).collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::fmi::Fmi;
    use crate::testing::{Fake, Probed};

    /// The FMU-state round trips, the varying steps and the threads pass on an FMU that keeps
    /// its state, steps exactly and shares nothing between instances.
    #[test]
    fn a_capable_fmu_passes_the_capability_probes() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            for interface in [Interface::CoSimulation, Interface::ModelExchange] {
                let probed = Probed::new();
                let fake = Fake::new(fmi, &[]);
                super::super::lifecycle::lifecycle(&mut probed.ctx(fake, interface));
                let mut ctx = probed.ctx(fake, interface);
                fmu_state(&mut ctx, false);
                fmu_state(&mut ctx, true);
                threads(&mut ctx).unwrap();
                if interface == Interface::CoSimulation {
                    variable_step(&mut ctx);
                }
                assert_eq!(probed.troubles(), Vec::<(String, String, String)>::new(), "{fmi:?} {interface:?}");
                let passed: Vec<String> =
                    probed.findings().into_iter().filter(|f| f.severity == Severity::Passed).map(|f| f.check).collect();
                for check in ["capability.fmu-state", "capability.serialize", "capability.threads"] {
                    assert!(passed.iter().any(|c| c == check), "{fmi:?} {interface:?}: {check} in {passed:?}");
                }
            }
        }
    }

    /// Every index runs once, results come back in index order, and a panicking thread becomes
    /// the given error rather than a panic of the caller.
    #[test]
    fn results_come_in_order_and_a_panic_is_an_error() {
        let got = concurrently(4, |i| if i == 2 { panic!("thread {i}") } else { Ok::<usize, String>(i * 10) }, || "panicked".to_owned());
        assert_eq!(got, vec![Ok(0), Ok(10), Err("panicked".to_owned()), Ok(30)]);
    }
}
