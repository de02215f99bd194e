//! The rules of the FMI 3.0 standard a description can break without being malformed XML: at
//! least the ones fmpy's validation applies (unique names and value references, one
//! independent variable, legal causality/variability/initial, required and forbidden start
//! values, units, model structure), plus references, ranges and array sizes.

use std::collections::{HashMap, HashSet};

use super::*;

fn is_c_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    matches!(chars.next(), Some(c) if c == '_' || c.is_ascii_alphabetic()) && chars.all(|c| c == '_' || c.is_ascii_alphanumeric())
}

fn named(v: &Variable) -> String {
    format!("variable '{}' (valueReference {})", v.name, v.value_reference)
}

pub(super) fn check(md: &ModelDescription) -> Vec<String> {
    let mut problems = Vec::new();
    check_header(md, &mut problems);
    check_definitions(md, &mut problems);
    let by_vr = check_names_and_references(md, &mut problems);
    for v in &md.model_variables {
        check_variable(md, v, &by_vr, &mut problems);
    }
    check_model_structure(md, &by_vr, &mut problems);
    if let Some(d) = &md.default_experiment {
        if let (Some(start), Some(stop)) = (d.start_time, d.stop_time) {
            if stop <= start || stop.is_nan() || start.is_nan() {
                problems.push(format!("DefaultExperiment: stopTime {stop} must be after startTime {start}"));
            }
        }
        if let Some(t) = d.tolerance.filter(|t| !(*t > 0.0 && t.is_finite())) {
            problems.push(format!("DefaultExperiment: tolerance {t} must be a positive number"));
        }
        if let Some(h) = d.step_size.filter(|h| !(*h > 0.0 && h.is_finite())) {
            problems.push(format!("DefaultExperiment: stepSize {h} must be a positive number"));
        }
    }
    problems
}

fn check_header(md: &ModelDescription, problems: &mut Vec<String>) {
    if md.model_name.trim().is_empty() {
        problems.push("modelName must not be empty".to_owned());
    }
    if md.instantiation_token.trim().is_empty() {
        problems.push("instantiationToken must not be empty".to_owned());
    }
    let interfaces = [
        ("ModelExchange", md.model_exchange.as_ref().map(|i| &i.common)),
        ("CoSimulation", md.co_simulation.as_ref().map(|i| &i.common)),
        ("ScheduledExecution", md.scheduled_execution.as_ref().map(|i| &i.common)),
    ];
    if interfaces.iter().all(|(_, i)| i.is_none()) {
        problems.push("the FMU declares no interface (ModelExchange, CoSimulation or ScheduledExecution)".to_owned());
    }
    for (name, common) in interfaces {
        if let Some(c) = common {
            if !is_c_identifier(&c.model_identifier) {
                problems.push(format!("{name}: modelIdentifier '{}' is not a C identifier", c.model_identifier));
            }
        }
    }
    if let Some(cs) = &md.co_simulation {
        if let Some(h) = cs.fixed_internal_step_size.filter(|h| !(*h > 0.0 && h.is_finite())) {
            problems.push(format!("CoSimulation: fixedInternalStepSize {h} must be a positive number"));
        }
    }
}

fn duplicates<'a>(names: impl Iterator<Item = &'a str>, what: &str, problems: &mut Vec<String>) {
    let mut seen = HashSet::new();
    for n in names {
        if !seen.insert(n) {
            problems.push(format!("{what} '{n}' is defined more than once"));
        }
    }
}

fn check_definitions(md: &ModelDescription, problems: &mut Vec<String>) {
    duplicates(md.unit_definitions.iter().map(|u| u.name.as_str()), "Unit", problems);
    for u in &md.unit_definitions {
        duplicates(u.display_units.iter().map(|d| d.name.as_str()), &format!("DisplayUnit of unit '{}'", u.name), problems);
    }
    duplicates(md.type_definitions.iter().map(|t| t.name.as_str()), "TypeDefinition", problems);
    duplicates(md.log_categories.iter().map(|c| c.name.as_str()), "log Category", problems);
    for t in &md.type_definitions {
        match &t.kind {
            TypeKind::Float(_, f) => check_units(md, &format!("type '{}'", t.name), f.unit.as_deref(), f.display_unit.as_deref(), problems),
            TypeKind::Enumeration { items, .. } => {
                if items.is_empty() {
                    problems.push(format!("EnumerationType '{}' has no Item", t.name));
                }
                duplicates(items.iter().map(|i| i.name.as_str()), &format!("Item of '{}'", t.name), problems);
            }
            _ => {}
        }
    }
}

