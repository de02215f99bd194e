//! FMI 3.0 `modelDescription.xml`: typed model, reading and writing, and a self-check.
//!
//! The attribute groups the standard shares are written once here: the capability flags every
//! interface has ([`InterfaceCommon`]), the attributes of every variable ([`Variable`], with
//! its dimensions and aliases), of every floating-point type (one [`Float`] for Float32 and
//! Float64) and of every integer type (one [`Int`] for Int8 to UInt64). Reading goes through
//! an element tree (`crate::tree`) so that errors name the element and attribute.

mod check;
mod read;
mod write;

#[cfg(test)]
mod tests;

use std::fmt;
use std::str::FromStr;

pub use crate::{escaped_and_cut, printable, DescriptionError};

fmi_enum! {
    /// `causality`; absent means `local`.
    #[derive(Default)]
    Causality, "causality" {
        Parameter = "parameter",
        CalculatedParameter = "calculatedParameter",
        /// A parameter that fixes array sizes (Dimension references it).
        StructuralParameter = "structuralParameter",
        Input = "input",
        Output = "output",
        #[default]
        Local = "local",
        Independent = "independent",
    }
}

fmi_enum! {
    /// `variability`; absent means `continuous` for Float variables, `discrete` for the others.
    Variability, "variability" {
        Constant = "constant",
        Fixed = "fixed",
        Tunable = "tunable",
        Discrete = "discrete",
        Continuous = "continuous",
    }
}

fmi_enum! {
    /// `initial`; absent means a default derived from causality and variability.
    Initial, "initial" {
        Exact = "exact",
        Approx = "approx",
        Calculated = "calculated",
    }
}

fmi_enum! {
    /// `variableNamingConvention`; absent means `flat`.
    #[derive(Default)]
    VariableNamingConvention, "variableNamingConvention" {
        #[default]
        Flat = "flat",
        Structured = "structured",
    }
}

fmi_enum! {
    /// One entry of a `dependenciesKind` list.
    DependencyKind, "dependenciesKind entry" {
        Independent = "independent",
        Constant = "constant",
        Fixed = "fixed",
        Tunable = "tunable",
        Discrete = "discrete",
        Dependent = "dependent",
    }
}

fmi_enum! {
    /// `intervalVariability` of a Clock.
    IntervalVariability, "intervalVariability" {
        Constant = "constant",
        Fixed = "fixed",
        Calculated = "calculated",
        Tunable = "tunable",
        Changing = "changing",
        Countdown = "countdown",
        Triggered = "triggered",
    }
}

fmi_enum! {
    /// The two floating-point types.
    FloatType, "floating-point type" {
        Float32 = "Float32",
        Float64 = "Float64",
    }
}

fmi_enum! {
    /// The eight integer types.
    IntType, "integer type" {
        Int8 = "Int8",
        UInt8 = "UInt8",
        Int16 = "Int16",
        UInt16 = "UInt16",
        Int32 = "Int32",
        UInt32 = "UInt32",
        Int64 = "Int64",
        UInt64 = "UInt64",
    }
}

impl IntType {
    /// The smallest and largest value of the type.
    pub fn range(self) -> (i128, i128) {
        match self {
            IntType::Int8 => (i8::MIN.into(), i8::MAX.into()),
            IntType::UInt8 => (0, u8::MAX.into()),
            IntType::Int16 => (i16::MIN.into(), i16::MAX.into()),
            IntType::UInt16 => (0, u16::MAX.into()),
            IntType::Int32 => (i32::MIN.into(), i32::MAX.into()),
            IntType::UInt32 => (0, u32::MAX.into()),
            IntType::Int64 => (i64::MIN.into(), i64::MAX.into()),
            IntType::UInt64 => (0, u64::MAX.into()),
        }
    }
}

impl Causality {
    /// The causalities whose variables are parameters (set before or while initializing).
    pub fn is_parameter(self) -> bool {
        matches!(self, Causality::Parameter | Causality::StructuralParameter)
    }
}

/// The capability flags every interface has.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InterfaceCommon {
    /// Prefix of nothing in 3.0 (functions are not prefixed), but the name of the binary.
    pub model_identifier: String,
    pub needs_execution_tool: bool,
    pub can_be_instantiated_only_once_per_process: bool,
    pub can_get_and_set_fmu_state: bool,
    pub can_serialize_fmu_state: bool,
    pub provides_directional_derivatives: bool,
    pub provides_adjoint_derivatives: bool,
    pub provides_per_element_dependencies: bool,
}

