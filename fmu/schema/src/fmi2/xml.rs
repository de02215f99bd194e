//! XML mapping: serde mirror types of the FMI 2.0 schema and conversions to the public model.
//!
//! Every attribute is an `Option<String>` here on purpose: parsing numbers, booleans and enums
//! ourselves lets errors name the element ("ScalarVariable 'x'") and the attribute, which
//! serde's own errors cannot. Unknown attributes and elements are ignored by serde, which is
//! what makes descriptions from other tools (vendor annotations, FMI extensions) readable.

use std::fmt::Display;
use std::str::FromStr;

use quick_xml::events::Event;
use quick_xml::{Reader, XmlVersion};
use serde::{Deserialize, Serialize};

use super::*;

/// Name of the root element.
const ROOT: &str = "fmiModelDescription";

/// Declares the children of a list element: the expected kinds plus a catch-all, so that a
/// vendor element between two `<ScalarVariable>`s is skipped instead of breaking serde's
/// "one field, one contiguous run of elements" rule (quick-xml reports that as a duplicate field).
macro_rules! children {
    ($name:ident { $($variant:ident($ty:ty)),+ $(,)? }) => {
        // Lists are consumed right after parsing, so boxing the big variant buys nothing.
        #[allow(clippy::large_enum_variant)]
        #[derive(Serialize, Deserialize)]
        enum $name {
            $($variant($ty),)+
            #[serde(other)]
            Other,
        }
    };
}

children!(FileChild { File(RawNamed) });
children!(UnitChild { Unit(RawUnit) });
children!(UnitPart { BaseUnit(RawBaseUnit), DisplayUnit(RawDisplayUnit) });
children!(SimpleTypeChild { SimpleType(RawSimpleType) });
children!(ItemChild { Item(RawItem) });
children!(CategoryChild { Category(RawCategory) });
children!(VariableChild { ScalarVariable(RawScalarVariable) });
children!(UnknownChild { Unknown(RawUnknown) });

/// Keeps the children of one kind, in document order.
macro_rules! only {
    ($list:expr, $name:ident :: $variant:ident) => {
        $list.into_iter().filter_map(|child| match child {
            $name::$variant(x) => Some(x),
            _ => None,
        })
    };
}

// ---------------------------------------------------------------------------------------------
// Mirror types. Field order is the schema's order, which is also the order we write.
// ---------------------------------------------------------------------------------------------

#[derive(Serialize, Deserialize, Default)]
pub(super) struct RawModelDescription {
    #[serde(rename = "@fmiVersion", skip_serializing_if = "Option::is_none")]
    fmi_version: Option<String>,
    #[serde(rename = "@modelName", skip_serializing_if = "Option::is_none")]
    model_name: Option<String>,
    #[serde(rename = "@guid", skip_serializing_if = "Option::is_none")]
    guid: Option<String>,
    #[serde(rename = "@description", skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    #[serde(rename = "@author", skip_serializing_if = "Option::is_none")]
    author: Option<String>,
    #[serde(rename = "@version", skip_serializing_if = "Option::is_none")]
    version: Option<String>,
    #[serde(rename = "@copyright", skip_serializing_if = "Option::is_none")]
    copyright: Option<String>,
    #[serde(rename = "@license", skip_serializing_if = "Option::is_none")]
    license: Option<String>,
    #[serde(rename = "@generationTool", skip_serializing_if = "Option::is_none")]
    generation_tool: Option<String>,
    #[serde(rename = "@generationDateAndTime", skip_serializing_if = "Option::is_none")]
    generation_date_and_time: Option<String>,
    #[serde(rename = "@variableNamingConvention", skip_serializing_if = "Option::is_none")]
    variable_naming_convention: Option<String>,
    #[serde(rename = "@numberOfEventIndicators", skip_serializing_if = "Option::is_none")]
    number_of_event_indicators: Option<String>,
    #[serde(rename = "ModelExchange", skip_serializing_if = "Option::is_none")]
    model_exchange: Option<RawInterface>,
    #[serde(rename = "CoSimulation", skip_serializing_if = "Option::is_none")]
    co_simulation: Option<RawInterface>,
    #[serde(rename = "UnitDefinitions", skip_serializing_if = "Option::is_none")]
    unit_definitions: Option<RawUnitDefinitions>,
    #[serde(rename = "TypeDefinitions", skip_serializing_if = "Option::is_none")]
    type_definitions: Option<RawTypeDefinitions>,
    #[serde(rename = "LogCategories", skip_serializing_if = "Option::is_none")]
    log_categories: Option<RawLogCategories>,
    #[serde(rename = "DefaultExperiment", skip_serializing_if = "Option::is_none")]
    default_experiment: Option<RawDefaultExperiment>,
    #[serde(rename = "ModelVariables", skip_serializing_if = "Option::is_none")]
    model_variables: Option<RawModelVariables>,
    #[serde(rename = "ModelStructure", skip_serializing_if = "Option::is_none")]
    model_structure: Option<RawModelStructure>,
}