fn check_units(md: &ModelDescription, what: &str, unit: Option<&str>, display_unit: Option<&str>, problems: &mut Vec<String>) {
    match (unit, display_unit) {
        (Some(u), du) => match md.unit(u) {
            None => problems.push(format!("{what}: the unit '{u}' is not defined in UnitDefinitions")),
            Some(def) => {
                if let Some(du) = du.filter(|du| !def.display_units.iter().any(|d| d.name == *du)) {
                    problems.push(format!("{what}: '{du}' is not a DisplayUnit of the unit '{u}'"));
                }
            }
        },
        (None, Some(du)) => problems.push(format!("{what}: displayUnit '{du}' without a unit")),
        (None, None) => {}
    }
}

fn check_names_and_references<'a>(md: &'a ModelDescription, problems: &mut Vec<String>) -> HashMap<u32, &'a Variable> {
    let mut names = HashSet::new();
    let mut by_vr: HashMap<u32, &Variable> = HashMap::new();
    for v in &md.model_variables {
        if v.name.trim().is_empty() {
            problems.push(format!("the variable with valueReference {} has an empty name", v.value_reference));
        }
        if !names.insert(v.name.as_str()) {
            problems.push(format!("the variable name '{}' is not unique", v.name));
        }
        for a in &v.aliases {
            if !names.insert(a.name.as_str()) {
                problems.push(format!("the alias name '{}' of {} is not unique", a.name, named(v)));
            }
        }
        if let Some(other) = by_vr.insert(v.value_reference, v) {
            problems.push(format!("{} has the same value reference as variable '{}'", named(v), other.name));
        }
    }
    let independent = md.model_variables.iter().filter(|v| v.causality() == Causality::Independent).count();
    if independent != 1 {
        problems.push(format!("exactly one independent variable must be defined, found {independent}"));
    }
    by_vr
}

/// The number of array elements of `v`, when its dimensions can be resolved from start values.
fn element_count(md: &ModelDescription, v: &Variable) -> Option<u64> {
    md.start_shape(v).map(|shape| shape.iter().product())
}

fn check_variable(md: &ModelDescription, v: &Variable, by_vr: &HashMap<u32, &Variable>, problems: &mut Vec<String>) {
    let what = named(v);
    let (causality, variability) = (v.causality(), v.variability());
    let is_float = matches!(v.kind, VariableKind::Float { .. });
    let is_clock = matches!(v.kind, VariableKind::Clock(_));
    if !is_float && variability == Variability::Continuous {
        problems.push(format!("{what} is of type {} and must not have variability=\"continuous\"", v.base_type()));
    }
    if causality == Causality::Independent {
        if !is_float || variability != Variability::Continuous {
            problems.push(format!("{what}: the independent variable must be a continuous Float32 or Float64"));
        }
        if v.has_start() || v.initial.is_some() {
            problems.push(format!("{what}: the independent variable must have neither start nor initial"));
        }
    } else if !is_clock {
        let allowed = allowed_initials(causality, variability);
        if allowed.is_empty() {
            problems.push(format!("{what}: causality=\"{causality}\" with variability=\"{variability}\" is not allowed"));
        } else if let Some(initial) = v.initial.filter(|i| !allowed.contains(i)) {
            let list: Vec<&str> = allowed.iter().map(|i| i.as_str()).collect();
            problems.push(format!("{what}: initial=\"{initial}\" is not allowed with causality=\"{causality}\" and variability=\"{variability}\" (allowed: {})", list.join(", ")));
        }
        let initial = v.initial();
        let needs_start = matches!(initial, Some(Initial::Exact | Initial::Approx)) || causality == Causality::Input;
        if needs_start && !v.has_start() {
            problems.push(format!(
                "{what} has no start value (required with causality=\"{causality}\" and initial=\"{}\")",
                initial.map_or("-", |i| i.as_str())
            ));
        }
        if initial == Some(Initial::Calculated) && v.has_start() {
            problems.push(format!("{what} has initial=\"calculated\" but provides a start value"));
        }
    }
    if v.has_start() {
        let expected = if v.dimensions.is_empty() { Some(1) } else { element_count(md, v) };
        let given = v.start_len() as u64;
        // An array may give one start value for every element, or one for all of them.
        if let Some(n) = expected.filter(|&n| given != n && !(given == 1 && n > 1)) {
            problems.push(format!("{what} has {given} start value(s) but {n} element(s)"));
        }
    }
    check_kind(md, v, &what, problems);
    for d in &v.dimensions {
        if let Dimension::Variable(vr) = d {
            match by_vr.get(vr) {
                None => problems.push(format!("{what}: a Dimension refers to valueReference {vr}, which is no variable")),
                Some(p) => {
                    let integral = matches!(p.kind, VariableKind::Int { .. });
                    let fixed = p.causality() == Causality::StructuralParameter || p.variability() == Variability::Constant;
                    if !(integral && fixed && p.dimensions.is_empty()) {
                        problems.push(format!(
                            "{what}: a Dimension refers to '{}', which is not a scalar integer structural parameter or constant",
                            p.name
                        ));
                    }
                }
            }
        }
    }
    if let Some(vr) = v.previous {
        if !by_vr.contains_key(&vr) {
            problems.push(format!("{what}: previous refers to valueReference {vr}, which is no variable"));
        }
    }
    for vr in v.clocks.iter().flatten() {
        if !by_vr.get(vr).is_some_and(|c| matches!(c.kind, VariableKind::Clock(_))) {
            problems.push(format!("{what}: clocks refers to valueReference {vr}, which is not a Clock"));
        }
    }
    if let Some(state) = v.derivative() {
        if !by_vr.get(&state).is_some_and(|s| matches!(s.kind, VariableKind::Float { .. })) {
            problems.push(format!("{what}: derivative refers to valueReference {state}, which is not a Float variable"));
        }
    }
    for a in &v.aliases {
        if a.display_unit.is_some() {
            check_units(md, &format!("alias '{}' of {what}", a.name), md.unit_of(v), a.display_unit.as_deref(), problems);
        }
    }
}

