//! FMI 2.0 `modelDescription.xml`: typed model, XML reading and writing, and a self-check.
//!
//! The exporter builds a [`ModelDescription`] and calls [`ModelDescription::to_xml`]; the
//! importer calls [`ModelDescription::from_xml`] on whatever FMU it was given (ours, the
//! Reference FMUs, Dymola, OpenModelica, ...). The public types are plain Rust data; the XML
//! shape lives in private serde mirror types (`xml.rs`) so that reading can report *which*
//! variable is broken instead of serde's context-free "missing field".
//!
//! Optional attributes whose schema has no default are `Option`s (absent stays absent on a
//! round trip); attributes with a schema default (`false`, `0`, `1`) are plain values and are
//! omitted on write when they equal that default.
//!
//! [`ModelDescription`] also implements serde's `Serialize`/`Deserialize` in this XML shape
//! (same conversions, same errors), for use with quick-xml's serde API directly.

mod check;
mod xml;

#[cfg(test)]
mod tests;

use std::fmt;
use std::str::FromStr;

pub use crate::{escaped_and_cut, printable, DescriptionError};
pub use check::{Problem, Rule};

fmi_enum! {
    /// `causality` of a ScalarVariable; absent means `local`.
    #[derive(Default)]
    Causality, "causality" {
        /// Independent parameter, set by the environment.
        Parameter = "parameter",
        /// Parameter computed from other parameters during initialization.
        CalculatedParameter = "calculatedParameter",
        /// Value provided from outside.
        Input = "input",
        /// Value offered to the outside.
        Output = "output",
        /// Internal variable (the default).
        #[default]
        Local = "local",
        /// The independent variable, usually time.
        Independent = "independent",
    }
}

fmi_enum! {
    /// `variability` of a ScalarVariable; absent means `continuous`.
    #[derive(Default)]
    Variability, "variability" {
        /// Never changes.
        Constant = "constant",
        /// Fixed after initialization.
        Fixed = "fixed",
        /// Changes only at external events (parameter changes).
        Tunable = "tunable",
        /// Changes only at events.
        Discrete = "discrete",
        /// No restriction (the default; Real only).
        #[default]
        Continuous = "continuous",
    }
}

fmi_enum! {
    /// `initial` of a ScalarVariable; absent means a default derived from causality and variability.
    Initial, "initial" {
        /// Initialized with the start value.
        Exact = "exact",
        /// Start value is an iteration guess.
        Approx = "approx",
        /// Computed during initialization; no start value allowed.
        Calculated = "calculated",
    }
}

fmi_enum! {
    /// `variableNamingConvention` of the model; absent means `flat`.
    #[derive(Default)]
    VariableNamingConvention, "variableNamingConvention" {
        /// Names are arbitrary strings.
        #[default]
        Flat = "flat",
        /// Names follow the structured grammar (`a.b[1]`, `der(x)`).
        Structured = "structured",
    }
}

fmi_enum! {
    /// One entry of an Unknown's `dependenciesKind` list.
    DependencyKind, "dependenciesKind entry" {
        /// No particular structure.
        Dependent = "dependent",
        /// Constant factor (Real only).
        Constant = "constant",
        /// Fixed factor (Real only).
        Fixed = "fixed",
        /// Tunable factor (Real only).
        Tunable = "tunable",
        /// Discrete factor (Real only).
        Discrete = "discrete",
    }
}

fmi_enum! {
    /// Which of the five FMI 2.0 base types a variable or simple type has.
    TypeKind, "type" {
        /// fmi2Real (f64).
        Real = "Real",
        /// fmi2Integer (i32).
        Integer = "Integer",
        /// fmi2Boolean.
        Boolean = "Boolean",
        /// fmi2String.
        String = "String",
        /// Enumeration (exchanged as fmi2Integer).
        Enumeration = "Enumeration",
    }
}

impl TypeKind {
    /// The value-reference space the kind lives in: Enumeration shares Integer's (fmi2GetInteger).
    pub fn base_type(self) -> TypeKind {
        match self {
            TypeKind::Enumeration => TypeKind::Integer,
            other => other,
        }
    }
}

