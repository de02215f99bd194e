//! What the importer knows of any FMU, whatever its FMI version: its variables, units,
//! default experiment and interfaces, in one shape the engine and the commands work with. Each
//! binding (`fmi2`, later `fmi3`) builds it from its own modelDescription schema.

use std::fmt;

/// The FMI version of an FMU.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    Fmi2,
    Fmi3,
}

/// An FMI interface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Interface {
    CoSimulation,
    ModelExchange,
}

impl Interface {
    /// The command-line spelling: `co-simulation`, `model-exchange`.
    pub fn name(self) -> &'static str {
        match self {
            Interface::CoSimulation => "co-simulation",
            Interface::ModelExchange => "model-exchange",
        }
    }

    /// The interface for its command-line spelling.
    pub fn from_name(name: &str) -> Option<Interface> {
        [Interface::CoSimulation, Interface::ModelExchange].into_iter().find(|i| i.name() == name.trim())
    }
}

impl fmt::Display for Interface {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Interface::CoSimulation => "Co-Simulation",
            Interface::ModelExchange => "Model Exchange",
        })
    }
}

/// The type of a variable's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Kind {
    /// FMI 2.0 Real, FMI 3.0 Float64.
    Real,
    /// FMI 2.0 Integer, FMI 3.0 Int32.
    Integer,
    Boolean,
    String,
    /// An Integer-valued enumeration item.
    Enumeration,
}

impl Kind {
    /// The type's name as FMI 2.0 spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Kind::Real => "Real",
            Kind::Integer => "Integer",
            Kind::Boolean => "Boolean",
            Kind::String => "String",
            Kind::Enumeration => "Enumeration",
        }
    }

    /// True for the types whose values are numbers (Booleans as 0/1).
    pub fn is_numeric(self) -> bool {
        !matches!(self, Kind::String)
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
    Integer(i64),
    Boolean(bool),
    String(String),
}

impl Start {
    /// The start value as a number, where it is one (Booleans as 0/1).
    pub fn as_number(&self) -> Option<f64> {
        match self {
            Start::Real(x) => Some(*x),
            Start::Integer(i) => Some(*i as f64),
            Start::Boolean(b) => Some(*b as i32 as f64),
            Start::String(_) => None,
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
        }
    }
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
