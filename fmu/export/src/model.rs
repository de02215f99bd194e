//! What a model author writes: the equations (the [`Model`] trait) and a declarative
//! table of variables ([`Variable`]), usually declared on the struct's fields with
//! `#[derive(Variables)]` and a named state vector with `#[derive(StateVector)]`.
//! Everything FMI-specific is derived from these.

use serde::{de::DeserializeOwned, Serialize};

use crate::scalar::Scalar;

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
    /// A String: read as text borrowed from the model, set by copying the importer's text.
    String {
        get: fn(&M) -> &str,
        set: Option<fn(&mut M, &str)>,
    },
}

impl<M> Clone for Access<M> {
    fn clone(&self) -> Self {
        match self {
            Access::State(i) => Access::State(*i),
            Access::Real { get, set } => Access::Real { get: *get, set: *set },
            Access::Integer { get, set } => Access::Integer { get: *get, set: *set },
            Access::Boolean { get, set } => Access::Boolean { get: *get, set: *set },
            Access::String { get, set } => Access::String { get: *get, set: *set },
        }
    }
}

/// FMI base type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BaseType {
    Real,
    Integer,
    Boolean,
    String,
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
    /// The values a parameter or input accepts (checked by the toolkit, see [`Range`]).
    pub range: Range,
    pub access: Access<M>,
    /// For a Real variable of the model struct: its index among the struct's real fields
    /// ([`Lift::field`]), through which the toolkit seeds and reads derivatives.
    pub field: Option<usize>,
}

impl<M> Clone for Variable<M> {
    fn clone(&self) -> Self {
        Variable { access: self.access.clone(), ..*self }
    }
}

