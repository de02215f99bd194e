//! Reading an FMI 3.0 modelDescription.xml: the element tree converted to the typed model,
//! every error naming the element and the attribute. Unknown elements and attributes (vendor
//! annotations, layered standards) are ignored, as the standard allows.

use std::str::FromStr;

use super::*;
use crate::tree::{self, Element};

const ROOT: &str = "fmiModelDescription";

/// Where an element is, for messages: `<Float64 name="h"> (line 12)`.
fn at(e: &Element) -> String {
    let name = e.attribute("name").map(|n| format!(" name=\"{}\"", escaped_and_cut(n, 80, "...")));
    let line = if e.line > 0 { format!(" (line {})", e.line) } else { String::new() };
    format!("<{}{}>{line}", e.name, name.unwrap_or_default())
}

fn bad(e: &Element, attribute: &str, value: &str, why: impl fmt::Display) -> DescriptionError {
    DescriptionError::new(format!("attribute {attribute}=\"{}\" on {}: {why}", escaped_and_cut(value, 80, "..."), at(e)))
}

/// An optional attribute parsed with `FromStr`.
fn opt<T: FromStr>(e: &Element, name: &str) -> Result<Option<T>, DescriptionError>
where
    T::Err: fmt::Display,
{
    match e.attribute(name) {
        None => Ok(None),
        Some(text) => text.trim().parse::<T>().map(Some).map_err(|err| bad(e, name, text, err)),
    }
}

/// A required attribute parsed with `FromStr`.
fn req<T: FromStr>(e: &Element, name: &str) -> Result<T, DescriptionError>
where
    T::Err: fmt::Display,
{
    opt(e, name)?.ok_or_else(|| DescriptionError::new(format!("missing attribute {name} on {}", at(e))))
}

fn text(e: &Element, name: &str) -> Option<String> {
    e.attribute(name).map(str::to_owned)
}

/// An xs:boolean: `true`, `false`, `1` or `0`.
fn boolean(e: &Element, name: &str) -> Result<Option<bool>, DescriptionError> {
    match e.attribute(name).map(str::trim) {
        None => Ok(None),
        Some("true" | "1") => Ok(Some(true)),
        Some("false" | "0") => Ok(Some(false)),
        Some(other) => Err(bad(e, name, other, "not a boolean (true, false, 1 or 0)")),
    }
}

fn flag(e: &Element, name: &str) -> Result<bool, DescriptionError> {
    Ok(boolean(e, name)?.unwrap_or(false))
}

/// An xs:double, with the XML Schema spellings of the non-finite values.
pub(super) fn parse_real(text: &str) -> Result<f64, String> {
    match text.trim() {
        "INF" | "+INF" => Ok(f64::INFINITY),
        "-INF" => Ok(f64::NEG_INFINITY),
        "NaN" => Ok(f64::NAN),
        t => t.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| "not a number".to_owned()),
    }
}

fn real(e: &Element, name: &str) -> Result<Option<f64>, DescriptionError> {
    match e.attribute(name) {
        None => Ok(None),
        Some(t) => parse_real(t).map(Some).map_err(|why| bad(e, name, t, why)),
    }
}

/// A float of `precision`: Float32 values are rounded to single precision as the FMU holds them.
fn float_value(precision: FloatType, text: &str) -> Result<f64, String> {
    let v = parse_real(text)?;
    Ok(match precision {
        FloatType::Float32 if v.is_finite() && v.abs() > f32::MAX as f64 => return Err("outside the range of Float32".to_owned()),
        FloatType::Float32 => v as f32 as f64,
        FloatType::Float64 => v,
    })
}

/// A whitespace-separated list attribute, each item converted by `item`.
fn list<T>(e: &Element, name: &str, item: impl Fn(&str) -> Result<T, String>) -> Result<Option<Vec<T>>, DescriptionError> {
    match e.attribute(name) {
        None => Ok(None),
        Some(t) => t.split_whitespace().map(|x| item(x).map_err(|why| bad(e, name, x, why))).collect::<Result<Vec<T>, _>>().map(Some),
    }
}

fn integer(ty: IntType, text: &str) -> Result<i128, String> {
    let v: i128 = text.trim().parse().map_err(|_| format!("not an integer of type {ty}"))?;
    let (lo, hi) = ty.range();
    if v < lo || v > hi {
        return Err(format!("outside the range of {ty} ({lo} to {hi})"));
    }
    Ok(v)
}

fn int_attributes(e: &Element, ty: IntType) -> Result<Int, DescriptionError> {
    let one = |name: &str| -> Result<Option<i128>, DescriptionError> {
        match e.attribute(name) {
            None => Ok(None),
            Some(t) => integer(ty, t).map(Some).map_err(|why| bad(e, name, t, why)),
        }
    };
    Ok(Int { quantity: text(e, "quantity"), min: one("min")?, max: one("max")? })
}

