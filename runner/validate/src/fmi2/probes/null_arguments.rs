//! The NULL arguments of the arguments probe that the FMI 3.0 set has too
//! (fmi3/capabilities.rs): a NULL fmi2Component passed to every function that takes one, a
//! NULL FMUstate pointer to fmi2GetFMUstate, and a NULL element in fmi2SetString's values.
//!
//! The rule for all of them is the FMI 3.0 probes' rule: the standard requires valid
//! arguments and fixes no status for invalid ones, so a NULL is the importer's error, which a
//! robust FMU refuses with fmi2Error. Any other answer, and a crash, is a warning, whoever made
//! the FMU (the FMI 3.0 Reference FMUs' crash in fmi3GetFMUState(instance, NULL) is reported
//! so). For the FMUs this project builds a warning fails all the same: tests/run validates
//! them with --strict.

use fmi_c::fmi2 as c;

use super::state_machine::{base_of, reach, status_query};
use super::{capabilities, Ctx};
use crate::fmi2::model::{Base, Grid};
use crate::fmi2::raw::{Code, Instance, Outcome, NULL_COMPONENT};
use crate::fmi2::run::Failure;
use crate::fmi2::table::{may_set, Function, State};
use crate::report::Severity;

/// A call's outcome without its value.
fn unit<T>(o: Outcome<T>) -> Outcome<()> {
    Outcome { code: o.code, value: (), log: o.log }
}

/// The functions the NULL-component cells call: every one of the interface that takes an
/// fmi2Component, fmi2FreeInstance included, as the FMI 3.0 probes call fmi3FreeInstance(NULL):
/// both standards say the call is ignored (FMI 2.0 section 2.1.5: "If a null pointer is
/// provided for "c", the function call is ignored (does not have an effect)"), so its only
/// possible fault is a crash. The FMU state functions that take a state or its bytes only
/// where the FMU declares it can make them, so that the other arguments are valid ones.
fn null_component_functions(ctx: &Ctx) -> Vec<Function> {
    let (get_set, serialize, _) = capabilities(ctx.fmu);
    Function::of(ctx.fmu.interface)
        .filter(|f| match f {
            Function::GetTypesPlatform | Function::GetVersion | Function::Instantiate => false,
            Function::SetFmuState | Function::FreeFmuState => get_set,
            Function::SerializedFmuStateSize | Function::SerializeFmuState | Function::DeSerializeFmuState => get_set && serialize,
            _ => true,
        })
        .collect()
}

/// What the FMU state functions are given besides the NULL component: a state the instance
/// saved and its bytes.
struct Saved {
    state: c::FmuState,
    bytes: Vec<u8>,
}

