//! The arguments no importer should pass but some do, each call in a fresh instance after
//! initialization: zero-length arrays (nothing to do, which must succeed), value references
//! the FMU does not have (which the standard says must give Error), and NULL where the
//! standard requires an instance, an array or a pointer.
//!
//! For a NULL the standard fixes no status: it requires valid arguments, so a NULL is the
//! importer's error, which a robust FMU refuses with Error. Any other answer, and a crash, is
//! a warning, whoever made the FMU. For the FMUs this project builds a warning fails all the
//! same: tests/run validates them with --strict.

use super::capabilities::serialize;
use super::values::{changed, readable, snapshot};
use crate::failure::Failure;
use crate::fmi::{Code, Interface, Op, Outcome, State, Type, Version};
use crate::instance::{null_instance, FmuState, Instance};
use crate::model::Grid;
use crate::probe::Ctx;
use crate::report::Severity;
use crate::run::{after_initialization, reach};

/// One call of the arguments probe: the check, the get or set, NULL value references?, NULL
/// values?, the number of values claimed, the value reference passed.
struct Access {
    check: &'static str,
    op: Op,
    null_vrs: bool,
    null_values: bool,
    n: usize,
    vr: Option<u32>,
}

/// The probe: zero-length and NULL arrays, unknown value references, NULL instances and
/// pointers.
pub(super) fn arguments(ctx: &mut Ctx) {
    let (model, table, interface) = (ctx.model(), ctx.binary.table(), ctx.interface);
    let fmi = ctx.fmi();
    let error = Code::error_of(fmi).name();
    // After initialization, where values are read and inputs set.
    let state = after_initialization(ctx.binary, interface);
    let readable = readable(ctx, state);
    let unknown = model.unknown_vr();
    let mut accesses: Vec<Access> = Vec::new();
    for ty in Type::ALL {
        let (get, set) = (Op::Get(ty), Op::Set(ty));
        let readable_var = readable.iter().map(|&i| &model.vars[i]).find(|v| v.ty == ty);
        let settable_var = model.of(ty).find(|v| (table.may_set)(set, interface, state, v) == Some(true));
        for op in [get, set] {
            accesses.push(Access { check: "arguments.zero-length", op, null_vrs: true, null_values: true, n: 0, vr: None });
        }
        for op in [get, set] {
            accesses.push(Access { check: "arguments.null-arrays", op, null_vrs: true, null_values: false, n: 1, vr: None });
        }
        for op in [get, set] {
            accesses.push(Access { check: "arguments.unknown-vr", op, null_vrs: false, null_values: false, n: 1, vr: Some(unknown) });
        }
        for (op, var) in [(get, readable_var), (set, settable_var)] {
            if let Some(v) = var {
                accesses.push(Access { check: "arguments.null-arrays", op, null_vrs: false, null_values: true, n: 1, vr: Some(v.vr) });
            }
        }
    }
    // The Model Exchange vectors, and the sizes where the version asks for them.
    let (nx, nz) = (model.nx(), model.nz());
    let vectors: Vec<(Op, usize)> = match interface {
        Interface::ModelExchange => [
            (Op::GetContinuousStates, nx),
            (Op::GetDerivatives, nx),
            (Op::GetNominalsOfContinuousStates, nx),
            (Op::GetEventIndicators, nz),
            (Op::SetContinuousStates, nx),
            (Op::GetNumberOfContinuousStates, 1),
            (Op::GetNumberOfEventIndicators, 1),
        ]
        .into_iter()
        .filter(|(op, _)| table.has(*op))
        .collect(),
        Interface::CoSimulation => Vec::new(),
    };
    // Counted from the plan: after a crash another process runs the rest.
    let count = |check: &str| accesses.iter().filter(|a| a.check == check).count();
    let zero = count("arguments.zero-length") + vectors.iter().filter(|(_, n)| *n == 0).count();
    let null = count("arguments.null-arrays") + vectors.iter().filter(|(_, n)| *n > 0).count();
    let unknown_refused = count("arguments.unknown-vr");
    for access in accesses {
        let check = access.check;
        let crash = if check == "arguments.null-arrays" { Severity::Warning } else { Severity::Error };
        if !ctx.cell(check, crash) {
            continue;
        }
        let mut inst = match reach(ctx, state) {
            Ok(inst) => inst,
            Err(f) => return ctx.skip(check, format!("the state {} could not be reached: {}", state.name(), f.message)),
        };
        let before = snapshot(inst.as_mut(), model, &readable);
        let ty = access.op.access().expect("a get or a set").0;
        let variable = access.vr.map(|vr| match model.vars.iter().find(|v| v.vr == vr && v.ty == ty) {
            Some(v) => v.name.clone(),
            None => format!("value reference {vr} (no {} variable has it)", type_name(inst.as_ref(), ty)),
        });
        let value = Some(format!(
            "vr {}, nvr {}, value {}",
            if access.null_vrs { "NULL" } else { "a valid array" },
            access.n,
            if access.null_values { "NULL" } else { "a valid array" }
        ));
        let outcome = inst.raw_access(
            access.op,
            access.null_vrs,
            access.null_values,
            access.n,
            access.vr.unwrap_or(0),
            variable.as_deref(),
            value.clone(),
        );
        if outcome.code.is_missing() {
            continue;
        }
        let name = inst.core().name(access.op);
        let mut failure = Failure::new("").at(name, state).with_log(outcome.log.clone());
        failure.variable = variable.clone();
        failure.value = value.clone();
        let code = outcome.code.name();
        match check {
            "arguments.zero-length" => {
                if !outcome.code.ok() {
                    let message = format!("{name} with zero values (NULL arrays) returned {code}: nothing to do should succeed");
                    ctx.warn(check, Failure { message, ..failure.clone() });
                }
            }
            "arguments.null-arrays" => {
                if !outcome.code.is_error() {
                    let message = format!(
                        "{name} with a NULL array and {} value returned {code}; a robust FMU refuses it with {error} (the standard requires arrays of nvr elements, so this is the importer's error)",
                        access.n
                    );
                    ctx.warn(check, Failure { message, ..failure.clone() });
                    continue;
                }
            }
            _ => {
                if !outcome.code.is_error() {
                    let section = fmi.wrong_value_reference_section();
                    let message = format!(
                        "{name} of value reference {unknown}, which no variable has, returned {code}: the standard requires {error} for a wrong value reference ({section})"
                    );
                    ctx.fail(check, Failure { message, ..failure.clone() });
                    continue;
                }
            }
        }
        if check != "arguments.zero-length" && !before.is_empty() {
            let after = snapshot(inst.as_mut(), model, &readable);
            if let Some((changed_name, old, new)) = changed(&before, &after, model) {
                let message = format!(
                    "the refused {name} changed {changed_name} from {} to {}: a refused call must leave the instance as it was",
                    old.shown(),
                    new.shown()
                );
                ctx.fail(check, Failure { message, ..failure.clone() }.variable(changed_name));
            }
        }
    }
    for (op, n) in vectors {
        let check = if n == 0 { "arguments.zero-length" } else { "arguments.null-arrays" };
        if !ctx.cell(check, if n == 0 { Severity::Error } else { Severity::Warning }) {
            continue;
        }
        let mut inst = match reach(ctx, State::ContinuousTimeMode) {
            Ok(inst) => inst,
            Err(failure) => return ctx.skip(check, format!("the state ContinuousTimeMode could not be reached: {}", failure.message)),
        };
        let outcome = match op {
            Op::GetNumberOfContinuousStates | Op::GetNumberOfEventIndicators => inst.number_of(op, true).unit(),
            _ => inst.null_vector(op, n),
        };
        if outcome.code.is_missing() {
            continue;
        }
        let name = inst.core().name(op);
        let failure = Failure::new("").at(name, State::ContinuousTimeMode).value(format!("NULL, {n}")).with_log(outcome.log.clone());
        let code = outcome.code.name();
        if n == 0 && !outcome.code.ok() {
            ctx.warn(check, Failure { message: format!("{name} with zero values returned {code}"), ..failure });
        } else if n > 0 && !outcome.code.is_error() {
            let message = format!("{name} with a NULL array of {n} values returned {code}; a robust FMU refuses it with {error}");
            ctx.warn(check, Failure { message, ..failure });
        }
    }
    let null_instances = null_instance_cells(ctx, state);
    let null = null + null_pointer_cells(ctx, state);
    ctx.pass("arguments.zero-length", format!("{zero} calls with zero values and NULL arrays succeeded"));
    let free = table.name(Op::FreeInstance, interface);
    ctx.pass(
        "arguments.null-instance",
        format!("{null_instances} calls with {} refused with {error} ({free} ignored it)", null_instance(fmi)),
    );
    if null > 0 {
        ctx.pass(
            "arguments.null-arrays",
            format!("{null} calls with a NULL array and a nonzero length, or another NULL pointer, refused with {error}"),
        );
    }
    ctx.pass(
        "arguments.unknown-vr",
        format!("{unknown_refused} gets and sets of the unknown value reference {unknown} refused with {error}"),
    );
}