fn float_attributes(e: &Element, precision: FloatType) -> Result<Float, DescriptionError> {
    let bound = |name: &str| -> Result<Option<f64>, DescriptionError> {
        match e.attribute(name) {
            None => Ok(None),
            Some(t) => float_value(precision, t).map(Some).map_err(|why| bad(e, name, t, why)),
        }
    };
    Ok(Float {
        quantity: text(e, "quantity"),
        unit: text(e, "unit"),
        display_unit: text(e, "displayUnit"),
        relative_quantity: flag(e, "relativeQuantity")?,
        unbounded: flag(e, "unbounded")?,
        min: bound("min")?,
        max: bound("max")?,
        nominal: bound("nominal")?,
    })
}

fn clock_attributes(e: &Element) -> Result<ClockAttributes, DescriptionError> {
    Ok(ClockAttributes {
        can_be_deactivated: flag(e, "canBeDeactivated")?,
        priority: opt(e, "priority")?,
        interval_variability: opt(e, "intervalVariability")?,
        interval_decimal: real(e, "intervalDecimal")?,
        shift_decimal: real(e, "shiftDecimal")?,
        supports_fraction: flag(e, "supportsFraction")?,
        resolution: opt(e, "resolution")?,
        interval_counter: opt(e, "intervalCounter")?,
        shift_counter: opt(e, "shiftCounter")?,
    })
}

fn interface_common(e: &Element) -> Result<InterfaceCommon, DescriptionError> {
    Ok(InterfaceCommon {
        model_identifier: req(e, "modelIdentifier")?,
        needs_execution_tool: flag(e, "needsExecutionTool")?,
        can_be_instantiated_only_once_per_process: flag(e, "canBeInstantiatedOnlyOncePerProcess")?,
        can_get_and_set_fmu_state: flag(e, "canGetAndSetFMUState")?,
        can_serialize_fmu_state: flag(e, "canSerializeFMUState")?,
        provides_directional_derivatives: flag(e, "providesDirectionalDerivatives")?,
        provides_adjoint_derivatives: flag(e, "providesAdjointDerivatives")?,
        provides_per_element_dependencies: flag(e, "providesPerElementDependencies")?,
    })
}

fn model_exchange(e: &Element) -> Result<ModelExchange, DescriptionError> {
    Ok(ModelExchange {
        common: interface_common(e)?,
        needs_completed_integrator_step: flag(e, "needsCompletedIntegratorStep")?,
        provides_evaluate_discrete_states: flag(e, "providesEvaluateDiscreteStates")?,
    })
}

fn co_simulation(e: &Element) -> Result<CoSimulation, DescriptionError> {
    Ok(CoSimulation {
        common: interface_common(e)?,
        can_handle_variable_communication_step_size: flag(e, "canHandleVariableCommunicationStepSize")?,
        fixed_internal_step_size: real(e, "fixedInternalStepSize")?,
        max_output_derivative_order: opt(e, "maxOutputDerivativeOrder")?.unwrap_or(0),
        recommended_intermediate_input_smoothness: opt(e, "recommendedIntermediateInputSmoothness")?.unwrap_or(0),
        provides_intermediate_update: flag(e, "providesIntermediateUpdate")?,
        might_return_early_from_do_step: flag(e, "mightReturnEarlyFromDoStep")?,
        can_return_early_after_intermediate_update: flag(e, "canReturnEarlyAfterIntermediateUpdate")?,
        has_event_mode: flag(e, "hasEventMode")?,
        provides_evaluate_discrete_states: flag(e, "providesEvaluateDiscreteStates")?,
    })
}

fn unit(e: &Element) -> Result<Unit, DescriptionError> {
    let base_unit = match e.child("BaseUnit") {
        None => None,
        Some(b) => {
            let exponent = |name: &str| -> Result<i32, DescriptionError> { Ok(opt(b, name)?.unwrap_or(0)) };
            Some(BaseUnit {
                kg: exponent("kg")?,
                m: exponent("m")?,
                s: exponent("s")?,
                a: exponent("A")?,
                k: exponent("K")?,
                mol: exponent("mol")?,
                cd: exponent("cd")?,
                rad: exponent("rad")?,
                factor: real(b, "factor")?.unwrap_or(1.0),
                offset: real(b, "offset")?.unwrap_or(0.0),
            })
        }
    };
    let display_units = e
        .children_named("DisplayUnit")
        .map(|d| {
            Ok(DisplayUnit {
                name: req(d, "name")?,
                factor: real(d, "factor")?.unwrap_or(1.0),
                offset: real(d, "offset")?.unwrap_or(0.0),
                inverse: flag(d, "inverse")?,
            })
        })
        .collect::<Result<_, DescriptionError>>()?;
    Ok(Unit { name: req(e, "name")?, base_unit, display_units })
}

