//! Writing an FMI 3.0 modelDescription.xml from the typed model, in the schema's element order;
//! defaulted attributes are written only when they differ from their default.

use super::*;
use crate::format_real;
use crate::tree::{self, Element};

fn float_text(precision: FloatType, v: f64) -> String {
    match precision {
        // Single precision's own shortest form: 0.1f32 is "0.1", not "0.10000000149011612".
        FloatType::Float32 if v.is_finite() => {
            let text = format!("{:?}", v as f32);
            text.strip_suffix(".0").map(str::to_owned).unwrap_or(text)
        }
        _ => format_real(v),
    }
}

fn flag(e: Element, name: &str, v: bool) -> Element {
    if v {
        e.with(name, "true")
    } else {
        e
    }
}

fn joined<T>(items: &[T], f: impl Fn(&T) -> String) -> String {
    items.iter().map(f).collect::<Vec<_>>().join(" ")
}

fn interface(name: &str, c: &InterfaceCommon) -> Element {
    let e = Element::new(name).with("modelIdentifier", c.model_identifier.clone());
    let e = flag(e, "needsExecutionTool", c.needs_execution_tool);
    let e = flag(e, "canBeInstantiatedOnlyOncePerProcess", c.can_be_instantiated_only_once_per_process);
    let e = flag(e, "canGetAndSetFMUState", c.can_get_and_set_fmu_state);
    let e = flag(e, "canSerializeFMUState", c.can_serialize_fmu_state);
    let e = flag(e, "providesDirectionalDerivatives", c.provides_directional_derivatives);
    let e = flag(e, "providesAdjointDerivatives", c.provides_adjoint_derivatives);
    flag(e, "providesPerElementDependencies", c.provides_per_element_dependencies)
}

fn float_attributes(e: Element, precision: FloatType, f: &Float) -> Element {
    let e = e.with_opt("quantity", f.quantity.clone()).with_opt("unit", f.unit.clone()).with_opt("displayUnit", f.display_unit.clone());
    let e = flag(e, "relativeQuantity", f.relative_quantity);
    let e = flag(e, "unbounded", f.unbounded);
    let num = |v: Option<f64>| v.map(|x| float_text(precision, x));
    e.with_opt("min", num(f.min)).with_opt("max", num(f.max)).with_opt("nominal", num(f.nominal))
}

fn int_attributes(e: Element, i: &Int) -> Element {
    e.with_opt("quantity", i.quantity.clone()).with_opt("min", i.min.map(|v| v.to_string())).with_opt("max", i.max.map(|v| v.to_string()))
}

fn clock_attributes(e: Element, c: &ClockAttributes) -> Element {
    let e = flag(e, "canBeDeactivated", c.can_be_deactivated);
    let e = e.with_opt("priority", c.priority.map(|v| v.to_string()));
    let e = e.with_opt("intervalVariability", c.interval_variability.map(|v| v.as_str().to_owned()));
    let e = e.with_opt("intervalDecimal", c.interval_decimal.map(format_real)).with_opt("shiftDecimal", c.shift_decimal.map(format_real));
    let e = flag(e, "supportsFraction", c.supports_fraction);
    e.with_opt("resolution", c.resolution.map(|v| v.to_string()))
        .with_opt("intervalCounter", c.interval_counter.map(|v| v.to_string()))
        .with_opt("shiftCounter", c.shift_counter.map(|v| v.to_string()))
}

fn type_definition(t: &TypeDefinition) -> Element {
    let base = match &t.kind {
        TypeKind::Float(p, _) => BaseType::Float(*p),
        TypeKind::Int(i, _) => BaseType::Int(*i),
        TypeKind::Boolean => BaseType::Boolean,
        TypeKind::String => BaseType::String,
        TypeKind::Binary { .. } => BaseType::Binary,
        TypeKind::Enumeration { .. } => BaseType::Enumeration,
        TypeKind::Clock(_) => BaseType::Clock,
    };
    let e = Element::new(&format!("{}Type", base.as_str())).with("name", t.name.clone()).with_opt("description", t.description.clone());
    match &t.kind {
        TypeKind::Float(p, f) => float_attributes(e, *p, f),
        TypeKind::Int(_, i) => int_attributes(e, i),
        TypeKind::Boolean | TypeKind::String => e,
        TypeKind::Binary { mime_type, max_size } => {
            e.with_opt("mimeType", mime_type.clone()).with_opt("maxSize", max_size.map(|v| v.to_string()))
        }
        TypeKind::Enumeration { quantity, items } => {
            let mut e = e.with_opt("quantity", quantity.clone());
            e.children = items
                .iter()
                .map(|i| {
                    Element::new("Item")
                        .with("name", i.name.clone())
                        .with("value", i.value.to_string())
                        .with_opt("description", i.description.clone())
                })
                .collect();
            e
        }
        TypeKind::Clock(c) => clock_attributes(e, c),
    }
}