/// `<ModelExchange>`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelExchange {
    pub common: InterfaceCommon,
    pub needs_completed_integrator_step: bool,
    pub provides_evaluate_discrete_states: bool,
}

/// `<CoSimulation>`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CoSimulation {
    pub common: InterfaceCommon,
    pub can_handle_variable_communication_step_size: bool,
    pub fixed_internal_step_size: Option<f64>,
    pub max_output_derivative_order: u32,
    pub recommended_intermediate_input_smoothness: i32,
    pub provides_intermediate_update: bool,
    pub might_return_early_from_do_step: bool,
    pub can_return_early_after_intermediate_update: bool,
    pub has_event_mode: bool,
    pub provides_evaluate_discrete_states: bool,
}

/// `<ScheduledExecution>`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ScheduledExecution {
    pub common: InterfaceCommon,
}

/// `<Unit>`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Unit {
    pub name: String,
    pub base_unit: Option<BaseUnit>,
    pub display_units: Vec<DisplayUnit>,
}

/// `<BaseUnit>`: exponents of the SI base units; `base = factor * value + offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseUnit {
    pub kg: i32,
    pub m: i32,
    pub s: i32,
    pub a: i32,
    pub k: i32,
    pub mol: i32,
    pub cd: i32,
    pub rad: i32,
    pub factor: f64,
    pub offset: f64,
}

impl Default for BaseUnit {
    fn default() -> Self {
        BaseUnit { kg: 0, m: 0, s: 0, a: 0, k: 0, mol: 0, cd: 0, rad: 0, factor: 1.0, offset: 0.0 }
    }
}

/// `<DisplayUnit>`: `display = factor * value + offset` (or its reciprocal with `inverse`).
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayUnit {
    pub name: String,
    pub factor: f64,
    pub offset: f64,
    pub inverse: bool,
}

/// The attributes of a floating-point variable or type.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Float {
    pub quantity: Option<String>,
    pub unit: Option<String>,
    pub display_unit: Option<String>,
    pub relative_quantity: bool,
    pub unbounded: bool,
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub nominal: Option<f64>,
}

/// The attributes of an integer variable or type (also Enumeration's bounds).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Int {
    pub quantity: Option<String>,
    pub min: Option<i128>,
    pub max: Option<i128>,
}

/// One `<Item>` of an EnumerationType.
#[derive(Debug, Clone, PartialEq)]
pub struct Item {
    pub name: String,
    pub value: i64,
    pub description: Option<String>,
}

/// The attributes of a Clock variable or type.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ClockAttributes {
    pub can_be_deactivated: bool,
    pub priority: Option<u32>,
    pub interval_variability: Option<IntervalVariability>,
    pub interval_decimal: Option<f64>,
    pub shift_decimal: Option<f64>,
    pub supports_fraction: bool,
    pub resolution: Option<u64>,
    pub interval_counter: Option<u64>,
    pub shift_counter: Option<u64>,
}

/// What a TypeDefinition declares.
#[derive(Debug, Clone, PartialEq)]
pub enum TypeKind {
    Float(FloatType, Float),
    Int(IntType, Int),
    Boolean,
    String,
    Binary { mime_type: Option<String>, max_size: Option<u64> },
    Enumeration { quantity: Option<String>, items: Vec<Item> },
    Clock(ClockAttributes),
}

/// A `<...Type>` of TypeDefinitions.
#[derive(Debug, Clone, PartialEq)]
pub struct TypeDefinition {
    pub name: String,
    pub description: Option<String>,
    pub kind: TypeKind,
}

/// `<Category>` of LogCategories.
#[derive(Debug, Clone, PartialEq)]
pub struct Category {
    pub name: String,
    pub description: Option<String>,
}

/// `<DefaultExperiment>`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DefaultExperiment {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub tolerance: Option<f64>,
    pub step_size: Option<f64>,
}

/// One `<Dimension>`: a fixed size, or the size a structural parameter (or constant) holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dimension {
    Fixed(u64),
    Variable(u32),
}

/// An `<Alias>` of a variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Alias {
    pub name: String,
    pub description: Option<String>,
    pub display_unit: Option<String>,
}

