//! FMI 2.0 Co-Simulation export toolkit.
//!
//! A model crate implements [`Model`] (equations plus a declarative variable table) and calls
//! [`export_fmu!`]; the toolkit supplies all 34 `fmi2*` functions with the standard's state
//! machine, logging, FMU state capture and serialization, the built-in solvers (Euler, RK4,
//! Dormand–Prince 5(4) with event location), and generates `modelDescription.xml` and the
//! documentation page from the same table.

pub mod controls;
pub mod describe;
pub mod description;
pub mod documentation;
pub mod ffi;
pub mod fmu_state;
pub mod harness;
pub mod instance;
pub mod logging;
pub mod model;
pub mod phase_cosine;
pub mod solver;
pub mod state_machine;
pub mod table;
pub mod units;

pub use model::{
    require_finite, require_non_negative, require_positive, Causality, EventOutcome, Initial, Model, ModelError, ModelInfo, Variability,
    Variable,
};
pub use phase_cosine::PhaseCosine;