/// The version's name of a variable type (`Real`, `Float64`).
fn type_name(inst: &dyn Instance, ty: Type) -> &'static str {
    inst.core().name(Op::Get(ty)).trim_start_matches(inst.core().fmi().prefix()).trim_start_matches("Get")
}

/// The functions the NULL-instance cells call: every one the interface's table probes that
/// takes an instance, FreeInstance included: both standards say the call is ignored (FMI 2.0
/// section 2.1.5: "If a null pointer is provided for "c", the function call is ignored (does
/// not have an effect)"), so its only possible fault is a crash. The FMU state functions that
/// take a state or its bytes only where the FMU declares it can make them, so that the other
/// arguments are valid ones.
fn null_instance_functions(ctx: &Ctx) -> Vec<Op> {
    let capabilities = ctx.model().capabilities(ctx.interface);
    let (get_set, serialize) = (capabilities.can_get_and_set_fmu_state, capabilities.can_serialize_fmu_state);
    ctx.binary
        .table()
        .probed(ctx.interface)
        .filter(|op| match op {
            Op::GetTypesPlatform | Op::GetVersion | Op::Instantiate => false,
            Op::SetFmuState | Op::FreeFmuState => get_set,
            Op::SerializedFmuStateSize | Op::SerializeFmuState | Op::DeserializeFmuState => get_set && serialize,
            _ => true,
        })
        .collect()
}

