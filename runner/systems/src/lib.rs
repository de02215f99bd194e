//! Systems of FMUs: an SSP 1.0 or 2.0 system structure (a `.ssp` archive, a `SystemStructure.ssd`,
//! or a folder holding one) read and flattened ([`ssd`]), its FMUs loaded ([`System::open`]), and
//! run by a fixed-step co-simulation master ([`master`]): Jacobi (every component steps from t
//! with the outputs at t, libcosim's and fmpy's semantics) or Gauss-Seidel in data-flow order.

pub mod master;
pub mod ssd;
mod system;
pub mod xml;

pub use master::{Bound, Coupling, Failure, Master, Outcome};
pub use system::{is_system, Component, ComponentFiles, ComponentFmu, System, SystemFiles};
