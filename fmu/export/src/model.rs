//! What a model author writes: the equations (the [`Model`] trait) and a declarative
//! table of variables ([`Variable`]). Everything FMI-specific is derived from these two.

use serde::{de::DeserializeOwned, Serialize};

/// Static facts about a model that end up in `modelDescription.xml` and its documentation.
#[derive(Debug, Clone, Copy)]
pub struct ModelInfo {
    /// FMI `modelIdentifier`: also the name of the shared library and of the `.fmu`.
    pub identifier: &'static str,
    /// One-line description (the `description` attribute).
    pub description: &'static str,
    /// `DefaultExperiment` stop time (s).
    pub stop_time: f64,
    /// `DefaultExperiment` relative tolerance, used when `fmi2SetupExperiment` gives none.
    pub tolerance: f64,
    /// `DefaultExperiment` step size: the suggested communication (output) interval (s).
    pub output_interval: f64,
    /// The derivation in Markdown (usually `include_str!` of the crate's `derivation.md`),
    /// rendered into `documentation/index.html`.
    pub documentation: &'static str,
}

/// FMI 2.0 causality of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    Parameter,
    CalculatedParameter,
    Input,
    Output,
    Local,
    Independent,
}

/// FMI 2.0 variability of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Variability {
    Constant,
    Fixed,
    Tunable,
    Discrete,
    Continuous,
}

/// FMI 2.0 `initial` attribute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Initial {
    Exact,
    Approx,
    Calculated,
}

/// How the toolkit reads and writes one variable of model `M`.
pub enum Access<M> {
    /// A continuous state: element `i` of the state vector the solver integrates.
    State(usize),
    Real {
        get: fn(&M) -> f64,
        set: Option<fn(&mut M, f64)>,
    },
    Integer {
        get: fn(&M) -> i32,
        set: Option<fn(&mut M, i32)>,
    },
    Boolean {
        get: fn(&M) -> bool,
        set: Option<fn(&mut M, bool)>,
    },
}

impl<M> Clone for Access<M> {
    fn clone(&self) -> Self {
        match self {
            Access::State(i) => Access::State(*i),
            Access::Real { get, set } => Access::Real { get: *get, set: *set },
            Access::Integer { get, set } => Access::Integer { get: *get, set: *set },
            Access::Boolean { get, set } => Access::Boolean { get: *get, set: *set },
        }
    }
}

/// FMI base type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseType {
    Real,
    Integer,
    Boolean,
}

/// One row of a model's variable table.
pub struct Variable<M> {
    pub name: &'static str,
    pub description: &'static str,
    pub causality: Causality,
    pub variability: Variability,
    /// `None` lets FMI's default for the causality/variability pair apply.
    pub initial: Option<Initial>,
    /// SI unit name known to [`crate::units`] (`"m"`, `"N/m"`, ...).
    pub unit: Option<&'static str>,
    /// Display unit known to [`crate::units`] (`"deg"`, `"lbf/in"`, ...).
    pub display_unit: Option<&'static str>,
    pub access: Access<M>,
}

impl<M> Clone for Variable<M> {
    fn clone(&self) -> Self {
        Variable { access: self.access.clone(), ..*self }
    }
}

impl<M> Variable<M> {
    fn new(name: &'static str, description: &'static str, causality: Causality, variability: Variability, access: Access<M>) -> Self {
        Variable { name, description, causality, variability, initial: None, unit: None, display_unit: None, access }
    }

    /// A real parameter (`causality="parameter"`, `variability="fixed"`, `initial="exact"`).
    pub fn parameter(name: &'static str, description: &'static str, get: fn(&M) -> f64, set: fn(&mut M, f64)) -> Self {
        Self::new(name, description, Causality::Parameter, Variability::Fixed, Access::Real { get, set: Some(set) }).initial(Initial::Exact)
    }