impl<M> Variable<M> {
    fn new(name: &'static str, description: &'static str, causality: Causality, variability: Variability, access: Access<M>) -> Self {
        Variable {
            name,
            description,
            causality,
            variability,
            initial: None,
            unit: None,
            display_unit: None,
            range: Range::Any,
            access,
            field: None,
        }
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

    /// A String parameter (fixed, exact; `.variability(Variability::Tunable)` for tunable).
    pub fn string_parameter(name: &'static str, description: &'static str, get: fn(&M) -> &str, set: fn(&mut M, &str)) -> Self {
        Self::new(name, description, Causality::Parameter, Variability::Fixed, Access::String { get, set: Some(set) })
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

    /// A continuous real output computed by [`Equations::outputs`].
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

    /// Declares the values a parameter or input accepts.
    pub fn range(mut self, range: Range) -> Self {
        self.range = range;
        self
    }

    /// Overrides the `initial` attribute.
    pub fn initial(mut self, initial: Initial) -> Self {
        self.initial = Some(initial);
        self
    }

    /// Names the struct's real field `k` ([`Lift::field`]) as this variable's value.
    pub fn field(mut self, k: usize) -> Self {
        self.field = Some(k);
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
            Access::String { .. } => BaseType::String,
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
    /// What the default [`Model::communication_point`] returns: it changed nothing, so
    /// what the toolkit derived from the model's fields (its lift into dual numbers for output
    /// derivatives) still holds. A model's own `communication_point` returns `Continue`.
    #[doc(hidden)]
    Unchanged,
}

/// The values a parameter or input accepts. The toolkit checks every declared range when
/// initialization ends, before [`Equations::initial_state`], with the messages of the
/// `require_*` helpers, and writes the bounds as `min`/`max` into modelDescription.xml where
/// FMI can say them (`min="0"` for both `Positive` and `NonNegative`: FMI bounds are
/// inclusive). Non-finite Reals are refused when they are set, whatever the range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Range {
    /// Every value.
    Any,
    /// Any finite number.
    Finite,
    /// Finite and greater than zero.
    Positive,
    /// Finite and zero or greater.
    NonNegative,
    /// Finite and within the bounds given (inclusive).
    Bounds { min: Option<f64>, max: Option<f64> },
    /// One of these integers.
    OneOf(&'static [i32]),
}

impl Range {
    /// The lower bound modelDescription.xml declares.
    pub fn min(&self) -> Option<f64> {
        match self {
            Range::Positive | Range::NonNegative => Some(0.0),
            Range::Bounds { min, .. } => *min,
            Range::OneOf(values) => values.iter().min().map(|&v| v as f64),
            Range::Any | Range::Finite => None,
        }
    }

    /// The upper bound modelDescription.xml declares.
    pub fn max(&self) -> Option<f64> {
        match self {
            Range::Bounds { max, .. } => *max,
            Range::OneOf(values) => values.iter().max().map(|&v| v as f64),
            _ => None,
        }
    }

    /// Checks `value` of the variable `name` (a `kind`: "parameter" or "input").
    pub fn check(&self, kind: &str, name: &str, value: f64) -> Result<(), ModelError> {
        let refuse = |rule: &str| Err(ModelError(format!("{kind} {name} = {value} must be {rule}")));
        let within = |min: Option<f64>, max: Option<f64>| min.is_none_or(|m| value >= m) && max.is_none_or(|m| value <= m);
        match *self {
            Range::Any => Ok(()),
            Range::Finite if !value.is_finite() => refuse("a finite number"),
            Range::Positive if !(value.is_finite() && value > 0.0) => refuse("a finite number greater than zero"),
            Range::NonNegative if !(value.is_finite() && value >= 0.0) => refuse("a finite number, zero or greater"),
            Range::Bounds { min, max } if !(value.is_finite() && within(min, max)) => match (min, max) {
                (Some(min), Some(max)) => refuse(&format!("a finite number from {min} to {max}")),
                (Some(min), None) => refuse(&format!("a finite number, {min} or greater")),
                (None, Some(max)) => refuse(&format!("a finite number, {max} or less")),
                (None, None) => refuse("a finite number"),
            },
            Range::OneOf(values) if !values.iter().any(|&v| v as f64 == value) => refuse(&self.to_string()),
            _ => Ok(()),
        }
    }
}

impl std::fmt::Display for Range {
    /// The range as the documentation and the catalogue show it (`> 0`, `from 1 to 2`, ...).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Range::Any => Ok(()),
            Range::Finite => f.write_str("finite"),
            Range::Positive => f.write_str("> 0"),
            Range::NonNegative => f.write_str(">= 0"),
            Range::Bounds { min: Some(min), max: Some(max) } => write!(f, "from {min} to {max}"),
            Range::Bounds { min: Some(min), max: None } => write!(f, ">= {min}"),
            Range::Bounds { min: None, max: Some(max) } => write!(f, "<= {max}"),
            Range::Bounds { min: None, max: None } => f.write_str("finite"),
            // Signed, as the handbook writes the assembly choice: "+1 or -1".
            Range::OneOf(values) => {
                let listed: Vec<String> = values.iter().map(|v| if *v > 0 { format!("+{v}") } else { v.to_string() }).collect();
                match listed.split_last() {
                    Some((last, [])) => f.write_str(last),
                    Some((last, rest)) => write!(f, "{} or {last}", rest.join(", ")),
                    None => f.write_str("one of no values"),
                }
            }
        }
    }
}

/// Checks that a real parameter is finite and strictly positive, naming it otherwise.
pub fn require_positive(name: &str, value: f64) -> Result<(), ModelError> {
    Range::Positive.check("parameter", name, value)
}

/// Checks that a real parameter is finite (any sign), naming it otherwise.
pub fn require_finite(name: &str, value: f64) -> Result<(), ModelError> {
    Range::Finite.check("parameter", name, value)
}

/// Checks that a real parameter is finite and not negative, naming it otherwise.
pub fn require_non_negative(name: &str, value: f64) -> Result<(), ModelError> {
    Range::NonNegative.check("parameter", name, value)
}

/// A model's variable table, usually generated by `#[derive(Variables)]` from the struct's
/// fields: each field marked `#[parameter(...)]`, `#[input(...)]` or `#[output(...)]` is one
/// row, in field order, its doc comment the description, its type the FMI type (`f64` Real,
/// `i32` Integer, `bool` Boolean, `String` String: parameters only); the rows of the state vector
/// (`#[variables(states = S)]`, `S` a `#[derive(StateVector)]` struct) come before the first
/// output, or after the row a state names with `after`. Keys: `name = "M"` (the FMI name;
/// default the field's), `unit`, `display`, a range (`positive`, `non_negative`, `finite`,
/// `min = a`, `max = b`, `one_of(1, -1)`, see [`Range`]), `discrete` (a Real output that
/// changes only at events), `tunable` (a parameter settable after initialization), `when = expr` (the row exists only where `expr` holds), and on
/// the struct `bound = "P: Trait"` for generic models.
pub trait Variables: Sized {
    /// Every field of the model struct with its type, in declaration order (the derive writes
    /// it): part of the tag of serialized FMU states, which hold the struct.
    const LAYOUT: &'static str = "";

