//! `ModelDescription::check`: the FMI 2.0 rules that fmpy's validation applies (plus a few
//! neighbouring ones from the standard), checked on the typed model.
//!
//! Each rule appends human-readable lines; nothing stops at the first problem, so an exporter
//! test sees everything that is wrong at once.

use std::collections::hash_map::Entry;
use std::collections::{BTreeSet, HashMap, HashSet};

use super::*;

/// Which of the standard's rules a problem breaks, for tools that group them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Rule {
    /// fmiVersion, modelName, guid, the interfaces and their modelIdentifiers.
    Header,
    /// Unique names and value references, one independent variable.
    Names,
    /// The causality/variability combination and the `initial` it allows.
    Initial,
    /// Which variables need, and which must not have, a start value.
    Start,
    /// min <= max, min <= start <= max, nominal > 0.
    Ranges,
    /// `declaredType` names a SimpleType of the same kind.
    DeclaredType,
    /// Units and display units used are defined.
    Units,
    /// `derivative` points at another Real variable.
    Derivative,
    /// Unique names inside UnitDefinitions, TypeDefinitions and LogCategories.
    Definitions,
    /// ModelStructure lists and their dependencies.
    ModelStructure,
    /// DefaultExperiment values.
    DefaultExperiment,
}

/// One problem `check` found: the rule, the variable it concerns (if one) and the message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    pub rule: Rule,
    pub variable: Option<String>,
    pub message: String,
}

/// The problems found so far, each tagged with the rule being checked when it was pushed.
pub(super) struct Problems {
    list: Vec<Problem>,
    rule: Rule,
    variable: Option<String>,
}

impl Problems {
    fn push(&mut self, message: String) {
        self.list.push(Problem { rule: self.rule, variable: self.variable.clone(), message });
    }

    /// Checks `rule` next (about `variable`, when it is one variable's).
    fn now(&mut self, rule: Rule, variable: Option<&str>) -> &mut Problems {
        self.rule = rule;
        self.variable = variable.map(str::to_owned);
        self
    }
}

/// Runs every rule and returns the problems found (empty means clean).
pub(super) fn check(md: &ModelDescription) -> Vec<Problem> {
    let mut problems = Problems { list: Vec::new(), rule: Rule::Header, variable: None };
    let lookup = Lookup::new(md);
    check_header(md, problems.now(Rule::Header, None));
    check_names_and_references(md, problems.now(Rule::Names, None));
    for (position, variable) in md.model_variables.iter().enumerate() {
        let at = at(variable, position as u32 + 1);
        let name = Some(variable.name.as_str());
        check_combination(variable, &at, problems.now(Rule::Initial, name));
        check_start(variable, &at, problems.now(Rule::Start, name));
        check_ranges(&lookup, variable, &at, problems.now(Rule::Ranges, name));
        check_declared_type(&lookup, variable, &at, problems.now(Rule::DeclaredType, name));
        check_units(&lookup, variable, &at, problems.now(Rule::Units, name));
        check_derivative(md, variable, &at, problems.now(Rule::Derivative, name));
    }
    check_definitions(md, &lookup, problems.now(Rule::Definitions, None));
    check_model_structure(md, problems.now(Rule::ModelStructure, None));
    check_default_experiment(md, problems.now(Rule::DefaultExperiment, None));
    problems.list
}

/// Units and simple types by name: exports from large models have 10^5 variables, so the
/// per-variable lookups must not be linear scans.
struct Lookup<'a> {
    units: HashMap<&'a str, &'a Unit>,
    types: HashMap<&'a str, &'a SimpleType>,
}

impl<'a> Lookup<'a> {
    fn new(md: &'a ModelDescription) -> Self {
        // Reversed so that, as with a linear search, the first of duplicated names wins.
        Lookup {
            units: md.unit_definitions.iter().rev().map(|u| (u.name.as_str(), u)).collect(),
            types: md.type_definitions.iter().rev().map(|t| (t.name.as_str(), t)).collect(),
        }
    }

    /// The Real SimpleType a Real variable declares, if it exists and is Real.
    fn declared_real(&self, real: &RealVariable) -> Option<&'a RealAttributes> {
        match &self.types.get(real.declared_type.as_deref()?)?.kind {
            SimpleTypeKind::Real(t) => Some(t),
            _ => None,
        }
    }
}

/// How a variable is named in messages: name plus 1-based index, the two things a reader
/// of modelDescription.xml can search for.
fn at(variable: &ScalarVariable, index: u32) -> String {
    format!("variable '{}' (index {index})", variable.name)
}