/// Which FMI 2.0 initialization case (the standard's table, cases A to E) a combination falls in.
fn initial_case(causality: Causality, variability: Variability) -> Option<char> {
    use Causality as C;
    use Variability as V;
    match (causality, variability) {
        (C::Output | C::Local, V::Constant) => Some('A'),
        (C::Parameter, V::Fixed | V::Tunable) => Some('A'),
        (C::CalculatedParameter | C::Local, V::Fixed | V::Tunable) => Some('B'),
        (C::Output | C::Local, V::Discrete | V::Continuous) => Some('C'),
        (C::Input, V::Discrete | V::Continuous) => Some('D'),
        (C::Independent, V::Continuous) => Some('E'),
        _ => None,
    }
}

impl Causality {
    /// Whether the standard allows this causality with `variability` (FMI 2.0 section 2.2.7 table).
    pub fn allows(self, variability: Variability) -> bool {
        initial_case(self, variability).is_some()
    }
}

impl Initial {
    /// Default `initial` for a legal combination; `None` where `initial` must not be given
    /// (inputs, the independent variable) or the combination itself is illegal.
    pub fn default_for(causality: Causality, variability: Variability) -> Option<Initial> {
        match initial_case(causality, variability)? {
            'A' => Some(Initial::Exact),
            'B' | 'C' => Some(Initial::Calculated),
            _ => None,
        }
    }

    /// Values of `initial` the standard allows for a combination (empty: must be absent).
    pub fn allowed_for(causality: Causality, variability: Variability) -> &'static [Initial] {
        match initial_case(causality, variability) {
            Some('A') => &[Initial::Exact],
            Some('B') => &[Initial::Approx, Initial::Calculated],
            Some('C') => &[Initial::Exact, Initial::Approx, Initial::Calculated],
            _ => &[],
        }
    }
}

/// The attributes `<ModelExchange>` and `<CoSimulation>` share (written once, as in the
/// standard's schema, where both types list them alike).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct InterfaceCommon {
    /// Prefix of the C functions and name of the shared library.
    pub model_identifier: String,
    /// The FMU only talks to an external tool.
    pub needs_execution_tool: bool,
    /// Only one instance per process.
    pub can_be_instantiated_only_once_per_process: bool,
    /// Ignores the memory callbacks.
    pub can_not_use_memory_management_functions: bool,
    /// Supports fmi2Get/SetFMUstate.
    pub can_get_and_set_fmu_state: bool,
    /// Supports fmi2SerializeFMUstate.
    pub can_serialize_fmu_state: bool,
    /// Supports fmi2GetDirectionalDerivative.
    pub provides_directional_derivative: bool,
    /// `SourceFiles/File@name` entries (source FMUs only).
    pub source_files: Vec<String>,
}

/// `<ModelExchange>`: capability flags of the Model Exchange interface.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelExchange {
    /// The attributes every interface has.
    pub common: InterfaceCommon,
    /// fmi2CompletedIntegratorStep need not be called.
    pub completed_integrator_step_not_needed: bool,
}

/// `<CoSimulation>`: capability flags of the Co-Simulation interface.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct CoSimulation {
    /// The attributes every interface has.
    pub common: InterfaceCommon,
    /// fmi2DoStep accepts a varying communication step size.
    pub can_handle_variable_communication_step_size: bool,
    /// Uses input derivatives set with fmi2SetRealInputDerivatives.
    pub can_interpolate_inputs: bool,
    /// Highest output derivative order fmi2GetRealOutputDerivatives provides.
    pub max_output_derivative_order: u32,
    /// fmi2DoStep can run asynchronously (spelled as in the standard).
    pub can_run_asynchronuously: bool,
}

/// `<Unit>`: a unit, its SI decomposition and its display units.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Unit {
    /// Unit name as used by `unit` attributes, e.g. `"m/s"`.
    pub name: String,
    /// SI decomposition, if given.
    pub base_unit: Option<BaseUnit>,
    /// Alternative units for display.
    pub display_units: Vec<DisplayUnit>,
}

