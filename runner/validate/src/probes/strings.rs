//! The String variables: after initialization GetString gives a text for every one, the start
//! value where nothing can have changed it; and SetString copies the text it is given (FMI 2.0
//! section 2.1.7: "All strings passed as arguments to fmi2SetString must be copied inside this
//! function, because there is no guarantee of the lifetime of strings when this function
//! returns"), so after the set the caller overwrites its buffer and the text read back must be
//! the one set; not copied is an error.
//!
//! Gets come after initialization only: in FMI 2.0 Initialization Mode condition 2 of the
//! standard's table guarantees them for outputs and InitialUnknowns alone, not for the
//! parameters and inputs whose values are known.

use std::ffi::CString;

use crate::failure::Failure;
use crate::fmi::{Op, State, Type};
use crate::model::{Causality, Initial, Start, Var, Variability};
use crate::probe::Ctx;
use crate::report::Severity;
use crate::run::{after_initialization, reach};

const CHECK: &str = "variables.string";

/// The start value `v` must still have after initialization when nothing set it: a
/// parameter's with initial="exact", an input's, a constant's.
fn fixed_start(v: &Var) -> Option<&str> {
    let kept = v.variability == Variability::Constant
        || v.causality == Causality::Input
        || (v.causality == Causality::Parameter && v.initial == Some(Initial::Exact));
    match &v.start {
        Some(Start::Text(s)) if kept => Some(s),
        _ => None,
    }
}

/// The probe's one cell.
pub(super) fn strings(ctx: &mut Ctx) {
    if !ctx.cell(CHECK, Severity::Error) {
        return;
    }
    match check(ctx) {
        Ok(Some(message)) => ctx.pass(CHECK, message),
        // FMI 3.0 arrays of Strings are not probed.
        Ok(None) if ctx.fmi() == crate::fmi::Fmi::Fmi3 => ctx.skip(CHECK, "the FMU has no scalar String variables"),
        Ok(None) => ctx.skip(CHECK, "the FMU has no String variables"),
        Err(failure) => ctx.fail(CHECK, failure),
    }
}

