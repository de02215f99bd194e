//! Builds a model's `modelDescription.xml` from its variable table: the same table the C glue
//! serves, so the description and the binary cannot disagree.

use crate::logging::CATEGORIES;
use crate::model::{Access, BaseType, Causality, Initial, Model, Variability};
use crate::structure;
use crate::table::{guid, ranges, Slot, Start, Table};
use crate::units;
use fmi_schema::fmi2 as d;

fn causality(c: Causality) -> d::Causality {
    match c {
        Causality::Parameter => d::Causality::Parameter,
        Causality::CalculatedParameter => d::Causality::CalculatedParameter,
        Causality::Input => d::Causality::Input,
        Causality::Output => d::Causality::Output,
        Causality::Local => d::Causality::Local,
        Causality::Independent => d::Causality::Independent,
    }
}

fn variability(v: Variability) -> d::Variability {
    match v {
        Variability::Constant => d::Variability::Constant,
        Variability::Fixed => d::Variability::Fixed,
        Variability::Tunable => d::Variability::Tunable,
        Variability::Discrete => d::Variability::Discrete,
        Variability::Continuous => d::Variability::Continuous,
    }
}

fn initial(i: Initial) -> d::Initial {
    match i {
        Initial::Exact => d::Initial::Exact,
        Initial::Approx => d::Initial::Approx,
        Initial::Calculated => d::Initial::Calculated,
    }
}