/// Makes `f` on `inst` with a NULL component (the instance is in `null_component` mode).
fn null_component_call(inst: &mut Instance, f: Function, saved: &Saved) -> Outcome<()> {
    let model = &inst.fmu.model;
    let grid = Grid::new(&model.md, true);
    let first = |base: Base| model.of(base).next().map(|v| (vec![v.vr], v.name.clone())).unwrap_or((Vec::new(), "no variables".into()));
    match f {
        Function::SetDebugLogging => inst.set_debug_logging(false),
        Function::FreeInstance => inst.status(f, None, None, |api, c| {
            // SAFETY: a NULL component, which the FMU must ignore.
            api.free_instance.map(|g| unsafe { g(c) }).map(|()| Code::OK.0)
        }),
        Function::SetupExperiment => inst.setup_experiment(grid.tolerance, grid.start, grid.stop),
        Function::DoStep => inst.do_step(grid.start, grid.h),
        Function::GetReal | Function::GetInteger | Function::GetBoolean => {
            let base = base_of(f).expect("a numeric get");
            let (vrs, name) = first(base);
            unit(inst.get_numbers(base, &vrs, &name))
        }
        Function::GetString => {
            let (vrs, name) = first(Base::String);
            unit(inst.get_strings(&vrs, &name))
        }
        Function::SetReal | Function::SetInteger | Function::SetBoolean => {
            let base = base_of(f).expect("a numeric set");
            let (vrs, name) = first(base);
            let values = vec![1.0; vrs.len()];
            inst.set_numbers(base, &vrs, &values, &name)
        }
        Function::SetString => {
            let (vrs, name) = first(Base::String);
            let values = vec!["runner validate".to_owned(); vrs.len()];
            inst.set_strings(&vrs, &values, &name)
        }
        Function::GetFmuState => unit(inst.get_fmu_state()),
        Function::SetFmuState => inst.set_fmu_state(saved.state),
        Function::FreeFmuState => {
            // A copy: the caller frees the state with the real component afterwards.
            let mut state = saved.state;
            inst.free_fmu_state(&mut state)
        }
        Function::SerializedFmuStateSize => inst.status(f, None, None, |api, c| {
            let mut n = 0usize;
            // SAFETY: a state the instance saved and a valid out pointer.
            api.serialized_fmu_state_size.map(|g| unsafe { g(c, saved.state, &mut n) })
        }),
        Function::SerializeFmuState => {
            let mut bytes = vec![0u8; saved.bytes.len()];
            inst.status(f, None, Some(format!("{} bytes", bytes.len())), |api, c| {
                // SAFETY: a state the instance saved and a buffer of the size the FMU asked for.
                api.serialize_fmu_state.map(|g| unsafe { g(c, saved.state, bytes.as_mut_ptr() as *mut c::Byte, bytes.len()) })
            })
        }
        Function::DeSerializeFmuState => unit(inst.deserialize(&saved.bytes)),
        Function::GetDirectionalDerivative | Function::SetRealInputDerivatives | Function::GetRealOutputDerivatives => {
            inst.status(f, None, Some("no variables".to_owned()), |api, c| {
                // SAFETY: zero-length arrays: the FMU reads no element.
                unsafe {
                    match f {
                        Function::GetDirectionalDerivative => {
                            api.get_directional_derivative.map(|g| g(c, [].as_ptr(), 0, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr()))
                        }
                        Function::SetRealInputDerivatives => {
                            api.set_real_input_derivatives.map(|g| g(c, [].as_ptr(), 0, [].as_ptr(), [].as_ptr()))
                        }
                        _ => api.get_real_output_derivatives.map(|g| g(c, [].as_ptr(), 0, [].as_ptr(), [].as_mut_ptr())),
                    }
                }
            })
        }
        Function::GetStatus
        | Function::GetRealStatus
        | Function::GetIntegerStatus
        | Function::GetBooleanStatus
        | Function::GetStringStatus => status_query(inst, f),
        Function::NewDiscreteStates => unit(inst.new_discrete_states()),
        Function::CompletedIntegratorStep => unit(inst.completed_integrator_step()),
        Function::SetTime => inst.set_time(grid.start),
        Function::SetContinuousStates => inst.set_continuous_states(&vec![0.0; model.nx()]),
        Function::GetDerivatives
        | Function::GetEventIndicators
        | Function::GetContinuousStates
        | Function::GetNominalsOfContinuousStates => {
            let n = if f == Function::GetEventIndicators { model.event_indicators } else { model.nx() };
            unit(inst.get_vector(f, n))
        }
        // fmi2EnterInitializationMode, fmi2ExitInitializationMode, fmi2Terminate, fmi2Reset,
        // fmi2EnterEventMode, fmi2EnterContinuousTimeMode, fmi2CancelStep.
        _ => inst.simple(f),
    }
}