/// The type of a variable with its type-specific attributes and start values (one per
/// element of an array, in row-major order; a scalar has one).
#[derive(Debug, Clone, PartialEq)]
pub enum VariableKind {
    Float { precision: FloatType, attributes: Float, start: Option<Vec<f64>>, derivative: Option<u32>, reinit: bool },
    Int { ty: IntType, attributes: Int, start: Option<Vec<i128>> },
    Boolean { start: Option<Vec<bool>> },
    String { start: Option<Vec<String>> },
    Binary { mime_type: Option<String>, max_size: Option<u64>, start: Option<Vec<Vec<u8>>> },
    Enumeration { attributes: Int, start: Option<Vec<i128>> },
    Clock(ClockAttributes),
}

/// The element name of each kind of variable, as written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BaseType {
    Float(FloatType),
    Int(IntType),
    Boolean,
    String,
    Binary,
    Enumeration,
    Clock,
}

impl BaseType {
    /// The element name (`Float64`, `UInt8`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            BaseType::Float(f) => f.as_str(),
            BaseType::Int(i) => i.as_str(),
            BaseType::Boolean => "Boolean",
            BaseType::String => "String",
            BaseType::Binary => "Binary",
            BaseType::Enumeration => "Enumeration",
            BaseType::Clock => "Clock",
        }
    }
}

impl fmt::Display for BaseType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One variable of ModelVariables.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    pub name: String,
    pub value_reference: u32,
    pub description: Option<String>,
    /// As written; `None` means `local` (see [`Variable::causality`]).
    pub causality: Option<Causality>,
    /// As written; `None` means the type's default (see [`Variable::variability`]).
    pub variability: Option<Variability>,
    /// As written; `None` means the standard's default (see [`Variable::initial`]).
    pub initial: Option<Initial>,
    pub can_handle_multiple_set_per_time_instant: Option<bool>,
    pub intermediate_update: bool,
    pub previous: Option<u32>,
    pub clocks: Option<Vec<u32>>,
    pub declared_type: Option<String>,
    pub dimensions: Vec<Dimension>,
    pub aliases: Vec<Alias>,
    pub kind: VariableKind,
}

impl Variable {
    /// A scalar with `kind` and every optional attribute absent.
    pub fn new(name: impl Into<String>, value_reference: u32, kind: VariableKind) -> Variable {
        Variable {
            name: name.into(),
            value_reference,
            description: None,
            causality: None,
            variability: None,
            initial: None,
            can_handle_multiple_set_per_time_instant: None,
            intermediate_update: false,
            previous: None,
            clocks: None,
            declared_type: None,
            dimensions: Vec::new(),
            aliases: Vec::new(),
            kind,
        }
    }

    /// Effective causality.
    pub fn causality(&self) -> Causality {
        self.causality.unwrap_or_default()
    }

    /// Effective variability: Float variables default to continuous, the others to discrete.
    pub fn variability(&self) -> Variability {
        self.variability.unwrap_or(match self.kind {
            VariableKind::Float { .. } => Variability::Continuous,
            _ => Variability::Discrete,
        })
    }

    /// Effective `initial`: as written, else the standard's default for the causality and
    /// variability (FMI 3.0, table of section 2.4.7.5); `None` where none applies.
    pub fn initial(&self) -> Option<Initial> {
        self.initial.or_else(|| default_initial(self.causality(), self.variability()))
    }

    /// The type of the variable.
    pub fn base_type(&self) -> BaseType {
        match &self.kind {
            VariableKind::Float { precision, .. } => BaseType::Float(*precision),
            VariableKind::Int { ty, .. } => BaseType::Int(*ty),
            VariableKind::Boolean { .. } => BaseType::Boolean,
            VariableKind::String { .. } => BaseType::String,
            VariableKind::Binary { .. } => BaseType::Binary,
            VariableKind::Enumeration { .. } => BaseType::Enumeration,
            VariableKind::Clock(_) => BaseType::Clock,
        }
    }

    /// Number of start values given (0 when absent).
    pub fn start_len(&self) -> usize {
        match &self.kind {
            VariableKind::Float { start, .. } => start.as_ref().map_or(0, Vec::len),
            VariableKind::Int { start, .. } | VariableKind::Enumeration { start, .. } => start.as_ref().map_or(0, Vec::len),
            VariableKind::Boolean { start } => start.as_ref().map_or(0, Vec::len),
            VariableKind::String { start } => start.as_ref().map_or(0, Vec::len),
            VariableKind::Binary { start, .. } => start.as_ref().map_or(0, Vec::len),
            VariableKind::Clock(_) => 0,
        }
    }