/// `<BaseUnit>`: exponents of the SI base units; `base = factor * value + offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct BaseUnit {
    /// Exponent of kilogram.
    pub kg: i32,
    /// Exponent of metre.
    pub m: i32,
    /// Exponent of second.
    pub s: i32,
    /// Exponent of ampere (attribute `A`).
    pub a: i32,
    /// Exponent of kelvin (attribute `K`).
    pub k: i32,
    /// Exponent of mole.
    pub mol: i32,
    /// Exponent of candela.
    pub cd: i32,
    /// Exponent of radian.
    pub rad: i32,
    /// Scale to the base unit (default 1).
    pub factor: f64,
    /// Offset to the base unit (default 0).
    pub offset: f64,
}

impl Default for BaseUnit {
    fn default() -> Self {
        BaseUnit { kg: 0, m: 0, s: 0, a: 0, k: 0, mol: 0, cd: 0, rad: 0, factor: 1.0, offset: 0.0 }
    }
}

/// `<DisplayUnit>`: `display = factor * value + offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayUnit {
    /// Display unit name, unique within its Unit.
    pub name: String,
    /// Scale from the unit (default 1).
    pub factor: f64,
    /// Offset from the unit (default 0).
    pub offset: f64,
}

impl DisplayUnit {
    /// A display unit `name` with the given conversion.
    pub fn new(name: impl Into<String>, factor: f64, offset: f64) -> Self {
        DisplayUnit { name: name.into(), factor, offset }
    }
}

/// `<SimpleType>` under TypeDefinitions: defaults that variables refer to via `declaredType`.
#[derive(Debug, Clone, PartialEq)]
pub struct SimpleType {
    /// Type name referenced by `declaredType`.
    pub name: String,
    /// Free text.
    pub description: Option<String>,
    /// The type element and its attributes.
    pub kind: SimpleTypeKind,
}

impl SimpleType {
    /// Which base type this simple type defines.
    pub fn type_kind(&self) -> TypeKind {
        match self.kind {
            SimpleTypeKind::Real(_) => TypeKind::Real,
            SimpleTypeKind::Integer(_) => TypeKind::Integer,
            SimpleTypeKind::Boolean => TypeKind::Boolean,
            SimpleTypeKind::String => TypeKind::String,
            SimpleTypeKind::Enumeration(_) => TypeKind::Enumeration,
        }
    }
}

/// The type element of a SimpleType.
#[derive(Debug, Clone, PartialEq)]
pub enum SimpleTypeKind {
    /// `<Real>` with unit and range defaults.
    Real(RealAttributes),
    /// `<Integer>` with range defaults.
    Integer(IntegerAttributes),
    /// `<Boolean/>`.
    Boolean,
    /// `<String/>`.
    String,
    /// `<Enumeration>` with its items.
    Enumeration(EnumerationType),
}

/// The schema's attribute group `fmi2RealAttributes`: what a `<Real>` SimpleType defines and
/// a `<Real>` variable may override (written once for both).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RealAttributes {
    /// Physical quantity, e.g. `"Velocity"`.
    pub quantity: Option<String>,
    /// Unit name (must be in UnitDefinitions).
    pub unit: Option<String>,
    /// Default display unit (must belong to `unit`).
    pub display_unit: Option<String>,
    /// Offsets must be ignored for display (a difference quantity).
    pub relative_quantity: bool,
    /// Lower bound.
    pub min: Option<f64>,
    /// Upper bound.
    pub max: Option<f64>,
    /// Typical magnitude (> 0).
    pub nominal: Option<f64>,
    /// Value may grow without bound (e.g. a crank angle).
    pub unbounded: bool,
}

/// The schema's attribute group `fmi2IntegerAttributes`: what an `<Integer>` SimpleType defines
/// and an `<Integer>` or `<Enumeration>` variable may override (written once for all three).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IntegerAttributes {
    /// Physical quantity.
    pub quantity: Option<String>,
    /// Lower bound.
    pub min: Option<i32>,
    /// Upper bound.
    pub max: Option<i32>,
}

/// `<Enumeration>` of a SimpleType.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EnumerationType {
    /// Physical quantity.
    pub quantity: Option<String>,
    /// The named values.
    pub items: Vec<EnumerationItem>,
}