    /// The rows, in value-reference order (solver controls are appended by the toolkit).
    fn variables() -> Vec<Variable<Self>>;

    /// The model over dual numbers (see [`Lift`]): the derive gives it for a struct generic
    /// over its number type; `None` (a model written on `f64`) means no exact derivatives, and
    /// the FMU declares none.
    fn lifting() -> Option<Lifting<Self>> {
        None
    }
}

/// The toolkit's handles on a model's [`Lift`] (written by `#[derive(Variables)]`, so that a
/// model written on `f64` needs none).
pub struct Lifting<M> {
    /// [`Lift::refresh`].
    pub refresh: fn(&mut M),
    /// [`Lift::derived_current`].
    pub derived_current: fn(&M) -> bool,
    /// One forward pass in dual numbers ([`crate::core::derivatives::forward`]).
    pub forward: fn(&M, &crate::core::derivatives::Pass, &mut crate::core::derivatives::KeptLift, &mut [f64]) -> Result<(), ModelError>,
    /// [`Lifting::forward`] for an implicit solver's block d(der x)/dx, without the general
    /// pass's bookkeeping ([`crate::core::derivatives::states`]).
    pub states:
        fn(&M, &crate::core::derivatives::StatesPass, &mut crate::core::derivatives::KeptLift, &mut [f64]) -> Result<(), ModelError>,
    /// Output derivatives along the trajectory ([`crate::core::derivatives::trajectory`]).
    pub trajectory: fn(&mut M, &[f64], &mut crate::core::derivatives::Trajectory) -> Result<(), ModelError>,
}

/// Computes the `#[derived]` fields of `model` from its parameters again ([`Lift::refresh`];
/// nothing for a model without them). The toolkit calls it whenever parameters change.
pub fn refresh<M: Variables>(model: &mut M) {
    if let Some(lifting) = M::lifting() {
        (lifting.refresh)(model);
    }
}

impl<M> Clone for Lifting<M> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<M> Copy for Lifting<M> {}

/// Checks every range `M` declares against `model`'s current values, in table order (the
/// toolkit does so before [`Equations::initial_state`]).
pub fn check_ranges<M: Variables>(model: &M) -> Result<(), ModelError> {
    for v in M::variables().iter().filter(|v| v.range != Range::Any) {
        let value = match &v.access {
            Access::Real { get, .. } => get(model),
            Access::Integer { get, .. } => get(model) as f64,
            _ => continue,
        };
        let kind = if v.causality == Causality::Input { "input" } else { "parameter" };
        v.range.check(kind, v.name, value)?;
    }
    Ok(())
}

/// One state's row and where it goes in the table: right after the variable named `after`,
/// or (`None`) with the other states before the first output.
pub struct StateVariable<M> {
    pub variable: Variable<M>,
    pub after: Option<&'static str>,
}

/// Named components of the state vector, from `#[derive(StateVector)]` on a struct of `f64`
/// fields (each one state, in order, its doc comment the description; `#[state(unit, display,
/// name, after)]`). The derive also gives the struct index constants (`State::Z_S`), `LEN`,
/// and `load(x)`/`store(x)` between the struct and the solver's slice.
pub trait StateVector {
    /// Number of states.
    const LEN: usize;
    /// The state rows of the table of model `M`.
    fn variables<M>() -> Vec<StateVariable<M>>;
}

/// The table of a model with states: `rows` (parameters, inputs, outputs) with the states
/// placed before row `states_at` or after the row they name. Panics on an `after` that names
/// no row: an authoring mistake that every model's table test and `runner build` meet.
pub fn place_states<M>(rows: Vec<Variable<M>>, states_at: usize, states: Vec<StateVariable<M>>) -> Vec<Variable<M>> {
    for s in &states {
        if let Some(after) = s.after {
            assert!(
                rows.iter().any(|r| r.name == after),
                "state '{}' is placed after '{after}', which is no variable of the model",
                s.variable.name
            );
        }
    }
    let mut out = Vec::with_capacity(rows.len() + states.len());
    let mut placed: Vec<Option<StateVariable<M>>> = states.into_iter().map(Some).collect();
    let mut take = |out: &mut Vec<Variable<M>>, after: Option<&str>| {
        for slot in placed.iter_mut() {
            if slot.as_ref().is_some_and(|s| s.after == after) {
                out.push(slot.take().expect("checked").variable);
            }
        }
    };
    for (i, row) in rows.into_iter().enumerate() {
        if i == states_at {
            take(&mut out, None);
        }
        let name = row.name;
        out.push(row);
        take(&mut out, Some(name));
    }
    take(&mut out, None);
    out
}

/// The equations of a model, over the number type `T` (see [`Scalar`]): `f64` to simulate,
/// dual numbers to differentiate. Implemented once for every `T`
/// (`impl<T: Scalar> Equations<T> for Model<T>`): the toolkit's exact derivatives (directional,
/// adjoint, output derivatives) are these functions run on dual numbers, so they cannot
/// disagree with the simulation.
pub trait Equations<T: Scalar> {
    /// Checks what the declared ranges cannot (conditions across parameters, such as a linkage
    /// that must assemble; the toolkit has checked every [`Range`] before) and fills the
    /// initial state `x` (called when initialization ends, and for initial unknowns read
    /// during initialization; the toolkit calls it again after any parameter change). It may
    /// set the model's discrete state (its starting regime).
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError>;