fn check_kind(md: &ModelDescription, v: &Variable, what: &str, problems: &mut Vec<String>) {
    let declared = v.declared_type.as_deref().map(|name| (name, md.type_definition(name)));
    if let Some((name, None)) = declared {
        problems.push(format!("{what}: declaredType '{name}' is not defined in TypeDefinitions"));
    }
    let declared = declared.and_then(|(_, t)| t);
    match &v.kind {
        VariableKind::Float { precision, attributes, start, .. } => {
            if let Some(t) = declared.filter(|t| !matches!(t.kind, TypeKind::Float(p, _) if p == *precision)) {
                problems.push(format!("{what}: declaredType '{}' is not a {precision} type", t.name));
            }
            let unit = attributes.unit.as_deref().or_else(|| md.unit_of(v));
            check_units(md, what, unit, md.display_unit_of(v), problems);
            let (min, max) = (attributes.min, attributes.max);
            if let (Some(lo), Some(hi)) = (min, max) {
                if lo > hi {
                    problems.push(format!("{what}: min {lo} is greater than max {hi}"));
                }
            }
            for s in start.iter().flatten() {
                if min.is_some_and(|lo| *s < lo) || max.is_some_and(|hi| *s > hi) {
                    problems.push(format!(
                        "{what}: start {s} is outside [{}, {}]",
                        min.map_or("-inf".into(), |x| x.to_string()),
                        max.map_or("inf".into(), |x| x.to_string())
                    ));
                }
            }
            if let Some(n) = attributes.nominal.filter(|n| !(*n > 0.0 && n.is_finite())) {
                problems.push(format!("{what}: nominal {n} must be a positive number"));
            }
        }
        VariableKind::Int { ty, attributes, start } => {
            if let Some(t) = declared.filter(|t| !matches!(t.kind, TypeKind::Int(i, _) if i == *ty)) {
                problems.push(format!("{what}: declaredType '{}' is not a {ty} type", t.name));
            }
            check_int_range(what, attributes, start.as_deref(), problems);
        }
        VariableKind::Enumeration { attributes, start } => match declared.map(|t| &t.kind) {
            Some(TypeKind::Enumeration { items, .. }) => {
                check_int_range(what, attributes, start.as_deref(), problems);
                for s in start.iter().flatten() {
                    if !items.iter().any(|i| i128::from(i.value) == *s) {
                        problems.push(format!(
                            "{what}: start {s} is not a value of the enumeration '{}'",
                            v.declared_type.as_deref().unwrap_or("")
                        ));
                    }
                }
            }
            Some(_) => problems.push(format!("{what}: an Enumeration's declaredType must be an EnumerationType")),
            None if v.declared_type.is_none() => problems.push(format!("{what}: an Enumeration must have a declaredType")),
            None => {}
        },
        VariableKind::Boolean { .. } | VariableKind::String { .. } | VariableKind::Binary { .. } | VariableKind::Clock(_) => {
            let matches = |t: &TypeDefinition| {
                matches!(
                    (&v.kind, &t.kind),
                    (VariableKind::Boolean { .. }, TypeKind::Boolean)
                        | (VariableKind::String { .. }, TypeKind::String)
                        | (VariableKind::Binary { .. }, TypeKind::Binary { .. })
                        | (VariableKind::Clock(_), TypeKind::Clock(_))
                )
            };
            if let Some(t) = declared.filter(|t| !matches(t)) {
                problems.push(format!("{what}: declaredType '{}' is not a {} type", t.name, v.base_type()));
            }
            if let VariableKind::Binary { max_size: Some(m), start: Some(s), .. } = &v.kind {
                if let Some(long) = s.iter().find(|b| b.len() as u64 > *m) {
                    problems.push(format!("{what}: a start value of {} bytes exceeds maxSize {m}", long.len()));
                }
            }
        }
    }
}

