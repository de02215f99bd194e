//! The export toolkit: turns a model (equations and variables declared once) into an FMU.
//!
//! A model crate declares its variables on its struct's fields (`#[derive(Variables)]`, and
//! `#[derive(StateVector)]` for named states), implements [`Model`] (the equations) and calls
//! [`export_fmu!`]. The toolkit's model [`core`] owns time, the solver ([`solvers`]), events,
//! the variable rules and FMU-state capture, independently of the FMI version and interface.
//! One [`frontend`] puts the Co-Simulation and Model Exchange state machines and the C boundary
//! over it, written once over a small per-version trait; [`fmi2`] and [`fmi3`] hold what is
//! each version's own: its state tables, its C functions (all 44 `fmi2*` and all 75 `fmi3*`,
//! in the same binary, from [`export_fmu!`]) and its `modelDescription.xml` writer (the
//! ModelStructure dependencies found by [`structure`]); [`documentation`] renders the page from
//! the same table.
//!
//! # Example
//!
//! A first-order decay `x' = -x / tau` (the model `runner new` starts from), exported and run
//! through the toolkit's [`harness`] (the FMU's own core, without the C layer) against its
//! closed form `x = exp(-t / tau)`:
//!
//! ```
//! use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
//! use serde::{Deserialize, Serialize};
//!
//! /// Generic over its number type, so the toolkit can differentiate the equations exactly.
//! #[derive(Debug, Clone, Serialize, Deserialize, Variables)]
//! #[variables(states = State)]
//! pub struct Decay<T = f64> {
//!     /// Time constant
//!     #[parameter(unit = "s", positive)]
//!     pub tau: T,
//!     /// Rate of decay x / tau
//!     #[output(unit = "1/s")]
//!     pub rate: T,
//! }
//!
//! /// The state vector.
//! #[derive(StateVector)]
//! pub struct State<T = f64> {
//!     /// The decaying quantity
//!     pub x: T,
//! }
//!
//! impl Default for Decay {
//!     fn default() -> Self {
//!         Decay { tau: 1.0, rate: 1.0 }
//!     }
//! }
//!
//! impl<T: Scalar> Equations<T> for Decay<T> {
//!     fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
//!         State { x: T::one() }.store(x);
//!         Ok(())
//!     }
//!     fn derivatives(&self, _t: T, x: &[T], dx: &mut [T]) {
//!         State { x: -State::load(x).x / self.tau }.store(dx);
//!     }
//!     fn outputs(&mut self, _t: T, x: &[T]) {
//!         self.rate = State::load(x).x / self.tau;
//!     }
//! }
//!
//! impl Model for Decay {
//!     const N_STATES: usize = State::LEN;
//!     fn info() -> ModelInfo {
//!         ModelInfo {
//!             identifier: "decay",
//!             description: "x' = -x / tau",
//!             stop_time: 5.0,
//!             tolerance: 1e-6,
//!             output_interval: 0.01,
//!             documentation: "# Decay",
//!         }
//!     }
//! }
//!
//! // The FMI 2.0 and 3.0 C functions (in a cdylib, the FMU's binary).
//! fmu_export::export_fmu!(Decay);
//!
//! fn main() {
//!     // The DOPRI5 run at rtol 1e-10 meets the closed form to 1e-8.
//!     let mut h = fmu_export::harness::Harness::<Decay>::new();
//!     h.set("tau", 0.5).unwrap();
//!     h.initialize(Some(1e-10)).unwrap();
//!     let run = h.run(2.0, 0.1, &["x"]).unwrap();
//!     for (t, x) in run.time.iter().zip(run.get("x")) {
//!         assert!((x - (-t / 0.5).exp()).abs() < 1e-8);
//!     }
//!     // A range the variable declares is checked, naming it.
//!     let mut h = fmu_export::harness::Harness::<Decay>::new();
//!     h.set("tau", 0.0).unwrap();
//!     assert!(h.initialize(None).unwrap_err().contains("tau"));
//! }
//! ```

pub mod catalogue;
pub mod core;
pub mod documentation;
mod export;
pub mod fmi2;
pub mod fmi3;
pub mod frontend;
pub mod harness;
pub mod logging;
pub mod model;
pub mod phase_cosine;
pub mod scalar;
pub mod structure;
pub mod table;
pub mod taylor3;
pub mod units;

// The derive macros' generated code names this crate `::fmu_export`, also from inside it.
extern crate self as fmu_export;

pub use fmu_derive::{StateVector, Variables};
pub use model::{
    require_finite, require_non_negative, require_positive, Causality, Derived, Equations, EventOutcome, Initial, Lift, Model, ModelError,
    ModelInfo, Range, StateVariable, StateVector, Variability, Variable, Variables,
};
pub use nalgebra;
pub use phase_cosine::{Harmonic, PhaseCosine};
pub use scalar::{Dual2_64, Dual3_64, Dual64, DualSVec64, Scalar};
pub use solvers;
pub use taylor3::Taylor3;
