//! An FMI 2.0 modelDescription.xml in the importer's model.

use fmi_schema::fmi2 as s;

use crate::model::{
    Capabilities, Causality, DefaultExperiment, Description, DisplayUnit, FmiVersion, Kind, Start, Unit, Variability, Variable,
};

fn causality(c: s::Causality) -> Causality {
    match c {
        s::Causality::Parameter => Causality::Parameter,
        s::Causality::CalculatedParameter => Causality::CalculatedParameter,
        s::Causality::Input => Causality::Input,
        s::Causality::Output => Causality::Output,
        s::Causality::Local => Causality::Local,
        s::Causality::Independent => Causality::Independent,
    }
}

fn variability(v: s::Variability) -> Variability {
    match v {
        s::Variability::Constant => Variability::Constant,
        s::Variability::Fixed => Variability::Fixed,
        s::Variability::Tunable => Variability::Tunable,
        s::Variability::Discrete => Variability::Discrete,
        s::Variability::Continuous => Variability::Continuous,
    }
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

fn start(v: Option<s::StartValue>) -> Option<Start> {
    Some(match v? {
        s::StartValue::Real(x) => Start::Real(x),
        s::StartValue::Integer(i) | s::StartValue::Enumeration(i) => Start::Integer(i128::from(i)),
        s::StartValue::Boolean(b) => Start::Boolean(b),
        s::StartValue::String(t) => Start::String(t),
    })
}

/// The importer's description of an FMI 2.0 FMU.
pub fn describe(md: &s::ModelDescription) -> Description {
    // The attributes both interfaces share, read the same way for either.
    let common = |c: &s::InterfaceCommon| Capabilities {
        model_identifier: c.model_identifier.clone(),
        needs_execution_tool: c.needs_execution_tool,
        can_be_instantiated_only_once_per_process: c.can_be_instantiated_only_once_per_process,
        can_get_and_set_fmu_state: c.can_get_and_set_fmu_state,
        can_serialize_fmu_state: c.can_serialize_fmu_state,
        provides_directional_derivative: c.provides_directional_derivative,
        ..Default::default()
    };
    let co_simulation = md.co_simulation.as_ref().map(|cs| Capabilities {
        can_handle_variable_communication_step_size: cs.can_handle_variable_communication_step_size,
        can_interpolate_inputs: cs.can_interpolate_inputs,
        max_output_derivative_order: cs.max_output_derivative_order,
        ..common(&cs.common)
    });
    let model_exchange = md.model_exchange.as_ref().map(|me| common(&me.common));
    let variables = md
        .model_variables
        .iter()
        .map(|v| Variable {
            name: v.name.clone(),
            value_reference: v.value_reference,
            description: v.description.clone(),
            kind: kind(v.type_kind()),
            causality: causality(v.causality()),
            variability: variability(v.variability()),
            unit: md.unit_of(v).map(str::to_owned),
            display_unit: md.display_unit_of(v).map(str::to_owned),
            start: start(v.start()),
            dimensions: Vec::new(),
        })
        .collect();
    let units = md
        .unit_definitions
        .iter()
        .map(|u| Unit {
            name: u.name.clone(),
            display_units: u
                .display_units
                .iter()
                .map(|d| DisplayUnit { name: d.name.clone(), factor: d.factor, offset: d.offset })
                .collect(),
        })
        .collect();
    let number_of_continuous_states = md.model_variables.iter().filter(|v| v.derivative().is_some()).count();
    Description {
        fmi_version: FmiVersion::Fmi2,
        fmi_version_text: md.fmi_version.clone(),
        model_name: md.model_name.clone(),
        description: md.description.clone(),
        instantiation_token: md.guid.clone(),
        generation_tool: md.generation_tool.clone(),
        co_simulation,
        model_exchange,
        default_experiment: md.default_experiment.as_ref().map(|e| DefaultExperiment {
            start_time: e.start_time,
            stop_time: e.stop_time,
            tolerance: e.tolerance,
            step_size: e.step_size,
        }),
        units,
        variables,
        number_of_continuous_states,
        number_of_event_indicators: md.number_of_event_indicators.unwrap_or(0) as usize,
    }
}