/// ModelExchange and CoSimulation share one mirror: each simply leaves the other's flags empty.
#[derive(Serialize, Deserialize, Default)]
struct RawInterface {
    #[serde(rename = "@modelIdentifier", skip_serializing_if = "Option::is_none")]
    model_identifier: Option<String>,
    #[serde(rename = "@needsExecutionTool", skip_serializing_if = "Option::is_none")]
    needs_execution_tool: Option<String>,
    #[serde(rename = "@completedIntegratorStepNotNeeded", skip_serializing_if = "Option::is_none")]
    completed_integrator_step_not_needed: Option<String>,
    #[serde(rename = "@canHandleVariableCommunicationStepSize", skip_serializing_if = "Option::is_none")]
    can_handle_variable_communication_step_size: Option<String>,
    #[serde(rename = "@canInterpolateInputs", skip_serializing_if = "Option::is_none")]
    can_interpolate_inputs: Option<String>,
    #[serde(rename = "@maxOutputDerivativeOrder", skip_serializing_if = "Option::is_none")]
    max_output_derivative_order: Option<String>,
    #[serde(rename = "@canRunAsynchronuously", skip_serializing_if = "Option::is_none")]
    can_run_asynchronuously: Option<String>,
    #[serde(rename = "@canBeInstantiatedOnlyOncePerProcess", skip_serializing_if = "Option::is_none")]
    can_be_instantiated_only_once_per_process: Option<String>,
    #[serde(rename = "@canNotUseMemoryManagementFunctions", skip_serializing_if = "Option::is_none")]
    can_not_use_memory_management_functions: Option<String>,
    #[serde(rename = "@canGetAndSetFMUstate", skip_serializing_if = "Option::is_none")]
    can_get_and_set_fmu_state: Option<String>,
    #[serde(rename = "@canSerializeFMUstate", skip_serializing_if = "Option::is_none")]
    can_serialize_fmu_state: Option<String>,
    #[serde(rename = "@providesDirectionalDerivative", skip_serializing_if = "Option::is_none")]
    provides_directional_derivative: Option<String>,
    #[serde(rename = "SourceFiles", skip_serializing_if = "Option::is_none")]
    source_files: Option<RawSourceFiles>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawSourceFiles {
    #[serde(rename = "$value", default)]
    files: Vec<FileChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawNamed {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawUnitDefinitions {
    #[serde(rename = "$value", default)]
    units: Vec<UnitChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawUnit {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    /// BaseUnit (first) and DisplayUnits.
    #[serde(rename = "$value", default)]
    parts: Vec<UnitPart>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawBaseUnit {
    #[serde(rename = "@kg", skip_serializing_if = "Option::is_none")]
    kg: Option<String>,
    #[serde(rename = "@m", skip_serializing_if = "Option::is_none")]
    m: Option<String>,
    #[serde(rename = "@s", skip_serializing_if = "Option::is_none")]
    s: Option<String>,
    #[serde(rename = "@A", skip_serializing_if = "Option::is_none")]
    a: Option<String>,
    #[serde(rename = "@K", skip_serializing_if = "Option::is_none")]
    k: Option<String>,
    #[serde(rename = "@mol", skip_serializing_if = "Option::is_none")]
    mol: Option<String>,
    #[serde(rename = "@cd", skip_serializing_if = "Option::is_none")]
    cd: Option<String>,
    #[serde(rename = "@rad", skip_serializing_if = "Option::is_none")]
    rad: Option<String>,
    #[serde(rename = "@factor", skip_serializing_if = "Option::is_none")]
    factor: Option<String>,
    #[serde(rename = "@offset", skip_serializing_if = "Option::is_none")]
    offset: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawDisplayUnit {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "@factor", skip_serializing_if = "Option::is_none")]
    factor: Option<String>,
    #[serde(rename = "@offset", skip_serializing_if = "Option::is_none")]
    offset: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawTypeDefinitions {
    #[serde(rename = "$value", default)]
    types: Vec<SimpleTypeChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawSimpleType {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "@description", skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    #[serde(rename = "Real", skip_serializing_if = "Option::is_none")]
    real: Option<RawReal>,
    #[serde(rename = "Integer", skip_serializing_if = "Option::is_none")]
    integer: Option<RawInteger>,
    #[serde(rename = "Boolean", skip_serializing_if = "Option::is_none")]
    boolean: Option<RawPlain>,
    #[serde(rename = "String", skip_serializing_if = "Option::is_none")]
    string: Option<RawPlain>,
    #[serde(rename = "Enumeration", skip_serializing_if = "Option::is_none")]
    enumeration: Option<RawEnumerationType>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawEnumerationType {
    #[serde(rename = "@quantity", skip_serializing_if = "Option::is_none")]
    quantity: Option<String>,
    #[serde(rename = "$value", default)]
    items: Vec<ItemChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawItem {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "@value", skip_serializing_if = "Option::is_none")]
    value: Option<String>,
    #[serde(rename = "@description", skip_serializing_if = "Option::is_none")]
    description: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawLogCategories {
    #[serde(rename = "$value", default)]
    categories: Vec<CategoryChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawCategory {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "@description", skip_serializing_if = "Option::is_none")]
    description: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawDefaultExperiment {
    #[serde(rename = "@startTime", skip_serializing_if = "Option::is_none")]
    start_time: Option<String>,
    #[serde(rename = "@stopTime", skip_serializing_if = "Option::is_none")]
    stop_time: Option<String>,
    #[serde(rename = "@tolerance", skip_serializing_if = "Option::is_none")]
    tolerance: Option<String>,
    #[serde(rename = "@stepSize", skip_serializing_if = "Option::is_none")]
    step_size: Option<String>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawModelVariables {
    #[serde(rename = "$value", default)]
    variables: Vec<VariableChild>,
}

/// The schema's `xs:choice` of type elements is five optional children here, so that
/// "none given" and "two given" become our own clear errors instead of serde's.
#[derive(Serialize, Deserialize, Default)]
struct RawScalarVariable {
    #[serde(rename = "@name", skip_serializing_if = "Option::is_none")]
    name: Option<String>,
    #[serde(rename = "@valueReference", skip_serializing_if = "Option::is_none")]
    value_reference: Option<String>,
    #[serde(rename = "@description", skip_serializing_if = "Option::is_none")]
    description: Option<String>,
    #[serde(rename = "@causality", skip_serializing_if = "Option::is_none")]
    causality: Option<String>,
    #[serde(rename = "@variability", skip_serializing_if = "Option::is_none")]
    variability: Option<String>,
    #[serde(rename = "@initial", skip_serializing_if = "Option::is_none")]
    initial: Option<String>,
    #[serde(rename = "@canHandleMultipleSetPerTimeInstant", skip_serializing_if = "Option::is_none")]
    can_handle_multiple_set_per_time_instant: Option<String>,
    #[serde(rename = "Real", skip_serializing_if = "Option::is_none")]
    real: Option<RawReal>,
    #[serde(rename = "Integer", skip_serializing_if = "Option::is_none")]
    integer: Option<RawInteger>,
    #[serde(rename = "Boolean", skip_serializing_if = "Option::is_none")]
    boolean: Option<RawPlain>,
    #[serde(rename = "String", skip_serializing_if = "Option::is_none")]
    string: Option<RawPlain>,
    #[serde(rename = "Enumeration", skip_serializing_if = "Option::is_none")]
    enumeration: Option<RawInteger>,
}

/// `<Real>` of a variable or a SimpleType (the type's version just lacks the last four).
#[derive(Serialize, Deserialize, Default)]
struct RawReal {
    #[serde(rename = "@declaredType", skip_serializing_if = "Option::is_none")]
    declared_type: Option<String>,
    #[serde(rename = "@quantity", skip_serializing_if = "Option::is_none")]
    quantity: Option<String>,
    #[serde(rename = "@unit", skip_serializing_if = "Option::is_none")]
    unit: Option<String>,
    #[serde(rename = "@displayUnit", skip_serializing_if = "Option::is_none")]
    display_unit: Option<String>,
    #[serde(rename = "@relativeQuantity", skip_serializing_if = "Option::is_none")]
    relative_quantity: Option<String>,
    #[serde(rename = "@min", skip_serializing_if = "Option::is_none")]
    min: Option<String>,
    #[serde(rename = "@max", skip_serializing_if = "Option::is_none")]
    max: Option<String>,
    #[serde(rename = "@nominal", skip_serializing_if = "Option::is_none")]
    nominal: Option<String>,
    #[serde(rename = "@unbounded", skip_serializing_if = "Option::is_none")]
    unbounded: Option<String>,
    #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
    start: Option<String>,
    #[serde(rename = "@derivative", skip_serializing_if = "Option::is_none")]
    derivative: Option<String>,
    #[serde(rename = "@reinit", skip_serializing_if = "Option::is_none")]
    reinit: Option<String>,
}

/// `<Integer>` of a variable or SimpleType, and `<Enumeration>` of a variable (same attributes).
#[derive(Serialize, Deserialize, Default)]
struct RawInteger {
    #[serde(rename = "@declaredType", skip_serializing_if = "Option::is_none")]
    declared_type: Option<String>,
    #[serde(rename = "@quantity", skip_serializing_if = "Option::is_none")]
    quantity: Option<String>,
    #[serde(rename = "@min", skip_serializing_if = "Option::is_none")]
    min: Option<String>,
    #[serde(rename = "@max", skip_serializing_if = "Option::is_none")]
    max: Option<String>,
    #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
    start: Option<String>,
}

/// `<Boolean>`/`<String>` of a variable; empty `<Boolean/>`/`<String/>` in a SimpleType.
#[derive(Serialize, Deserialize, Default)]
struct RawPlain {
    #[serde(rename = "@declaredType", skip_serializing_if = "Option::is_none")]
    declared_type: Option<String>,
    #[serde(rename = "@start", skip_serializing_if = "Option::is_none")]
    start: Option<String>,
}

/// ModelStructure is required by the schema, so it is always written, even when empty.
#[derive(Serialize, Deserialize, Default)]
struct RawModelStructure {
    #[serde(rename = "Outputs", skip_serializing_if = "Option::is_none")]
    outputs: Option<RawUnknowns>,
    #[serde(rename = "Derivatives", skip_serializing_if = "Option::is_none")]
    derivatives: Option<RawUnknowns>,
    #[serde(rename = "InitialUnknowns", skip_serializing_if = "Option::is_none")]
    initial_unknowns: Option<RawUnknowns>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawUnknowns {
    #[serde(rename = "$value", default)]
    unknowns: Vec<UnknownChild>,
}

#[derive(Serialize, Deserialize, Default)]
struct RawUnknown {
    #[serde(rename = "@index", skip_serializing_if = "Option::is_none")]
    index: Option<String>,
    #[serde(rename = "@dependencies", skip_serializing_if = "Option::is_none")]
    dependencies: Option<String>,
    #[serde(rename = "@dependenciesKind", skip_serializing_if = "Option::is_none")]
    dependencies_kind: Option<String>,
}

// ---------------------------------------------------------------------------------------------
// Reading.
// ---------------------------------------------------------------------------------------------

/// Parses a whole document: well-formedness and root first, then serde, then validation.
pub(super) fn read(text: &str) -> Result<ModelDescription, DescriptionError> {
    // A UTF-8 byte order mark is legal in XML but not something quick-xml skips in a &str.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    scan(text)?;
    let raw: RawModelDescription =
        quick_xml::de::from_str(text).map_err(|e| DescriptionError::new(format!("invalid modelDescription.xml: {e}")))?;
    raw.into_model()
}

/// Walks the raw event stream once so that malformed XML is reported with a line and column
/// (serde's errors have no position) and a wrong root element is named as such.
fn scan(text: &str) -> Result<(), DescriptionError> {
    let malformed = |offset: u64, what: &str| {
        let (line, column) = line_column(text, offset as usize);
        DescriptionError::new(format!("malformed XML at line {line}, column {column}: {what}"))
    };
    let mut reader = Reader::from_str(text);
    let mut seen_root = false;
    // Open elements with the offset of their start tag, to say where an unclosed one began.
    let mut open: Vec<(String, u64)> = Vec::new();
    loop {
        let offset = reader.buffer_position();
        let event = reader.read_event().map_err(|e| malformed(reader.error_position(), &e.to_string()))?;
        match event {
            Event::Start(ref e) | Event::Empty(ref e) => {
                let name = e.name().0.to_string();
                // The reader checks attributes only when asked; serde would report a duplicated
                // attribute or a bad escape without a position.
                for attribute in e.attributes() {
                    let problem = match attribute {
                        Err(error) => Some(error.to_string()),
                        Ok(a) => a.normalized_value(XmlVersion::Implicit1_0).err().map(|error| error.to_string()),
                    };
                    if let Some(problem) = problem {
                        return Err(malformed(offset, &format!("in the attributes of <{name}>: {problem}")));
                    }
                }
                if open.is_empty() {
                    if seen_root {
                        return Err(malformed(offset, &format!("second root element <{name}>")));
                    }
                    if name != ROOT {
                        return Err(DescriptionError::new(format!(
                            "root element is <{name}>, expected <{ROOT}> (not a modelDescription.xml)"
                        )));
                    }
                    // Checked here as well as after parsing, so that an FMI 1.0 or 3.0 file gets the
                    // version message rather than whatever its different layout trips over first.
                    if let Ok(Some(attribute)) = e.try_get_attribute("fmiVersion") {
                        if let Ok(version) = attribute.normalized_value(XmlVersion::Implicit1_0) {
                            check_version(&version)?;
                        }
                    }
                    seen_root = true;
                }
                if matches!(event, Event::Start(_)) {
                    open.push((name, offset));
                }
            }
            Event::End(_) => {
                open.pop();
            }
            Event::Text(ref t) if open.is_empty() && !t.trim().is_empty() => {
                return Err(malformed(offset, "text outside the root element"));
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if let Some((unclosed, offset)) = open.last() {
        let (line, column) = line_column(text, *offset as usize);
        return Err(DescriptionError::new(format!(
            "malformed XML: the document ends before <{unclosed}> (opened at line {line}, column {column}) is closed"
        )));
    }
    if !seen_root {
        return Err(DescriptionError::new(format!("malformed XML: no <{ROOT}> element found")));
    }
    Ok(())
}

/// Accepts "2.0" and maintenance releases "2.0.x", which share the 2.0 schema.
fn check_version(version: &str) -> Result<(), DescriptionError> {
    let version = version.trim();
    if version == "2.0" || version.starts_with("2.0.") {
        Ok(())
    } else {
        Err(DescriptionError::new(format!("fmiVersion is {version}, only FMI 2.0 is supported")))
    }
}

/// 1-based line and column of a byte offset.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text.as_bytes()[..offset];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
    let column = String::from_utf8_lossy(&before[line_start..]).chars().count() + 1;
    (line, column)
}

/// Parses attribute `attr` of element `at` (a phrase like "ScalarVariable 'x'") with `parse`.
fn parse_with<T>(
    value: Option<&str>,
    attr: &str,
    at: &str,
    expected: &str,
    parse: impl Fn(&str) -> Option<T>,
) -> Result<Option<T>, DescriptionError> {
    match value {
        None => Ok(None),
        Some(text) => parse(text.trim())
            .map(Some)
            .ok_or_else(|| DescriptionError::new(format!("attribute {attr}=\"{text}\" on {at} is not {expected}"))),
    }
}

/// xs:double. Rust's parser already accepts the XML Schema spellings `INF`, `-INF` and `NaN`
/// (it is case-insensitive for those), plus exponents like `1E-4`.
pub(super) fn parse_real(text: &str) -> Option<f64> {
    text.parse().ok()
}

/// xs:boolean: `true`, `false`, `1`, `0`.
fn parse_bool(text: &str) -> Option<bool> {
    match text {
        "true" | "1" => Some(true),
        "false" | "0" => Some(false),
        _ => None,
    }
}

fn real(v: &Option<String>, attr: &str, at: &str) -> Result<Option<f64>, DescriptionError> {
    parse_with(v.as_deref(), attr, at, "a number", parse_real)
}

fn int(v: &Option<String>, attr: &str, at: &str) -> Result<Option<i32>, DescriptionError> {
    parse_with(v.as_deref(), attr, at, "an integer", |t| t.parse().ok())
}

fn uint(v: &Option<String>, attr: &str, at: &str) -> Result<Option<u32>, DescriptionError> {
    parse_with(v.as_deref(), attr, at, "an unsigned integer", |t| t.parse().ok())
}

fn boolean(v: &Option<String>, attr: &str, at: &str) -> Result<Option<bool>, DescriptionError> {
    parse_with(v.as_deref(), attr, at, "a boolean (true or false)", parse_bool)
}

fn flag(v: &Option<String>, attr: &str, at: &str) -> Result<bool, DescriptionError> {
    Ok(boolean(v, attr, at)?.unwrap_or(false))
}

fn enumeration<T: FromStr<Err = String>>(v: &Option<String>, attr: &str, at: &str) -> Result<Option<T>, DescriptionError> {
    match v {
        None => Ok(None),
        Some(text) => text.parse().map(Some).map_err(|e| DescriptionError::new(format!("attribute {attr} on {at}: {e}"))),
    }
}

fn required(v: Option<String>, attr: &str, at: &str) -> Result<String, DescriptionError> {
    v.ok_or_else(|| DescriptionError::new(format!("missing attribute {attr} on {at}")))
}

/// Parses an xs:list attribute item by item.
fn list<T>(
    v: &Option<String>,
    attr: &str,
    at: &str,
    parse: impl Fn(&str) -> Result<T, String>,
) -> Result<Option<Vec<T>>, DescriptionError> {
    let Some(text) = v else { return Ok(None) };
    text.split_whitespace()
        .map(|item| parse(item).map_err(|e| DescriptionError::new(format!("attribute {attr} on {at}: {e}"))))
        .collect::<Result<Vec<T>, _>>()
        .map(Some)
}

/// "Unit 'm'" or, when the name is missing, "Unit #2" so errors always point somewhere.
fn label(element: &str, name: &Option<String>, position: usize) -> String {
    match name {
        Some(n) => format!("{element} '{n}'"),
        None => format!("{element} #{}", position + 1),
    }
}

impl RawModelDescription {
    fn into_model(self) -> Result<ModelDescription, DescriptionError> {
        let at = ROOT;
        // The version decides how to read everything else, so it is checked first.
        let fmi_version = required(self.fmi_version, "fmiVersion", at)?;
        check_version(&fmi_version)?;
        let model_exchange = self
            .model_exchange
            .map(|raw| {
                let at = "ModelExchange";
                Ok::<_, DescriptionError>(ModelExchange {
                    common: raw.common(at)?,
                    completed_integrator_step_not_needed: flag(
                        &raw.completed_integrator_step_not_needed,
                        "completedIntegratorStepNotNeeded",
                        at,
                    )?,
                })
            })
            .transpose()?;
        let co_simulation = self
            .co_simulation
            .map(|raw| {
                let at = "CoSimulation";
                Ok::<_, DescriptionError>(CoSimulation {
                    common: raw.common(at)?,
                    can_handle_variable_communication_step_size: flag(
                        &raw.can_handle_variable_communication_step_size,
                        "canHandleVariableCommunicationStepSize",
                        at,
                    )?,
                    can_interpolate_inputs: flag(&raw.can_interpolate_inputs, "canInterpolateInputs", at)?,
                    max_output_derivative_order: uint(&raw.max_output_derivative_order, "maxOutputDerivativeOrder", at)?.unwrap_or(0),
                    can_run_asynchronuously: flag(&raw.can_run_asynchronuously, "canRunAsynchronuously", at)?,
                })
            })
            .transpose()?;

        let unit_definitions = self.unit_definitions.map(|d| d.units).unwrap_or_default();
        let unit_definitions =
            only!(unit_definitions, UnitChild::Unit).enumerate().map(|(i, raw)| raw.into_model(i)).collect::<Result<Vec<_>, _>>()?;
        let type_definitions = self.type_definitions.map(|d| d.types).unwrap_or_default();
        let type_definitions = only!(type_definitions, SimpleTypeChild::SimpleType)
            .enumerate()
            .map(|(i, raw)| raw.into_model(i))
            .collect::<Result<Vec<_>, _>>()?;
        let log_categories = self.log_categories.map(|d| d.categories).unwrap_or_default();
        let log_categories = only!(log_categories, CategoryChild::Category)
            .enumerate()
            .map(|(i, raw)| {
                let at = label("Category", &raw.name, i);
                Ok(Category { name: required(raw.name, "name", &at)?, description: raw.description })
            })
            .collect::<Result<Vec<_>, DescriptionError>>()?;
        let default_experiment = self
            .default_experiment
            .map(|raw| {
                let at = "DefaultExperiment";
                Ok::<_, DescriptionError>(DefaultExperiment {
                    start_time: real(&raw.start_time, "startTime", at)?,
                    stop_time: real(&raw.stop_time, "stopTime", at)?,
                    tolerance: real(&raw.tolerance, "tolerance", at)?,
                    step_size: real(&raw.step_size, "stepSize", at)?,
                })
            })
            .transpose()?;
        let model_variables =
            self.model_variables.ok_or_else(|| DescriptionError::new(format!("missing element ModelVariables in {ROOT}")))?.variables;
        let model_variables = only!(model_variables, VariableChild::ScalarVariable)
            .enumerate()
            .map(|(i, raw)| raw.into_model(i))
            .collect::<Result<Vec<_>, _>>()?;
        // ModelStructure is required by the schema, but an FMU that omits it is still usable
        // for simulation, so reading accepts it as empty; `check` judges the content.
        let model_structure = match self.model_structure {
            None => ModelStructure::default(),
            Some(raw) => ModelStructure {
                outputs: unknowns(raw.outputs, "ModelStructure/Outputs")?,
                derivatives: unknowns(raw.derivatives, "ModelStructure/Derivatives")?,
                initial_unknowns: unknowns(raw.initial_unknowns, "ModelStructure/InitialUnknowns")?,
            },
        };

        Ok(ModelDescription {
            fmi_version,
            model_name: required(self.model_name, "modelName", at)?,
            guid: required(self.guid, "guid", at)?,
            description: self.description,
            author: self.author,
            version: self.version,
            copyright: self.copyright,
            license: self.license,
            generation_tool: self.generation_tool,
            generation_date_and_time: self.generation_date_and_time,
            variable_naming_convention: enumeration(&self.variable_naming_convention, "variableNamingConvention", at)?,
            number_of_event_indicators: uint(&self.number_of_event_indicators, "numberOfEventIndicators", at)?,
            model_exchange,
            co_simulation,
            unit_definitions,
            type_definitions,
            log_categories,
            default_experiment,
            model_variables,
            model_structure,
        })
    }
}

impl RawInterface {
    /// The attributes both interfaces share, read once for either.
    fn common(&self, at: &str) -> Result<InterfaceCommon, DescriptionError> {
        Ok(InterfaceCommon {
            model_identifier: required(self.model_identifier.clone(), "modelIdentifier", at)?,
            needs_execution_tool: flag(&self.needs_execution_tool, "needsExecutionTool", at)?,
            can_be_instantiated_only_once_per_process: flag(
                &self.can_be_instantiated_only_once_per_process,
                "canBeInstantiatedOnlyOncePerProcess",
                at,
            )?,
            can_not_use_memory_management_functions: flag(
                &self.can_not_use_memory_management_functions,
                "canNotUseMemoryManagementFunctions",
                at,
            )?,
            can_get_and_set_fmu_state: flag(&self.can_get_and_set_fmu_state, "canGetAndSetFMUstate", at)?,
            can_serialize_fmu_state: flag(&self.can_serialize_fmu_state, "canSerializeFMUstate", at)?,
            provides_directional_derivative: flag(&self.provides_directional_derivative, "providesDirectionalDerivative", at)?,
            source_files: source_files(self.source_files.as_ref(), at)?,
        })
    }

    /// The mirror of the shared attributes; each interface adds its own.
    fn from_common(c: &InterfaceCommon) -> Self {
        RawInterface {
            model_identifier: Some(c.model_identifier.clone()),
            needs_execution_tool: flag_out(c.needs_execution_tool),
            can_be_instantiated_only_once_per_process: flag_out(c.can_be_instantiated_only_once_per_process),
            can_not_use_memory_management_functions: flag_out(c.can_not_use_memory_management_functions),
            can_get_and_set_fmu_state: flag_out(c.can_get_and_set_fmu_state),
            can_serialize_fmu_state: flag_out(c.can_serialize_fmu_state),
            provides_directional_derivative: flag_out(c.provides_directional_derivative),
            source_files: files_out(&c.source_files),
            ..RawInterface::default()
        }
    }
}

impl RawReal {
    /// The `fmi2RealAttributes` group, read once for variables and SimpleTypes.
    fn attributes(&self, at: &str) -> Result<RealAttributes, DescriptionError> {
        Ok(RealAttributes {
            quantity: self.quantity.clone(),
            unit: self.unit.clone(),
            display_unit: self.display_unit.clone(),
            relative_quantity: flag(&self.relative_quantity, "relativeQuantity", at)?,
            min: real(&self.min, "min", at)?,
            max: real(&self.max, "max", at)?,
            nominal: real(&self.nominal, "nominal", at)?,
            unbounded: flag(&self.unbounded, "unbounded", at)?,
        })
    }

    /// The mirror of the group; a variable adds declaredType, start, derivative and reinit.
    fn from_attributes(a: &RealAttributes) -> Self {
        RawReal {
            quantity: a.quantity.clone(),
            unit: a.unit.clone(),
            display_unit: a.display_unit.clone(),
            relative_quantity: flag_out(a.relative_quantity),
            min: opt_real(a.min),
            max: opt_real(a.max),
            nominal: opt_real(a.nominal),
            unbounded: flag_out(a.unbounded),
            ..RawReal::default()
        }
    }
}

impl RawInteger {
    /// The `fmi2IntegerAttributes` group (quantity, min, max), read once for Integer variables
    /// and SimpleTypes and Enumeration variables.
    fn attributes(&self, at: &str) -> Result<IntegerAttributes, DescriptionError> {
        Ok(IntegerAttributes { quantity: self.quantity.clone(), min: int(&self.min, "min", at)?, max: int(&self.max, "max", at)? })
    }

    /// The mirror of the group; a variable adds declaredType and start.
    fn from_attributes(a: &IntegerAttributes) -> Self {
        RawInteger { quantity: a.quantity.clone(), min: opt_display(a.min), max: opt_display(a.max), ..RawInteger::default() }
    }
}

fn source_files(raw: Option<&RawSourceFiles>, interface: &str) -> Result<Vec<String>, DescriptionError> {
    raw.map(|s| s.files.as_slice())
        .unwrap_or_default()
        .iter()
        .filter_map(|child| match child {
            FileChild::File(f) => Some(f),
            FileChild::Other => None,
        })
        .enumerate()
        .map(|(i, f)| required(f.name.clone(), "name", &format!("{interface}/SourceFiles/File #{}", i + 1)))
        .collect()
}

fn unknowns(raw: Option<RawUnknowns>, list_name: &str) -> Result<Vec<Unknown>, DescriptionError> {
    only!(raw.map(|u| u.unknowns).unwrap_or_default(), UnknownChild::Unknown)
        .enumerate()
        .map(|(i, raw)| {
            let at = format!("{list_name}/Unknown #{}", i + 1);
            Ok(Unknown {
                index: uint(&raw.index, "index", &at)?.ok_or_else(|| DescriptionError::new(format!("missing attribute index on {at}")))?,
                dependencies: list(&raw.dependencies, "dependencies", &at, |item| {
                    item.parse::<u32>().map_err(|_| format!("'{item}' is not a variable index"))
                })?,
                dependencies_kind: list(&raw.dependencies_kind, "dependenciesKind", &at, |item| item.parse::<DependencyKind>())?,
            })
        })
        .collect()
}

impl RawUnit {
    fn into_model(self, position: usize) -> Result<Unit, DescriptionError> {
        let at = label("Unit", &self.name, position);
        let mut base_units = Vec::new();
        let mut display_units = Vec::new();
        for part in self.parts {
            match part {
                UnitPart::BaseUnit(b) => base_units.push(b),
                UnitPart::DisplayUnit(d) => display_units.push(d),
                UnitPart::Other => {}
            }
        }
        let base_unit = base_units
            .into_iter()
            .next()
            .map(|b| {
                let at = format!("BaseUnit of {at}");
                let exponent = |v: &Option<String>, attr: &str| Ok::<_, DescriptionError>(int(v, attr, &at)?.unwrap_or(0));
                Ok::<_, DescriptionError>(BaseUnit {
                    kg: exponent(&b.kg, "kg")?,
                    m: exponent(&b.m, "m")?,
                    s: exponent(&b.s, "s")?,
                    a: exponent(&b.a, "A")?,
                    k: exponent(&b.k, "K")?,
                    mol: exponent(&b.mol, "mol")?,
                    cd: exponent(&b.cd, "cd")?,
                    rad: exponent(&b.rad, "rad")?,
                    factor: real(&b.factor, "factor", &at)?.unwrap_or(1.0),
                    offset: real(&b.offset, "offset", &at)?.unwrap_or(0.0),
                })
            })
            .transpose()?;
        let display_units = display_units
            .into_iter()
            .enumerate()
            .map(|(i, d)| {
                let at = format!("{} of {at}", label("DisplayUnit", &d.name, i));
                Ok(DisplayUnit {
                    factor: real(&d.factor, "factor", &at)?.unwrap_or(1.0),
                    offset: real(&d.offset, "offset", &at)?.unwrap_or(0.0),
                    name: required(d.name, "name", &at)?,
                })
            })
            .collect::<Result<Vec<_>, DescriptionError>>()?;
        Ok(Unit { name: required(self.name, "name", &at)?, base_unit, display_units })
    }
}

impl RawSimpleType {
    fn into_model(self, position: usize) -> Result<SimpleType, DescriptionError> {
        let at = label("SimpleType", &self.name, position);
        let mut kinds = Vec::new();
        if let Some(r) = &self.real {
            kinds.push(SimpleTypeKind::Real(r.attributes(&format!("Real of {at}"))?));
        }
        if let Some(i) = &self.integer {
            kinds.push(SimpleTypeKind::Integer(i.attributes(&format!("Integer of {at}"))?));
        }
        if self.boolean.is_some() {
            kinds.push(SimpleTypeKind::Boolean);
        }
        if self.string.is_some() {
            kinds.push(SimpleTypeKind::String);
        }
        if let Some(e) = self.enumeration {
            let items = only!(e.items, ItemChild::Item)
                .enumerate()
                .map(|(i, item)| {
                    let at = format!("{} of Enumeration of {at}", label("Item", &item.name, i));
                    Ok(EnumerationItem {
                        value: int(&item.value, "value", &at)?
                            .ok_or_else(|| DescriptionError::new(format!("missing attribute value on {at}")))?,
                        name: required(item.name, "name", &at)?,
                        description: item.description,
                    })
                })
                .collect::<Result<Vec<_>, DescriptionError>>()?;
            kinds.push(SimpleTypeKind::Enumeration(EnumerationType { quantity: e.quantity, items }));
        }
        let kind = single_kind(kinds, &at)?;
        Ok(SimpleType { name: required(self.name, "name", &at)?, description: self.description, kind })
    }
}

/// Enforces the schema's "exactly one type element" with a message naming the element.
fn single_kind<T>(mut kinds: Vec<T>, at: &str) -> Result<T, DescriptionError> {
    match kinds.len() {
        1 => Ok(kinds.remove(0)),
        0 => Err(DescriptionError::new(format!("{at} has no type element (Real, Integer, Boolean, String or Enumeration)"))),
        _ => Err(DescriptionError::new(format!(
            "{at} has more than one type element (exactly one of Real, Integer, Boolean, String or Enumeration is allowed)"
        ))),
    }
}

impl RawScalarVariable {
    fn into_model(self, position: usize) -> Result<ScalarVariable, DescriptionError> {
        let at = label("ScalarVariable", &self.name, position);
        let mut kinds = Vec::new();
        if let Some(r) = &self.real {
            let at = format!("{at} (Real)");
            kinds.push(VariableType::Real(RealVariable {
                declared_type: r.declared_type.clone(),
                attributes: r.attributes(&at)?,
                start: real(&r.start, "start", &at)?,
                derivative: uint(&r.derivative, "derivative", &at)?,
                reinit: flag(&r.reinit, "reinit", &at)?,
            }));
        }
        if let Some(i) = &self.integer {
            let at = format!("{at} (Integer)");
            kinds.push(VariableType::Integer(IntegerVariable {
                declared_type: i.declared_type.clone(),
                attributes: i.attributes(&at)?,
                start: int(&i.start, "start", &at)?,
            }));
        }
        if let Some(b) = &self.boolean {
            let at = format!("{at} (Boolean)");
            kinds.push(VariableType::Boolean(BooleanVariable {
                declared_type: b.declared_type.clone(),
                start: boolean(&b.start, "start", &at)?,
            }));
        }
        if let Some(s) = &self.string {
            kinds.push(VariableType::String(StringVariable { declared_type: s.declared_type.clone(), start: s.start.clone() }));
        }
        if let Some(e) = &self.enumeration {
            let at = format!("{at} (Enumeration)");
            kinds.push(VariableType::Enumeration(EnumerationVariable {
                declared_type: e.declared_type.clone(),
                attributes: e.attributes(&at)?,
                start: int(&e.start, "start", &at)?,
            }));
        }
        let var_type = single_kind(kinds, &at)?;
        let value_reference = uint(&self.value_reference, "valueReference", &at)?
            .ok_or_else(|| DescriptionError::new(format!("missing attribute valueReference on {at}")))?;
        Ok(ScalarVariable {
            value_reference,
            causality: enumeration(&self.causality, "causality", &at)?,
            variability: enumeration(&self.variability, "variability", &at)?,
            initial: enumeration(&self.initial, "initial", &at)?,
            can_handle_multiple_set_per_time_instant: boolean(
                &self.can_handle_multiple_set_per_time_instant,
                "canHandleMultipleSetPerTimeInstant",
                &at,
            )?,
            name: required(self.name, "name", &at)?,
            description: self.description,
            var_type,
        })
    }
}

// ---------------------------------------------------------------------------------------------
// Writing.
// ---------------------------------------------------------------------------------------------

/// Serializes with the XML declaration, 2-space indentation and a trailing newline.
pub(super) fn write(model: &ModelDescription) -> Result<String, DescriptionError> {
    let raw = RawModelDescription::from_model(model);
    let mut body = String::new();
    let mut serializer = quick_xml::se::Serializer::with_root(&mut body, Some(ROOT))
        .map_err(|e| DescriptionError::new(format!("cannot write modelDescription.xml: {e}")))?;
    serializer.indent(' ', 2);
    raw.serialize(serializer).map_err(|e| DescriptionError::new(format!("cannot write modelDescription.xml: {e}")))?;
    Ok(format!("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n{body}\n"))
}

pub(super) use crate::format_real;

fn opt_real(v: Option<f64>) -> Option<String> {
    v.map(format_real)
}

fn opt_display<T: Display>(v: Option<T>) -> Option<String> {
    v.map(|x| x.to_string())
}

/// A defaulted flag is written only when it differs from the schema default `false`.
fn flag_out(v: bool) -> Option<String> {
    v.then(|| "true".to_string())
}

/// A defaulted number is written only when it differs (bitwise, so -0.0 survives) from its default.
fn real_unless(v: f64, default: f64) -> Option<String> {
    (v.to_bits() != default.to_bits()).then(|| format_real(v))
}

fn int_unless(v: i32, default: i32) -> Option<String> {
    (v != default).then(|| v.to_string())
}

fn list_out<T: Display>(v: &Option<Vec<T>>) -> Option<String> {
    v.as_ref().map(|items| items.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(" "))
}

fn files_out(files: &[String]) -> Option<RawSourceFiles> {
    (!files.is_empty())
        .then(|| RawSourceFiles { files: files.iter().map(|f| FileChild::File(RawNamed { name: Some(f.clone()) })).collect() })
}

fn unknowns_out(list: &[Unknown]) -> Option<RawUnknowns> {
    // An empty list element would be schema-invalid (Unknown is minOccurs 1), so omit it.
    (!list.is_empty()).then(|| RawUnknowns {
        unknowns: list
            .iter()
            .map(|u| {
                UnknownChild::Unknown(RawUnknown {
                    index: Some(u.index.to_string()),
                    dependencies: list_out(&u.dependencies),
                    dependencies_kind: list_out(&u.dependencies_kind),
                })
            })
            .collect(),
    })
}

impl RawModelDescription {
    fn from_model(m: &ModelDescription) -> Self {
        RawModelDescription {
            fmi_version: Some(m.fmi_version.clone()),
            model_name: Some(m.model_name.clone()),
            guid: Some(m.guid.clone()),
            description: m.description.clone(),
            author: m.author.clone(),
            version: m.version.clone(),
            copyright: m.copyright.clone(),
            license: m.license.clone(),
            generation_tool: m.generation_tool.clone(),
            generation_date_and_time: m.generation_date_and_time.clone(),
            variable_naming_convention: opt_display(m.variable_naming_convention),
            number_of_event_indicators: opt_display(m.number_of_event_indicators),
            model_exchange: m.model_exchange.as_ref().map(|me| RawInterface {
                completed_integrator_step_not_needed: flag_out(me.completed_integrator_step_not_needed),
                ..RawInterface::from_common(&me.common)
            }),
            co_simulation: m.co_simulation.as_ref().map(|cs| RawInterface {
                can_handle_variable_communication_step_size: flag_out(cs.can_handle_variable_communication_step_size),
                can_interpolate_inputs: flag_out(cs.can_interpolate_inputs),
                max_output_derivative_order: (cs.max_output_derivative_order != 0).then(|| cs.max_output_derivative_order.to_string()),
                can_run_asynchronuously: flag_out(cs.can_run_asynchronuously),
                ..RawInterface::from_common(&cs.common)
            }),
            unit_definitions: (!m.unit_definitions.is_empty()).then(|| RawUnitDefinitions {
                units: m.unit_definitions.iter().map(|u| UnitChild::Unit(RawUnit::from_model(u))).collect(),
            }),
            type_definitions: (!m.type_definitions.is_empty()).then(|| RawTypeDefinitions {
                types: m.type_definitions.iter().map(|t| SimpleTypeChild::SimpleType(RawSimpleType::from_model(t))).collect(),
            }),
            log_categories: (!m.log_categories.is_empty()).then(|| RawLogCategories {
                categories: m
                    .log_categories
                    .iter()
                    .map(|c| CategoryChild::Category(RawCategory { name: Some(c.name.clone()), description: c.description.clone() }))
                    .collect(),
            }),
            default_experiment: m.default_experiment.as_ref().map(|d| RawDefaultExperiment {
                start_time: opt_real(d.start_time),
                stop_time: opt_real(d.stop_time),
                tolerance: opt_real(d.tolerance),
                step_size: opt_real(d.step_size),
            }),
            model_variables: Some(RawModelVariables {
                variables: m.model_variables.iter().map(|v| VariableChild::ScalarVariable(RawScalarVariable::from_model(v))).collect(),
            }),
            model_structure: Some(RawModelStructure {
                outputs: unknowns_out(&m.model_structure.outputs),
                derivatives: unknowns_out(&m.model_structure.derivatives),
                initial_unknowns: unknowns_out(&m.model_structure.initial_unknowns),
            }),
        }
    }
}

impl RawUnit {
    fn from_model(u: &Unit) -> Self {
        let base_unit = u.base_unit.as_ref().map(|b| {
            UnitPart::BaseUnit(RawBaseUnit {
                kg: int_unless(b.kg, 0),
                m: int_unless(b.m, 0),
                s: int_unless(b.s, 0),
                a: int_unless(b.a, 0),
                k: int_unless(b.k, 0),
                mol: int_unless(b.mol, 0),
                cd: int_unless(b.cd, 0),
                rad: int_unless(b.rad, 0),
                factor: real_unless(b.factor, 1.0),
                offset: real_unless(b.offset, 0.0),
            })
        });
        let display_units = u.display_units.iter().map(|d| {
            UnitPart::DisplayUnit(RawDisplayUnit {
                name: Some(d.name.clone()),
                factor: real_unless(d.factor, 1.0),
                offset: real_unless(d.offset, 0.0),
            })
        });
        RawUnit { name: Some(u.name.clone()), parts: base_unit.into_iter().chain(display_units).collect() }
    }
}

impl RawSimpleType {
    fn from_model(t: &SimpleType) -> Self {
        let mut raw = RawSimpleType { name: Some(t.name.clone()), description: t.description.clone(), ..RawSimpleType::default() };
        match &t.kind {
            SimpleTypeKind::Real(r) => raw.real = Some(RawReal::from_attributes(r)),
            SimpleTypeKind::Integer(i) => raw.integer = Some(RawInteger::from_attributes(i)),
            SimpleTypeKind::Boolean => raw.boolean = Some(RawPlain::default()),
            SimpleTypeKind::String => raw.string = Some(RawPlain::default()),
            SimpleTypeKind::Enumeration(e) => {
                raw.enumeration = Some(RawEnumerationType {
                    quantity: e.quantity.clone(),
                    items: e
                        .items
                        .iter()
                        .map(|item| {
                            ItemChild::Item(RawItem {
                                name: Some(item.name.clone()),
                                value: Some(item.value.to_string()),
                                description: item.description.clone(),
                            })
                        })
                        .collect(),
                })
            }
        }
        raw
    }
}

impl RawScalarVariable {
    fn from_model(v: &ScalarVariable) -> Self {
        let mut raw = RawScalarVariable {
            name: Some(v.name.clone()),
            value_reference: Some(v.value_reference.to_string()),
            description: v.description.clone(),
            causality: opt_display(v.causality),
            variability: opt_display(v.variability),
            initial: opt_display(v.initial),
            can_handle_multiple_set_per_time_instant: opt_display(v.can_handle_multiple_set_per_time_instant),
            ..RawScalarVariable::default()
        };
        match &v.var_type {
            VariableType::Real(r) => {
                raw.real = Some(RawReal {
                    declared_type: r.declared_type.clone(),
                    start: opt_real(r.start),
                    derivative: opt_display(r.derivative),
                    reinit: flag_out(r.reinit),
                    ..RawReal::from_attributes(&r.attributes)
                })
            }
            VariableType::Integer(i) => {
                raw.integer = Some(RawInteger {
                    declared_type: i.declared_type.clone(),
                    start: opt_display(i.start),
                    ..RawInteger::from_attributes(&i.attributes)
                })
            }
            VariableType::Boolean(b) => {
                raw.boolean = Some(RawPlain { declared_type: b.declared_type.clone(), start: opt_display(b.start) })
            }
            VariableType::String(s) => raw.string = Some(RawPlain { declared_type: s.declared_type.clone(), start: s.start.clone() }),
            VariableType::Enumeration(e) => {
                raw.enumeration = Some(RawInteger {
                    declared_type: e.declared_type.clone(),
                    start: opt_display(e.start),
                    ..RawInteger::from_attributes(&e.attributes)
                })
            }
        }
        raw
    }
}

// ---------------------------------------------------------------------------------------------
// Serde for the public root type, so it can also be used with quick-xml's serde API directly.
// ---------------------------------------------------------------------------------------------

impl Serialize for ModelDescription {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        RawModelDescription::from_model(self).serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for ModelDescription {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        RawModelDescription::deserialize(deserializer)?.into_model().map_err(serde::de::Error::custom)
    }
}