fn check_int_range(what: &str, attributes: &Int, start: Option<&[i128]>, problems: &mut Vec<String>) {
    if let (Some(lo), Some(hi)) = (attributes.min, attributes.max) {
        if lo > hi {
            problems.push(format!("{what}: min {lo} is greater than max {hi}"));
        }
    }
    for s in start.into_iter().flatten() {
        if attributes.min.is_some_and(|lo| *s < lo) || attributes.max.is_some_and(|hi| *s > hi) {
            problems.push(format!(
                "{what}: start {s} is outside [{}, {}]",
                attributes.min.map_or("-".into(), |x| x.to_string()),
                attributes.max.map_or("-".into(), |x| x.to_string())
            ));
        }
    }
}

fn check_model_structure(md: &ModelDescription, by_vr: &HashMap<u32, &Variable>, problems: &mut Vec<String>) {
    let s = &md.model_structure;
    let lists = [
        ("Output", &s.outputs),
        ("ContinuousStateDerivative", &s.continuous_state_derivatives),
        ("ClockedState", &s.clocked_states),
        ("InitialUnknown", &s.initial_unknowns),
        ("EventIndicator", &s.event_indicators),
    ];
    for (name, list) in lists {
        let mut seen = HashSet::new();
        for u in list {
            if !by_vr.contains_key(&u.value_reference) {
                problems.push(format!("ModelStructure: {name} valueReference {} is no variable", u.value_reference));
            }
            if !seen.insert(u.value_reference) {
                problems.push(format!("ModelStructure: {name} valueReference {} is listed twice", u.value_reference));
            }
            for d in u.dependencies.iter().flatten() {
                if !by_vr.contains_key(d) {
                    problems
                        .push(format!("ModelStructure: {name} {} depends on valueReference {d}, which is no variable", u.value_reference));
                }
            }
            match (&u.dependencies, &u.dependencies_kind) {
                (None, Some(_)) => {
                    problems.push(format!("ModelStructure: {name} {} has dependenciesKind without dependencies", u.value_reference))
                }
                (Some(d), Some(k)) if d.len() != k.len() => problems.push(format!(
                    "ModelStructure: {name} {} lists {} dependencies but {} dependenciesKind",
                    u.value_reference,
                    d.len(),
                    k.len()
                )),
                _ => {}
            }
        }
    }
    let listed = |list: &[Unknown]| list.iter().map(|u| u.value_reference).collect::<HashSet<u32>>();
    let outputs: HashSet<u32> =
        md.model_variables.iter().filter(|v| v.causality() == Causality::Output).map(|v| v.value_reference).collect();
    if listed(&s.outputs) != outputs {
        problems.push("ModelStructure: Output must list exactly the variables with causality=\"output\"".to_owned());
    }
    for u in &s.continuous_state_derivatives {
        if by_vr.get(&u.value_reference).is_some_and(|v| v.derivative().is_none()) {
            problems.push(format!("ModelStructure: ContinuousStateDerivative {} has no derivative attribute", u.value_reference));
        }
    }
    // The expected initial unknowns, as fmpy's validation computes them.
    let mut expected = HashSet::new();
    for v in md.model_variables.iter().filter(|v| !matches!(v.kind, VariableKind::Clock(_))) {
        let calculated = matches!(v.initial(), Some(Initial::Approx | Initial::Calculated));
        if (v.causality() == Causality::Output && calculated && v.clocks.is_none()) || v.causality() == Causality::CalculatedParameter {
            expected.insert(v.value_reference);
        }
    }
    for u in &s.continuous_state_derivatives {
        if let Some(der) = by_vr.get(&u.value_reference) {
            for v in [Some(*der), der.derivative().and_then(|vr| by_vr.get(&vr).copied())].into_iter().flatten() {
                if matches!(v.initial(), Some(Initial::Approx | Initial::Calculated)) {
                    expected.insert(v.value_reference);
                }
            }
        }
    }
    let actual = listed(&s.initial_unknowns);
    if actual != expected {
        let names = |set: &HashSet<u32>| {
            let mut n: Vec<&str> = set.iter().filter_map(|vr| by_vr.get(vr)).map(|v| v.name.as_str()).collect();
            n.sort();
            n.join(", ")
        };
        problems.push(format!("ModelStructure: InitialUnknown lists {{{}}}, expected {{{}}}", names(&actual), names(&expected)));
    }
}
