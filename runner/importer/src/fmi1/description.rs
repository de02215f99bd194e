//! An FMI 1.0 modelDescription.xml in the importer's model.

use fmi_schema::fmi1 as s;

use crate::model::{
    Capabilities, Causality, DefaultExperiment, Description, DisplayUnit, FmiVersion, Kind, Start, Unit, Variability, Variable,
};

/// FMI 1.0's causality and variability in FMI 2.0's words, which the importer's model speaks:
/// a `parameter` (set before initialization only) is a fixed parameter; `internal` and `none`
/// are locals.
fn causality_and_variability(v: &s::ScalarVariable) -> (Causality, Variability) {
    let variability = match v.variability {
        s::Variability::Constant => Variability::Constant,
        s::Variability::Parameter => Variability::Fixed,
        s::Variability::Discrete => Variability::Discrete,
        s::Variability::Continuous => Variability::Continuous,
    };
    let causality = match (v.causality, v.variability) {
        (s::Causality::Output, _) => Causality::Output,
        (_, s::Variability::Parameter) => Causality::Parameter,
        (s::Causality::Input, _) => Causality::Input,
        (s::Causality::Internal | s::Causality::None, _) => Causality::Local,
    };
    (causality, variability)
}

fn kind(k: s::TypeKind) -> Kind {
    match k {
        s::TypeKind::Real => Kind::Real,
        s::TypeKind::Integer => Kind::Integer,
        s::TypeKind::Boolean => Kind::Boolean,
        s::TypeKind::String => Kind::String,
        s::TypeKind::Enumeration => Kind::Enumeration,
    }
}

fn start(v: &Option<s::StartValue>) -> Option<Start> {
    Some(match v.as_ref()? {
        s::StartValue::Real(x) => Start::Real(*x),
        s::StartValue::Integer(i) => Start::Integer(i128::from(*i)),
        s::StartValue::Boolean(b) => Start::Boolean(*b),
        s::StartValue::String(t) => Start::String(t.clone()),
    })
}

/// The importer's description of an FMI 1.0 FMU: Co-Simulation when it has an
/// `Implementation` element, else Model Exchange (FMI 1.0 FMUs offer one interface).
/// Negated aliases are left out: the value their value reference reads is the other sign's.
pub fn describe(md: &s::ModelDescription) -> Description {
    let identifier = md.model_identifier.clone();
    let co_simulation = md.co_simulation.as_ref().map(|cs| Capabilities {
        model_identifier: identifier.clone(),
        needs_execution_tool: cs.needs_tool,
        can_be_instantiated_only_once_per_process: cs.capabilities.can_be_instantiated_only_once_per_process,
        can_handle_variable_communication_step_size: cs.capabilities.can_handle_variable_communication_step_size,
        can_interpolate_inputs: cs.capabilities.can_interpolate_inputs,
        max_output_derivative_order: cs.capabilities.max_output_derivative_order,
        ..Default::default()
    });
    let model_exchange = md.co_simulation.is_none().then(|| Capabilities {
        model_identifier: identifier,
        needs_completed_integrator_step: true,
        ..Default::default()
    });
    let variables = md
        .model_variables
        .iter()
        .filter(|v| v.alias != s::Alias::NegatedAlias)
        .map(|v| {
            let (causality, variability) = causality_and_variability(v);
            Variable {
                name: v.name.clone(),
                value_reference: v.value_reference,
                description: v.description.clone(),
                kind: kind(v.kind),
                causality,
                variability,
                unit: md.unit_of(v).map(str::to_owned),
                display_unit: md.display_unit_of(v).map(str::to_owned),
                start: start(&v.start),
                dimensions: Vec::new(),
            }
        })
        .collect();
    let units = md
        .units
        .iter()
        .map(|u| Unit {
            name: u.unit.clone(),
            display_units: u.display_units.iter().map(|d| DisplayUnit { name: d.name.clone(), factor: d.gain, offset: d.offset }).collect(),
        })
        .collect();
    Description {
        fmi_version: FmiVersion::Fmi1,
        fmi_version_text: md.fmi_version.clone(),
        model_name: md.model_name.clone(),
        description: md.description.clone(),
        instantiation_token: md.guid.clone(),
        generation_tool: md.generation_tool.clone(),
        co_simulation,
        model_exchange,
        default_experiment: md.default_experiment.map(|e| DefaultExperiment {
            start_time: e.start_time,
            stop_time: e.stop_time,
            tolerance: e.tolerance,
            step_size: None,
        }),
        units,
        variables,
        number_of_continuous_states: md.number_of_continuous_states as usize,
        number_of_event_indicators: md.number_of_event_indicators as usize,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FMI 1.0's words in the importer's model: a `parameter` is a fixed parameter whatever its
    /// causality but output, `internal` and `none` are locals, an input stays one; a negated
    /// alias is left out; no Implementation element means Model Exchange.
    #[test]
    fn causality_variability_and_aliases_in_the_importers_words() {
        let xml = r#"<fmiModelDescription fmiVersion="1.0" modelName="m" modelIdentifier="m" guid="g" numberOfContinuousStates="1">
  <ModelVariables>
    <ScalarVariable name="k" valueReference="0" variability="parameter"><Real start="2"/></ScalarVariable>
    <ScalarVariable name="u" valueReference="1" causality="input"><Real start="0"/></ScalarVariable>
    <ScalarVariable name="x" valueReference="2" causality="none"><Real/></ScalarVariable>
    <ScalarVariable name="minus_x" valueReference="2" alias="negatedAlias"><Real/></ScalarVariable>
    <ScalarVariable name="y" valueReference="3" causality="output" variability="discrete"><Integer/></ScalarVariable>
  </ModelVariables>
</fmiModelDescription>"#;
        let d = describe(&s::ModelDescription::from_xml(xml).unwrap());
        let of = |name: &str| d.variable(name).map(|v| (v.causality, v.variability, v.kind));
        assert_eq!(of("k"), Some((Causality::Parameter, Variability::Fixed, Kind::Real)));
        assert_eq!(of("u"), Some((Causality::Input, Variability::Continuous, Kind::Real)));
        assert_eq!(of("x"), Some((Causality::Local, Variability::Continuous, Kind::Real)));
        assert_eq!(of("minus_x"), None, "a negated alias reads the other sign");
        assert_eq!(of("y"), Some((Causality::Output, Variability::Discrete, Kind::Integer)));
        assert!(d.co_simulation.is_none() && d.model_exchange.as_ref().is_some_and(|me| me.model_identifier == "m"));
        assert_eq!((d.fmi_version, d.number_of_continuous_states), (FmiVersion::Fmi1, 1));
    }
}
