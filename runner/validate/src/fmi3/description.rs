//! An FMI 3.0 modelDescription.xml read for the validator: the static findings (the schema's
//! rules, the instantiationToken) and the declared interfaces (the validator's side), and the
//! probes' [`Model`] (the probe process's): the scalar Float64, Int32, Boolean and String
//! variables, the only types the probes exchange.

use fmi_schema::fmi3 as s;

use super::rules;
use crate::fmi::{Interface, Type};
use crate::model::{Capabilities, Causality, Declared, Experiment, Initial, Model, Start, Var, Variability};
use crate::report::Finding;

/// Reads `xml` for the static checks: what it declares, and the findings of its rules.
pub(crate) fn declared(xml: &str) -> Result<Declared, String> {
    let md = s::ModelDescription::from_xml(xml).map_err(|e| e.message().to_owned())?;
    let mut findings = vec![Finding::passed("description.xml", "modelDescription.xml is a well-formed FMI 3.0 description")];
    rules::check(&md, &mut findings);
    let interfaces = [
        (Interface::CoSimulation, md.co_simulation.as_ref().map(|c| c.common.model_identifier.clone())),
        (Interface::ModelExchange, md.model_exchange.as_ref().map(|m| m.common.model_identifier.clone())),
    ]
    .into_iter()
    .filter_map(|(i, id)| Some((i, id?)))
    .collect();
    if md.scheduled_execution.is_some() {
        findings.push(Finding::skipped(
            "dynamic checks",
            "Scheduled Execution is declared but not probed: the validator drives Co-Simulation and Model Exchange",
        ));
    }
    let event_mode = md.co_simulation.as_ref().is_some_and(|c| c.has_event_mode);
    Ok(Declared { fmi_version: md.fmi_version.clone(), model_name: md.model_name.clone(), interfaces, event_mode, findings })
}

/// The probes' view of `xml`.
pub(crate) fn model(xml: &str) -> Result<Model, String> {
    let md = s::ModelDescription::from_xml(xml).map_err(|e| e.message().to_owned())?;
    let state_vrs: Vec<u32> = md
        .model_structure
        .continuous_state_derivatives
        .iter()
        .filter_map(|u| md.variable_by_reference(u.value_reference)?.derivative())
        .collect();
    let vars: Vec<Var> = md.model_variables.iter().filter_map(|v| variable(v, state_vrs.contains(&v.value_reference))).collect();
    let index = |vr: u32| vars.iter().position(|v| v.vr == vr);
    let initial_unknowns = md.model_structure.initial_unknowns.iter().filter_map(|u| index(u.value_reference)).collect();
    // The sizes, arrays counted by their start sizes; unknown where a size cannot be known.
    let count = |unknowns: &[s::Unknown]| -> Option<usize> {
        unknowns
            .iter()
            .map(|u| md.variable_by_reference(u.value_reference).and_then(|v| md.start_shape(v)))
            .try_fold(0usize, |n, shape| Some(n + shape?.iter().product::<u64>() as usize))
    };
    let capabilities = |common: &s::InterfaceCommon| Capabilities {
        model_identifier: common.model_identifier.clone(),
        can_get_and_set_fmu_state: common.can_get_and_set_fmu_state,
        can_serialize_fmu_state: common.can_serialize_fmu_state,
        can_be_instantiated_only_once_per_process: common.can_be_instantiated_only_once_per_process,
        ..Capabilities::default()
    };
    let experiment = md.default_experiment.unwrap_or_default();
    Ok(Model {
        token: md.instantiation_token.clone(),
        value_references: md.model_variables.iter().map(|v| v.value_reference).collect(),
        initial_unknowns,
        nx: count(&md.model_structure.continuous_state_derivatives),
        nz: count(&md.model_structure.event_indicators),
        experiment: Experiment {
            start: experiment.start_time,
            stop: experiment.stop_time,
            step: experiment.step_size,
            tolerance: experiment.tolerance,
        },
        co_simulation: md.co_simulation.as_ref().map(|cs| Capabilities {
            can_handle_variable_communication_step_size: cs.can_handle_variable_communication_step_size,
            event_mode: cs.has_event_mode,
            early_return: cs.might_return_early_from_do_step,
            ..capabilities(&cs.common)
        }),
        model_exchange: md
            .model_exchange
            .as_ref()
            .map(|me| Capabilities { needs_completed_integrator_step: me.needs_completed_integrator_step, ..capabilities(&me.common) }),
        vars,
    })
}

