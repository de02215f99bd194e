//! FMI 1.0 modelDescription.xml (`fmiModelDescription fmiVersion="1.0"`), read only: the typed
//! model of what an importer needs (header, units, types, default experiment, ScalarVariables
//! with FMI 1.0's causality, variability and alias, the Co-Simulation `Implementation`), and
//! `check()`, the standard's rules on it. One schema serves both FMI 1.0 documents: a
//! description with an `Implementation` element is a Co-Simulation FMU, else Model Exchange.

use std::collections::{HashMap, HashSet};
use std::fmt;
use std::str::FromStr;

use crate::tree::{self, Element};
use crate::DescriptionError;

fmi_enum! {
    /// `causality` of a ScalarVariable (default `internal`).
    Causality, "FMI 1.0 causality" {
        Input = "input",
        Output = "output",
        Internal = "internal",
        None = "none",
    }
}

fmi_enum! {
    /// `variability` of a ScalarVariable (default `continuous`).
    Variability, "FMI 1.0 variability" {
        Constant = "constant",
        Parameter = "parameter",
        Discrete = "discrete",
        Continuous = "continuous",
    }
}

fmi_enum! {
    /// `alias` of a ScalarVariable (default `noAlias`).
    Alias, "FMI 1.0 alias" {
        NoAlias = "noAlias",
        Alias = "alias",
        NegatedAlias = "negatedAlias",
    }
}

/// The type element of a ScalarVariable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TypeKind {
    Real,
    Integer,
    Boolean,
    String,
    Enumeration,
}

impl TypeKind {
    fn of(element: &str) -> Option<TypeKind> {
        Some(match element {
            "Real" => TypeKind::Real,
            "Integer" => TypeKind::Integer,
            "Boolean" => TypeKind::Boolean,
            "String" => TypeKind::String,
            "Enumeration" => TypeKind::Enumeration,
            _ => return None,
        })
    }

    /// The element's name.
    pub fn as_str(self) -> &'static str {
        match self {
            TypeKind::Real => "Real",
            TypeKind::Integer => "Integer",
            TypeKind::Boolean => "Boolean",
            TypeKind::String => "String",
            TypeKind::Enumeration => "Enumeration",
        }
    }
}

/// A start value, typed by the variable's type element.
#[derive(Debug, Clone, PartialEq)]
pub enum StartValue {
    Real(f64),
    /// Integer and Enumeration.
    Integer(i32),
    Boolean(bool),
    String(String),
}

/// One ScalarVariable.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarVariable {
    pub name: String,
    pub value_reference: u32,
    pub description: Option<String>,
    pub causality: Causality,
    pub variability: Variability,
    pub alias: Alias,
    pub kind: TypeKind,
    pub declared_type: Option<String>,
    pub start: Option<StartValue>,
    /// `fixed` of the start value (meaningful with a start value only).
    pub fixed: Option<bool>,
    pub unit: Option<String>,
    pub display_unit: Option<String>,
    pub min: Option<f64>,
    pub max: Option<f64>,
    /// The line of the element, for messages.
    pub line: usize,
}

/// A `Type` of TypeDefinitions.
#[derive(Debug, Clone, PartialEq)]
pub struct TypeDefinition {
    pub name: String,
    pub kind: TypeKind,
    pub unit: Option<String>,
    pub display_unit: Option<String>,
}

/// A `DisplayUnitDefinition`: `display = gain * value + offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayUnit {
    pub name: String,
    pub gain: f64,
    pub offset: f64,
}

/// A `BaseUnit` of UnitDefinitions.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseUnit {
    pub unit: String,
    pub display_units: Vec<DisplayUnit>,
}

/// `DefaultExperiment` (FMI 1.0 has no step size).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DefaultExperiment {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub tolerance: Option<f64>,
}