    /// An integer parameter (fixed, exact).
    pub fn integer_parameter(name: &'static str, description: &'static str, get: fn(&M) -> i32, set: fn(&mut M, i32)) -> Self {
        Self::new(name, description, Causality::Parameter, Variability::Fixed, Access::Integer { get, set: Some(set) })
            .initial(Initial::Exact)
    }

    /// A boolean parameter (fixed, exact).
    pub fn boolean_parameter(name: &'static str, description: &'static str, get: fn(&M) -> bool, set: fn(&mut M, bool)) -> Self {
        Self::new(name, description, Causality::Parameter, Variability::Fixed, Access::Boolean { get, set: Some(set) })
            .initial(Initial::Exact)
    }

    /// A continuous real input, held constant over each communication step.
    pub fn input(name: &'static str, description: &'static str, get: fn(&M) -> f64, set: fn(&mut M, f64)) -> Self {
        Self::new(name, description, Causality::Input, Variability::Continuous, Access::Real { get, set: Some(set) })
    }

    /// A continuous state exposed as an output; element `index` of the state vector.
    pub fn state(name: &'static str, description: &'static str, index: usize) -> Self {
        Self::new(name, description, Causality::Output, Variability::Continuous, Access::State(index))
    }

    /// A continuous real output computed by [`Model::outputs`].
    pub fn output(name: &'static str, description: &'static str, get: fn(&M) -> f64) -> Self {
        Self::new(name, description, Causality::Output, Variability::Continuous, Access::Real { get, set: None })
    }

    /// A discrete real output (changes only at events), computed by the model.
    pub fn discrete_output(name: &'static str, description: &'static str, get: fn(&M) -> f64) -> Self {
        Self::new(name, description, Causality::Output, Variability::Discrete, Access::Real { get, set: None })
    }

    /// A discrete integer output.
    pub fn integer_output(name: &'static str, description: &'static str, get: fn(&M) -> i32) -> Self {
        Self::new(name, description, Causality::Output, Variability::Discrete, Access::Integer { get, set: None })
    }

    /// A discrete boolean output.
    pub fn boolean_output(name: &'static str, description: &'static str, get: fn(&M) -> bool) -> Self {
        Self::new(name, description, Causality::Output, Variability::Discrete, Access::Boolean { get, set: None })
    }

    /// A real parameter computed from others (`causality="calculatedParameter"`).
    pub fn calculated_parameter(name: &'static str, description: &'static str, get: fn(&M) -> f64) -> Self {
        Self::new(name, description, Causality::CalculatedParameter, Variability::Fixed, Access::Real { get, set: None })
            .initial(Initial::Calculated)
    }

    /// Sets the SI unit.
    pub fn unit(mut self, unit: &'static str) -> Self {
        self.unit = Some(unit);
        self
    }

    /// Sets the display unit (the handbook's unit, e.g. `"deg"`); values stay SI.
    pub fn display(mut self, display_unit: &'static str) -> Self {
        self.display_unit = Some(display_unit);
        self
    }

    /// Overrides the `initial` attribute.
    pub fn initial(mut self, initial: Initial) -> Self {
        self.initial = Some(initial);
        self
    }

    /// Overrides the variability (e.g. a `tunable` parameter).
    pub fn variability(mut self, variability: Variability) -> Self {
        self.variability = variability;
        self
    }

    /// The FMI base type.
    pub fn base_type(&self) -> BaseType {
        match self.access {
            Access::State(_) | Access::Real { .. } => BaseType::Real,
            Access::Integer { .. } => BaseType::Integer,
            Access::Boolean { .. } => BaseType::Boolean,
        }
    }

    /// True when the importer may set this variable.
    pub fn is_settable(&self) -> bool {
        matches!(self.causality, Causality::Parameter | Causality::Input)
    }
}

/// A refusal from model code, reported through the FMI logger and status.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelError(pub String);

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ModelError {}

impl From<String> for ModelError {
    fn from(s: String) -> Self {
        ModelError(s)
    }
}