/// The kind of element `name` declares in ModelVariables, or `None` for other elements.
fn base_type_of(element: &str, suffix: &str) -> Option<BaseType> {
    let name = element.strip_suffix(suffix)?;
    if let Ok(f) = name.parse::<FloatType>() {
        return Some(BaseType::Float(f));
    }
    if let Ok(i) = name.parse::<IntType>() {
        return Some(BaseType::Int(i));
    }
    Some(match name {
        "Boolean" => BaseType::Boolean,
        "String" => BaseType::String,
        "Binary" => BaseType::Binary,
        "Enumeration" => BaseType::Enumeration,
        "Clock" => BaseType::Clock,
        _ => return None,
    })
}

fn type_definition(e: &Element, base: BaseType) -> Result<TypeDefinition, DescriptionError> {
    let kind = match base {
        BaseType::Float(p) => TypeKind::Float(p, float_attributes(e, p)?),
        BaseType::Int(i) => TypeKind::Int(i, int_attributes(e, i)?),
        BaseType::Boolean => TypeKind::Boolean,
        BaseType::String => TypeKind::String,
        BaseType::Binary => TypeKind::Binary { mime_type: text(e, "mimeType"), max_size: opt(e, "maxSize")? },
        BaseType::Enumeration => TypeKind::Enumeration {
            quantity: text(e, "quantity"),
            items: e
                .children_named("Item")
                .map(|i| Ok(Item { name: req(i, "name")?, value: req(i, "value")?, description: text(i, "description") }))
                .collect::<Result<_, DescriptionError>>()?,
        },
        BaseType::Clock => TypeKind::Clock(clock_attributes(e)?),
    };
    Ok(TypeDefinition { name: req(e, "name")?, description: text(e, "description"), kind })
}

/// The `value` attributes of the `<Start>` children (String and Binary start values).
fn start_children(e: &Element) -> Result<Option<Vec<String>>, DescriptionError> {
    let starts: Vec<&Element> = e.children_named("Start").collect();
    if starts.is_empty() {
        return Ok(None);
    }
    starts.iter().map(|s| req::<String>(s, "value")).collect::<Result<Vec<_>, _>>().map(Some)
}

fn variable(e: &Element, base: BaseType) -> Result<Variable, DescriptionError> {
    let kind = match base {
        BaseType::Float(precision) => VariableKind::Float {
            precision,
            attributes: float_attributes(e, precision)?,
            start: list(e, "start", |t| float_value(precision, t))?,
            derivative: opt(e, "derivative")?,
            reinit: flag(e, "reinit")?,
        },
        BaseType::Int(ty) => VariableKind::Int { ty, attributes: int_attributes(e, ty)?, start: list(e, "start", |t| integer(ty, t))? },
        BaseType::Boolean => VariableKind::Boolean {
            start: list(e, "start", |t| match t {
                "true" | "1" => Ok(true),
                "false" | "0" => Ok(false),
                _ => Err("not a boolean (true, false, 1 or 0)".to_owned()),
            })?,
        },
        BaseType::String => VariableKind::String { start: start_children(e)? },
        BaseType::Binary => {
            let start = match start_children(e)? {
                None => None,
                Some(texts) => Some(
                    texts
                        .iter()
                        .map(|t| unhex(t).map_err(|why| DescriptionError::new(format!("a <Start> of {}: {why}", at(e)))))
                        .collect::<Result<Vec<_>, _>>()?,
                ),
            };
            VariableKind::Binary { mime_type: text(e, "mimeType"), max_size: opt(e, "maxSize")?, start }
        }
        BaseType::Enumeration => VariableKind::Enumeration {
            attributes: int_attributes(e, IntType::Int64)?,
            start: list(e, "start", |t| integer(IntType::Int64, t))?,
        },
        BaseType::Clock => VariableKind::Clock(clock_attributes(e)?),
    };
    let dimensions = e
        .children_named("Dimension")
        .map(|d| match (opt::<u64>(d, "start")?, opt::<u32>(d, "valueReference")?) {
            (Some(n), None) => Ok(Dimension::Fixed(n)),
            (None, Some(vr)) => Ok(Dimension::Variable(vr)),
            _ => Err(DescriptionError::new(format!("a <Dimension> of {} needs exactly one of start and valueReference", at(e)))),
        })
        .collect::<Result<_, DescriptionError>>()?;
    let aliases = e
        .children_named("Alias")
        .map(|a| Ok(Alias { name: req(a, "name")?, description: text(a, "description"), display_unit: text(a, "displayUnit") }))
        .collect::<Result<_, DescriptionError>>()?;
    Ok(Variable {
        name: req(e, "name")?,
        value_reference: req(e, "valueReference")?,
        description: text(e, "description"),
        causality: opt(e, "causality")?,
        variability: opt(e, "variability")?,
        initial: opt(e, "initial")?,
        can_handle_multiple_set_per_time_instant: boolean(e, "canHandleMultipleSetPerTimeInstant")?,
        intermediate_update: flag(e, "intermediateUpdate")?,
        previous: opt(e, "previous")?,
        clocks: list(e, "clocks", |t| t.parse::<u32>().map_err(|_| "not a value reference".to_owned()))?,
        declared_type: text(e, "declaredType"),
        dimensions,
        aliases,
        kind,
    })
}