/// `<Item>` of an Enumeration type.
#[derive(Debug, Clone, PartialEq)]
pub struct EnumerationItem {
    /// Item name.
    pub name: String,
    /// Integer value, unique within the enumeration.
    pub value: i32,
    /// Free text.
    pub description: Option<String>,
}

/// `<Category>` under LogCategories.
#[derive(Debug, Clone, PartialEq)]
pub struct Category {
    /// Name passed to fmi2SetDebugLogging.
    pub name: String,
    /// Free text.
    pub description: Option<String>,
}

impl Category {
    /// A category with an optional description.
    pub fn new(name: impl Into<String>, description: Option<&str>) -> Self {
        Category { name: name.into(), description: description.map(str::to_string) }
    }
}

/// `<DefaultExperiment>`: suggested simulation settings.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct DefaultExperiment {
    /// Start time.
    pub start_time: Option<f64>,
    /// Stop time.
    pub stop_time: Option<f64>,
    /// Relative tolerance.
    pub tolerance: Option<f64>,
    /// Preferred communication step size (Co-Simulation).
    pub step_size: Option<f64>,
}

/// `<ScalarVariable>`: one model variable with exactly one type element.
#[derive(Debug, Clone, PartialEq)]
pub struct ScalarVariable {
    /// Unique name.
    pub name: String,
    /// Handle used in fmi2Get/Set calls.
    pub value_reference: u32,
    /// Free text.
    pub description: Option<String>,
    /// As written; `None` means `local` (see [`ScalarVariable::causality`]).
    pub causality: Option<Causality>,
    /// As written; `None` means `continuous` (see [`ScalarVariable::variability`]).
    pub variability: Option<Variability>,
    /// As written; `None` means the table default (see [`ScalarVariable::initial`]).
    pub initial: Option<Initial>,
    /// Model Exchange inputs only: whether several sets per instant are allowed.
    pub can_handle_multiple_set_per_time_instant: Option<bool>,
    /// The type element (Real, Integer, Boolean, String or Enumeration).
    pub var_type: VariableType,
}

/// The type element of a ScalarVariable.
#[derive(Debug, Clone, PartialEq)]
pub enum VariableType {
    /// `<Real>`.
    Real(RealVariable),
    /// `<Integer>`.
    Integer(IntegerVariable),
    /// `<Boolean>`.
    Boolean(BooleanVariable),
    /// `<String>`.
    String(StringVariable),
    /// `<Enumeration>`.
    Enumeration(EnumerationVariable),
}

/// `<Real>` of a ScalarVariable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RealVariable {
    /// SimpleType providing defaults.
    pub declared_type: Option<String>,
    /// Quantity, unit, display unit, range and nominal (each overrides the declared type's).
    pub attributes: RealAttributes,
    /// Start value.
    pub start: Option<f64>,
    /// 1-based index of the state this variable is the derivative of.
    pub derivative: Option<u32>,
    /// Model Exchange: the state can be reinitialized at events.
    pub reinit: bool,
}

/// `<Integer>` of a ScalarVariable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct IntegerVariable {
    /// SimpleType providing defaults.
    pub declared_type: Option<String>,
    /// Quantity and range.
    pub attributes: IntegerAttributes,
    /// Start value.
    pub start: Option<i32>,
}

/// `<Boolean>` of a ScalarVariable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct BooleanVariable {
    /// SimpleType providing defaults.
    pub declared_type: Option<String>,
    /// Start value.
    pub start: Option<bool>,
}

/// `<String>` of a ScalarVariable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StringVariable {
    /// SimpleType providing defaults.
    pub declared_type: Option<String>,
    /// Start value (`Some("")` is an empty start string, not an absent one).
    pub start: Option<String>,
}

/// `<Enumeration>` of a ScalarVariable.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EnumerationVariable {
    /// The Enumeration SimpleType (required by the standard; `check` reports a missing one).
    pub declared_type: Option<String>,
    /// Quantity and range, as for Integer.
    pub attributes: IntegerAttributes,
    /// Start value (an item value).
    pub start: Option<i32>,
}

