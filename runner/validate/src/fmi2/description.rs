//! An FMI 2.0 modelDescription.xml read for the validator: the static findings and the
//! declared interfaces (the validator's side), and the probes' [`Model`] (the probe process's).

use std::collections::HashSet;

use fmi_schema::fmi2 as s;

use super::rules;
use crate::fmi::{Interface, Type};
use crate::model::{Capabilities, Causality, Declared, Experiment, Initial, Model, Start, Var, Variability};
use crate::report::Finding;

/// Reads `xml` for the static checks: what it declares, and the findings of its rules.
pub(crate) fn declared(xml: &str) -> Result<Declared, String> {
    let md = s::ModelDescription::from_xml(xml).map_err(|e| e.message().to_owned())?;
    let mut findings = vec![Finding::passed("description.xml", "modelDescription.xml is a well-formed FMI 2.0 description")];
    rules::check(&md, &mut findings);
    let interfaces = [
        (Interface::CoSimulation, md.co_simulation.as_ref().map(|c| c.common.model_identifier.clone())),
        (Interface::ModelExchange, md.model_exchange.as_ref().map(|m| m.common.model_identifier.clone())),
    ]
    .into_iter()
    .filter_map(|(i, id)| Some((i, id?)))
    .collect();
    Ok(Declared { fmi_version: md.fmi_version.clone(), model_name: md.model_name.clone(), interfaces, event_mode: false, findings })
}

/// The probes' view of `xml`.
pub(crate) fn model(xml: &str) -> Result<Model, String> {
    let md = s::ModelDescription::from_xml(xml).map_err(|e| e.message().to_owned())?;
    let position = |index: u32| (index as usize).checked_sub(1).filter(|&p| p < md.model_variables.len());
    let mut states = Vec::new();
    for unknown in &md.model_structure.derivatives {
        let Some(d) = position(unknown.index) else { continue };
        let Some(state) = md.model_variables[d].derivative().and_then(position) else { continue };
        states.push(state);
    }
    let state_set: HashSet<usize> = states.iter().copied().collect();
    let vars = md.model_variables.iter().enumerate().map(|(i, v)| variable(&md, v, state_set.contains(&i))).collect();
    let capabilities = |common: &s::InterfaceCommon| Capabilities {
        model_identifier: common.model_identifier.clone(),
        can_get_and_set_fmu_state: common.can_get_and_set_fmu_state,
        can_serialize_fmu_state: common.can_serialize_fmu_state,
        can_be_instantiated_only_once_per_process: common.can_be_instantiated_only_once_per_process,
        ..Capabilities::default()
    };
    let experiment = md.default_experiment.clone().unwrap_or_default();
    Ok(Model {
        token: md.guid.clone(),
        vars,
        value_references: md.model_variables.iter().map(|v| v.value_reference).collect(),
        nx: Some(states.len()),
        initial_unknowns: md.model_structure.initial_unknowns.iter().filter_map(|u| position(u.index)).collect(),
        nz: Some(md.number_of_event_indicators.unwrap_or(0) as usize),
        experiment: Experiment {
            start: experiment.start_time,
            stop: experiment.stop_time,
            step: experiment.step_size,
            tolerance: experiment.tolerance,
        },
        co_simulation: md.co_simulation.as_ref().map(|cs| Capabilities {
            can_handle_variable_communication_step_size: cs.can_handle_variable_communication_step_size,
            ..capabilities(&cs.common)
        }),
        // Called after every step whatever the FMU declares: an FMU must accept the call.
        model_exchange: md
            .model_exchange
            .as_ref()
            .map(|me| Capabilities { needs_completed_integrator_step: true, ..capabilities(&me.common) }),
    })
}