fn check_header(md: &ModelDescription, problems: &mut Problems) {
    if md.fmi_version != "2.0" {
        problems.push(format!("fmiVersion is \"{}\", must be \"2.0\"", md.fmi_version));
    }
    if md.model_name.is_empty() {
        problems.push("modelName is empty".to_string());
    }
    if md.guid.is_empty() {
        problems.push("guid is empty".to_string());
    }
    if md.model_exchange.is_none() && md.co_simulation.is_none() {
        problems.push("neither ModelExchange nor CoSimulation is present".to_string());
    }
    for (interface, identifier) in [
        ("ModelExchange", md.model_exchange.as_ref().map(|m| &m.common.model_identifier)),
        ("CoSimulation", md.co_simulation.as_ref().map(|c| &c.common.model_identifier)),
    ] {
        if let Some(identifier) = identifier {
            let valid_c_name = identifier.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
                && identifier.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !valid_c_name {
                problems.push(format!("{interface} modelIdentifier \"{identifier}\" is not a valid C identifier"));
            }
        }
    }
}

/// Unique names, and value references unique within each base type's fmi2Get/Set space.
fn check_names_and_references(md: &ModelDescription, problems: &mut Problems) {
    let mut names: HashMap<&str, u32> = HashMap::new();
    let mut references: HashMap<(TypeKind, u32), (&str, u32)> = HashMap::new();
    for (position, variable) in md.model_variables.iter().enumerate() {
        let index = position as u32 + 1;
        if variable.name.is_empty() {
            problems.push(format!("variable at index {index} has an empty name"));
        }
        // Neither naming convention allows these (fmpy checks them for "flat").
        for (c, what) in [('\r', "carriage return"), ('\n', "line feed"), ('\t', "tab")] {
            if variable.name.contains(c) {
                problems.push(format!("variable name {:?} (index {index}) contains a {what}", variable.name));
            }
        }
        match names.entry(&variable.name) {
            Entry::Occupied(first) => {
                problems.push(format!("variable name '{}' is not unique (indices {} and {index})", variable.name, first.get()))
            }
            Entry::Vacant(slot) => {
                slot.insert(index);
            }
        }
        let base = variable.type_kind().base_type();
        match references.get(&(base, variable.value_reference)) {
            // FMI 2.0 allows a shared reference only for alias variables (identical values at all
            // times); our exporter never writes aliases, so a shared one is reported.
            Some((other, other_index)) => problems.push(format!(
                "{} value reference {} is used by both '{other}' (index {other_index}) and '{}' (index {index}); \
                 FMI 2.0 allows this only for alias variables",
                base, variable.value_reference, variable.name
            )),
            None => {
                references.insert((base, variable.value_reference), (&variable.name, index));
            }
        }
    }
    let independents: Vec<&str> =
        md.model_variables.iter().filter(|v| v.causality() == Causality::Independent).map(|v| v.name.as_str()).collect();
    if independents.len() > 1 {
        problems.push(format!("more than one variable has causality=\"independent\": {}", independents.join(", ")));
    }
}

/// The standard's causality/variability table and the `initial` values each cell allows.
fn check_combination(variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    let causality = variable.causality();
    let variability = variability_text(variable);
    if variable.type_kind() != TypeKind::Real && variable.variability() == Variability::Continuous {
        problems.push(format!(
            "{at} is of type {} and must not have variability=\"continuous\"{}",
            variable.type_kind(),
            if variable.variability.is_none() { " (the default when variability is absent)" } else { "" }
        ));
    }
    if !causality.allows(variable.variability()) {
        problems.push(format!("{at}: the combination causality=\"{causality}\" and variability=\"{variability}\" is not allowed"));
        return;
    }
    if let Some(initial) = variable.initial {
        let allowed = Initial::allowed_for(causality, variable.variability());
        if allowed.is_empty() {
            problems.push(format!("{at} has causality=\"{causality}\" and must not define initial (it has initial=\"{initial}\")"));
        } else if !allowed.contains(&initial) {
            let allowed: Vec<&str> = allowed.iter().map(|i| i.as_str()).collect();
            problems.push(format!(
                "{at}: initial=\"{initial}\" is not allowed with causality=\"{causality}\" and \
                 variability=\"{variability}\" (allowed: {})",
                allowed.join(", ")
            ));
        }
    }
}

fn variability_text(variable: &ScalarVariable) -> String {
    match variable.variability {
        Some(v) => v.to_string(),
        None => format!("{} (default)", Variability::Continuous),
    }
}