/// A start value of any type, as returned by [`ScalarVariable::start`].
#[derive(Debug, Clone, PartialEq)]
pub enum StartValue {
    /// Real start.
    Real(f64),
    /// Integer start.
    Integer(i32),
    /// Boolean start.
    Boolean(bool),
    /// String start.
    String(String),
    /// Enumeration start (item value).
    Enumeration(i32),
}

impl ScalarVariable {
    /// A variable with the given type element and every optional attribute absent.
    pub fn new(name: impl Into<String>, value_reference: u32, var_type: VariableType) -> Self {
        ScalarVariable {
            name: name.into(),
            value_reference,
            description: None,
            causality: None,
            variability: None,
            initial: None,
            can_handle_multiple_set_per_time_instant: None,
            var_type,
        }
    }

    /// Effective causality (`local` when absent).
    pub fn causality(&self) -> Causality {
        self.causality.unwrap_or_default()
    }

    /// Effective variability (`continuous` when absent).
    pub fn variability(&self) -> Variability {
        self.variability.unwrap_or_default()
    }

    /// Effective initial: as written, else the standard's default for causality and variability;
    /// `None` for inputs and the independent variable, which have no `initial`.
    pub fn initial(&self) -> Option<Initial> {
        self.initial.or_else(|| Initial::default_for(self.causality(), self.variability()))
    }

    /// Which base type the variable has.
    pub fn type_kind(&self) -> TypeKind {
        match self.var_type {
            VariableType::Real(_) => TypeKind::Real,
            VariableType::Integer(_) => TypeKind::Integer,
            VariableType::Boolean(_) => TypeKind::Boolean,
            VariableType::String(_) => TypeKind::String,
            VariableType::Enumeration(_) => TypeKind::Enumeration,
        }
    }

    /// `declaredType` of the type element, if any.
    pub fn declared_type(&self) -> Option<&str> {
        match &self.var_type {
            VariableType::Real(r) => r.declared_type.as_deref(),
            VariableType::Integer(i) => i.declared_type.as_deref(),
            VariableType::Boolean(b) => b.declared_type.as_deref(),
            VariableType::String(s) => s.declared_type.as_deref(),
            VariableType::Enumeration(e) => e.declared_type.as_deref(),
        }
    }

    /// The start value, whatever its type.
    pub fn start(&self) -> Option<StartValue> {
        match &self.var_type {
            VariableType::Real(r) => r.start.map(StartValue::Real),
            VariableType::Integer(i) => i.start.map(StartValue::Integer),
            VariableType::Boolean(b) => b.start.map(StartValue::Boolean),
            VariableType::String(s) => s.start.clone().map(StartValue::String),
            VariableType::Enumeration(e) => e.start.map(StartValue::Enumeration),
        }
    }

    /// Whether a start value is given.
    pub fn has_start(&self) -> bool {
        match &self.var_type {
            VariableType::Real(r) => r.start.is_some(),
            VariableType::Integer(i) => i.start.is_some(),
            VariableType::Boolean(b) => b.start.is_some(),
            VariableType::String(s) => s.start.is_some(),
            VariableType::Enumeration(e) => e.start.is_some(),
        }
    }

    /// Start of a Real variable (`None` for other types or when absent).
    pub fn real_start(&self) -> Option<f64> {
        match &self.var_type {
            VariableType::Real(r) => r.start,
            _ => None,
        }
    }

    /// Start of an Integer or Enumeration variable (both are exchanged as fmi2Integer).
    pub fn integer_start(&self) -> Option<i32> {
        match &self.var_type {
            VariableType::Integer(i) => i.start,
            VariableType::Enumeration(e) => e.start,
            _ => None,
        }
    }

    /// Start of a Boolean variable.
    pub fn boolean_start(&self) -> Option<bool> {
        match &self.var_type {
            VariableType::Boolean(b) => b.start,
            _ => None,
        }
    }

    /// Start of a String variable.
    pub fn string_start(&self) -> Option<&str> {
        match &self.var_type {
            VariableType::String(s) => s.start.as_deref(),
            _ => None,
        }
    }

    /// The Real type element, if the variable is Real.
    pub fn as_real(&self) -> Option<&RealVariable> {
        match &self.var_type {
            VariableType::Real(r) => Some(r),
            _ => None,
        }
    }

