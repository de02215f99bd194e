//! An FMI 3.0 modelDescription.xml in the importer's model.

use fmi_schema::fmi3 as s;

use crate::model::{
    Capabilities, Causality, DefaultExperiment, Description, Dimension, DisplayUnit, FmiVersion, Kind, Start, Unit, Variability, Variable,
};

fn causality(c: s::Causality) -> Causality {
    match c {
        s::Causality::Parameter => Causality::Parameter,
        s::Causality::CalculatedParameter => Causality::CalculatedParameter,
        s::Causality::StructuralParameter => Causality::StructuralParameter,
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

fn kind(b: s::BaseType) -> Kind {
    match b {
        s::BaseType::Float(s::FloatType::Float64) => Kind::Real,
        s::BaseType::Float(s::FloatType::Float32) => Kind::Float32,
        s::BaseType::Int(i) => match i {
            s::IntType::Int8 => Kind::Int8,
            s::IntType::UInt8 => Kind::UInt8,
            s::IntType::Int16 => Kind::Int16,
            s::IntType::UInt16 => Kind::UInt16,
            s::IntType::Int32 => Kind::Integer,
            s::IntType::UInt32 => Kind::UInt32,
            s::IntType::Int64 => Kind::Int64,
            s::IntType::UInt64 => Kind::UInt64,
        },
        s::BaseType::Boolean => Kind::Boolean,
        s::BaseType::String => Kind::String,
        s::BaseType::Binary => Kind::Binary,
        s::BaseType::Enumeration => Kind::Enumeration,
        s::BaseType::Clock => Kind::Clock,
    }
}

/// The start values of `v`: one value for a scalar, a list for an array.
fn start(v: &s::Variable) -> Option<Start> {
    let items: Vec<Start> = match &v.kind {
        s::VariableKind::Float { start, .. } => start.as_ref()?.iter().map(|x| Start::Real(*x)).collect(),
        s::VariableKind::Int { start, .. } | s::VariableKind::Enumeration { start, .. } => {
            start.as_ref()?.iter().map(|x| Start::Integer(*x)).collect()
        }
        s::VariableKind::Boolean { start } => start.as_ref()?.iter().map(|x| Start::Boolean(*x)).collect(),
        s::VariableKind::String { start } => start.as_ref()?.iter().map(|x| Start::String(x.clone())).collect(),
        s::VariableKind::Binary { start, .. } => start.as_ref()?.iter().map(|x| Start::Binary(x.clone())).collect(),
        s::VariableKind::Clock(_) => return None,
    };
    if v.dimensions.is_empty() && items.len() == 1 {
        items.into_iter().next()
    } else {
        Some(Start::List(items))
    }
}

fn common(c: &s::InterfaceCommon) -> Capabilities {
    Capabilities {
        model_identifier: c.model_identifier.clone(),
        needs_execution_tool: c.needs_execution_tool,
        can_be_instantiated_only_once_per_process: c.can_be_instantiated_only_once_per_process,
        can_get_and_set_fmu_state: c.can_get_and_set_fmu_state,
        can_serialize_fmu_state: c.can_serialize_fmu_state,
        provides_directional_derivative: c.provides_directional_derivatives,
        ..Default::default()
    }
}

/// The importer's description of an FMI 3.0 FMU.
pub fn describe(md: &s::ModelDescription) -> Description {
    let co_simulation = md.co_simulation.as_ref().map(|cs| Capabilities {
        can_handle_variable_communication_step_size: cs.can_handle_variable_communication_step_size,
        max_output_derivative_order: cs.max_output_derivative_order,
        has_event_mode: cs.has_event_mode,
        might_return_early_from_do_step: cs.might_return_early_from_do_step,
        ..common(&cs.common)
    });
    let model_exchange = md
        .model_exchange
        .as_ref()
        .map(|me| Capabilities { needs_completed_integrator_step: me.needs_completed_integrator_step, ..common(&me.common) });
    let variables = md
        .model_variables
        .iter()
        .map(|v| Variable {
            name: v.name.clone(),
            value_reference: v.value_reference,
            description: v.description.clone(),
            kind: kind(v.base_type()),
            causality: causality(v.causality()),
            variability: variability(v.variability()),
            unit: md.unit_of(v).map(str::to_owned),
            display_unit: md.display_unit_of(v).map(str::to_owned),
            start: start(v),
            dimensions: v
                .dimensions
                .iter()
                .map(|d| match *d {
                    s::Dimension::Fixed(n) => Dimension::Fixed(n),
                    s::Dimension::Variable(vr) => Dimension::Variable(vr),
                })
                .collect(),
        })
        .collect();
    let units = md
        .unit_definitions
        .iter()
        .map(|u| Unit {
            name: u.name.clone(),
            // An inverse display unit (display = 1 / (factor value + offset)) has no factor and
            // offset of the usual form; it is left out of conversions rather than misapplied.
            display_units: u
                .display_units
                .iter()
                .filter(|d| !d.inverse)
                .map(|d| DisplayUnit { name: d.name.clone(), factor: d.factor, offset: d.offset })
                .collect(),
        })
        .collect();
    let structure = &md.model_structure;
    let elements = |list: &[s::Unknown]| -> usize {
        list.iter()
            .map(|u| {
                md.variable_by_reference(u.value_reference)
                    .and_then(|v| md.start_shape(v))
                    .map_or(1, |shape| shape.iter().product::<u64>() as usize)
            })
            .sum()
    };
    Description {
        fmi_version: FmiVersion::Fmi3,
        fmi_version_text: md.fmi_version.clone(),
        model_name: md.model_name.clone(),
        description: md.description.clone(),
        instantiation_token: md.instantiation_token.clone(),
        generation_tool: md.generation_tool.clone(),
        co_simulation,
        model_exchange,
        default_experiment: md.default_experiment.map(|e| DefaultExperiment {
            start_time: e.start_time,
            stop_time: e.stop_time,
            tolerance: e.tolerance,
            step_size: e.step_size,
        }),
        units,
        variables,
        number_of_continuous_states: elements(&structure.continuous_state_derivatives),
        number_of_event_indicators: elements(&structure.event_indicators),
    }
}
