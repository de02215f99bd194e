//! The values the state-machine and arguments probes watch: which variables can be read in a
//! state, a snapshot of them before and after a call that must change nothing, and values to
//! set (the current one for a legal set, another one for an illegal set, so that it shows).

use std::collections::HashMap;

use crate::fmi::{Op, State, Type, Version};
use crate::instance::Instance;
use crate::model::{Model, Start, Var};
use crate::probe::Ctx;
use crate::run::reach;
use crate::table::Rule;

/// A value read or to set.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Val {
    Num(f64),
    Text(Option<String>),
}

impl Val {
    /// Equal, numbers bit for bit.
    pub(super) fn same(&self, other: &Val) -> bool {
        match (self, other) {
            (Val::Num(a), Val::Num(b)) => a.to_bits() == b.to_bits(),
            (a, b) => a == b,
        }
    }

    pub(super) fn shown(&self) -> String {
        match self {
            Val::Num(v) => v.to_string(),
            Val::Text(Some(t)) => format!("{t:?}"),
            Val::Text(None) => "NULL".to_owned(),
        }
    }
}

/// The variables whose reads succeed in `state`, found one by one on a scratch instance, for
/// the before-and-after comparisons.
pub(super) fn readable(ctx: &Ctx, state: State) -> Vec<usize> {
    let (model, table) = (ctx.model(), ctx.binary.table());
    let candidates: Vec<usize> = (0..model.vars.len())
        .filter(|&i| {
            let v = &model.vars[i];
            match table.rule(Op::Get(v.ty), ctx.interface, state) {
                Rule::Allowed => state != State::Gone,
                Rule::GetIf => (table.may_get_in_initialization)(v, model.initial_unknowns.contains(&i)),
                _ => false,
            }
        })
        .collect();
    if candidates.is_empty() {
        return Vec::new();
    }
    let Ok(mut inst) = reach(ctx, state) else { return Vec::new() };
    let mut found = Vec::new();
    for i in candidates {
        if read_one(inst.as_mut(), &model.vars[i]).is_some() {
            found.push(i);
        } else if inst.core().state != state {
            // A refused read moved it on (into Error): start again.
            let Ok(fresh) = reach(ctx, state) else { break };
            inst = fresh;
        }
    }
    found
}

/// The value of one variable, if its read succeeds.
pub(super) fn read_one(inst: &mut dyn Instance, v: &Var) -> Option<Val> {
    if v.ty == Type::String {
        let got = inst.get_strings(&[v.vr], &v.name);
        return got.code.ok().then(|| Val::Text(got.value.into_iter().next().flatten()));
    }
    let got = inst.get_numbers(v.ty, &[v.vr], &v.name);
    got.code.ok().then(|| Val::Num(got.value[0]))
}

/// The readable values now, by variable name; reads that fail are left out.
pub(super) fn snapshot(inst: &mut dyn Instance, model: &Model, readable: &[usize]) -> HashMap<String, Val> {
    let state = inst.core().state;
    let mut values = HashMap::new();
    for ty in Type::ALL {
        let vars: Vec<&Var> = readable.iter().map(|&i| &model.vars[i]).filter(|v| v.ty == ty).collect();
        if vars.is_empty() {
            continue;
        }
        let vrs: Vec<u32> = vars.iter().map(|v| v.vr).collect();
        let type_name = inst.core().name(Op::Get(ty)).trim_start_matches(inst.core().fmi().prefix()).trim_start_matches("Get");
        let names = format!("{} readable {type_name} variable(s)", vars.len());
        let got: Option<Vec<Val>> = if ty == Type::String {
            let got = inst.get_strings(&vrs, &names);
            got.code.ok().then(|| got.value.into_iter().map(Val::Text).collect())
        } else {
            let got = inst.get_numbers(ty, &vrs, &names);
            got.code.ok().then(|| got.value.into_iter().map(Val::Num).collect())
        };
        for (v, value) in vars.iter().zip(got.into_iter().flatten()) {
            values.insert(v.name.clone(), value);
        }
    }
    // An observation, not a step of the state machine.
    inst.core_mut().state = state;
    values
}

/// The first readable value that differs between two snapshots.
pub(super) fn changed(before: &HashMap<String, Val>, after: &HashMap<String, Val>, model: &Model) -> Option<(String, Val, Val)> {
    model.vars.iter().find_map(|v| match (before.get(&v.name), after.get(&v.name)) {
        (Some(a), Some(b)) if !a.same(b) => Some((v.name.clone(), a.clone(), b.clone())),
        _ => None,
    })
}