    /// `unit` written on the variable itself (see [`ModelDescription::unit_of`] for declared types).
    pub fn unit(&self) -> Option<&str> {
        self.as_real().and_then(|r| r.attributes.unit.as_deref())
    }

    /// 1-based index of the state this Real variable is the derivative of.
    pub fn derivative(&self) -> Option<u32> {
        self.as_real().and_then(|r| r.derivative)
    }
}

/// `<Unknown>` of Outputs, Derivatives or InitialUnknowns.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Unknown {
    /// 1-based ScalarVariable index.
    pub index: u32,
    /// 1-based indices of the knowns it depends on; `None` means "depends on all knowns",
    /// `Some(vec![])` means "depends on none" (the standard distinguishes the two).
    pub dependencies: Option<Vec<u32>>,
    /// Kind of each dependency (same length as `dependencies` when present).
    pub dependencies_kind: Option<Vec<DependencyKind>>,
}

impl Unknown {
    /// An unknown with no dependency information (depends on all knowns).
    pub fn new(index: u32) -> Self {
        Unknown { index, dependencies: None, dependencies_kind: None }
    }

    /// An unknown that depends on exactly `dependencies` (1-based indices).
    pub fn with_dependencies(index: u32, dependencies: Vec<u32>) -> Self {
        Unknown { index, dependencies: Some(dependencies), dependencies_kind: None }
    }
}

/// `<ModelStructure>`: outputs, exposed derivatives and initial unknowns.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ModelStructure {
    /// One entry per variable with causality output.
    pub outputs: Vec<Unknown>,
    /// State derivatives (optional for Co-Simulation).
    pub derivatives: Vec<Unknown>,
    /// Unknowns of Initialization Mode, sorted by index.
    pub initial_unknowns: Vec<Unknown>,
}

/// `<fmiModelDescription>`: the whole model description.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelDescription {
    /// `"2.0"` (reading rejects anything that is not FMI 2.0).
    pub fmi_version: String,
    /// Model class name.
    pub model_name: String,
    /// Fingerprint that the binary checks in fmi2Instantiate.
    pub guid: String,
    /// Free text.
    pub description: Option<String>,
    /// Author.
    pub author: Option<String>,
    /// Model version.
    pub version: Option<String>,
    /// Copyright notice.
    pub copyright: Option<String>,
    /// License text.
    pub license: Option<String>,
    /// Exporting tool.
    pub generation_tool: Option<String>,
    /// xs:dateTime of generation, kept as text.
    pub generation_date_and_time: Option<String>,
    /// As written; `None` means flat.
    pub variable_naming_convention: Option<VariableNamingConvention>,
    /// Number of event indicators (Model Exchange).
    pub number_of_event_indicators: Option<u32>,
    /// Model Exchange interface, if offered.
    pub model_exchange: Option<ModelExchange>,
    /// Co-Simulation interface, if offered (see [`ModelDescription::co_simulation`]).
    pub co_simulation: Option<CoSimulation>,
    /// UnitDefinitions.
    pub unit_definitions: Vec<Unit>,
    /// TypeDefinitions.
    pub type_definitions: Vec<SimpleType>,
    /// LogCategories.
    pub log_categories: Vec<Category>,
    /// DefaultExperiment.
    pub default_experiment: Option<DefaultExperiment>,
    /// ModelVariables in index order (index = position + 1).
    pub model_variables: Vec<ScalarVariable>,
    /// ModelStructure.
    pub model_structure: ModelStructure,
}

impl ModelDescription {
    /// An FMI 2.0 description with only the required attributes set and everything else empty.
    pub fn new(model_name: impl Into<String>, guid: impl Into<String>) -> Self {
        ModelDescription {
            fmi_version: "2.0".to_string(),
            model_name: model_name.into(),
            guid: guid.into(),
            description: None,
            author: None,
            version: None,
            copyright: None,
            license: None,
            generation_tool: None,
            generation_date_and_time: None,
            variable_naming_convention: None,
            number_of_event_indicators: None,
            model_exchange: None,
            co_simulation: None,
            unit_definitions: Vec::new(),
            type_definitions: Vec::new(),
            log_categories: Vec::new(),
            default_experiment: None,
            model_variables: Vec::new(),
            model_structure: ModelStructure::default(),
        }
    }

