//! Builds a model's FMI 3.0 `modelDescription.xml` from its variable table (the same table
//! FMI 2.0's description, the C glue and the documentation use), with the ModelStructure
//! dependencies `structure` finds, written through `fmi_schema::fmi3`. Units go through
//! TypeDefinitions, as the Reference FMUs write them: each Float64 variable with a unit
//! declares the type of its unit and display unit.

use super::event_indicator_name;
use crate::logging::CATEGORIES;
use crate::model::{Access, BaseType, Causality, Initial, Model, Variability};
use crate::structure;
use crate::table::{guid, ranges, Slot, Start, Table};
use crate::units;
use fmi_schema::fmi3 as d;

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

/// The interface flags both interfaces share: FMU state with serialization, many instances,
/// and exact directional and adjoint derivatives (from the model's equations in dual numbers,
/// core::derivatives) for a model generic over its number type.
fn common<M: Model>(identifier: &str) -> d::InterfaceCommon {
    let exact = M::lifting().is_some();
    d::InterfaceCommon {
        model_identifier: identifier.to_owned(),
        can_get_and_set_fmu_state: true,
        can_serialize_fmu_state: true,
        provides_directional_derivatives: exact,
        provides_adjoint_derivatives: exact,
        ..Default::default()
    }
}

/// The FMI 3.0 description of model `M` as data.
pub fn model_description<M: Model>() -> d::ModelDescription {
    let info = M::info();
    let table = Table::<M>::new();
    let defaults = M::default();
    let mut md = d::ModelDescription::new(info.identifier, guid::<M>());
    md.description = Some(info.description.to_owned());
    md.generation_tool = Some(format!("fmu toolkit {}", env!("CARGO_PKG_VERSION")));
    md.variable_naming_convention = Some(d::VariableNamingConvention::Flat);
    // One binary serves both interfaces (and FMI 2.0 too).
    md.model_exchange = Some(d::ModelExchange {
        common: common::<M>(info.identifier),
        // fmi3CompletedIntegratorStep checks sign changes and the constraints' drift.
        needs_completed_integrator_step: true,
        provides_evaluate_discrete_states: false,
    });
    md.co_simulation = Some(d::CoSimulation {
        common: common::<M>(info.identifier),
        can_handle_variable_communication_step_size: true,
        // Steps stop at located events when the importer allows early return.
        might_return_early_from_do_step: true,
        has_event_mode: true,
        // Exact output derivatives along the trajectory (core::derivatives).
        max_output_derivative_order: if M::lifting().is_some() { crate::core::MAX_ORDER as u32 } else { 0 },
        ..Default::default()
    });
    md.log_categories = CATEGORIES
        .iter()
        .map(|c| d::Category { name: c.name.to_owned(), description: Some(c.description.replace("fmi2", "fmi3")) })
        .collect();
    md.default_experiment = Some(d::DefaultExperiment {
        start_time: Some(0.0),
        stop_time: Some(info.stop_time),
        tolerance: Some(info.tolerance),
        step_size: Some(info.output_interval),
    });

    for u in units::UNITS {
        if table.rows.iter().any(|r| r.unit == Some(u.name)) {
            md.unit_definitions.push(d::Unit {
                name: u.name.to_owned(),
                base_unit: Some(d::BaseUnit { kg: u.base.kg, m: u.base.m, s: u.base.s, rad: u.base.rad, ..Default::default() }),
                display_units: u
                    .display_units
                    .iter()
                    .map(|du| d::DisplayUnit { name: du.name.to_owned(), factor: du.factor, offset: du.offset, inverse: false })
                    .collect(),
            });
        }
    }

    // Units through TypeDefinitions, as the Reference FMUs declare them (some importers read a
    // variable's unit only from its declared type): one Float64 type per unit and display unit
    // the variables use, in the toolkit's order of units.
    for u in units::UNITS {
        for display_unit in std::iter::once(None).chain(u.display_units.iter().map(|du| Some(du.name))) {
            if table.rows.iter().any(|r| r.unit == Some(u.name) && r.display_unit == display_unit) {
                md.type_definitions.push(d::TypeDefinition {
                    name: type_name(u, display_unit),
                    description: None,
                    kind: d::TypeKind::Float(
                        d::FloatType::Float64,
                        d::Float {
                            quantity: Some(u.quantity.to_owned()),
                            unit: Some(u.name.to_owned()),
                            display_unit: display_unit.map(str::to_owned),
                            ..Default::default()
                        },
                    ),
                });
            }
        }
    }

    // Value references are the table's indices, as in FMI 2.0.
    let state_vr = |k: usize| table.rows.iter().position(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k)).map(|i| i as u32);
    for (vr, (row, range)) in table.rows.iter().zip(ranges::<M>()).enumerate() {
        let start = row.start(&defaults);
        let kind = match row.base_type {
            BaseType::Real => d::VariableKind::Float {
                precision: d::FloatType::Float64,
                attributes: d::Float {
                    // A unit the toolkit does not know has no type: it stays on the variable,
                    // where the description's check names it.
                    unit: row.unit.filter(|u| units::unit(u).is_none()).map(str::to_owned),
                    display_unit: row.display_unit.filter(|_| row.unit.and_then(units::unit).is_none()).map(str::to_owned),
                    min: range.min(),
                    max: range.max(),
                    ..Default::default()
                },
                start: match start {
                    Some(Start::Real(v)) => Some(vec![v]),
                    _ => None,
                },
                derivative: match row.slot {
                    Slot::Derivative(k) => state_vr(k),
                    _ => None,
                },
                // An event may change any state (an impact, a projection onto the constraints).
                reinit: matches!(row.slot, Slot::Model(Access::State(_))),
            },
            BaseType::Integer => d::VariableKind::Int {
                ty: d::IntType::Int32,
                attributes: d::Int { min: range.min().map(|v| v as i128), max: range.max().map(|v| v as i128), ..Default::default() },
                start: match start {
                    Some(Start::Integer(v)) => Some(vec![i128::from(v)]),
                    _ => None,
                },
            },
            BaseType::Boolean => d::VariableKind::Boolean {
                start: match start {
                    Some(Start::Boolean(v)) => Some(vec![v]),
                    _ => None,
                },
            },
            BaseType::String => d::VariableKind::String {
                start: match start {
                    Some(Start::String(v)) => Some(vec![v]),
                    _ => None,
                },
            },
        };
        let mut v = d::Variable::new(row.name, vr as u32, kind);
        v.declared_type = row.unit.and_then(units::unit).map(|u| type_name(u, row.display_unit));
        v.description = Some(row.description.to_owned());
        v.causality = Some(causality(row.causality));
        v.variability = Some(variability(row.variability));
        v.initial = row.initial.map(initial);
        md.model_variables.push(v);
    }
    // FMI 3.0 names each event indicator as a variable; theirs follow the table's.
    let first_indicator = table.rows.len() as u32;
    for k in 0..M::N_EVENT_INDICATORS {
        let kind = d::VariableKind::Float {
            precision: d::FloatType::Float64,
            attributes: d::Float::default(),
            start: None,
            derivative: None,
            reinit: false,
        };
        let mut v = d::Variable::new(event_indicator_name(k), first_indicator + k as u32, kind);
        v.description = Some(format!("Event indicator {k}: an event where it changes sign"));
        v.causality = Some(d::Causality::Local);
        v.variability = Some(d::Variability::Continuous);
        md.model_variables.push(v);
    }

    // ModelStructure (FMI 3.0 section 2.4.8): every output; every state derivative, in state
    // order; as initial unknowns, the outputs whose initial is approx or calculated, every
    // calculated parameter, and every derivative; every event indicator. The dependencies are
    // those probing the equations finds, as for FMI 2.0 (value references here, indices
    // there); a discrete output and an event indicator claim none, which declares a
    // dependence on all knowns.
    let dependencies = structure::dependencies::<M>();
    let listed = |found: &Option<Vec<usize>>, vr: u32| d::Unknown {
        value_reference: vr,
        dependencies: found.as_ref().map(|rows| rows.iter().map(|&j| j as u32).collect()),
        dependencies_kind: None,
    };
    for (i, row) in table.rows.iter().enumerate() {
        let vr = i as u32;
        if row.causality == Causality::Output {
            md.model_structure.outputs.push(listed(&dependencies.continuous[i], vr));
        }
        let initial = row.initial.map(initial).or_else(|| d::default_initial(causality(row.causality), variability(row.variability)));
        let is_initial_unknown = (row.causality == Causality::Output && initial != Some(d::Initial::Exact))
            || row.causality == Causality::CalculatedParameter
            || matches!(row.slot, Slot::Derivative(_));
        if is_initial_unknown {
            md.model_structure.initial_unknowns.push(listed(&dependencies.initial[i], vr));
        }
    }
    for k in 0..M::N_STATES {
        if let Some(i) = table.rows.iter().position(|r| matches!(r.slot, Slot::Derivative(j) if j == k)) {
            md.model_structure.continuous_state_derivatives.push(listed(&dependencies.continuous[i], i as u32));
        }
    }
    for k in 0..M::N_EVENT_INDICATORS {
        md.model_structure.event_indicators.push(d::Unknown::new(first_indicator + k as u32));
    }
    md
}

