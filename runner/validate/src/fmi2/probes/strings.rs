//! The String variables (the FMI 3.0 set's `variables.string`, fmi3/capabilities.rs): after
//! initialization fmi2GetString gives a text for every one, the start value where nothing can
//! have changed it; and fmi2SetString copies the text it is given (section 2.1.7: "All strings
//! passed as arguments to fmi2SetString must be copied inside this function, because there is
//! no guarantee of the lifetime of strings when this function returns"), so after the set the
//! caller overwrites its buffer and the text read back must be the one set; not copied is an
//! error.
//!
//! Gets come after initialization only: in Initialization Mode condition 2 of the standard's
//! table guarantees them for outputs and InitialUnknowns alone, not for the parameters and
//! inputs whose values are known.

use std::ffi::{CStr, CString};

use fmi_c::fmi2 as c;

use super::state_machine::reach;
use super::Ctx;
use crate::fmi2::model::{Base, Causality, Initial, Var, Variability};
use crate::fmi2::raw::{Code, Instance, Outcome};
use crate::fmi2::run::{expect_ok, Failure};
use crate::fmi2::table::{may_set, Function, Interface, State};
use crate::report::Severity;

const CHECK: &str = "variables.string";

/// The start value `v` must still have after initialization when nothing set it: a
/// parameter's with initial="exact", an input's, a constant's.
fn fixed_start(v: &Var) -> Option<&str> {
    let kept = v.variability == Variability::Constant
        || v.causality == Causality::Input
        || (v.causality == Causality::Parameter && v.initial == Some(Initial::Exact));
    match &v.start {
        Some(fmi_schema::fmi2::StartValue::String(s)) if kept => Some(s),
        _ => None,
    }
}

/// fmi2GetString of one variable: the pointer the FMU gave and its text.
fn get_one(inst: &mut Instance, v: &Var) -> Outcome<(c::FmiString, Option<String>)> {
    let vr = [v.vr];
    inst.call(
        Function::GetString,
        Some(&v.name),
        Some("1 value reference".to_owned()),
        |api, c| {
            let mut out: [c::FmiString; 1] = [std::ptr::null()];
            // SAFETY: arrays of one element; the text is read before the next call.
            api.get_string.map(|g| {
                let code = Code(unsafe { g(c, vr.as_ptr(), 1, out.as_mut_ptr()) });
                let text = (!out[0].is_null()).then(|| unsafe { CStr::from_ptr(out[0]) }.to_string_lossy().into_owned());
                (code, (out[0], text))
            })
        },
        (std::ptr::null(), None),
    )
}

/// The state after initialization, where every variable may be read.
fn after_initialization(interface: Interface) -> State {
    match interface {
        Interface::CoSimulation => State::StepComplete,
        Interface::ModelExchange => State::EventMode,
    }
}

/// The probe's one cell.
pub(super) fn strings(ctx: &mut Ctx) {
    if !ctx.cell(CHECK, Severity::Error) {
        return;
    }
    match check(ctx) {
        Ok(Some(message)) => ctx.pass(CHECK, message),
        Ok(None) => ctx.skip(CHECK, "the FMU has no String variables"),
        Err(failure) => ctx.fail(CHECK, failure),
    }
}

fn check(ctx: &Ctx) -> Result<Option<String>, Failure> {
    let fmu = ctx.fmu;
    let model = &fmu.model;
    let after = after_initialization(fmu.interface);
    let vars: Vec<&Var> = model.of(Base::String).collect();
    if vars.is_empty() {
        return Ok(None);
    }
    let mut inst = reach(fmu, after)?;
    let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
    let got = inst.get_strings(&vrs, &format!("all {} String variable(s)", vars.len()));
    let texts = expect_ok(got, Function::GetString, after)?;
    for (v, text) in vars.iter().zip(&texts) {
        let problem = match (text, fixed_start(v)) {
            (None, _) => Some("returned fmi2OK but a NULL pointer for it".to_owned()),
            (Some(t), Some(start)) if t != start => Some(format!("gave {t:?}, but its start value is {start:?} and nothing set it")),
            _ => None,
        };
        if let Some(problem) = problem {
            return Err(Failure::new(format!("fmi2GetString of '{}' after initialization {problem}", v.name))
                .at(Function::GetString, after)
                .variable(v.name.clone()));
        }
    }
    let read = format!("fmi2GetString gave a text for each of the {} String variable(s), start values as declared", vars.len());
    // The set: of a variable settable after initialization (an input, a tunable parameter),
    // to a text of the validator's own; else of one settable in Initialization Mode, to its
    // start value (any other text could make the initialization fail, a file name for one).
    let late = vars.iter().find(|v| may_set(Function::SetString, fmu.interface, after, v) == Some(true));
    let early = vars
        .iter()
        .find(|v| may_set(Function::SetString, fmu.interface, State::InitializationMode, v) == Some(true) && fixed_start(v).is_some());
    let (v, at, wanted) = match (late, early) {
        (Some(v), _) => (*v, after, "runner validate: a text of its own, ünïcödé".to_owned()),
        (None, Some(v)) => (*v, State::InitializationMode, fixed_start(v).unwrap_or_default().to_owned()),
        (None, None) => return Ok(Some(format!("{read}; none of them can be set"))),
    };
    drop(inst);
    let mut inst = reach(fmu, at)?;
    let mut buffer = CString::new(wanted.replace('\0', " ")).expect("NUL removed").into_bytes_with_nul();
    let caller = buffer.as_ptr() as c::FmiString;
    let vr = [v.vr];
    let set = inst.status(Function::SetString, Some(&v.name), Some(format!("{wanted:?}")), |api, c| {
        // SAFETY: arrays of one element, a NUL-terminated text alive for the call.
        api.set_string.map(|g| unsafe { g(c, vr.as_ptr(), 1, [caller].as_ptr()) })
    });
    expect_ok(set, Function::SetString, at).map_err(|f| f.variable(v.name.clone()))?;
    // The caller's buffer is the caller's: overwritten, the FMU's copy must not change.
    let len = buffer.len() - 1;
    buffer[..len].fill(b'#');
    if at == State::InitializationMode {
        let exit = inst.simple(Function::ExitInitializationMode);
        expect_ok(exit, Function::ExitInitializationMode, at)?;
        inst.state = after;
    }
    let got = get_one(&mut inst, v);
    let (pointer, text) = expect_ok(got, Function::GetString, after).map_err(|f| f.variable(v.name.clone()))?;
    if text.as_deref() != Some(wanted.as_str()) {
        let shown = text.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 100, "...")));
        let how =
            if pointer == caller { "returned the caller's own buffer, the pointer given to fmi2SetString" } else { "gave another text" };
        return Err(Failure::new(format!(
            "fmi2SetString of '{}' to {wanted:?} in {}, then the caller's buffer overwritten with '#': fmi2GetString {how}, {shown}; the FMU must copy the text it is given",
            v.name,
            at.name()
        ))
        .at(Function::SetString, at)
        .variable(v.name.clone())
        .value(format!("{wanted:?}")));
    }
    let to = if at == State::InitializationMode { "to its start value " } else { "" };
    Ok(Some(format!(
        "{read}; fmi2SetString of '{}' {to}in {} was copied: read back after the caller overwrote its buffer",
        v.name,
        at.name()
    )))
}