fn unknown(e: &Element) -> Result<Unknown, DescriptionError> {
    Ok(Unknown {
        value_reference: req(e, "valueReference")?,
        dependencies: list(e, "dependencies", |t| t.parse::<u32>().map_err(|_| "not a value reference".to_owned()))?,
        dependencies_kind: list(e, "dependenciesKind", |t| t.parse::<DependencyKind>())?,
    })
}

fn model_structure(e: &Element) -> Result<ModelStructure, DescriptionError> {
    let mut s = ModelStructure::default();
    for child in &e.children {
        let target = match child.name.as_str() {
            "Output" => &mut s.outputs,
            "ContinuousStateDerivative" => &mut s.continuous_state_derivatives,
            "ClockedState" => &mut s.clocked_states,
            "InitialUnknown" => &mut s.initial_unknowns,
            "EventIndicator" => &mut s.event_indicators,
            _ => continue,
        };
        target.push(unknown(child)?);
    }
    Ok(s)
}

/// Accepts "3.0" and its maintenance releases ("3.0.1", "3.0.2"), which share the schema.
fn check_version(root: &Element) -> Result<String, DescriptionError> {
    let version: String = req(root, "fmiVersion")?;
    if version.trim() == "3.0" || version.trim().starts_with("3.0.") {
        Ok(version)
    } else {
        Err(DescriptionError::new(format!("fmiVersion is {}, expected 3.0", escaped_and_cut(&version, 40, "..."))))
    }
}

pub(super) fn read(xml: &str) -> Result<ModelDescription, DescriptionError> {
    let root = tree::parse(xml)?;
    if root.name != ROOT {
        return Err(DescriptionError::new(format!("root element is <{}>, expected <{ROOT}> (not a modelDescription.xml)", root.name)));
    }
    let fmi_version = check_version(&root)?;
    let mut md = ModelDescription::new(req::<String>(&root, "modelName")?, req::<String>(&root, "instantiationToken")?);
    md.fmi_version = fmi_version;
    md.description = text(&root, "description");
    md.author = text(&root, "author");
    md.version = text(&root, "version");
    md.copyright = text(&root, "copyright");
    md.license = text(&root, "license");
    md.generation_tool = text(&root, "generationTool");
    md.generation_date_and_time = text(&root, "generationDateAndTime");
    md.variable_naming_convention = opt(&root, "variableNamingConvention")?;
    for child in &root.children {
        match child.name.as_str() {
            "ModelExchange" => md.model_exchange = Some(model_exchange(child)?),
            "CoSimulation" => md.co_simulation = Some(co_simulation(child)?),
            "ScheduledExecution" => md.scheduled_execution = Some(ScheduledExecution { common: interface_common(child)? }),
            "UnitDefinitions" => md.unit_definitions = child.children_named("Unit").map(unit).collect::<Result<_, _>>()?,
            "TypeDefinitions" => {
                for t in &child.children {
                    if let Some(base) = base_type_of(&t.name, "Type") {
                        md.type_definitions.push(type_definition(t, base)?);
                    }
                }
            }
            "LogCategories" => {
                md.log_categories = child
                    .children_named("Category")
                    .map(|c| Ok(Category { name: req(c, "name")?, description: text(c, "description") }))
                    .collect::<Result<_, DescriptionError>>()?
            }
            "DefaultExperiment" => {
                md.default_experiment = Some(DefaultExperiment {
                    start_time: real(child, "startTime")?,
                    stop_time: real(child, "stopTime")?,
                    tolerance: real(child, "tolerance")?,
                    step_size: real(child, "stepSize")?,
                })
            }
            "ModelVariables" => {
                for v in &child.children {
                    if let Some(base) = base_type_of(&v.name, "") {
                        md.model_variables.push(variable(v, base)?);
                    }
                }
            }
            "ModelStructure" => md.model_structure = model_structure(child)?,
            _ => {}
        }
    }
    if root.child("ModelVariables").is_none() {
        return Err(DescriptionError::new(format!("missing element ModelVariables in {ROOT}")));
    }
    Ok(md)
}