/// The `Capabilities` of a Co-Simulation FMU.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Capabilities {
    pub can_handle_variable_communication_step_size: bool,
    pub can_handle_events: bool,
    pub can_reject_steps: bool,
    pub can_interpolate_inputs: bool,
    pub max_output_derivative_order: u32,
    pub can_run_asynchronuously: bool,
    pub can_signal_events: bool,
    pub can_be_instantiated_only_once_per_process: bool,
    pub can_not_use_memory_management_functions: bool,
}

/// The `Implementation` element: the FMU is a Co-Simulation slave, stand-alone or wrapping a
/// simulation tool.
#[derive(Debug, Clone, PartialEq)]
pub struct CoSimulation {
    /// `CoSimulation_Tool`: the binary drives an external tool (the runner cannot provide it).
    pub needs_tool: bool,
    pub capabilities: Capabilities,
}

/// An FMI 1.0 model description.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelDescription {
    pub fmi_version: String,
    pub model_name: String,
    pub model_identifier: String,
    pub guid: String,
    pub description: Option<String>,
    pub generation_tool: Option<String>,
    pub number_of_continuous_states: u32,
    pub number_of_event_indicators: u32,
    pub units: Vec<BaseUnit>,
    pub type_definitions: Vec<TypeDefinition>,
    pub default_experiment: Option<DefaultExperiment>,
    pub model_variables: Vec<ScalarVariable>,
    /// `Some` for a Co-Simulation FMU (it has an `Implementation` element).
    pub co_simulation: Option<CoSimulation>,
}

fn error_at(element: &Element, what: String) -> DescriptionError {
    DescriptionError::new(format!("line {}: <{}>: {what}", element.line, element.name))
}

fn required<'a>(element: &'a Element, name: &str) -> Result<&'a str, DescriptionError> {
    element.attribute(name).ok_or_else(|| error_at(element, format!("the required attribute {name} is missing")))
}

fn parsed<T: FromStr>(element: &Element, name: &str) -> Result<Option<T>, DescriptionError>
where
    T::Err: fmt::Display,
{
    element
        .attribute(name)
        .map(|text| text.trim().parse::<T>().map_err(|e| error_at(element, format!("{name}=\"{text}\": {e}"))))
        .transpose()
}

fn boolean(element: &Element, name: &str) -> Result<Option<bool>, DescriptionError> {
    element
        .attribute(name)
        .map(|text| match text.trim() {
            "true" | "1" => Ok(true),
            "false" | "0" => Ok(false),
            other => Err(error_at(element, format!("{name}=\"{other}\" is not a boolean (true or false)"))),
        })
        .transpose()
}

/// A real as XML Schema writes it (with INF, -INF and NaN).
fn real(element: &Element, name: &str) -> Result<Option<f64>, DescriptionError> {
    element
        .attribute(name)
        .map(|text| match text.trim() {
            "INF" => Ok(f64::INFINITY),
            "-INF" => Ok(f64::NEG_INFINITY),
            "NaN" => Ok(f64::NAN),
            t => t.parse::<f64>().map_err(|e| error_at(element, format!("{name}=\"{text}\" is not a number: {e}"))),
        })
        .transpose()
}

fn optional(element: &Element, name: &str) -> Option<String> {
    element.attribute(name).map(str::to_owned)
}