impl From<&str> for ModelError {
    fn from(s: &str) -> Self {
        ModelError(s.to_owned())
    }
}

/// What the simulation does after an event.
#[derive(Debug, Clone, PartialEq, Serialize, serde::Deserialize)]
pub enum EventOutcome {
    /// Go on integrating (the model may have changed mode and the state).
    Continue,
    /// The experiment is over at this time (e.g. the projectile landed, a limit position):
    /// the step ends early, `fmi2Terminated` becomes true, and `reason` is logged.
    Stop { reason: String },
}

/// Checks that a real parameter is finite and strictly positive, naming it otherwise.
pub fn require_positive(name: &str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ModelError(format!("parameter {name} = {value} must be a finite number greater than zero")))
    }
}

/// Checks that a real parameter is finite (any sign), naming it otherwise.
pub fn require_finite(name: &str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ModelError(format!("parameter {name} = {value} must be a finite number")))
    }
}

/// Checks that a real parameter is finite and not negative, naming it otherwise.
pub fn require_non_negative(name: &str, value: f64) -> Result<(), ModelError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ModelError(format!("parameter {name} = {value} must be a finite number, zero or greater")))
    }
}

/// The equations of one lab system.
///
/// The toolkit owns time, the state vector, the solver and the FMI state machine; the model
/// owns its parameters, inputs, discrete mode and computed outputs (its struct fields), and
/// supplies the right-hand side. `Default` gives the start values of the variable table.
pub trait Model: Default + Clone + Send + Serialize + DeserializeOwned + 'static {
    /// Number of continuous states (fixed for the model; unused states may have zero rate).
    const N_STATES: usize;
    /// Number of event indicators watched for sign changes.
    const N_EVENT_INDICATORS: usize = 0;

    /// Identifier, description, default experiment and documentation.
    fn info() -> ModelInfo;

    /// The declarative variable table (solver controls are appended by the toolkit).
    fn variables() -> Vec<Variable<Self>>;

    /// Checks the parameters and fills the initial state `x` (called when initialization
    /// ends, and for initial unknowns read during initialization). The toolkit calls it again
    /// after any parameter change and before the solver starts, so it is also the place to
    /// derive constants the right-hand side needs from the parameters (see quarter_car).
    fn initial_state(&mut self, x: &mut [f64]) -> Result<(), ModelError>;

    /// The right-hand side: `dx = f(t, x, inputs)`.
    fn derivatives(&self, t: f64, x: &[f64], dx: &mut [f64]);

    /// Computes the output fields from the current time and state.
    fn outputs(&mut self, _t: f64, _x: &[f64]) {}

    /// Event indicators: an event fires where one changes sign.
    fn event_indicators(&self, _t: f64, _x: &[f64], _z: &mut [f64]) {}

    /// Handles an event at time `t`; `fired[i]` is true for each indicator that changed sign.
    /// The model may change its mode and the state `x` (e.g. an impact).
    fn on_event(&mut self, _t: f64, _x: &mut [f64], _fired: &[bool]) -> Result<EventOutcome, ModelError> {
        Ok(EventOutcome::Continue)
    }

    /// Called at each communication point: may project `x` back onto constraints (mechanisms)
    /// and return `Stop` (a limit position) or an error.
    fn communication_point(&mut self, _t: f64, _x: &mut [f64]) -> Result<EventOutcome, ModelError> {
        Ok(EventOutcome::Continue)
    }

    /// How far `x` is off the model's algebraic constraints, relative to the model's size
    /// (a loop-closure gap over the link lengths); 0 for a model without constraints (the
    /// default). Model Exchange has no communication points: there a drift beyond the relative
    /// tolerance asks for a step event (`fmi2CompletedIntegratorStep`), in whose event mode
    /// `communication_point` projects `x` back. Co-Simulation never calls it.
    fn constraint_drift(&self, _x: &[f64]) -> f64 {
        0.0
    }
}