fn variable(v: &Variable) -> Element {
    let e = Element::new(v.base_type().as_str()).with("name", v.name.clone()).with("valueReference", v.value_reference.to_string());
    let e = e.with_opt("description", v.description.clone());
    let e = e.with_opt("causality", v.causality.map(|c| c.as_str().to_owned()));
    let e = e.with_opt("variability", v.variability.map(|c| c.as_str().to_owned()));
    let e = e.with_opt("canHandleMultipleSetPerTimeInstant", v.can_handle_multiple_set_per_time_instant.map(|b| b.to_string()));
    let e = flag(e, "intermediateUpdate", v.intermediate_update);
    let e = e.with_opt("previous", v.previous.map(|p| p.to_string()));
    let e = e.with_opt("clocks", v.clocks.as_ref().map(|c| joined(c, u32::to_string)));
    let e = e.with_opt("declaredType", v.declared_type.clone());
    let e = e.with_opt("initial", v.initial.map(|i| i.as_str().to_owned()));
    let mut starts: Vec<Element> = Vec::new();
    let mut e = match &v.kind {
        VariableKind::Float { precision, attributes, start, derivative, reinit } => {
            let e = float_attributes(e, *precision, attributes);
            let e = e.with_opt("start", start.as_ref().map(|s| joined(s, |x| float_text(*precision, *x))));
            let e = e.with_opt("derivative", derivative.map(|d| d.to_string()));
            flag(e, "reinit", *reinit)
        }
        VariableKind::Int { attributes, start, .. } | VariableKind::Enumeration { attributes, start } => {
            int_attributes(e, attributes).with_opt("start", start.as_ref().map(|s| joined(s, i128::to_string)))
        }
        VariableKind::Boolean { start } => e.with_opt("start", start.as_ref().map(|s| joined(s, bool::to_string))),
        VariableKind::String { start } => {
            starts.extend(start.iter().flatten().map(|s| Element::new("Start").with("value", s.clone())));
            e
        }
        VariableKind::Binary { mime_type, max_size, start } => {
            starts.extend(start.iter().flatten().map(|s| Element::new("Start").with("value", hex(s))));
            e.with_opt("mimeType", mime_type.clone()).with_opt("maxSize", max_size.map(|m| m.to_string()))
        }
        VariableKind::Clock(c) => clock_attributes(e, c),
    };
    // Schema order of the children: Dimension, Alias, then Start (String, Binary).
    e.children.extend(v.dimensions.iter().map(|d| match d {
        Dimension::Fixed(n) => Element::new("Dimension").with("start", n.to_string()),
        Dimension::Variable(vr) => Element::new("Dimension").with("valueReference", vr.to_string()),
    }));
    e.children.extend(v.aliases.iter().map(|a| {
        Element::new("Alias")
            .with("name", a.name.clone())
            .with_opt("description", a.description.clone())
            .with_opt("displayUnit", a.display_unit.clone())
    }));
    e.children.extend(starts);
    e
}

fn unknown(name: &str, u: &Unknown) -> Element {
    Element::new(name)
        .with("valueReference", u.value_reference.to_string())
        .with_opt("dependencies", u.dependencies.as_ref().map(|d| joined(d, u32::to_string)))
        .with_opt("dependenciesKind", u.dependencies_kind.as_ref().map(|d| joined(d, |k| k.as_str().to_owned())))
}