fn scalar_variable(element: &Element) -> Result<ScalarVariable, DescriptionError> {
    let name = required(element, "name")?.to_owned();
    let at = |what: String| error_at(element, format!("variable '{name}': {what}"));
    let value_reference = required(element, "valueReference")?
        .trim()
        .parse::<u32>()
        .map_err(|e| at(format!("valueReference=\"{}\": {e}", element.attribute("valueReference").unwrap_or(""))))?;
    let typed: Vec<(&Element, TypeKind)> = element.children.iter().filter_map(|c| TypeKind::of(&c.name).map(|k| (c, k))).collect();
    let [(type_element, kind)] = typed.as_slice() else {
        return Err(at(format!(
            "a ScalarVariable has exactly one type element (Real, Integer, Boolean, String or Enumeration), this one has {}",
            typed.len()
        )));
    };
    let start = match kind {
        TypeKind::Real => real(type_element, "start")?.map(StartValue::Real),
        TypeKind::Integer | TypeKind::Enumeration => parsed::<i32>(type_element, "start")?.map(StartValue::Integer),
        TypeKind::Boolean => boolean(type_element, "start")?.map(StartValue::Boolean),
        TypeKind::String => optional(type_element, "start").map(StartValue::String),
    };
    let real_attribute = |n: &str| if *kind == TypeKind::String || *kind == TypeKind::Boolean { Ok(None) } else { real(type_element, n) };
    Ok(ScalarVariable {
        value_reference,
        description: optional(element, "description"),
        causality: parsed(element, "causality").map_err(|e| at(e.message().to_owned()))?.unwrap_or(Causality::Internal),
        variability: parsed(element, "variability").map_err(|e| at(e.message().to_owned()))?.unwrap_or(Variability::Continuous),
        alias: parsed(element, "alias").map_err(|e| at(e.message().to_owned()))?.unwrap_or(Alias::NoAlias),
        kind: *kind,
        declared_type: optional(type_element, "declaredType"),
        start,
        fixed: boolean(type_element, "fixed")?,
        unit: optional(type_element, "unit"),
        display_unit: optional(type_element, "displayUnit"),
        min: real_attribute("min")?,
        max: real_attribute("max")?,
        line: element.line,
        name,
    })
}

