//! The FMI 3.0 probes of what an FMU declares it can do, and of its robustness, the FMI 2.0
//! set's counterparts (FMU state: FMI 3.0.2 section 2.2.6.4):
//!
//! - `fmu-state` / `serialize`: with canGetAndSetFMUState (canSerializeFMUState), a state
//!   saved half-way (fmi3GetFMUState; serialized with fmi3SerializedFMUStateSize and
//!   fmi3SerializeFMUState, the original freed, and fmi3DeserializeFMUState) and restored with
//!   fmi3SetFMUState must continue bit for bit as the run did; fmi3FreeFMUState must give
//!   back NULL (the standard: "The function returns a null pointer in argument FMUState").
//! - `arguments`: a NULL instance, NULL value-reference arrays with nvr > 0 and NULL value or
//!   output arrays; the importer's error, which a robust FMU refuses with fmi3Error (any
//!   other answer, or a crash, is a warning, as for FMI 2.0).
//! - `threads`: unless canBeInstantiatedOnlyOncePerProcess, instances running at once on
//!   threads must each give the sequential run's bits.
//! - `strings`: fmi3GetString gives a text for every String variable (the start value where
//!   the description fixes it), and fmi3SetString copies the text it is given.

use std::ffi::CString;

use fmi_c::fmi3 as c;
use fmi_schema::fmi3::{self as s, Causality, Variability};

use super::probes::{advance, begin, difference, drive, failure, legal, simulate, Ctx, Failure, Trajectory};
use super::raw::{Code, Instance, Interface};
use crate::concurrent::concurrently;
use crate::report::{Finding, Severity};

/// Instances the threads probe runs at once.
const INSTANCES: usize = 3;

/// The capability flags of the probed interface.
fn common<'m>(ctx: &Ctx<'m>) -> Option<&'m s::InterfaceCommon> {
    let md = &ctx.child.model.md;
    match ctx.interface {
        Interface::CoSimulation => md.co_simulation.as_ref().map(|c| &c.common),
        Interface::ModelExchange => md.model_exchange.as_ref().map(|m| &m.common),
    }
}

/// Get/set (or serialized) FMU state: a state saved half-way and restored must reproduce the
/// continuation bit for bit.
pub(super) fn fmu_state(ctx: &mut Ctx, serialized: bool) {
    let check = if serialized { "capability.serialize" } else { "capability.fmu-state" };
    if !ctx.cell(check) {
        return;
    }
    let flags = common(ctx);
    let declared = flags.is_some_and(|c| if serialized { c.can_serialize_fmu_state } else { c.can_get_and_set_fmu_state });
    if !declared {
        let flag = if serialized { "canSerializeFMUState" } else { "canGetAndSetFMUState" };
        return ctx.report(Finding::skipped(check, format!("the FMU declares {flag}=false")));
    }
    match round_trip(ctx, serialized) {
        Ok(Some(message)) => ctx.pass(check, message),
        Ok(None) => ctx.report(Finding::skipped(check, "not exercised: the model ended the run before its half-way point")),
        Err(f) => ctx.report(f.finding(check)),
    }
}