    /// True when the variable has a start attribute.
    pub fn has_start(&self) -> bool {
        match &self.kind {
            VariableKind::Float { start, .. } => start.is_some(),
            VariableKind::Int { start, .. } | VariableKind::Enumeration { start, .. } => start.is_some(),
            VariableKind::Boolean { start } => start.is_some(),
            VariableKind::String { start } => start.is_some(),
            VariableKind::Binary { start, .. } => start.is_some(),
            VariableKind::Clock(_) => false,
        }
    }

    /// The state this variable is the derivative of (its value reference).
    pub fn derivative(&self) -> Option<u32> {
        match self.kind {
            VariableKind::Float { derivative, .. } => derivative,
            _ => None,
        }
    }
}

/// The standard's default `initial` for a causality and variability.
pub fn default_initial(causality: Causality, variability: Variability) -> Option<Initial> {
    use Causality as C;
    use Variability as V;
    match (causality, variability) {
        (C::Parameter | C::StructuralParameter, V::Fixed | V::Tunable) => Some(Initial::Exact),
        (C::CalculatedParameter, V::Fixed | V::Tunable) => Some(Initial::Calculated),
        (C::Input, V::Discrete | V::Continuous) => Some(Initial::Exact),
        (C::Output | C::Local, V::Constant) => Some(Initial::Exact),
        (C::Output | C::Local, V::Fixed | V::Tunable | V::Discrete | V::Continuous) => Some(Initial::Calculated),
        _ => None,
    }
}

/// The `initial` values the standard allows for a causality and variability.
pub fn allowed_initials(causality: Causality, variability: Variability) -> &'static [Initial] {
    use Causality as C;
    use Variability as V;
    match (causality, variability) {
        (C::Parameter | C::StructuralParameter, V::Fixed | V::Tunable) => &[Initial::Exact],
        (C::CalculatedParameter, V::Fixed | V::Tunable) => &[Initial::Approx, Initial::Calculated],
        (C::Input, V::Discrete | V::Continuous) => &[Initial::Exact],
        (C::Output | C::Local, V::Constant) => &[Initial::Exact],
        (C::Local, V::Fixed | V::Tunable) => &[Initial::Approx, Initial::Calculated],
        (C::Output | C::Local, V::Discrete | V::Continuous) => &[Initial::Exact, Initial::Approx, Initial::Calculated],
        _ => &[],
    }
}

/// One entry of ModelStructure.
#[derive(Debug, Clone, PartialEq)]
pub struct Unknown {
    pub value_reference: u32,
    /// `None`: dependent on all knowns; `Some(empty)`: on none.
    pub dependencies: Option<Vec<u32>>,
    pub dependencies_kind: Option<Vec<DependencyKind>>,
}

impl Unknown {
    /// An unknown without dependency information.
    pub fn new(value_reference: u32) -> Unknown {
        Unknown { value_reference, dependencies: None, dependencies_kind: None }
    }
}

/// `<ModelStructure>`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelStructure {
    pub outputs: Vec<Unknown>,
    pub continuous_state_derivatives: Vec<Unknown>,
    pub clocked_states: Vec<Unknown>,
    pub initial_unknowns: Vec<Unknown>,
    pub event_indicators: Vec<Unknown>,
}

/// The whole modelDescription.xml of an FMI 3.0 FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelDescription {
    pub fmi_version: String,
    pub model_name: String,
    pub instantiation_token: String,
    pub description: Option<String>,
    pub author: Option<String>,
    pub version: Option<String>,
    pub copyright: Option<String>,
    pub license: Option<String>,
    pub generation_tool: Option<String>,
    pub generation_date_and_time: Option<String>,
    pub variable_naming_convention: Option<VariableNamingConvention>,
    pub model_exchange: Option<ModelExchange>,
    pub co_simulation: Option<CoSimulation>,
    pub scheduled_execution: Option<ScheduledExecution>,
    pub unit_definitions: Vec<Unit>,
    pub type_definitions: Vec<TypeDefinition>,
    pub log_categories: Vec<Category>,
    pub default_experiment: Option<DefaultExperiment>,
    pub model_variables: Vec<Variable>,
    pub model_structure: ModelStructure,
}