/// Start values: required for exact/approx and inputs, forbidden for calculated and independent.
fn check_start(variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    let causality = variable.causality();
    let initial = variable.initial();
    let has_start = variable.has_start();
    let initial_text = |i: Initial| match variable.initial {
        Some(_) => format!("initial=\"{i}\""),
        None => format!("initial=\"{i}\" (the default for its causality and variability)"),
    };
    if !has_start {
        if causality == Causality::Input {
            problems.push(format!("{at} has causality=\"input\" but no start value"));
        } else if let Some(i @ (Initial::Exact | Initial::Approx)) = initial {
            problems.push(format!("{at} has {} but no start value", initial_text(i)));
        }
    } else if causality == Causality::Independent {
        problems.push(format!("{at} has causality=\"independent\" but provides a start value"));
    } else if initial == Some(Initial::Calculated) {
        problems.push(format!("{at} has {} but provides a start value", initial_text(Initial::Calculated)));
    }
    if causality == Causality::Independent && variable.type_kind() != TypeKind::Real {
        problems.push(format!("{at} has causality=\"independent\" but is not Real"));
    }
}

/// min <= max, min <= start <= max, nominal > 0; bounds not on the variable come from its
/// declared type, as the standard's attribute inheritance says.
fn check_ranges(lookup: &Lookup, variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    fn range<T: PartialOrd + std::fmt::Display + Copy>(
        min: Option<T>,
        max: Option<T>,
        start: Option<T>,
        at: &str,
        problems: &mut Problems,
    ) {
        if let (Some(min), Some(max)) = (min, max) {
            if min > max {
                problems.push(format!("{at} has min={min} greater than max={max}"));
            }
        }
        if let Some(start) = start {
            if min.is_some_and(|min| start < min) || max.is_some_and(|max| start > max) {
                let show = |v: Option<T>| v.map_or("-".to_string(), |v| v.to_string());
                problems.push(format!("{at} has start={start} outside [min, max] = [{}, {}]", show(min), show(max)));
            }
        }
    }
    match &variable.var_type {
        VariableType::Real(r) => {
            let declared = lookup.declared_real(r);
            let min = r.attributes.min.or_else(|| declared.and_then(|t| t.min));
            let max = r.attributes.max.or_else(|| declared.and_then(|t| t.max));
            range(min, max, r.start, at, problems);
            if let Some(nominal) = r.attributes.nominal {
                if nominal.is_nan() || nominal <= 0.0 {
                    problems.push(format!("{at} has nominal={nominal}, must be > 0"));
                }
            }
        }
        VariableType::Integer(i) => {
            let declared = i.declared_type.as_deref().and_then(|name| match &lookup.types.get(name)?.kind {
                SimpleTypeKind::Integer(t) => Some(t),
                _ => None,
            });
            let min = i.attributes.min.or_else(|| declared.and_then(|t| t.min));
            let max = i.attributes.max.or_else(|| declared.and_then(|t| t.max));
            range(min, max, i.start, at, problems)
        }
        VariableType::Enumeration(e) => range(e.attributes.min, e.attributes.max, e.start, at, problems),
        VariableType::Boolean(_) | VariableType::String(_) => {}
    }
}

/// `declaredType` must name a SimpleType of the same kind; Enumerations must declare one.
fn check_declared_type(lookup: &Lookup, variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    let kind = variable.type_kind();
    match variable.declared_type() {
        None if kind == TypeKind::Enumeration => {
            problems.push(format!("{at} is an Enumeration without the required declaredType"));
        }
        None => {}
        Some(name) => match lookup.types.get(name) {
            None => problems.push(format!("{at} has declaredType \"{name}\", which is not in TypeDefinitions")),
            Some(t) if t.type_kind() != kind => {
                problems.push(format!("{at} is {kind} but its declaredType \"{name}\" is of type {}", t.type_kind()))
            }
            Some(_) => {}
        },
    }
}

/// Units referenced must be defined; display units must belong to the unit.
fn check_units(lookup: &Lookup, variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    let Some(real) = variable.as_real() else { return };
    // Same resolution as ModelDescription::unit_of/display_unit_of: own attribute first.
    let declared = lookup.declared_real(real);
    let unit = real.attributes.unit.as_deref().or_else(|| declared.and_then(|t| t.unit.as_deref()));
    let display_unit = real.attributes.display_unit.as_deref().or_else(|| declared.and_then(|t| t.display_unit.as_deref()));
    check_unit_pair(lookup, unit, display_unit, at, problems);
}