/// One variable as the probes see it: `None` for the types and arrays they do not exchange.
fn variable(v: &s::Variable, is_state: bool) -> Option<Var> {
    if !v.dimensions.is_empty() {
        return None;
    }
    let one = |n: usize| n == 1;
    let (ty, start, min, max) = match &v.kind {
        s::VariableKind::Float { precision: s::FloatType::Float64, attributes, start, .. } => {
            (Type::Real, start.as_ref().filter(|s| one(s.len())).map(|s| Start::Number(s[0])), attributes.min, attributes.max)
        }
        s::VariableKind::Int { ty: s::IntType::Int32, attributes, start } => (
            Type::Integer,
            start.as_ref().filter(|s| one(s.len())).map(|s| Start::Number(s[0] as f64)),
            attributes.min.map(|m| m as f64),
            attributes.max.map(|m| m as f64),
        ),
        s::VariableKind::Boolean { start } => {
            (Type::Boolean, start.as_ref().filter(|s| one(s.len())).map(|s| Start::Number(s[0] as i32 as f64)), None, None)
        }
        s::VariableKind::String { start } => {
            (Type::String, start.as_ref().filter(|s| one(s.len())).map(|s| Start::Text(s[0].clone())), None, None)
        }
        _ => return None,
    };
    Some(Var {
        name: v.name.clone(),
        vr: v.value_reference,
        ty,
        causality: Causality::parse(v.causality().as_str()).expect("every FMI 3.0 causality is one of the validator's"),
        variability: Variability::parse(v.variability().as_str()).expect("every FMI 3.0 variability is one of the validator's"),
        initial: v.initial().map(|i| Initial::parse(i.as_str()).expect("every FMI 3.0 initial is one of the validator's")),
        is_state,
        start,
        min,
        max,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<fmiModelDescription fmiVersion="3.0" modelName="m" instantiationToken="{t}">
  <ModelExchange modelIdentifier="m" needsCompletedIntegratorStep="true"/>
  <CoSimulation modelIdentifier="m" hasEventMode="true" canGetAndSetFMUState="true"/>
  <ModelVariables>
    <Float64 name="x" valueReference="1" causality="output" variability="continuous" initial="exact" start="1" min="-2"/>
    <Float64 name="der(x)" valueReference="2" causality="local" variability="continuous" derivative="1"/>
    <Int32 name="n" valueReference="3" causality="parameter" variability="fixed" start="4"/>
    <UInt8 name="b" valueReference="4" causality="parameter" variability="fixed" start="4"/>
    <Float64 name="v" valueReference="5" causality="parameter" variability="fixed" start="1 2"><Dimension start="2"/></Float64>
    <String name="label" valueReference="6" causality="parameter" variability="fixed"><Start value="a"/></String>
  </ModelVariables>
  <ModelStructure>
    <Output valueReference="1"/>
    <ContinuousStateDerivative valueReference="2"/>
    <InitialUnknown valueReference="2"/>
  </ModelStructure>
</fmiModelDescription>"#;

    /// The view keeps the four types the probes exchange, scalars only, and counts the states
    /// from ModelStructure.
    #[test]
    fn the_model_is_what_the_description_says() {
        let m = model(XML).unwrap();
        let names: Vec<&str> = m.vars.iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["x", "der(x)", "n", "label"]);
        assert_eq!((m.vars[0].is_state, m.nx, m.nz), (true, Some(1), Some(0)));
        assert!(m.vars[0].is_state && m.vars[0].min == Some(-2.0));
        assert_eq!(m.vars[3].start, Some(Start::Text("a".into())));
        assert_eq!(m.unknown_vr(), 7, "past every variable, those not exchanged too");
        let cs = m.co_simulation.as_ref().unwrap();
        assert!(cs.event_mode && cs.can_get_and_set_fmu_state && !cs.early_return);
        assert!(m.model_exchange.as_ref().unwrap().needs_completed_integrator_step);
        let d = declared(XML).unwrap();
        assert_eq!(d.interfaces.len(), 2);
        assert!(d.findings.iter().any(|f| f.check == "description.token"));
    }
}
