//! The export toolkit: turns a model (equations and variables declared once) into an FMU.
//!
//! A model crate declares its variables on its struct's fields (`#[derive(Variables)]`, and
//! `#[derive(StateVector)]` for named states), implements [`Model`] (the equations) and calls
//! [`export_fmu!`]. The toolkit's model [`core`] owns time, the solver ([`solvers`]), events,
//! the variable rules and FMU-state capture, independently of the FMI version and interface;
//! the front end [`fmi2`] puts the FMI 2.0 Co-Simulation and Model Exchange state machines and
//! all 44 `fmi2*` C functions over it and writes `modelDescription.xml` (its ModelStructure
//! dependencies found by [`structure`]); the front end [`fmi3`] does the same for FMI 3.0 (all
//! 75 `fmi3*` functions, in the same binary); [`documentation`] renders the page from the same
//! table.

pub mod catalogue;
pub mod core;
pub mod documentation;
pub mod fmi2;
pub mod fmi3;
mod glue;
pub mod harness;
pub mod logging;
pub mod model;
pub mod phase_cosine;
pub mod structure;
pub mod table;
pub mod units;

// The derive macros' generated code names this crate `::fmu_export`, also from inside it.
extern crate self as fmu_export;

pub use fmu_derive::{StateVector, Variables};
pub use model::{
    require_finite, require_non_negative, require_positive, Causality, EventOutcome, Initial, Model, ModelError, ModelInfo, Range,
    StateVariable, StateVector, Variability, Variable, Variables,
};
pub use phase_cosine::PhaseCosine;
pub use solvers;