/// What the FMU state functions are given besides the NULL instance: a state the instance
/// saved and its bytes.
struct Saved {
    state: FmuState,
    bytes: Vec<u8>,
}

/// Makes `op` on `inst` with valid arguments (the instance being in NULL-instance mode).
fn with_valid_arguments(inst: &mut dyn Instance, op: Op, saved: &Saved) -> Outcome<()> {
    let model = inst.core().model();
    let grid = Grid::new(&model.experiment, true);
    let first = |ty: Type| model.of(ty).next().map(|v| (vec![v.vr], v.name.clone())).unwrap_or((Vec::new(), "no variables".into()));
    match op {
        Op::SetDebugLogging => inst.set_debug_logging(false),
        Op::SetupExperiment => {
            inst.setup_experiment(&grid).unwrap_or(Outcome { code: Code::missing(inst.core().fmi()), value: (), log: None })
        }
        Op::EnterInitializationMode => inst.enter_initialization_mode(&grid),
        Op::DoStep => inst.do_step(grid.start, grid.h).unit(),
        Op::Get(Type::String) => {
            let (vrs, name) = first(Type::String);
            inst.get_strings(&vrs, &name).unit()
        }
        Op::Get(ty) => {
            let (vrs, name) = first(ty);
            inst.get_numbers(ty, &vrs, &name).unit()
        }
        Op::Set(Type::String) => {
            let (vrs, name) = first(Type::String);
            let values = vec!["runner validate".to_owned(); vrs.len()];
            inst.set_strings(&vrs, &values, &name)
        }
        Op::Set(ty) => {
            let (vrs, name) = first(ty);
            let values = vec![1.0; vrs.len()];
            inst.set_numbers(ty, &vrs, &values, &name)
        }
        Op::GetFmuState => inst.get_fmu_state().unit(),
        Op::SetFmuState => inst.set_fmu_state(saved.state),
        Op::FreeFmuState => {
            // A copy: the caller frees the state with the real instance afterwards.
            let mut state = saved.state;
            inst.free_fmu_state(&mut state)
        }
        Op::SerializedFmuStateSize => inst.serialized_fmu_state_size(saved.state).unit(),
        Op::SerializeFmuState => {
            let mut bytes = vec![0u8; saved.bytes.len()];
            inst.serialize_fmu_state(saved.state, &mut bytes)
        }
        Op::DeserializeFmuState => inst.deserialize_fmu_state(&saved.bytes).unit(),
        Op::GetDirectionalDerivative | Op::SetInputDerivatives | Op::GetOutputDerivatives | Op::Status(_) => inst.other(op),
        Op::UpdateDiscreteStates => inst.update_discrete_states().unit(),
        Op::CompletedIntegratorStep => inst.completed_integrator_step().unit(),
        Op::SetTime => inst.set_time(grid.start),
        Op::SetContinuousStates => inst.set_continuous_states(&vec![0.0; model.nx()]),
        Op::GetDerivatives | Op::GetEventIndicators | Op::GetContinuousStates | Op::GetNominalsOfContinuousStates => {
            let n = if op == Op::GetEventIndicators { model.nz() } else { model.nx() };
            inst.get_vector(op, n).unit()
        }
        Op::GetNumberOfContinuousStates | Op::GetNumberOfEventIndicators => inst.number_of(op, false).unit(),
        // ExitInitializationMode, Terminate, Reset, EnterEventMode, EnterContinuousTimeMode,
        // EnterStepMode, CancelStep, FreeInstance.
        _ => inst.simple(op),
    }
}