pub(super) fn write(md: &ModelDescription) -> String {
    let mut root = Element::new("fmiModelDescription")
        .with("fmiVersion", md.fmi_version.clone())
        .with("modelName", md.model_name.clone())
        .with("instantiationToken", md.instantiation_token.clone())
        .with_opt("description", md.description.clone())
        .with_opt("author", md.author.clone())
        .with_opt("version", md.version.clone())
        .with_opt("copyright", md.copyright.clone())
        .with_opt("license", md.license.clone())
        .with_opt("generationTool", md.generation_tool.clone())
        .with_opt("generationDateAndTime", md.generation_date_and_time.clone())
        .with_opt("variableNamingConvention", md.variable_naming_convention.map(|c| c.as_str().to_owned()));
    let children = &mut root.children;
    if let Some(me) = &md.model_exchange {
        let e = interface("ModelExchange", &me.common);
        let e = flag(e, "needsCompletedIntegratorStep", me.needs_completed_integrator_step);
        children.push(flag(e, "providesEvaluateDiscreteStates", me.provides_evaluate_discrete_states));
    }
    if let Some(cs) = &md.co_simulation {
        let e = interface("CoSimulation", &cs.common);
        let e = flag(e, "canHandleVariableCommunicationStepSize", cs.can_handle_variable_communication_step_size);
        let e = e.with_opt("fixedInternalStepSize", cs.fixed_internal_step_size.map(format_real));
        let e = e.with_opt(
            "maxOutputDerivativeOrder",
            (cs.max_output_derivative_order != 0).then(|| cs.max_output_derivative_order.to_string()),
        );
        let smoothness = cs.recommended_intermediate_input_smoothness;
        let e = e.with_opt("recommendedIntermediateInputSmoothness", (smoothness != 0).then(|| smoothness.to_string()));
        let e = flag(e, "providesIntermediateUpdate", cs.provides_intermediate_update);
        let e = flag(e, "mightReturnEarlyFromDoStep", cs.might_return_early_from_do_step);
        let e = flag(e, "canReturnEarlyAfterIntermediateUpdate", cs.can_return_early_after_intermediate_update);
        let e = flag(e, "hasEventMode", cs.has_event_mode);
        children.push(flag(e, "providesEvaluateDiscreteStates", cs.provides_evaluate_discrete_states));
    }
    if let Some(se) = &md.scheduled_execution {
        children.push(interface("ScheduledExecution", &se.common));
    }
    if !md.unit_definitions.is_empty() {
        let mut units = Element::new("UnitDefinitions");
        for u in &md.unit_definitions {
            let mut e = Element::new("Unit").with("name", u.name.clone());
            if let Some(b) = &u.base_unit {
                let mut base = Element::new("BaseUnit");
                for (name, exponent) in
                    [("kg", b.kg), ("m", b.m), ("s", b.s), ("A", b.a), ("K", b.k), ("mol", b.mol), ("cd", b.cd), ("rad", b.rad)]
                {
                    if exponent != 0 {
                        base = base.with(name, exponent.to_string());
                    }
                }
                let base = base.with_opt("factor", (b.factor != 1.0).then(|| format_real(b.factor)));
                e.children.push(base.with_opt("offset", (b.offset != 0.0).then(|| format_real(b.offset))));
            }
            for d in &u.display_units {
                let du = Element::new("DisplayUnit").with("name", d.name.clone());
                let du = du.with_opt("factor", (d.factor != 1.0).then(|| format_real(d.factor)));
                let du = du.with_opt("offset", (d.offset != 0.0).then(|| format_real(d.offset)));
                e.children.push(flag(du, "inverse", d.inverse));
            }
            units.children.push(e);
        }
        children.push(units);
    }
    if !md.type_definitions.is_empty() {
        children.push(Element { children: md.type_definitions.iter().map(type_definition).collect(), ..Element::new("TypeDefinitions") });
    }
    if !md.log_categories.is_empty() {
        let categories = md
            .log_categories
            .iter()
            .map(|c| Element::new("Category").with("name", c.name.clone()).with_opt("description", c.description.clone()));
        children.push(Element { children: categories.collect(), ..Element::new("LogCategories") });
    }
    if let Some(d) = &md.default_experiment {
        children.push(
            Element::new("DefaultExperiment")
                .with_opt("startTime", d.start_time.map(format_real))
                .with_opt("stopTime", d.stop_time.map(format_real))
                .with_opt("tolerance", d.tolerance.map(format_real))
                .with_opt("stepSize", d.step_size.map(format_real)),
        );
    }
    children.push(Element { children: md.model_variables.iter().map(variable).collect(), ..Element::new("ModelVariables") });
    let s = &md.model_structure;
    let mut structure = Element::new("ModelStructure");
    for (name, list) in [
        ("Output", &s.outputs),
        ("ContinuousStateDerivative", &s.continuous_state_derivatives),
        ("ClockedState", &s.clocked_states),
        ("InitialUnknown", &s.initial_unknowns),
        ("EventIndicator", &s.event_indicators),
    ] {
        structure.children.extend(list.iter().map(|u| unknown(name, u)));
    }
    children.push(structure);
    tree::write(&root)
}