    /// The right-hand side: `dx = f(t, x, inputs)`, in the current regime.
    fn derivatives(&self, t: T, x: &[T], dx: &mut [T]);

    /// Computes the output fields from the current time and state. Only the fields of the
    /// table's computed variables: while a master reads output derivatives (of any order) at every
    /// step, the toolkit gives the `f64` model those fields from the same evaluation in dual
    /// numbers (`core::derivatives::Trajectory::shares_outputs`) instead of calling this in `f64`.
    fn outputs(&mut self, _t: T, _x: &[T]) {}
}

/// A model struct over another number type: `#[derive(Variables)]` writes it for a struct
/// generic over its number type (the type parameter whose default is `f64`,
/// `struct Car<T = f64>`), whose Real variables are of that type. The toolkit lifts the `f64`
/// model it simulates into dual numbers to differentiate its equations.
pub trait Lift: Sized {
    /// The same model with number type `U` (`Self` is `Over<f64>`).
    type Over<U: Scalar>: Equations<U> + Clone;

    /// A copy with every real field converted to `U` (derivative parts zero) and the
    /// `#[derived]` fields computed again from the converted ones.
    fn lift<U: Scalar>(&self) -> Self::Over<U>;

    /// The real field number `k` of a lifted model, as [`Variable::field`] numbers them.
    /// Panics on a number the struct does not have (the table only holds valid ones).
    fn field<U: Scalar>(model: &mut Self::Over<U>, k: usize) -> &mut U;