fn check(ctx: &Ctx) -> Result<Option<String>, Failure> {
    let (model, table, interface) = (ctx.model(), ctx.binary.table(), ctx.interface);
    let vars: Vec<&Var> = model.of(Type::String).collect();
    if vars.is_empty() {
        return Ok(None);
    }
    let get = table.name(Op::Get(Type::String), interface);
    let set = table.name(Op::Set(Type::String), interface);
    let mut inst = reach(ctx, after_initialization(ctx.binary, interface))?;
    let after = inst.core().state;
    let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
    let got = inst.get_strings(&vrs, &format!("all {} String variable(s)", vars.len()));
    let texts = inst.core().expect(got, Op::Get(Type::String), after)?;
    for (v, text) in vars.iter().zip(&texts) {
        let problem = match (text, fixed_start(v)) {
            (None, _) => Some(format!("returned {} but a NULL pointer for it", crate::fmi::Code::ok_of(ctx.fmi()).name())),
            (Some(t), Some(start)) if t != start => Some(format!("gave {t:?}, but its start value is {start:?} and nothing set it")),
            _ => None,
        };
        if let Some(problem) = problem {
            return Err(Failure::new(format!("{get} of '{}' after initialization {problem}", v.name))
                .at(get, after)
                .variable(v.name.clone()));
        }
    }
    let read = format!("{get} gave a text for each of the {} String variable(s), start values as declared", vars.len());
    // The set: of a variable settable after initialization (an input, a tunable parameter),
    // to a text of the validator's own; else of one settable in Initialization Mode, to its
    // start value (any other text could make the initialization fail, a file name for one).
    let settable = |v: &&&Var, state| (table.may_set)(Op::Set(Type::String), interface, state, v) == Some(true);
    let late = vars.iter().find(|v| settable(v, after));
    let early = vars.iter().find(|v| settable(v, State::InitializationMode) && fixed_start(v).is_some());
    let (v, at, wanted) = match (late, early) {
        (Some(v), _) => (*v, after, "runner validate: a text of its own, ünïcödé".to_owned()),
        (None, Some(v)) => (*v, State::InitializationMode, fixed_start(v).unwrap_or_default().to_owned()),
        (None, None) => return Ok(Some(format!("{read}; none of them can be set"))),
    };
    drop(inst);
    let mut inst = reach(ctx, at)?;
    let mut buffer = CString::new(wanted.replace('\0', " ")).expect("NUL removed").into_bytes_with_nul();
    let caller = buffer.as_ptr() as *const std::ffi::c_char;
    let set_outcome = inst.set_string_pointer(v.vr, caller, &v.name, format!("{wanted:?}"));
    inst.core().expect(set_outcome, Op::Set(Type::String), at).map_err(|f| f.variable(v.name.clone()))?;
    // The caller's buffer is the caller's: overwritten, the FMU's copy must not change.
    let len = buffer.len() - 1;
    buffer[..len].fill(b'#');
    if at == State::InitializationMode {
        let exit = inst.simple(Op::ExitInitializationMode);
        inst.core().expect(exit, Op::ExitInitializationMode, at)?;
        inst.core_mut().state = after;
    }
    let got = inst.get_string_pointer(v.vr, &v.name);
    let (pointer, text) = inst.core().expect(got, Op::Get(Type::String), after).map_err(|f| f.variable(v.name.clone()))?;
    if text.as_deref() != Some(wanted.as_str()) {
        let shown = text.map_or("NULL".to_owned(), |t| format!("{:?}", fmi_schema::escaped_and_cut(&t, 100, "...")));
        let how = if pointer == caller {
            format!("returned the caller's own buffer, the pointer given to {set}")
        } else {
            "gave another text".to_owned()
        };
        return Err(Failure::new(format!(
            "{set} of '{}' to {wanted:?} in {}, then the caller's buffer overwritten with '#': {get} {how}, {shown}; the FMU must copy the text it is given",
            v.name,
            at.name()
        ))
        .at(set, at)
        .variable(v.name.clone())
        .value(format!("{wanted:?}")));
    }
    let to = if at == State::InitializationMode { "to its start value " } else { "" };
    Ok(Some(format!("{read}; {set} of '{}' {to}in {} was copied: read back after the caller overwrote its buffer", v.name, at.name())))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::var;

    use crate::fmi::{Fmi, Interface};
    use crate::testing::{Fake, Probed};

    /// The fake's String parameter reads its start value after initialization, and a text
    /// set to it is copied (the probe overwrites its own buffer before reading it back).
    #[test]
    fn a_copied_string_reads_back() {
        for fmi in [Fmi::Fmi2, Fmi::Fmi3] {
            let probed = Probed::new();
            strings(&mut probed.ctx(Fake::new(fmi, &[]), Interface::CoSimulation));
            let findings = probed.findings();
            assert_eq!(findings.len(), 1);
            assert_eq!(findings[0].severity, crate::report::Severity::Passed, "{:?}", findings[0]);
            assert!(findings[0].message.contains("of 'label' in"), "{}", findings[0].message);
        }
    }

    #[test]
    fn a_start_value_holds_where_nothing_can_change_it() {
        let mut p = var("p", 0, Type::String, Causality::Parameter, Variability::Fixed, Some(Initial::Exact));
        p.start = Some(Start::Text("a".into()));
        assert_eq!(fixed_start(&p), Some("a"));
        let mut out = var("y", 1, Type::String, Causality::Output, Variability::Discrete, Some(Initial::Calculated));
        out.start = Some(Start::Text("b".into()));
        assert_eq!(fixed_start(&out), None, "an output may be computed");
        let mut input = var("u", 2, Type::String, Causality::Input, Variability::Discrete, None);
        input.start = Some(Start::Text("c".into()));
        assert_eq!(fixed_start(&input), Some("c"));
    }
}