/// The round trip of [`fmu_state`]: `Ok(None)` when the run ended before the half-way point.
fn round_trip(ctx: &Ctx, serialized: bool) -> Result<Option<String>, Failure> {
    let model = &ctx.child.model;
    let mut inst = ctx.instantiate(ctx.cs_options())?;
    let mut run = begin(ctx, &mut inst)?;
    advance(ctx, &mut inst, &mut run, (model.steps / 2).max(1))?;
    if run.ended || run.k == model.steps {
        return Ok(None);
    }
    let (saved_run, saved_mode, t_saved) = (run.clone(), inst.state, run.t);
    let mut state: c::FmuState = std::ptr::null_mut();
    legal(&inst, "fmi3GetFMUState", inst.get_fmu_state(&mut state))?;
    if state.is_null() {
        return Err(failure(&inst, "fmi3GetFMUState", "fmi3GetFMUState returned fmi3OK but no FMU state (NULL)".into()));
    }
    let mut bytes = Vec::new();
    if serialized {
        bytes = inst
            .serialize(state)
            .map_err(|(call, what)| failure(&inst, call, format!("{call} of the state saved at t = {t_saved} {what}")))?;
        free(&inst, &mut state)?;
    }
    advance(ctx, &mut inst, &mut run, model.steps)?;
    let first: Trajectory = run.trajectory();
    if serialized {
        let (code, restored) = inst.deserialize(&bytes);
        legal(&inst, "fmi3DeserializeFMUState", code)?;
        if restored.is_null() {
            return Err(failure(
                &inst,
                "fmi3DeserializeFMUState",
                "fmi3DeserializeFMUState returned fmi3OK but no FMU state (NULL)".into(),
            ));
        }
        state = restored;
    }
    legal(&inst, "fmi3SetFMUState", inst.set_fmu_state(state))?;
    inst.state = saved_mode;
    let mut again = saved_run;
    advance(ctx, &mut inst, &mut again, model.steps)?;
    free(&inst, &mut state)?;
    let second = again.trajectory();
    let how = if serialized {
        format!("serialized ({} bytes), freed, deserialized and set with fmi3SetFMUState", bytes.len())
    } else {
        "restored with fmi3SetFMUState".to_owned()
    };
    if first != second {
        let differs = difference(model, &first, &second, "in the first continuation", "after the restore");
        return Err(Failure {
            message: format!("the state saved at t = {t_saved} and {how} does not reproduce the continuation: {differs}"),
            call: "fmi3SetFMUState".into(),
            state: saved_mode.into(),
            log: inst.log.take(),
        });
    }
    Ok(Some(format!("the state saved at t = {t_saved} and {how} reproduces the continuation to t = {} bit for bit", second.end)))
}

/// fmi3FreeFMUState, which must succeed and give back NULL.
fn free(inst: &Instance, state: &mut c::FmuState) -> Result<(), Failure> {
    legal(inst, "fmi3FreeFMUState", inst.free_fmu_state(state))?;
    if !state.is_null() {
        return Err(failure(
            inst,
            "fmi3FreeFMUState",
            "fmi3FreeFMUState returned without setting the FMUState argument to NULL (\"The function returns a null pointer in argument FMUState\")"
                .into(),
        ));
    }
    Ok(())
}

/// The value types the arguments probe passes NULL arrays to.
#[derive(Clone, Copy, PartialEq)]
enum Type {
    Float64,
    Int32,
    Boolean,
    String,
}

impl Type {
    const ALL: [Type; 4] = [Type::Float64, Type::Int32, Type::Boolean, Type::String];

    fn name(self) -> &'static str {
        match self {
            Type::Float64 => "Float64",
            Type::Int32 => "Int32",
            Type::Boolean => "Boolean",
            Type::String => "String",
        }
    }

    fn of(self, v: &s::Variable) -> bool {
        v.dimensions.is_empty()
            && matches!(
                (&v.kind, self),
                (s::VariableKind::Float { precision: s::FloatType::Float64, .. }, Type::Float64)
                    | (s::VariableKind::Int { ty: s::IntType::Int32, .. }, Type::Int32)
                    | (s::VariableKind::Boolean { .. }, Type::Boolean)
                    | (s::VariableKind::String { .. }, Type::String)
            )
    }
}

