//! What the importer knows of any FMU, whatever its FMI version: its variables, units,
//! default experiment and interfaces, in one shape the engine and the commands work with. Each
//! binding (`fmi2`, later `fmi3`) builds it from its own modelDescription schema.

use std::fmt;

pub use fmi_c::{FmiVersion, Interface};

/// The type of a variable's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// FMI 2.0 Real, FMI 3.0 Float64.
    Real,
    /// FMI 3.0 Float32.
    Float32,
    /// FMI 2.0 Integer, FMI 3.0 Int32.
    Integer,
    Int8,
    UInt8,
    Int16,
    UInt16,
    UInt32,
    Int64,
    UInt64,
    Boolean,
    String,
    /// FMI 3.0 Binary: bytes, written as hexadecimal text.
    Binary,
    /// An enumeration item (Int32 in FMI 2.0, Int64 in FMI 3.0).
    Enumeration,
    /// FMI 3.0 Clock (Scheduled Execution and clocked Co-Simulation; not simulated).
    Clock,
}

impl Kind {
    /// The type's name (FMI 2.0's spelling for the types it has).
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Real => "Real",
            Kind::Float32 => "Float32",
            Kind::Integer => "Integer",
            Kind::Int8 => "Int8",
            Kind::UInt8 => "UInt8",
            Kind::Int16 => "Int16",
            Kind::UInt16 => "UInt16",
            Kind::UInt32 => "UInt32",
            Kind::Int64 => "Int64",
            Kind::UInt64 => "UInt64",
            Kind::Boolean => "Boolean",
            Kind::String => "String",
            Kind::Binary => "Binary",
            Kind::Enumeration => "Enumeration",
            Kind::Clock => "Clock",
        }
    }

    /// The type's name as the FMU's FMI version spells it (`Real` or `Float64`, ...).
    pub fn name_in(self, version: FmiVersion) -> &'static str {
        match (self, version) {
            (Kind::Real, FmiVersion::Fmi3) => "Float64",
            (Kind::Integer, FmiVersion::Fmi3) => "Int32",
            _ => self.as_str(),
        }
    }

    /// True for the types whose values are numbers (Booleans as 0/1).
    pub fn is_numeric(self) -> bool {
        !matches!(self, Kind::String | Kind::Binary | Kind::Clock)
    }

    /// The smallest and largest value of an integer type (`None` for the others).
    pub fn integer_range(self) -> Option<(i128, i128)> {
        Some(match self {
            Kind::Int8 => (i8::MIN.into(), i8::MAX.into()),
            Kind::UInt8 => (0, u8::MAX.into()),
            Kind::Int16 => (i16::MIN.into(), i16::MAX.into()),
            Kind::UInt16 => (0, u16::MAX.into()),
            Kind::Integer => (i32::MIN.into(), i32::MAX.into()),
            Kind::UInt32 => (0, u32::MAX.into()),
            Kind::Int64 => (i64::MIN.into(), i64::MAX.into()),
            Kind::UInt64 => (0, u64::MAX.into()),
            _ => return None,
        })
    }
}

impl fmt::Display for Kind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A variable's causality.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    /// FMI 3.0: a parameter that fixes array sizes.
    StructuralParameter,
    Input,
    Output,
    Local,
    Independent,
}

impl Causality {
    /// The standard's spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Causality::Parameter => "parameter",
            Causality::CalculatedParameter => "calculatedParameter",
            Causality::StructuralParameter => "structuralParameter",
            Causality::Input => "input",
            Causality::Output => "output",
            Causality::Local => "local",
            Causality::Independent => "independent",
        }
    }
}

impl fmt::Display for Causality {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A variable's variability.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

impl Variability {
    /// The standard's spelling.
    pub fn as_str(self) -> &'static str {
        match self {
            Variability::Constant => "constant",
            Variability::Fixed => "fixed",
            Variability::Tunable => "tunable",
            Variability::Discrete => "discrete",
            Variability::Continuous => "continuous",
        }
    }
}

impl fmt::Display for Variability {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A start value as the description gives it.
#[derive(Debug, Clone, PartialEq)]
pub enum Start {
    Real(f64),
    Integer(i128),
    Boolean(bool),
    String(String),
    Binary(Vec<u8>),
    /// The element values of an array variable, row-major (one value: all elements equal).
    List(Vec<Start>),
}

impl Start {
    /// The start value as a number, where it is one (Booleans as 0/1).
    pub fn as_number(&self) -> Option<f64> {
        match self {
            Start::Real(x) => Some(*x),
            Start::Integer(i) => Some(*i as f64),
            Start::Boolean(b) => Some(*b as i32 as f64),
            Start::String(_) | Start::Binary(_) | Start::List(_) => None,
        }
    }
}

impl fmt::Display for Start {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Start::Real(x) => write!(f, "{x}"),
            Start::Integer(x) => write!(f, "{x}"),
            Start::Boolean(x) => write!(f, "{x}"),
            Start::String(x) => write!(f, "{x:?}"),
            Start::Binary(x) => f.write_str(&x.iter().map(|b| format!("{b:02x}")).collect::<String>()),
            Start::List(items) => f.write_str(&items.iter().map(Start::to_string).collect::<Vec<_>>().join(" ")),
        }
    }
}

/// Bytes of hexadecimal text, as FMI 3.0 and result files write Binary values.
pub fn parse_hex(text: &str) -> Result<Vec<u8>, String> {
    fmi_schema::fmi3::unhex(text)
}

/// One dimension of an array variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dimension {
    /// A fixed size.
    Fixed(u64),
    /// The size is the value of this (structural parameter's) value reference.
    Variable(u32),
}