fn check_unit_pair(lookup: &Lookup, unit: Option<&str>, display_unit: Option<&str>, at: &str, problems: &mut Problems) {
    let defined = unit.and_then(|u| lookup.units.get(u));
    if let (Some(unit), None) = (unit, defined) {
        problems.push(format!("{at} has unit \"{unit}\", which is not defined in UnitDefinitions"));
    }
    if let Some(display) = display_unit {
        match (unit, defined) {
            (None, _) => problems.push(format!("{at} has displayUnit \"{display}\" but no unit")),
            (Some(unit), Some(u)) if !u.display_units.iter().any(|d| d.name == display) => {
                problems.push(format!("{at} has displayUnit \"{display}\", which is not a DisplayUnit of unit \"{unit}\""))
            }
            _ => {}
        }
    }
}

/// `derivative` must point at another existing Real variable.
fn check_derivative(md: &ModelDescription, variable: &ScalarVariable, at: &str, problems: &mut Problems) {
    let Some(state) = variable.derivative() else { return };
    match md.variable_by_index(state) {
        None => problems.push(format!("{at} has derivative=\"{state}\", which is not a variable index (1..={})", md.model_variables.len())),
        Some(s) if s.type_kind() != TypeKind::Real => {
            problems.push(format!("{at} has derivative=\"{state}\" pointing at non-Real variable '{}'", s.name))
        }
        Some(s) if std::ptr::eq(s, variable) => problems.push(format!("{at} has derivative=\"{state}\" pointing at itself")),
        Some(_) => {}
    }
}

/// Uniqueness inside UnitDefinitions, TypeDefinitions and LogCategories, and units of types.
fn check_definitions(md: &ModelDescription, lookup: &Lookup, problems: &mut Problems) {
    duplicates(md.unit_definitions.iter().map(|u| u.name.as_str()), "Unit name", problems);
    for unit in &md.unit_definitions {
        duplicates(unit.display_units.iter().map(|d| d.name.as_str()), &format!("DisplayUnit name in unit \"{}\"", unit.name), problems);
    }
    duplicates(md.type_definitions.iter().map(|t| t.name.as_str()), "SimpleType name", problems);
    duplicates(md.log_categories.iter().map(|c| c.name.as_str()), "log category name", problems);
    for simple in &md.type_definitions {
        let at = format!("SimpleType '{}'", simple.name);
        match &simple.kind {
            SimpleTypeKind::Real(r) => {
                // A type's units are a units problem, whatever list they sit in.
                let rule = std::mem::replace(&mut problems.rule, Rule::Units);
                check_unit_pair(lookup, r.unit.as_deref(), r.display_unit.as_deref(), &at, problems);
                problems.rule = rule;
                if let (Some(min), Some(max)) = (r.min, r.max) {
                    if min > max {
                        problems.push(format!("{at} has min={min} greater than max={max}"));
                    }
                }
            }
            SimpleTypeKind::Enumeration(e) => {
                if e.items.is_empty() {
                    problems.push(format!("{at} is an Enumeration without items"));
                }
                let values: Vec<String> = e.items.iter().map(|i| i.value.to_string()).collect();
                duplicates(values.iter().map(String::as_str), &format!("item value in {at}"), problems);
                duplicates(e.items.iter().map(|i| i.name.as_str()), &format!("item name in {at}"), problems);
            }
            _ => {}
        }
    }
}

fn duplicates<'a>(names: impl Iterator<Item = &'a str>, what: &str, problems: &mut Problems) {
    let mut seen = HashSet::new();
    let mut reported = HashSet::new();
    for name in names {
        if !seen.insert(name) && reported.insert(name) {
            problems.push(format!("{what} \"{name}\" is not unique"));
        }
    }
}