impl ModelDescription {
    /// Reads an FMI 1.0 modelDescription.xml; the error names the element, line and attribute.
    pub fn from_xml(xml: &str) -> Result<ModelDescription, DescriptionError> {
        let root = tree::parse(xml)?;
        if root.name != "fmiModelDescription" {
            return Err(DescriptionError::new(format!("the root element is <{}>, not <fmiModelDescription>", root.name)));
        }
        let fmi_version = required(&root, "fmiVersion")?.trim().to_owned();
        if !fmi_version.starts_with("1.") {
            return Err(error_at(&root, format!("fmiVersion=\"{fmi_version}\" is not FMI 1.0")));
        }
        let count = |name: &str| parsed::<u32>(&root, name).map(Option::unwrap_or_default);
        let units = match root.child("UnitDefinitions") {
            Some(definitions) => definitions
                .children_named("BaseUnit")
                .map(|u| {
                    Ok(BaseUnit {
                        unit: required(u, "unit")?.to_owned(),
                        display_units: u
                            .children_named("DisplayUnitDefinition")
                            .map(|d| {
                                Ok(DisplayUnit {
                                    name: required(d, "displayUnit")?.to_owned(),
                                    gain: real(d, "gain")?.unwrap_or(1.0),
                                    offset: real(d, "offset")?.unwrap_or(0.0),
                                })
                            })
                            .collect::<Result<_, DescriptionError>>()?,
                    })
                })
                .collect::<Result<_, DescriptionError>>()?,
            None => Vec::new(),
        };
        let type_definitions = match root.child("TypeDefinitions") {
            Some(definitions) => definitions
                .children_named("Type")
                .map(|t| {
                    let name = required(t, "name")?.to_owned();
                    let Some(element) = t.children.first() else {
                        return Err(error_at(t, format!("type '{name}' has no type element")));
                    };
                    let kind = match element.name.strip_suffix("Type").and_then(TypeKind::of) {
                        Some(kind) => kind,
                        None => return Err(error_at(element, format!("type '{name}': <{}> is not an FMI 1.0 type", element.name))),
                    };
                    Ok(TypeDefinition { name, kind, unit: optional(element, "unit"), display_unit: optional(element, "displayUnit") })
                })
                .collect::<Result<_, DescriptionError>>()?,
            None => Vec::new(),
        };
        let default_experiment = root
            .child("DefaultExperiment")
            .map(|e| {
                Ok::<_, DescriptionError>(DefaultExperiment {
                    start_time: real(e, "startTime")?,
                    stop_time: real(e, "stopTime")?,
                    tolerance: real(e, "tolerance")?,
                })
            })
            .transpose()?;
        let model_variables = match root.child("ModelVariables") {
            Some(variables) => variables.children_named("ScalarVariable").map(scalar_variable).collect::<Result<_, _>>()?,
            None => Vec::new(),
        };
        let co_simulation = root
            .child("Implementation")
            .map(|implementation| {
                let (kind, needs_tool) = match (implementation.child("CoSimulation_StandAlone"), implementation.child("CoSimulation_Tool"))
                {
                    (Some(kind), _) => (kind, false),
                    (None, Some(kind)) => (kind, true),
                    (None, None) => {
                        return Err(error_at(implementation, "neither CoSimulation_StandAlone nor CoSimulation_Tool".to_owned()))
                    }
                };
                let capabilities = match kind.child("Capabilities") {
                    Some(c) => Capabilities {
                        can_handle_variable_communication_step_size: boolean(c, "canHandleVariableCommunicationStepSize")?.unwrap_or(false),
                        can_handle_events: boolean(c, "canHandleEvents")?.unwrap_or(false),
                        can_reject_steps: boolean(c, "canRejectSteps")?.unwrap_or(false),
                        can_interpolate_inputs: boolean(c, "canInterpolateInputs")?.unwrap_or(false),
                        max_output_derivative_order: parsed(c, "maxOutputDerivativeOrder")?.unwrap_or(0),
                        can_run_asynchronuously: boolean(c, "canRunAsynchronuously")?.unwrap_or(false),
                        can_signal_events: boolean(c, "canSignalEvents")?.unwrap_or(false),
                        can_be_instantiated_only_once_per_process: boolean(c, "canBeInstantiatedOnlyOncePerProcess")?.unwrap_or(false),
                        can_not_use_memory_management_functions: boolean(c, "canNotUseMemoryManagementFunctions")?.unwrap_or(false),
                    },
                    None => Capabilities::default(),
                };
                Ok(CoSimulation { needs_tool, capabilities })
            })
            .transpose()?;
        Ok(ModelDescription {
            model_name: required(&root, "modelName")?.to_owned(),
            model_identifier: required(&root, "modelIdentifier")?.trim().to_owned(),
            guid: required(&root, "guid")?.to_owned(),
            description: optional(&root, "description"),
            generation_tool: optional(&root, "generationTool"),
            number_of_continuous_states: count("numberOfContinuousStates")?,
            number_of_event_indicators: count("numberOfEventIndicators")?,
            fmi_version,
            units,
            type_definitions,
            default_experiment,
            model_variables,
            co_simulation,
        })
    }

    /// The TypeDefinition called `name`.
    pub fn type_definition(&self, name: &str) -> Option<&TypeDefinition> {
        self.type_definitions.iter().find(|t| t.name == name)
    }

    /// The variable's unit: its own, else its declared type's.
    pub fn unit_of<'a>(&'a self, v: &'a ScalarVariable) -> Option<&'a str> {
        v.unit.as_deref().or_else(|| v.declared_type.as_deref().and_then(|t| self.type_definition(t)?.unit.as_deref()))
    }

    /// The variable's display unit: its own, else its declared type's.
    pub fn display_unit_of<'a>(&'a self, v: &'a ScalarVariable) -> Option<&'a str> {
        v.display_unit.as_deref().or_else(|| v.declared_type.as_deref().and_then(|t| self.type_definition(t)?.display_unit.as_deref()))
    }