/// One call of the arguments probe.
#[derive(Clone)]
enum Call {
    /// A function called with a NULL instance (else valid arguments).
    NullInstance(&'static str),
    /// fmi3Get<T> (`get`) or fmi3Set<T> of one value: NULL value references, or the value
    /// reference `vr` and NULL values.
    Values { ty: Type, get: bool, vr: Option<(String, u32)> },
    /// A Model Exchange getter or fmi3GetFMUState with a NULL output array or pointer (`n`
    /// elements).
    NullOutput(&'static str, usize),
}

impl Call {
    fn name(&self) -> String {
        match self {
            Call::NullInstance(f) | Call::NullOutput(f, _) => (*f).to_owned(),
            Call::Values { ty, get, .. } => format!("fmi3{}{}", if *get { "Get" } else { "Set" }, ty.name()),
        }
    }

    fn what(&self) -> String {
        match self {
            Call::NullInstance(_) => "a NULL instance".into(),
            Call::Values { vr: None, .. } => "NULL value references and nvr = 1".into(),
            Call::Values { vr: Some((name, _)), .. } => format!("the value reference of '{name}' and a NULL values array"),
            Call::NullOutput(_, n) => format!("a NULL output array of {n} elements"),
        }
    }
}

/// The state the arguments probe calls in: after initialization, where values are read.
fn argument_state(ctx: &Ctx) -> &'static str {
    match ctx.interface {
        Interface::CoSimulation if !ctx.cs_options().event_mode_used => "StepMode",
        _ => "EventMode",
    }
}

/// The calls of the arguments probe, for this FMU and interface.
fn argument_calls(ctx: &Ctx) -> Vec<Call> {
    let md = &ctx.child.model.md;
    let me = ctx.interface == Interface::ModelExchange;
    let mut calls = vec![Call::NullInstance("fmi3GetFloat64"), Call::NullInstance("fmi3EnterInitializationMode")];
    calls.push(Call::NullInstance(if me { "fmi3SetTime" } else { "fmi3DoStep" }));
    calls.push(Call::NullInstance("fmi3FreeInstance"));
    for ty in Type::ALL {
        calls.push(Call::Values { ty, get: true, vr: None });
        calls.push(Call::Values { ty, get: false, vr: None });
        let readable = md.model_variables.iter().find(|v| ty.of(v) && v.causality() != Causality::Independent);
        if let Some(v) = readable {
            calls.push(Call::Values { ty, get: true, vr: Some((v.name.clone(), v.value_reference)) });
        }
        // Settable after initialization: an input, or a tunable parameter.
        let settable = md.model_variables.iter().find(|v| {
            ty.of(v)
                && (v.causality() == Causality::Input || (v.causality() == Causality::Parameter && v.variability() == Variability::Tunable))
        });
        if let Some(v) = settable {
            calls.push(Call::Values { ty, get: false, vr: Some((v.name.clone(), v.value_reference)) });
        }
    }
    if common(ctx).is_some_and(|c| c.can_get_and_set_fmu_state) {
        calls.push(Call::NullOutput("fmi3GetFMUState", 1));
    }
    if me {
        let m = &ctx.child.model;
        calls.push(Call::NullOutput("fmi3GetNumberOfContinuousStates", 1));
        for (f, n) in [("fmi3GetContinuousStates", m.nx), ("fmi3GetEventIndicators", m.nz)] {
            if let Some(n) = n.filter(|n| *n > 0) {
                calls.push(Call::NullOutput(f, n));
            }
        }
    }
    calls
}

/// Makes `call` on `inst` (the NULL it probes, else valid arguments).
fn make(ctx: &Ctx, inst: &Instance, call: &Call) -> Code {
    let api = inst.api;
    let null_out: *mut f64 = std::ptr::null_mut();
    let m = &ctx.child.model;
    // SAFETY (every call below): the arguments are valid but for the NULL being probed, which
    // the FMU must not touch; a crash is what the child process is for.
    match call {
        Call::NullInstance(name) => {
            let null = std::ptr::null_mut();
            match *name {
                "fmi3GetFloat64" => {
                    let (vr, mut value) = (m.recorded.first().map_or(0, |r| r.1), 0.0);
                    inst.call(name, api.get_float64, |f, _| unsafe { f(null, &vr, 1, &mut value, 1) })
                }
                "fmi3EnterInitializationMode" => {
                    inst.call(name, api.enter_initialization_mode, |f, _| unsafe { f(null, false, 0.0, m.start, true, m.stop) })
                }
                "fmi3SetTime" => inst.call(name, api.set_time, |f, _| unsafe { f(null, m.start) }),
                "fmi3DoStep" => {
                    let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                    inst.call(name, api.do_step, |f, _| unsafe {
                        f(null, m.start, m.h, true, &mut event, &mut terminate, &mut early, &mut last)
                    })
                }
                // Returns nothing: the FMU must ignore it ("If a NULL pointer is provided for
                // argument instance, the function call is ignored (does not have an effect)").
                _ => inst.call(name, api.free_instance, |f, _| {
                    unsafe { f(null) };
                    Code::OK.0
                }),
            }
        }
        Call::Values { ty, get, vr } => {
            let vrs = vr.as_ref().map(|(_, vr)| [*vr]);
            let vr_ptr = vrs.as_ref().map_or(std::ptr::null(), |v| v.as_ptr());
            let name = call.name();
            // One valid value each, where the values are not the NULL being probed.
            let text = CString::new("runner validate").expect("no NUL");
            let (mut float, mut int, mut boolean, mut string) = (1.5f64, 1i32, true, text.as_ptr());
            let null_values = vr.is_some();
            macro_rules! values {
                ($value:ident, $ty:ty) => {
                    if null_values {
                        std::ptr::null_mut()
                    } else {
                        &mut $value as *mut $ty
                    }
                };
            }
            match (ty, get) {
                (Type::Float64, true) => inst.call(&name, api.get_float64, |f, i| unsafe { f(i, vr_ptr, 1, values!(float, f64), 1) }),
                (Type::Float64, false) => inst.call(&name, api.set_float64, |f, i| unsafe { f(i, vr_ptr, 1, values!(float, f64), 1) }),
                (Type::Int32, true) => inst.call(&name, api.get_int32, |f, i| unsafe { f(i, vr_ptr, 1, values!(int, i32), 1) }),
                (Type::Int32, false) => inst.call(&name, api.set_int32, |f, i| unsafe { f(i, vr_ptr, 1, values!(int, i32), 1) }),
                (Type::Boolean, true) => inst.call(&name, api.get_boolean, |f, i| unsafe { f(i, vr_ptr, 1, values!(boolean, bool), 1) }),
                (Type::Boolean, false) => inst.call(&name, api.set_boolean, |f, i| unsafe { f(i, vr_ptr, 1, values!(boolean, bool), 1) }),
                (Type::String, true) => {
                    inst.call(&name, api.get_string, |f, i| unsafe { f(i, vr_ptr, 1, values!(string, c::FmiString), 1) })
                }
                (Type::String, false) => {
                    inst.call(&name, api.set_string, |f, i| unsafe { f(i, vr_ptr, 1, values!(string, c::FmiString), 1) })
                }
            }
        }
        Call::NullOutput(name, n) => match *name {
            "fmi3GetFMUState" => inst.call(name, api.get_fmu_state, |f, i| unsafe { f(i, std::ptr::null_mut()) }),
            "fmi3GetNumberOfContinuousStates" => {
                inst.call(name, api.get_number_of_continuous_states, |f, i| unsafe { f(i, std::ptr::null_mut()) })
            }
            "fmi3GetContinuousStates" => inst.call(name, api.get_continuous_states, |f, i| unsafe { f(i, null_out, *n) }),
            _ => inst.call(name, api.get_event_indicators, |f, i| unsafe { f(i, null_out, *n) }),
        },
    }
}

/// NULL where the standard requires an instance or arrays: each call in a fresh instance,
/// refused with fmi3Error; a crash, or another answer, is a warning.
pub(super) fn arguments(ctx: &mut Ctx) {
    let state = argument_state(ctx);
    let calls = argument_calls(ctx);
    let (mut instance_calls, mut array_calls) = (0, 0);
    for call in &calls {
        let check = if matches!(call, Call::NullInstance(_)) { "arguments.null-instance" } else { "arguments.null-arrays" };
        if matches!(call, Call::NullInstance(_)) {
            instance_calls += 1;
        } else {
            array_calls += 1;
        }
        if !ctx.cell_with(check, Severity::Warning) {
            continue;
        }
        let inst = match drive(ctx, state) {
            Ok(i) => i,
            Err(f) => {
                ctx.report(Finding::skipped(check, format!("the state {state} could not be reached: {}", f.message)));
                continue;
            }
        };
        let variable = match call {
            Call::Values { vr: Some((variable, _)), .. } => Some(variable.clone()),
            _ => None,
        };
        inst.note(variable.clone(), Some(call.what()));
        let code = make(ctx, &inst, call);
        let free_instance = matches!(call, Call::NullInstance("fmi3FreeInstance"));
        if code != Code::MISSING && code != Code::ERROR && !free_instance {
            let name = call.name();
            let mut finding = Finding::warning(
                check,
                format!(
                    "{name} with {} returned {}; a robust FMU refuses it with fmi3Error (the standard requires valid arguments, so this is the importer's error)",
                    call.what(),
                    code.name()
                ),
            )
            .call(name)
            .state(state)
            .value(call.what())
            .log(inst.log.take());
            if let Some(variable) = variable {
                finding = finding.variable(variable);
            }
            ctx.report(finding);
        }
    }
    ctx.pass(
        "arguments.null-instance",
        format!("{instance_calls} calls with a NULL instance refused with fmi3Error (fmi3FreeInstance ignored it)"),
    );
    ctx.pass("arguments.null-arrays", format!("{array_calls} calls with NULL arrays and a nonzero length refused with fmi3Error"));
}

/// Instances running at once on threads must give what one run alone gave.
pub(super) fn threads(ctx: &mut Ctx) {
    const CHECK: &str = "capability.threads";
    if !ctx.cell(CHECK) {
        return;
    }
    if common(ctx).is_none_or(|c| c.can_be_instantiated_only_once_per_process) {
        return ctx.report(Finding::skipped(CHECK, "the FMU declares canBeInstantiatedOnlyOncePerProcess=true"));
    }
    let (reference, results) = {
        let shared: &Ctx = ctx;
        let alone = |slot: usize| -> Result<Trajectory, Failure> {
            let mut inst = shared.instantiate_in(shared.cs_options(), slot)?;
            simulate(shared, &mut inst)
        };
        let reference = alone(0);
        let panicked =
            || Failure { message: "the validator's thread panicked".into(), call: String::new(), state: String::new(), log: None };
        let results = if reference.is_ok() { concurrently(INSTANCES, |i| alone(i + 1), panicked) } else { Vec::new() };
        (reference, results)
    };
    let reference = match reference {
        Ok(t) => t,
        Err(f) => return ctx.report(f.finding(CHECK)),
    };
    for (i, result) in results.into_iter().enumerate() {
        let what = format!("instance {} of {INSTANCES} running at once on threads", i + 1);
        match result {
            Err(f) => ctx.report(Failure { message: format!("{what}: {}", f.message), ..f }.finding(CHECK)),
            Ok(t) if t != reference => {
                let differs = difference(&ctx.child.model, &reference, &t, "in the run alone", "in this one");
                ctx.report(Finding::error(CHECK, format!("{what} gave other results than one run alone: {differs}")));
            }
            Ok(_) => {}
        }
    }
    ctx.pass(CHECK, format!("{INSTANCES} instances running at once on {INSTANCES} threads each equal one run alone bit for bit"));
}

/// A scalar String variable, and the start value the description fixes for it (a parameter's
/// or input's).
fn strings(md: &s::ModelDescription) -> Vec<(String, u32, Option<String>)> {
    md.model_variables
        .iter()
        .filter(|v| Type::String.of(v))
        .map(|v| {
            let start = match &v.kind {
                s::VariableKind::String { start: Some(start) } if start.len() == 1 => Some(start[0].clone()),
                _ => None,
            };
            let fixed = matches!(v.causality(), Causality::Parameter | Causality::Input);
            (v.name.clone(), v.value_reference, start.filter(|_| fixed))
        })
        .collect()
}

/// fmi3GetString of every String variable in Initialization Mode (the start values where
/// fixed) and after it, then fmi3SetString of a parameter or input and the text read back.
pub(super) fn string_variables(ctx: &mut Ctx) {
    const CHECK: &str = "variables.string";
    if !ctx.cell(CHECK) {
        return;
    }
    let vars = strings(&ctx.child.model.md);
    if vars.is_empty() {
        return ctx.report(Finding::skipped(CHECK, "the FMU has no scalar String variables"));
    }
    let after = argument_state(ctx);
    let mut read = 0;
    for state in ["InitializationMode", after] {
        let inst = match drive(ctx, state) {
            Ok(i) => i,
            Err(f) => return ctx.report(f.finding(CHECK)),
        };
        // In Initialization Mode the variables whose start value the description fixes (the
        // others may not be readable yet), after it all.
        let asked: Vec<&(String, u32, Option<String>)> = vars.iter().filter(|v| state != "InitializationMode" || v.2.is_some()).collect();
        if asked.is_empty() {
            continue;
        }
        let vrs: Vec<u32> = asked.iter().map(|v| v.1).collect();
        let (code, texts) = inst.get_string(&vrs);
        if let Err(f) = legal(&inst, "fmi3GetString", code) {
            return ctx.report(f.finding(CHECK));
        }
        for ((name, _, start), text) in asked.iter().copied().zip(&texts) {
            let problem = match (text, start) {
                (None, _) => Some("returned fmi3OK but a NULL pointer for it".to_owned()),
                (Some(t), Some(start)) if state == "InitializationMode" && t != start => {
                    Some(format!("gave {t:?}, but its start value is {start:?} and nothing set it"))
                }
                _ => None,
            };
            if let Some(problem) = problem {
                let finding = Finding::error(CHECK, format!("fmi3GetString of '{name}' in {state} {problem}"))
                    .call("fmi3GetString")
                    .state(state)
                    .variable(name.clone())
                    .log(inst.log.take());
                return ctx.report(finding);
            }
        }
        read += texts.len();
    }
    // Settable in Initialization Mode: a parameter (fixed or tunable) or an input.
    let md = &ctx.child.model.md;
    let settable = md.model_variables.iter().find(|v| {
        Type::String.of(v) && matches!(v.causality(), Causality::Parameter | Causality::Input) && v.variability() != Variability::Constant
    });
    let Some(v) = settable else {
        return ctx
            .pass(CHECK, format!("fmi3GetString gave a text for each of {read} reads of String variables, start values as declared"));
    };
    let (name, vr) = (v.name.clone(), v.value_reference);
    let inst = match drive(ctx, "InitializationMode") {
        Ok(i) => i,
        Err(f) => return ctx.report(f.finding(CHECK)),
    };
    let wanted = "runner validate: a text of its own, ünïcödé";
    let mut buffer = CString::new(wanted).expect("no NUL").into_bytes_with_nul();
    let code = {
        let text = std::ffi::CStr::from_bytes_with_nul(&buffer).expect("one NUL at the end");
        inst.set_string(vr, text)
    };
    if let Err(f) = legal(&inst, "fmi3SetString", code) {
        return ctx.report(Failure { message: format!("{} (of '{name}' in InitializationMode)", f.message), ..f }.finding(CHECK));
    }
    // The caller's buffer is the caller's: overwritten, the FMU's copy must not change.
    let len = buffer.len() - 1;
    buffer[..len].fill(b'#');
    let (code, texts) = inst.get_string(&[vr]);
    if let Err(f) = legal(&inst, "fmi3GetString", code) {
        return ctx.report(f.finding(CHECK));
    }
    let got = texts.into_iter().next().flatten();
    if got.as_deref() != Some(wanted) {
        let shown = got.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 100, "...")));
        let finding = Finding::error(
            CHECK,
            format!("fmi3SetString of '{name}' to {wanted:?} then fmi3GetString gave {shown}: the FMU must copy the text it is given"),
        )
        .call("fmi3GetString")
        .state("InitializationMode")
        .variable(name)
        .log(inst.log.take());
        return ctx.report(finding);
    }
    ctx.pass(
        CHECK,
        format!(
            "fmi3GetString gave a text for each of {read} reads of String variables, start values as declared; fmi3SetString of '{name}' was copied and read back"
        ),
    );
}