/// The name of the type that declares `unit` shown in `display_unit`: what the unit measures,
/// and the display unit (`Angle`, `Angle_deg`, `TranslationalSpringConstant_lbf_per_in`).
fn type_name(unit: &units::UnitDef, display_unit: Option<&str>) -> String {
    match display_unit {
        None => unit.quantity.to_owned(),
        Some(du) => format!("{}_{}", unit.quantity, du.replace('/', "_per_").replace('.', "_")),
    }
}

/// The FMI 3.0 `modelDescription.xml` text of model `M`.
pub fn model_description_xml<M: Model>() -> String {
    model_description::<M>().to_xml()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{ModelError, ModelInfo, Variable, Variables};
    use serde::{Deserialize, Serialize};

    /// A bar of length `l` turning at a constant rate from `theta0`: units with and without
    /// display units, on parameters, a state, its derivative and an output.
    #[derive(Debug, Clone, Default, Serialize, Deserialize)]
    struct Bar {
        l: f64,
        theta0: f64,
        tip: f64,
    }

    impl Variables for Bar {
        fn variables() -> Vec<Variable<Self>> {
            vec![
                Variable::<Bar>::parameter("l", "length", |m| m.l, |m, v| m.l = v).unit("m"),
                Variable::<Bar>::parameter("theta0", "initial angle", |m| m.theta0, |m, v| m.theta0 = v).unit("rad").display("deg"),
                Variable::state("theta", "angle", 0).unit("rad").display("deg"),
                Variable::<Bar>::output("tip", "height of the tip", |m| m.tip).unit("m").display("mm"),
            ]
        }
    }

    impl crate::Equations<f64> for Bar {
        fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError> {
            x[0] = self.theta0;
            Ok(())
        }

        fn derivatives(&self, _t: f64, _x: &[f64], dx: &mut [f64]) {
            dx[0] = 1.0;
        }

        fn outputs(&mut self, _t: f64, x: &[f64]) {
            self.tip = self.l * x[0].sin();
        }
    }

    impl Model for Bar {
        const N_STATES: usize = 1;

        fn info() -> ModelInfo {
            ModelInfo {
                identifier: "bar",
                description: "a turning bar",
                stop_time: 1.0,
                tolerance: 1e-6,
                output_interval: 0.1,
                documentation: "",
            }
        }
    }

    /// Every variable's unit and display unit reach the importer through its declared type
    /// (none on the variable itself, which some importers refuse), read back from the XML as
    /// the table declares them: one type per unit and display unit, named by what the unit
    /// measures, each one used; and the description passes the schema's checks.
    #[test]
    fn units_are_declared_through_one_type_per_unit_and_display_unit() {
        let table = Table::<Bar>::new();
        let md = d::ModelDescription::from_xml(&model_description_xml::<Bar>()).unwrap();
        assert_eq!(md.check(), Vec::<String>::new());
        for row in &table.rows {
            let v = md.variable(row.name).unwrap();
            if let d::VariableKind::Float { attributes, .. } = &v.kind {
                assert_eq!((attributes.unit.as_deref(), attributes.display_unit.as_deref()), (None, None), "{}", row.name);
            }
            assert_eq!((md.unit_of(v), md.display_unit_of(v)), (row.unit, row.display_unit), "{}", row.name);
            assert_eq!(v.declared_type.is_some(), row.unit.is_some(), "{}", row.name);
        }
        let names: Vec<&str> = md.type_definitions.iter().map(|t| t.name.as_str()).collect();
        for expected in ["Length", "Length_mm", "Angle_deg", "AngularVelocity"] {
            assert!(names.contains(&expected), "{expected} in {names:?}");
        }
        assert!(!names.contains(&"Angle"), "no variable is in rad without a display unit: {names:?}");
        for t in &md.type_definitions {
            assert!(md.model_variables.iter().any(|v| v.declared_type.as_deref() == Some(&t.name)), "{} is used", t.name);
        }
        let angle = md.type_definition("Angle_deg").unwrap();
        assert!(matches!(&angle.kind, d::TypeKind::Float(d::FloatType::Float64, f)
            if (f.quantity.as_deref(), f.unit.as_deref(), f.display_unit.as_deref()) == (Some("Angle"), Some("rad"), Some("deg"))));
    }
}