impl ModelDescription {
    /// A description with the required attributes and nothing else.
    pub fn new(model_name: impl Into<String>, instantiation_token: impl Into<String>) -> ModelDescription {
        ModelDescription {
            fmi_version: "3.0".to_owned(),
            model_name: model_name.into(),
            instantiation_token: instantiation_token.into(),
            description: None,
            author: None,
            version: None,
            copyright: None,
            license: None,
            generation_tool: None,
            generation_date_and_time: None,
            variable_naming_convention: None,
            model_exchange: None,
            co_simulation: None,
            scheduled_execution: None,
            unit_definitions: Vec::new(),
            type_definitions: Vec::new(),
            log_categories: Vec::new(),
            default_experiment: None,
            model_variables: Vec::new(),
            model_structure: ModelStructure::default(),
        }
    }

    /// Reads modelDescription.xml of any FMI 3.0 FMU, ignoring vendor annotations.
    pub fn from_xml(xml: &str) -> Result<ModelDescription, DescriptionError> {
        read::read(xml)
    }

    /// Writes modelDescription.xml: UTF-8 declaration, two-space indentation.
    pub fn to_xml(&self) -> String {
        write::write(self)
    }

    /// The problems the standard's rules find; empty means clean.
    pub fn check(&self) -> Vec<String> {
        check::check(self).into_iter().map(printable).collect()
    }

    /// The variable called `name`.
    pub fn variable(&self, name: &str) -> Option<&Variable> {
        self.model_variables.iter().find(|v| v.name == name)
    }

    /// The variable with value reference `vr`.
    pub fn variable_by_reference(&self, vr: u32) -> Option<&Variable> {
        self.model_variables.iter().find(|v| v.value_reference == vr)
    }

    /// The TypeDefinition called `name`.
    pub fn type_definition(&self, name: &str) -> Option<&TypeDefinition> {
        self.type_definitions.iter().find(|t| t.name == name)
    }

    /// The Unit called `name`.
    pub fn unit(&self, name: &str) -> Option<&Unit> {
        self.unit_definitions.iter().find(|u| u.name == name)
    }

    /// The Float attributes a variable's declared type gives, if it declares a Float type.
    fn declared_float(&self, v: &Variable) -> Option<&Float> {
        match &self.type_definition(v.declared_type.as_deref()?)?.kind {
            TypeKind::Float(_, f) => Some(f),
            _ => None,
        }
    }

    /// Effective unit of a Float variable: its own, else its declared type's.
    pub fn unit_of<'a>(&'a self, v: &'a Variable) -> Option<&'a str> {
        match &v.kind {
            VariableKind::Float { attributes, .. } => {
                attributes.unit.as_deref().or_else(|| self.declared_float(v).and_then(|t| t.unit.as_deref()))
            }
            _ => None,
        }
    }

    /// Effective display unit of a Float variable: its own, else its declared type's.
    pub fn display_unit_of<'a>(&'a self, v: &'a Variable) -> Option<&'a str> {
        match &v.kind {
            VariableKind::Float { attributes, .. } => {
                attributes.display_unit.as_deref().or_else(|| self.declared_float(v).and_then(|t| t.display_unit.as_deref()))
            }
            _ => None,
        }
    }

    /// The sizes of `v`'s dimensions with the structural parameters at their start values;
    /// `None` when a dimension refers to no usable variable.
    pub fn start_shape(&self, v: &Variable) -> Option<Vec<u64>> {
        v.dimensions
            .iter()
            .map(|d| match *d {
                Dimension::Fixed(n) => Some(n),
                Dimension::Variable(vr) => match &self.variable_by_reference(vr)?.kind {
                    VariableKind::Int { start: Some(s), .. } if s.len() == 1 && s[0] >= 0 => u64::try_from(s[0]).ok(),
                    _ => None,
                },
            })
            .collect()
    }
}

/// Hex text of bytes, as FMI 3.0 writes Binary start values.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Bytes of hex text (even length, digits and a-f/A-F only).
pub fn unhex(text: &str) -> Result<Vec<u8>, String> {
    let text = text.trim();
    if !text.bytes().all(|b| b.is_ascii_hexdigit()) {
        return Err(format!("'{}' is not hexadecimal bytes", escaped_and_cut(text, 40, "...")));
    }
    if !text.len().is_multiple_of(2) {
        return Err(format!("'{}' is not hexadecimal bytes (odd number of digits)", escaped_and_cut(text, 40, "...")));
    }
    (0..text.len())
        .step_by(2)
        .map(|i| {
            u8::from_str_radix(&text[i..i + 2], 16).map_err(|_| format!("'{}' is not hexadecimal bytes", escaped_and_cut(text, 40, "...")))
        })
        .collect()
}