    /// The FMI 1.0 rules the description breaks, one message each (empty: none).
    pub fn check(&self) -> Vec<String> {
        let mut problems = Vec::new();
        let identifier = &self.model_identifier;
        let c_identifier = identifier.chars().next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            && identifier.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !c_identifier {
            problems.push(format!("modelIdentifier \"{identifier}\" is not a C identifier (it prefixes every function name)"));
        }
        if self.guid.trim().is_empty() {
            problems.push("guid is empty".to_owned());
        }
        if let Some(e) = &self.default_experiment {
            if let (Some(start), Some(stop)) = (e.start_time, e.stop_time) {
                if stop < start {
                    problems.push(format!("DefaultExperiment: stopTime {stop} is before startTime {start}"));
                }
            }
            if e.tolerance.is_some_and(|t| t.is_nan() || t <= 0.0) {
                problems.push(format!("DefaultExperiment: tolerance {} is not positive", e.tolerance.unwrap_or_default()));
            }
        }
        let mut names = HashSet::new();
        let mut bases: HashMap<(TypeKind, u32), &str> = HashMap::new();
        let units: HashSet<&str> = self.units.iter().map(|u| u.unit.as_str()).collect();
        for v in &self.model_variables {
            let at = format!("variable '{}' (line {})", v.name, v.line);
            if !names.insert(v.name.as_str()) {
                problems.push(format!("{at}: the name is used by another variable"));
            }
            if v.alias == Alias::NoAlias {
                if let Some(other) = bases.insert((v.kind, v.value_reference), &v.name) {
                    problems.push(format!(
                        "{at}: value reference {} of a {} is also '{other}', and neither is marked alias",
                        v.value_reference,
                        v.kind.as_str()
                    ));
                }
            }
            if v.causality == Causality::Input && v.start.is_none() {
                problems.push(format!("{at}: an input needs a start value"));
            }
            if matches!(v.variability, Variability::Constant | Variability::Parameter) && v.start.is_none() && v.alias == Alias::NoAlias {
                problems.push(format!("{at}: a {} needs a start value", v.variability));
            }
            if v.kind != TypeKind::Real && v.variability == Variability::Continuous {
                problems.push(format!("{at}: only a Real can be continuous, this is a {}", v.kind.as_str()));
            }
            if let (Some(min), Some(max)) = (v.min, v.max) {
                if min > max {
                    problems.push(format!("{at}: min {min} is above max {max}"));
                }
            }
            if let Some(StartValue::Real(x)) = &v.start {
                if v.min.is_some_and(|m| *x < m) || v.max.is_some_and(|m| *x > m) {
                    problems.push(format!("{at}: start {x} is outside [min, max]"));
                }
            }
            if let Some(t) = &v.declared_type {
                match self.type_definition(t) {
                    None => problems.push(format!("{at}: declaredType '{t}' is not in TypeDefinitions")),
                    Some(d) if d.kind != v.kind => {
                        problems.push(format!("{at}: declaredType '{t}' is a {}Type, the variable a {}", d.kind.as_str(), v.kind.as_str()))
                    }
                    Some(_) => {}
                }
            }
            if let Some(unit) = self.unit_of(v) {
                if !units.is_empty() && !units.contains(unit) {
                    problems.push(format!("{at}: unit '{unit}' is not a BaseUnit of UnitDefinitions"));
                }
            }
        }
        for v in self.model_variables.iter().filter(|v| v.alias != Alias::NoAlias) {
            if !bases.contains_key(&(v.kind, v.value_reference)) {
                problems.push(format!(
                    "variable '{}' (line {}): an {} of value reference {}, which no variable of its type has without alias",
                    v.name, v.line, v.alias, v.value_reference
                ));
            }
        }
        problems.into_iter().map(crate::printable).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const XML: &str = r#"<?xml version="1.0"?>
<fmiModelDescription fmiVersion="1.0" modelName="m" modelIdentifier="m" guid="{g}" numberOfContinuousStates="1" numberOfEventIndicators="2">
  <UnitDefinitions><BaseUnit unit="rad"><DisplayUnitDefinition displayUnit="deg" gain="57.29577951308232"/></BaseUnit></UnitDefinitions>
  <TypeDefinitions><Type name="Angle"><RealType quantity="angle" unit="rad"/></Type></TypeDefinitions>
  <DefaultExperiment startTime="0" stopTime="2" tolerance="1e-5"/>
  <ModelVariables>
    <ScalarVariable name="phi" valueReference="0" causality="output"><Real declaredType="Angle" start="1" fixed="true"/></ScalarVariable>
    <ScalarVariable name="minus_phi" valueReference="0" alias="negatedAlias"><Real/></ScalarVariable>
    <ScalarVariable name="k" valueReference="1" variability="parameter"><Real start="2"/></ScalarVariable>
    <ScalarVariable name="n" valueReference="0" variability="discrete" causality="output"><Integer start="3"/></ScalarVariable>
  </ModelVariables>
  <Implementation><CoSimulation_StandAlone><Capabilities canHandleVariableCommunicationStepSize="true"/></CoSimulation_StandAlone></Implementation>
</fmiModelDescription>"#;

    #[test]
    fn reads_the_header_variables_units_and_implementation() {
        let md = ModelDescription::from_xml(XML).unwrap();
        assert_eq!((md.model_identifier.as_str(), md.number_of_continuous_states, md.number_of_event_indicators), ("m", 1, 2));
        assert_eq!(md.model_variables.len(), 4);
        let phi = &md.model_variables[0];
        assert_eq!((phi.causality, phi.variability, phi.alias), (Causality::Output, Variability::Continuous, Alias::NoAlias));
        assert_eq!(md.unit_of(phi), Some("rad"), "the unit of the declared type");
        assert_eq!(md.model_variables[1].alias, Alias::NegatedAlias);
        assert_eq!(md.model_variables[2].causality, Causality::Internal, "the default causality");
        assert_eq!(md.model_variables[3].start, Some(StartValue::Integer(3)));
        assert_eq!(md.units[0].display_units[0].name, "deg");
        let cs = md.co_simulation.as_ref().expect("Implementation makes it Co-Simulation");
        assert!(!cs.needs_tool && cs.capabilities.can_handle_variable_communication_step_size);
        assert_eq!(md.default_experiment.unwrap().stop_time, Some(2.0));
        assert_eq!(md.check(), Vec::<String>::new());
    }

    #[test]
    fn refuses_bad_descriptions_naming_the_problem() {
        let bad = |from: &str, to: &str| ModelDescription::from_xml(&XML.replace(from, to)).unwrap_err().message().to_owned();
        assert!(bad(r#"modelIdentifier="m" "#, "").contains("modelIdentifier is missing"));
        assert!(bad(r#"causality="output"><Real"#, r#"causality="sideways"><Real"#).contains("'sideways' is not a valid FMI 1.0 causality"));
        assert!(bad(r#"<Integer start="3"/>"#, "").contains("variable 'n': a ScalarVariable has exactly one type element"));
        assert!(bad(r#"valueReference="1""#, r#"valueReference="-1""#).contains("variable 'k': valueReference=\"-1\""));
        assert!(bad(r#"fmiVersion="1.0""#, r#"fmiVersion="2.0""#).contains("is not FMI 1.0"));
    }

    #[test]
    fn check_finds_broken_rules() {
        let problems = |from: &str, to: &str| ModelDescription::from_xml(&XML.replace(from, to)).unwrap().check().join("\n");
        assert!(problems(r#"name="k""#, r#"name="phi""#).contains("the name is used by another variable"));
        assert!(problems(r#"alias="negatedAlias""#, "").contains("also 'phi', and neither is marked alias"));
        assert!(problems(r#"<Real start="2"/>"#, "<Real/>").contains("variable 'k' (line 9): a parameter needs a start value"));
        assert!(problems(r#"modelIdentifier="m""#, r#"modelIdentifier="a-b""#).contains("not a C identifier"));
        assert!(problems(r#"declaredType="Angle""#, r#"declaredType="Length""#).contains("declaredType 'Length' is not in TypeDefinitions"));
        assert!(problems(r#"stopTime="2""#, r#"stopTime="-1""#).contains("stopTime -1 is before startTime 0"));
    }
}