/// The NULL-component cells, each on a fresh instance in `state`; returns how many there are
/// (counted from the plan: after a crash another process runs the rest).
pub(super) fn null_instance(ctx: &mut Ctx, state: State) -> usize {
    const CHECK: &str = "arguments.null-instance";
    let fmu = ctx.fmu;
    let functions = null_component_functions(ctx);
    for &f in &functions {
        if !ctx.cell(CHECK, Severity::Warning) {
            continue;
        }
        let mut inst = match reach(fmu, state) {
            Ok(inst) => inst,
            Err(failure) => {
                ctx.skip(CHECK, format!("the state {} could not be reached: {}", state.name(), failure.message));
                return functions.len();
            }
        };
        // The state and bytes the state functions are given, saved with the real component.
        let mut saved = Saved { state: std::ptr::null_mut(), bytes: Vec::new() };
        if matches!(
            f,
            Function::SetFmuState
                | Function::FreeFmuState
                | Function::SerializedFmuStateSize
                | Function::SerializeFmuState
                | Function::DeSerializeFmuState
        ) {
            let got = inst.get_fmu_state();
            if !got.code.ok() || got.value.is_null() {
                ctx.skip(CHECK, format!("{} with a NULL fmi2Component not probed: fmi2GetFMUstate gave no state to pass", f.name()));
                continue;
            }
            saved.state = got.value;
            let bytes = if f == Function::SetFmuState || f == Function::FreeFmuState { None } else { Some(inst.serialize(saved.state)) };
            if let Some(bytes) = bytes {
                if !bytes.code.ok() {
                    let _ = inst.free_fmu_state(&mut saved.state);
                    ctx.skip(CHECK, format!("{} with a NULL fmi2Component not probed: fmi2SerializeFMUstate failed", f.name()));
                    continue;
                }
                saved.bytes = bytes.value;
            }
            inst.state = state;
        }
        inst.null_component = true;
        let outcome = null_component_call(&mut inst, f, &saved);
        inst.null_component = false;
        // fmi2FreeFMUstate accepted with a NULL component may have freed the state already.
        let freed_already = f == Function::FreeFmuState && outcome.code.ok();
        if !saved.state.is_null() && !freed_already {
            let _ = inst.free_fmu_state(&mut saved.state);
        }
        // fmi2FreeInstance returns nothing: not crashing is all it can show.
        if outcome.code == Code::MISSING || f == Function::FreeInstance || outcome.code == Code::ERROR {
            continue;
        }
        let failure = Failure::new(format!(
            "{} with a NULL fmi2Component returned {}; a robust FMU refuses it with fmi2Error (the standard requires the component fmi2Instantiate returned, so this is the importer's error)",
            f.name(),
            outcome.code.name()
        ))
        .at(f, state)
        .value(NULL_COMPONENT);
        ctx.warn(CHECK, failure);
    }
    functions.len()
}

/// The NULL pointers other than arrays: fmi2GetFMUstate's FMUstate pointer (where the FMU
/// declares canGetAndSetFMUstate) and a NULL element in fmi2SetString's values (of a String
/// variable settable in Initialization Mode); returns how many cells there are.
pub(super) fn null_pointers(ctx: &mut Ctx, state: State) -> usize {
    const CHECK: &str = "arguments.null-arrays";
    let fmu = ctx.fmu;
    let model = &fmu.model;
    let get_set = capabilities(fmu).0;
    let string = model.of(Base::String).find(|v| may_set(Function::SetString, fmu.interface, State::InitializationMode, v) == Some(true));
    let mut cells = 0;
    if get_set {
        cells += 1;
        if ctx.cell(CHECK, Severity::Warning) {
            match reach(fmu, state) {
                Err(failure) => ctx.skip(CHECK, format!("the state {} could not be reached: {}", state.name(), failure.message)),
                Ok(mut inst) => {
                    let what = "a NULL FMUstate pointer";
                    let outcome = inst.status(Function::GetFmuState, None, Some(what.to_owned()), |api, c| {
                        // SAFETY: deliberately NULL: the FMU must not write through it.
                        api.get_fmu_state.map(|g| unsafe { g(c, std::ptr::null_mut()) })
                    });
                    if outcome.code != Code::MISSING && outcome.code != Code::ERROR {
                        let failure = Failure::new(format!(
                            "fmi2GetFMUstate with {what} returned {}; a robust FMU refuses it with fmi2Error (the standard requires a pointer to write the state to, so this is the importer's error)",
                            outcome.code.name()
                        ))
                        .at(Function::GetFmuState, state)
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
            match reach(fmu, at) {
                Err(failure) => ctx.skip(CHECK, format!("the state {} could not be reached: {}", at.name(), failure.message)),
                Ok(mut inst) => {
                    let what = "a NULL element in the values array";
                    let vr = [v.vr];
                    let values: [c::FmiString; 1] = [std::ptr::null()];
                    let outcome = inst.status(Function::SetString, Some(&v.name), Some(what.to_owned()), |api, c| {
                        // SAFETY: valid arrays of one element, the element deliberately NULL.
                        api.set_string.map(|g| unsafe { g(c, vr.as_ptr(), 1, values.as_ptr()) })
                    });
                    if outcome.code != Code::MISSING && outcome.code != Code::ERROR {
                        let failure = Failure::new(format!(
                            "fmi2SetString of '{}' with {what} returned {}; a robust FMU refuses it with fmi2Error (a NULL is no text, so this is the importer's error)",
                            v.name,
                            outcome.code.name()
                        ))
                        .at(Function::SetString, at)
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