/// The description of model `M` as data.
pub fn model_description<M: Model>() -> d::ModelDescription {
    let info = M::info();
    let table = Table::<M>::new();
    let defaults = M::default();
    let mut md = d::ModelDescription::new(info.identifier, guid::<M>());
    md.description = Some(info.description.to_owned());
    md.generation_tool = Some(format!("fmu toolkit {}", env!("CARGO_PKG_VERSION")));
    md.variable_naming_convention = Some(d::VariableNamingConvention::Flat);
    md.number_of_event_indicators = Some(M::N_EVENT_INDICATORS as u32);
    // The same binary serves both interfaces (one fmi2Instantiate, by fmuType).
    let common = d::InterfaceCommon {
        model_identifier: info.identifier.to_owned(),
        can_get_and_set_fmu_state: true,
        can_serialize_fmu_state: true,
        can_not_use_memory_management_functions: true,
        can_be_instantiated_only_once_per_process: false,
        // Exact, from the model's equations in dual numbers (core::derivatives), for a model
        // generic over its number type.
        provides_directional_derivative: M::lifting().is_some(),
        ..Default::default()
    };
    md.model_exchange = Some(d::ModelExchange {
        common: common.clone(),
        // fmi2CompletedIntegratorStep checks sign changes and the constraints' drift.
        completed_integrator_step_not_needed: false,
    });
    // Exact output derivatives along the trajectory and inputs that follow the polynomials of
    // their derivatives over a step (core::derivatives, core::interpolation), for a model
    // generic over its number type.
    let exact = M::lifting().is_some();
    md.co_simulation = Some(d::CoSimulation {
        common,
        can_handle_variable_communication_step_size: true,
        can_interpolate_inputs: exact,
        max_output_derivative_order: if exact { crate::core::MAX_ORDER as u32 } else { 0 },
        ..Default::default()
    });
    md.log_categories = CATEGORIES.iter().map(|c| d::Category::new(c.name, Some(c.description))).collect();
    md.default_experiment = Some(d::DefaultExperiment {
        start_time: Some(0.0),
        stop_time: Some(info.stop_time),
        tolerance: Some(info.tolerance),
        step_size: Some(info.output_interval),
    });

    // Units actually used, in the toolkit's order, with their display units.
    for u in units::UNITS {
        if table.rows.iter().any(|r| r.unit == Some(u.name)) {
            md.unit_definitions.push(d::Unit {
                name: u.name.to_owned(),
                base_unit: Some(d::BaseUnit { kg: u.base.kg, m: u.base.m, s: u.base.s, rad: u.base.rad, ..Default::default() }),
                display_units: u.display_units.iter().map(|du| d::DisplayUnit::new(du.name, du.factor, du.offset)).collect(),
            });
        }
    }

    for (vr, (row, range)) in table.rows.iter().zip(ranges::<M>()).enumerate() {
        let start = row.start(&defaults);
        let var_type = match row.base_type {
            BaseType::Real => d::VariableType::Real(d::RealVariable {
                attributes: d::RealAttributes {
                    unit: row.unit.map(str::to_owned),
                    display_unit: row.display_unit.map(str::to_owned),
                    min: range.min(),
                    max: range.max(),
                    ..Default::default()
                },
                start: match start {
                    Some(Start::Real(v)) => Some(v),
                    _ => None,
                },
                // der(x) names its state x by 1-based index.
                derivative: match row.slot {
                    Slot::Derivative(k) => state_index(&table, k),
                    _ => None,
                },
                ..Default::default()
            }),
            BaseType::Integer => d::VariableType::Integer(d::IntegerVariable {
                // Integer ranges have integer bounds (one_of, or min/max written as integers).
                attributes: d::IntegerAttributes {
                    min: range.min().map(|v| v as i32),
                    max: range.max().map(|v| v as i32),
                    ..Default::default()
                },
                start: match start {
                    Some(Start::Integer(v)) => Some(v),
                    _ => None,
                },
                ..Default::default()
            }),
            BaseType::Boolean => d::VariableType::Boolean(d::BooleanVariable {
                start: match start {
                    Some(Start::Boolean(v)) => Some(v),
                    _ => None,
                },
                ..Default::default()
            }),
            BaseType::String => d::VariableType::String(d::StringVariable {
                start: match start {
                    Some(Start::String(v)) => Some(v),
                    _ => None,
                },
                ..Default::default()
            }),
        };
        let mut sv = d::ScalarVariable::new(row.name, vr as u32, var_type);
        sv.description = Some(row.description.to_owned());
        sv.causality = Some(causality(row.causality));
        sv.variability = Some(variability(row.variability));
        sv.initial = row.initial.map(initial);
        md.model_variables.push(sv);
    }

    // ModelStructure (FMI 2.0 section 2.2.8): every output; every state derivative, in state
    // order (which is the order of the state vector); as initial unknowns, the outputs whose
    // initial is approx or calculated, every calculated parameter and every derivative. The
    // dependencies are those probing the equations finds (`structure`); a discrete output
    // claims none, which declares a dependence on all knowns.
    let dependencies = structure::dependencies::<M>();
    let listed = |found: &Option<Vec<usize>>, index: u32| match found {
        Some(rows) => d::Unknown::with_dependencies(index, rows.iter().map(|&j| j as u32 + 1).collect()),
        None => d::Unknown::new(index),
    };
    for (i, row) in table.rows.iter().enumerate() {
        let index = i as u32 + 1;
        if row.causality == Causality::Output {
            md.model_structure.outputs.push(listed(&dependencies.continuous[i], index));
        }
        // An absent initial takes the standard's default for the causality/variability pair.
        let initial = row.initial.map(initial).or_else(|| d::Initial::default_for(causality(row.causality), variability(row.variability)));
        let is_initial_unknown = (row.causality == Causality::Output && initial != Some(d::Initial::Exact))
            || row.causality == Causality::CalculatedParameter
            || matches!(row.slot, Slot::Derivative(_));
        if is_initial_unknown {
            md.model_structure.initial_unknowns.push(listed(&dependencies.initial[i], index));
        }
    }
    for k in 0..M::N_STATES {
        if let Some(i) = table.rows.iter().position(|r| matches!(r.slot, Slot::Derivative(j) if j == k)) {
            md.model_structure.derivatives.push(listed(&dependencies.continuous[i], i as u32 + 1));
        }
    }
    md
}

/// The 1-based index of the row of state `k`.
fn state_index<M: Model>(table: &Table<M>, k: usize) -> Option<u32> {
    table.rows.iter().position(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k)).map(|i| i as u32 + 1)
}

/// The `modelDescription.xml` text of model `M`.
pub fn model_description_xml<M: Model>() -> Result<String, String> {
    model_description::<M>().to_xml().map_err(|e| e.to_string())
}