/// The NULL-instance cells, each on a fresh instance in `state`; returns how many there are
/// (counted from the plan: after a crash another process runs the rest).
fn null_instance_cells(ctx: &mut Ctx, state: State) -> usize {
    const CHECK: &str = "arguments.null-instance";
    let functions = null_instance_functions(ctx);
    let fmi = ctx.fmi();
    for &op in &functions {
        if !ctx.cell(CHECK, Severity::Warning) {
            continue;
        }
        let mut inst = match reach(ctx, state) {
            Ok(inst) => inst,
            Err(failure) => {
                ctx.skip(CHECK, format!("the state {} could not be reached: {}", state.name(), failure.message));
                return functions.len();
            }
        };
        let name = inst.core().name(op);
        // The state and bytes the state functions are given, saved with the real instance.
        let mut saved = Saved { state: std::ptr::null_mut(), bytes: Vec::new() };
        if op.takes_fmu_state() {
            let got = inst.get_fmu_state();
            if !got.code.ok() || got.value.is_null() {
                let get = inst.core().name(Op::GetFmuState);
                ctx.skip(CHECK, format!("{name} with {} not probed: {get} gave no state to pass", null_instance(fmi)));
                continue;
            }
            saved.state = got.value;
            if !matches!(op, Op::SetFmuState | Op::FreeFmuState) {
                match serialize(inst.as_mut(), saved.state) {
                    Ok(bytes) => saved.bytes = bytes,
                    Err(_) => {
                        let _ = inst.free_fmu_state(&mut saved.state);
                        let serialize = inst.core().name(Op::SerializeFmuState);
                        ctx.skip(CHECK, format!("{name} with {} not probed: {serialize} failed", null_instance(fmi)));
                        continue;
                    }
                }
            }
            inst.core_mut().state = state;
        }
        inst.core_mut().null_instance = true;
        let outcome = with_valid_arguments(inst.as_mut(), op, &saved);
        inst.core_mut().null_instance = false;
        // FreeFMUState accepted with a NULL instance may have freed the state already.
        let freed_already = op == Op::FreeFmuState && outcome.code.ok();
        if !saved.state.is_null() && !freed_already {
            let _ = inst.free_fmu_state(&mut saved.state);
        }
        // FreeInstance returns nothing: not crashing is all it can show.
        if outcome.code.is_missing() || op == Op::FreeInstance || outcome.code.is_error() {
            continue;
        }
        let instantiate = ctx.binary.table().name(Op::Instantiate, ctx.interface);
        let failure = Failure::new(format!(
            "{name} with {} returned {}; a robust FMU refuses it with {} (the standard requires the {} {instantiate} returned, so this is the importer's error)",
            null_instance(fmi),
            outcome.code.name(),
            Code::error_of(fmi).name(),
            fmi.instance_word()
        ))
        .at(name, state)
        .value(null_instance(fmi));
        ctx.warn(CHECK, failure);
    }
    functions.len()
}