    /// Writes modelDescription.xml: UTF-8 declaration, 2-space indent, FMI attribute names.
    pub fn to_xml(&self) -> Result<String, DescriptionError> {
        xml::write(self)
    }

    /// Reads modelDescription.xml of any FMI 2.0 FMU, ignoring vendor extras.
    pub fn from_xml(xml: &str) -> Result<Self, DescriptionError> {
        xml::read(xml)
    }

    /// Checks the rules of the standard that fmpy's validation applies; empty means clean.
    pub fn check(&self) -> Vec<String> {
        self.check_by_rule().into_iter().map(|p| p.message).collect()
    }

    /// [`ModelDescription::check`] with each problem tagged by the rule it breaks and the
    /// variable it concerns (`runner validate` groups its findings by them).
    pub fn check_by_rule(&self) -> Vec<Problem> {
        check::check(self).into_iter().map(|p| Problem { message: printable(p.message), ..p }).collect()
    }

    /// The variable called `name`.
    pub fn variable(&self, name: &str) -> Option<&ScalarVariable> {
        self.model_variables.iter().find(|v| v.name == name)
    }

    /// The variable at 1-based `index`, as used by ModelStructure and `derivative`.
    pub fn variable_by_index(&self, index: u32) -> Option<&ScalarVariable> {
        let position = (index as usize).checked_sub(1)?;
        self.model_variables.get(position)
    }

    /// 1-based index of the variable called `name`.
    pub fn index_of(&self, name: &str) -> Option<u32> {
        self.model_variables.iter().position(|v| v.name == name).map(|p| p as u32 + 1)
    }

    /// The Co-Simulation interface, or an error if the FMU does not offer one.
    pub fn co_simulation(&self) -> Result<&CoSimulation, DescriptionError> {
        self.co_simulation.as_ref().ok_or_else(|| DescriptionError::new("this FMU does not support Co-Simulation"))
    }

    /// Variables with causality output, in ModelVariables order.
    pub fn outputs(&self) -> impl Iterator<Item = &ScalarVariable> + '_ {
        self.model_variables.iter().filter(|v| v.causality() == Causality::Output)
    }

    /// Variables with causality input, in ModelVariables order.
    pub fn inputs(&self) -> impl Iterator<Item = &ScalarVariable> + '_ {
        self.model_variables.iter().filter(|v| v.causality() == Causality::Input)
    }

    /// Variables with causality parameter, in ModelVariables order.
    pub fn parameters(&self) -> impl Iterator<Item = &ScalarVariable> + '_ {
        self.model_variables.iter().filter(|v| v.causality() == Causality::Parameter)
    }

    /// The SimpleType called `name`.
    pub fn simple_type(&self, name: &str) -> Option<&SimpleType> {
        self.type_definitions.iter().find(|t| t.name == name)
    }

    /// The Unit called `name`.
    pub fn unit(&self, name: &str) -> Option<&Unit> {
        self.unit_definitions.iter().find(|u| u.name == name)
    }

    /// Effective unit of a Real variable: its own `unit`, else its declared type's.
    pub fn unit_of<'a>(&'a self, variable: &'a ScalarVariable) -> Option<&'a str> {
        let real = variable.as_real()?;
        real.attributes.unit.as_deref().or_else(|| self.declared_real(real).and_then(|t| t.unit.as_deref()))
    }

    /// Effective display unit of a Real variable: its own `displayUnit`, else its declared type's.
    pub fn display_unit_of<'a>(&'a self, variable: &'a ScalarVariable) -> Option<&'a str> {
        let real = variable.as_real()?;
        real.attributes.display_unit.as_deref().or_else(|| self.declared_real(real).and_then(|t| t.display_unit.as_deref()))
    }

    /// The Real SimpleType a Real variable declares, if it exists and is Real.
    fn declared_real(&self, real: &RealVariable) -> Option<&RealAttributes> {
        match &self.simple_type(real.declared_type.as_deref()?)?.kind {
            SimpleTypeKind::Real(t) => Some(t),
            _ => None,
        }
    }
}