/// Indices, dependency lists, and the exact contents of Outputs and InitialUnknowns (2.2.8).
fn check_model_structure(md: &ModelDescription, problems: &mut Problems) {
    let count = md.model_variables.len() as u32;
    let structure = &md.model_structure;
    let lists =
        [("Outputs", &structure.outputs), ("Derivatives", &structure.derivatives), ("InitialUnknowns", &structure.initial_unknowns)];
    for (list_name, list) in lists {
        let mut seen = HashSet::new();
        for (position, unknown) in list.iter().enumerate() {
            let at = format!("ModelStructure/{list_name}/Unknown #{} (index {})", position + 1, unknown.index);
            if md.variable_by_index(unknown.index).is_none() {
                problems.push(format!("{at} does not point at a variable (indices are 1-based, 1..={count})"));
            } else if !seen.insert(unknown.index) {
                problems.push(format!("{at} is listed more than once"));
            }
            if let Some(dependencies) = &unknown.dependencies {
                for &d in dependencies {
                    if md.variable_by_index(d).is_none() {
                        problems.push(format!("{at} has dependency {d}, which is not a variable index (1..={count})"));
                    }
                }
            }
            match (&unknown.dependencies, &unknown.dependencies_kind) {
                (None, Some(_)) => problems.push(format!("{at} has dependenciesKind without dependencies")),
                (Some(d), Some(k)) if d.len() != k.len() => {
                    problems.push(format!("{at} has {} dependencies but {} dependenciesKind entries", d.len(), k.len()))
                }
                _ => {}
            }
        }
    }

    let name_of = |index: u32| md.variable_by_index(index).map_or(format!("#{index}"), |v| v.name.clone());
    let listed = |list: &[Unknown]| -> BTreeSet<u32> { list.iter().map(|u| u.index).filter(|&i| i >= 1 && i <= count).collect() };
    let compare = |list_name: &str, expected: &BTreeSet<u32>, actual: &BTreeSet<u32>, why: &str, problems: &mut Problems| {
        let missing: Vec<String> = expected.difference(actual).map(|&i| name_of(i)).collect();
        let extra: Vec<String> = actual.difference(expected).map(|&i| name_of(i)).collect();
        if !missing.is_empty() {
            problems.push(format!("ModelStructure/{list_name} is missing {} ({why})", missing.join(", ")));
        }
        if !extra.is_empty() {
            problems.push(format!("ModelStructure/{list_name} must not list {} ({why})", extra.join(", ")));
        }
    };

    // Outputs: exactly the variables with causality output.
    let outputs: BTreeSet<u32> =
        (1..=count).filter(|&i| md.variable_by_index(i).is_some_and(|v| v.causality() == Causality::Output)).collect();
    compare("Outputs", &outputs, &listed(&structure.outputs), "it must list exactly the variables with causality=\"output\"", problems);

    // Derivatives: each entry must be a Real with a `derivative` attribute.
    for unknown in &structure.derivatives {
        if let Some(v) = md.variable_by_index(unknown.index) {
            if v.derivative().is_none() {
                problems.push(format!(
                    "ModelStructure/Derivatives lists '{}' (index {}), which has no derivative attribute",
                    v.name, unknown.index
                ));
            }
        }
    }

    // InitialUnknowns (FMI 2.0 section 2.2.8): outputs with initial approx/calculated, all
    // calculated parameters, and the states and derivatives listed under Derivatives with
    // initial approx/calculated.
    let not_exact = |v: &ScalarVariable| matches!(v.initial(), Some(Initial::Approx | Initial::Calculated));
    let mut expected: BTreeSet<u32> = (1..=count)
        .filter(|&i| {
            md.variable_by_index(i).is_some_and(|v| match v.causality() {
                Causality::Output => not_exact(v),
                Causality::CalculatedParameter => true,
                _ => false,
            })
        })
        .collect();
    for unknown in &structure.derivatives {
        let Some(derivative) = md.variable_by_index(unknown.index) else { continue };
        let state_index = derivative.derivative();
        for index in std::iter::once(unknown.index).chain(state_index) {
            if md.variable_by_index(index).is_some_and(not_exact) {
                expected.insert(index);
            }
        }
    }
    compare(
        "InitialUnknowns",
        &expected,
        &listed(&structure.initial_unknowns),
        "FMI 2.0 section 2.2.8: outputs and states/derivatives with initial approx or calculated, \
         and calculated parameters",
        problems,
    );
    if structure.initial_unknowns.windows(2).any(|w| w[0].index > w[1].index) {
        problems.push("ModelStructure/InitialUnknowns is not sorted by variable index".to_string());
    }
}

fn check_default_experiment(md: &ModelDescription, problems: &mut Problems) {
    let Some(experiment) = &md.default_experiment else { return };
    for (name, value) in [
        ("startTime", experiment.start_time),
        ("stopTime", experiment.stop_time),
        ("tolerance", experiment.tolerance),
        ("stepSize", experiment.step_size),
    ] {
        if value.is_some_and(|v| !v.is_finite()) {
            problems.push(format!("DefaultExperiment {name} is not a finite number"));
        }
    }
    if let (Some(start), Some(stop)) = (experiment.start_time, experiment.stop_time) {
        if stop <= start {
            problems.push(format!("DefaultExperiment stopTime={stop} is not greater than startTime={start}"));
        }
    }
    if let Some(tolerance) = experiment.tolerance {
        if tolerance <= 0.0 {
            problems.push(format!("DefaultExperiment tolerance={tolerance} must be > 0"));
        }
    }
    if let Some(step) = experiment.step_size {
        if step <= 0.0 {
            problems.push(format!("DefaultExperiment stepSize={step} must be > 0"));
        }
    }
}