/// The NULL pointers other than arrays: GetFMUState's state pointer (where the FMU declares
/// canGetAndSetFMUstate) and a NULL element in SetString's values (of a String variable
/// settable in Initialization Mode); returns how many cells there are.
fn null_pointer_cells(ctx: &mut Ctx, state: State) -> usize {
    const CHECK: &str = "arguments.null-arrays";
    let (model, table, interface, fmi) = (ctx.model(), ctx.binary.table(), ctx.interface, ctx.fmi());
    let error = Code::error_of(fmi).name();
    let get_set = model.capabilities(interface).can_get_and_set_fmu_state;
    let string =
        model.of(Type::String).find(|v| (table.may_set)(Op::Set(Type::String), interface, State::InitializationMode, v) == Some(true));
    let mut cells = 0;
    if get_set {
        cells += 1;
        if ctx.cell(CHECK, Severity::Warning) {
            match reach(ctx, state) {
                Err(failure) => ctx.skip(CHECK, format!("the state {} could not be reached: {}", state.name(), failure.message)),
                Ok(mut inst) => {
                    let what = format!("a NULL {} pointer", fmi.fmu_state_word());
                    let outcome = inst.get_fmu_state_into_null();
                    if !outcome.code.is_missing() && !outcome.code.is_error() {
                        let name = inst.core().name(Op::GetFmuState);
                        let failure = Failure::new(format!(
                            "{name} with {what} returned {}; a robust FMU refuses it with {error} (the standard requires a pointer to write the state to, so this is the importer's error)",
                            outcome.code.name()
                        ))
                        .at(name, state)
                        .value(what);
                        ctx.warn(CHECK, Failure { log: outcome.log, ..failure });
                    }
                }
            }
        }
    }
    if let Some(v) = string {
        cells += 1;
        if ctx.cell(CHECK, Severity::Warning) {
            let at = State::InitializationMode;
            match reach(ctx, at) {
                Err(failure) => ctx.skip(CHECK, format!("the state {} could not be reached: {}", at.name(), failure.message)),
                Ok(mut inst) => {
                    let what = "a NULL element in the values array";
                    let outcome = inst.set_string_pointer(v.vr, std::ptr::null(), &v.name, what.to_owned());
                    if !outcome.code.is_missing() && !outcome.code.is_error() {
                        let name = inst.core().name(Op::Set(Type::String));
                        let failure = Failure::new(format!(
                            "{name} of '{}' with {what} returned {}; a robust FMU refuses it with {error} (a NULL is no text, so this is the importer's error)",
                            v.name,
                            outcome.code.name()
                        ))
                        .at(name, at)
                        .variable(v.name.clone())
                        .value(what);
                        ctx.warn(CHECK, Failure { log: outcome.log, ..failure });
                    }
                }
            }
        }
    }
    cells
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi::Fmi;
    use crate::report::Severity;
    use crate::testing::{Fake, Fault, Probed};

    /// A robust FMU refuses every NULL and unknown value reference and does nothing for zero
    /// values: every check passes, on both versions.
    #[test]
    fn a_robust_fmu_passes_every_argument_check() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            for interface in [Interface::CoSimulation, Interface::ModelExchange] {
                let probed = Probed::new();
                arguments(&mut probed.ctx(Fake::new(fmi, &[]), interface));
                assert_eq!(probed.troubles(), Vec::<(String, String, String)>::new(), "{fmi:?} {interface:?}");
                let passed = probed.findings().into_iter().filter(|f| f.severity == Severity::Passed).count();
                assert_eq!(passed, 4, "{fmi:?} {interface:?}: zero-length, null-instance, null-arrays, unknown-vr");
            }
        }
    }

    /// An unknown value reference read as 0 is an error that quotes the standard's rule.
    #[test]
    fn an_unknown_value_reference_must_give_error() {
        let probed = Probed::new();
        arguments(&mut probed.ctx(Fake::new(Fmi::Fmi2, &[Fault::UnknownVr]), Interface::CoSimulation));
        let errors: Vec<_> = probed.findings().into_iter().filter(|f| f.severity == Severity::Error).collect();
        assert!(!errors.is_empty() && errors.iter().all(|f| f.check == "arguments.unknown-vr"), "{errors:#?}");
        assert_eq!((errors[0].call.as_deref(), errors[0].state.as_deref()), (Some("fmi2GetReal"), Some("StepComplete")));
        assert!(
            errors[0].message.contains("the standard requires fmi2Error for a wrong value reference (section 2.1.7)"),
            "{}",
            errors[0].message
        );
    }
}