/// One variable as the probes see it.
fn variable(md: &s::ModelDescription, v: &s::ScalarVariable, is_state: bool) -> Var {
    let (min, max) = match &v.var_type {
        s::VariableType::Real(r) => {
            let declared = r.declared_type.as_deref().and_then(|t| md.simple_type(t)).and_then(|t| match &t.kind {
                s::SimpleTypeKind::Real(rt) => Some(rt),
                _ => None,
            });
            (r.attributes.min.or(declared.and_then(|t| t.min)), r.attributes.max.or(declared.and_then(|t| t.max)))
        }
        s::VariableType::Integer(n) => (n.attributes.min.map(f64::from), n.attributes.max.map(f64::from)),
        s::VariableType::Enumeration(e) => (e.attributes.min.map(f64::from), e.attributes.max.map(f64::from)),
        _ => (None, None),
    };
    Var {
        name: v.name.clone(),
        vr: v.value_reference,
        ty: match v.type_kind().base_type() {
            s::TypeKind::Real => Type::Real,
            s::TypeKind::Boolean => Type::Boolean,
            s::TypeKind::String => Type::String,
            _ => Type::Integer,
        },
        causality: Causality::parse(v.causality().as_str()).expect("every FMI 2.0 causality is one of the validator's"),
        variability: Variability::parse(v.variability().as_str()).expect("every FMI 2.0 variability is one of the validator's"),
        initial: v.initial().map(|i| Initial::parse(i.as_str()).expect("every FMI 2.0 initial is one of the validator's")),
        is_state,
        start: v.start().map(|start| match start {
            s::StartValue::Real(x) => Start::Number(x),
            s::StartValue::Integer(i) | s::StartValue::Enumeration(i) => Start::Number(f64::from(i)),
            s::StartValue::Boolean(b) => Start::Number(b as i32 as f64),
            s::StartValue::String(text) => Start::Text(text),
        }),
        min,
        max,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<fmiModelDescription fmiVersion="2.0" modelName="m" guid="{8c4e810f-3df3-4a00-8276-176fa3c9f000}" numberOfEventIndicators="1">
  <ModelExchange modelIdentifier="m" canGetAndSetFMUstate="true"/>
  <CoSimulation modelIdentifier="m" canHandleVariableCommunicationStepSize="true"/>
  <TypeDefinitions><SimpleType name="Angle"><Real min="-4" max="4"/></SimpleType></TypeDefinitions>
  <DefaultExperiment stopTime="3" stepSize="0.01"/>
  <ModelVariables>
    <ScalarVariable name="x" valueReference="0" causality="output" initial="exact"><Real declaredType="Angle" start="1"/></ScalarVariable>
    <ScalarVariable name="der(x)" valueReference="1"><Real derivative="1"/></ScalarVariable>
    <ScalarVariable name="mode" valueReference="5" causality="parameter" variability="fixed"><Enumeration declaredType="E" start="2"/></ScalarVariable>
    <ScalarVariable name="on" valueReference="6" causality="input"><Boolean start="true"/></ScalarVariable>
    <ScalarVariable name="label" valueReference="7" causality="parameter" variability="fixed"><String start="a"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure>
    <Outputs><Unknown index="1"/></Outputs>
    <Derivatives><Unknown index="2"/></Derivatives>
    <InitialUnknowns><Unknown index="2"/></InitialUnknowns>
  </ModelStructure>
</fmiModelDescription>"#;

    /// The view keeps what the probes rely on: types (Enumeration as Integer), the states, ranges from declared types, capabilities per interface.
    #[test]
    fn the_model_is_what_the_description_says() {
        let xml = XML.replace(r#"<TypeDefinitions>"#, r#"<TypeDefinitions><SimpleType name="E"><Enumeration><Item name="a" value="1"/><Item name="b" value="2"/></Enumeration></SimpleType>"#);
        let m = model(&xml).unwrap();
        let types: Vec<Type> = m.vars.iter().map(|v| v.ty).collect();
        assert_eq!(types, [Type::Real, Type::Real, Type::Integer, Type::Boolean, Type::String]);
        assert_eq!((m.vars[0].is_state, m.nx, m.nz), (true, Some(1), Some(1)));
        assert_eq!((m.vars[0].min, m.vars[0].max), (Some(-4.0), Some(4.0)));
        assert_eq!(m.vars[2].start, Some(Start::Number(2.0)));
        assert_eq!(m.vars[3].start, Some(Start::Number(1.0)));
        assert!(m.initial_unknowns.contains(&1));
        assert!(
            m.model_exchange.as_ref().unwrap().can_get_and_set_fmu_state
                && m.model_exchange.as_ref().unwrap().needs_completed_integrator_step
        );
        assert!(m.co_simulation.as_ref().unwrap().can_handle_variable_communication_step_size);
        assert_eq!(m.experiment.stop, Some(3.0));
        assert_eq!(m.unknown_vr(), 8);
        let d = declared(&xml).unwrap();
        assert_eq!(d.interfaces, [(Interface::CoSimulation, "m".to_owned()), (Interface::ModelExchange, "m".to_owned())]);
        assert_eq!((d.findings[0].check.as_str(), d.findings[0].severity), ("description.xml", crate::report::Severity::Passed));
        assert!(d.findings.iter().any(|f| f.check == "description.guid"), "the rules ran: {:#?}", d.findings);
    }
}