/// A value for `v` other than `current` (and within its min and max where that is possible),
/// so that an accepted illegal set shows.
pub(super) fn different(v: &Var, current: Option<&Val>) -> Val {
    let start = || match &v.start {
        Some(Start::Number(x)) => Some(*x),
        _ => None,
    };
    match v.ty {
        Type::String => {
            let now = match current {
                Some(Val::Text(t)) => t.clone(),
                _ => None,
            };
            let text = if now.as_deref() == Some("runner validate") { "runner validate 2" } else { "runner validate" };
            Val::Text(Some(text.to_owned()))
        }
        Type::Boolean => {
            let now = match current {
                Some(Val::Num(x)) => *x != 0.0,
                _ => start().is_some_and(|x| x != 0.0),
            };
            Val::Num(if now { 0.0 } else { 1.0 })
        }
        Type::Real | Type::Integer => {
            let now = match current {
                Some(Val::Num(x)) if x.is_finite() => *x,
                _ => start().filter(|x| x.is_finite()).unwrap_or(0.0),
            };
            let within = |x: f64| v.min.is_none_or(|m| x >= m) && v.max.is_none_or(|m| x <= m);
            let candidates = [now + 1.0, now - 1.0, (v.min.unwrap_or(now) + v.max.unwrap_or(now + 2.0)) / 2.0, now * 2.0 + 1.0];
            let pick = candidates.into_iter().find(|&x| x != now && within(x) && (v.ty == Type::Real || x.fract() == 0.0));
            Val::Num(pick.unwrap_or(now + 1.0))
        }
    }
}

/// The value a legal set passes: the current one where it can be read, else the start value.
pub(super) fn same_value(v: &Var, current: Option<&Val>) -> Val {
    if let Some(value) = current {
        return value.clone();
    }
    match &v.start {
        Some(Start::Number(x)) => Val::Num(*x),
        Some(Start::Text(s)) => Val::Text(Some(s.clone())),
        None if v.ty == Type::String => Val::Text(Some(String::new())),
        None => Val::Num(0.0),
    }
}

/// Sets `v` to `value`.
pub(super) fn set_value(inst: &mut dyn Instance, v: &Var, value: &Val) -> crate::fmi::Outcome<()> {
    match value {
        Val::Num(x) => inst.set_numbers(v.ty, &[v.vr], &[*x], &v.name),
        Val::Text(t) => inst.set_strings(&[v.vr], &[t.clone().unwrap_or_default()], &v.name),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::var;
    use crate::model::{Causality, Variability};

    #[test]
    fn a_different_value_differs_and_keeps_to_the_range() {
        let mut k = var("k", 0, Type::Integer, Causality::Parameter, Variability::Fixed, None);
        (k.min, k.max) = (Some(0.0), Some(3.0));
        assert_eq!(different(&k, Some(&Val::Num(3.0))), Val::Num(2.0), "3 + 1 is out of range");
        k.start = Some(Start::Number(1.0));
        assert_eq!(different(&k, None), Val::Num(2.0), "from the start value");
        let b = var("b", 1, Type::Boolean, Causality::Input, Variability::Discrete, None);
        assert_eq!(different(&b, Some(&Val::Num(1.0))), Val::Num(0.0));
        let s = var("s", 2, Type::String, Causality::Parameter, Variability::Fixed, None);
        assert_eq!(different(&s, Some(&Val::Text(Some("runner validate".into())))), Val::Text(Some("runner validate 2".into())));
        assert_eq!(same_value(&s, None), Val::Text(Some(String::new())));
        assert_eq!(same_value(&k, None), Val::Num(1.0));
    }

    #[test]
    fn values_compare_bit_for_bit() {
        assert!(Val::Num(f64::NAN).same(&Val::Num(f64::NAN)));
        assert!(!Val::Num(0.0).same(&Val::Num(-0.0)));
        assert_eq!(Val::Text(None).shown(), "NULL");
        let model = Model { vars: vec![var("x", 0, Type::Real, Causality::Output, Variability::Continuous, None)], ..Model::default() };
        let before = HashMap::from([("x".to_owned(), Val::Num(1.0))]);
        let after = HashMap::from([("x".to_owned(), Val::Num(2.0))]);
        assert_eq!(changed(&before, &after, &model).map(|c| c.0), Some("x".to_owned()));
        assert_eq!(changed(&before, &before, &model), None);
    }
}