    /// Computes the `#[derived]` fields from the parameters again (the toolkit calls it after
    /// parameters change; a model without such fields has nothing to do).
    fn refresh(&mut self);

    /// [`Lift::refresh`] for a lifted model (after its parameters were given derivative parts).
    fn refresh_over<U: Scalar>(model: &mut Self::Over<U>);

    /// True when the `#[derived]` fields are those the parameters give (bit for bit): the
    /// toolkit checks it in debug builds before it integrates.
    fn derived_current(&self) -> bool;
}

/// A value a model derives from its parameters, for a `#[derived]` field: the toolkit computes
/// it with [`Derived::of`] whenever the parameters change (and for every lifted copy), so the
/// right-hand side reads it without repeating the work at every solver stage, and it can never
/// be stale. Its `PartialEq` is the debug builds' check that nothing changed a parameter
/// behind the toolkit's back; its `Default` (zeros: dual numbers have no `Default`, so it is
/// written out) is a placeholder until the toolkit computes it.
///
/// ```
/// use fmu_export::{Derived, Scalar};
///
/// struct Spring<T> { k: T, m: T }
///
/// /// The natural frequency sqrt(k/m).
/// #[derive(Debug, Clone, PartialEq)]
/// struct Natural<T> { omega: T }
///
/// impl<T: Scalar> Default for Natural<T> {
///     fn default() -> Self {
///         Natural { omega: T::zero() }
///     }
/// }
///
/// impl<T: Scalar> Derived<Spring<T>> for Natural<T> {
///     fn of(s: &Spring<T>) -> Self {
///         Natural { omega: (s.k / s.m).sqrt() }
///     }
/// }
/// assert_eq!(Natural::of(&Spring { k: 8.0, m: 2.0 }).omega, 2.0);
/// ```
pub trait Derived<M>: Default + Clone + PartialEq {
    /// The value for the model's current parameters.
    fn of(model: &M) -> Self;
}

/// One lab system as an FMU: its equations ([`Equations`] over `f64`, and over dual numbers
/// through [`Lift`] when it is generic over its number type), its identity, and its discrete
/// behaviour (events, projections).
///
/// The toolkit owns time, the state vector, the solver and the FMI state machine; the model
/// owns its parameters, inputs, discrete mode and computed outputs (its struct fields).
/// `Default` gives the start values of the variable table.
pub trait Model: Variables + Equations<f64> + Default + Clone + Send + Serialize + DeserializeOwned + 'static {
    /// Number of continuous states (fixed for the model; unused states may have zero rate).
    const N_STATES: usize;
    /// Number of event indicators watched for sign changes.
    const N_EVENT_INDICATORS: usize = 0;

    /// Identifier, description, default experiment and documentation.
    fn info() -> ModelInfo;

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
        Ok(EventOutcome::Unchanged)
    }

    /// How far `x` is off the model's algebraic constraints, relative to the model's size
    /// (a loop-closure gap over the link lengths); 0 for a model without constraints (the
    /// default). Model Exchange has no communication points: there a drift beyond the relative
    /// tolerance asks for a step event (`fmi2CompletedIntegratorStep`), in whose event mode
    /// `communication_point` projects `x` back. Co-Simulation never calls it.
    fn constraint_drift(&self, _x: &[f64]) -> f64 {
        0.0
    }

    /// Reads what the model needs from the FMU's `resources/` folder `dir`, or remembers `dir`
    /// to read from later (the road reads the table its String parameter names during
    /// initialization): called once, when the instance is created (`fmuResourceLocation`); an
    /// error refuses the instance with its message. A reset keeps what was read. Default:
    /// nothing.
    fn resources(&mut self, _dir: &std::path::Path) -> Result<(), ModelError> {
        Ok(())
    }
}

/// True when the derived value `d` is the one `model`'s parameters give now (what
/// [`Lift::derived_current`] checks for each `#[derived]` field).
pub fn is_current<M, D: Derived<M>>(d: &D, model: &M) -> bool {
    *d == D::of(model)
}