/// One variable of an FMU.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    pub name: String,
    pub value_reference: u32,
    pub description: Option<String>,
    pub kind: Kind,
    pub causality: Causality,
    pub variability: Variability,
    /// The effective unit (its own, else its declared type's).
    pub unit: Option<String>,
    /// The effective display unit.
    pub display_unit: Option<String>,
    pub start: Option<Start>,
    /// FMI 3.0 arrays: the dimensions (empty for a scalar).
    pub dimensions: Vec<Dimension>,
}

impl Variable {
    /// True for an array variable.
    pub fn is_array(&self) -> bool {
        !self.dimensions.is_empty()
    }
}

/// A display unit of a unit: `display = factor * value + offset`.
#[derive(Debug, Clone, PartialEq)]
pub struct DisplayUnit {
    pub name: String,
    pub factor: f64,
    pub offset: f64,
}

/// A unit with its display units.
#[derive(Debug, Clone, PartialEq)]
pub struct Unit {
    pub name: String,
    pub display_units: Vec<DisplayUnit>,
}

/// `DefaultExperiment`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DefaultExperiment {
    pub start_time: Option<f64>,
    pub stop_time: Option<f64>,
    pub tolerance: Option<f64>,
    pub step_size: Option<f64>,
}

/// The capability flags of one interface that the importer acts on or reports.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Capabilities {
    /// Prefix of the C functions and name of the shared library.
    pub model_identifier: String,
    pub needs_execution_tool: bool,
    pub can_be_instantiated_only_once_per_process: bool,
    pub can_get_and_set_fmu_state: bool,
    pub can_serialize_fmu_state: bool,
    pub provides_directional_derivative: bool,
    /// Co-Simulation: `fmi2DoStep` takes any step size.
    pub can_handle_variable_communication_step_size: bool,
    /// Co-Simulation: uses input derivatives.
    pub can_interpolate_inputs: bool,
    /// Co-Simulation: highest output derivative order provided.
    pub max_output_derivative_order: u32,
    /// FMI 3.0 Co-Simulation: events can be handled in Event Mode (`hasEventMode`).
    pub has_event_mode: bool,
    /// FMI 3.0 Co-Simulation: `fmi3DoStep` may return early at an event.
    pub might_return_early_from_do_step: bool,
    /// Model Exchange: the FMU needs `CompletedIntegratorStep` after every integrator step
    /// (FMI 3.0's `needsCompletedIntegratorStep`; FMI 2.0 FMUs get the call anyway).
    pub needs_completed_integrator_step: bool,
}

/// An FMU's description, whatever its version.
#[derive(Debug, Clone, PartialEq)]
pub struct Description {
    pub fmi_version: FmiVersion,
    /// `fmiVersion` as written.
    pub fmi_version_text: String,
    pub model_name: String,
    pub description: Option<String>,
    /// FMI 2.0 GUID or FMI 3.0 instantiation token.
    pub instantiation_token: String,
    pub generation_tool: Option<String>,
    pub co_simulation: Option<Capabilities>,
    pub model_exchange: Option<Capabilities>,
    pub default_experiment: Option<DefaultExperiment>,
    pub units: Vec<Unit>,
    pub variables: Vec<Variable>,
    /// Number of continuous states (Model Exchange).
    pub number_of_continuous_states: usize,
    pub number_of_event_indicators: usize,
}

impl Description {
    /// The variable called `name`.
    pub fn variable(&self, name: &str) -> Option<&Variable> {
        self.variables.iter().find(|v| v.name == name)
    }

    /// Variables with causality output, in description order.
    pub fn outputs(&self) -> impl Iterator<Item = &Variable> + '_ {
        self.variables.iter().filter(|v| v.causality == Causality::Output)
    }

    /// Variables with causality input, in description order.
    pub fn inputs(&self) -> impl Iterator<Item = &Variable> + '_ {
        self.variables.iter().filter(|v| v.causality == Causality::Input)
    }

    /// The variable with value reference `vr`: in FMI 3.0 value references are unique; in
    /// FMI 2.0 aliases share one, and the first is returned.
    pub fn variable_by_reference(&self, vr: u32) -> Option<&Variable> {
        self.variables.iter().find(|v| v.value_reference == vr)
    }

    /// The sizes of an array variable's dimensions, with structural parameters at `size_of`
    /// (a value set for them) or else at their start values; an error names what is missing.
    pub fn shape(&self, v: &Variable, size_of: &dyn Fn(u32) -> Option<u64>) -> Result<Vec<u64>, String> {
        v.dimensions
            .iter()
            .map(|d| match *d {
                Dimension::Fixed(n) => Ok(n),
                Dimension::Variable(vr) => size_of(vr)
                    .or_else(|| match self.variable_by_reference(vr).and_then(|p| p.start.as_ref()) {
                        Some(Start::Integer(n)) => u64::try_from(*n).ok(),
                        _ => None,
                    })
                    .ok_or_else(|| format!("the size of {} is given by value reference {vr}, which has no usable value", v.name)),
            })
            .collect()
    }

    /// The Unit called `name`.
    pub fn unit(&self, name: &str) -> Option<&Unit> {
        self.units.iter().find(|u| u.name == name)
    }

    /// The capabilities of `interface`, if the FMU offers it.
    pub fn interface(&self, interface: Interface) -> Option<&Capabilities> {
        match interface {
            Interface::CoSimulation => self.co_simulation.as_ref(),
            Interface::ModelExchange => self.model_exchange.as_ref(),
        }
    }
}
