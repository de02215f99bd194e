//! One module per command; each owns its options and defaults.

pub mod animate;
pub mod build;
pub mod compare;
pub mod handbook;
pub mod info;
pub mod linearize;
pub mod new;
pub mod serve;
pub mod simulate;
pub mod sweep;
pub mod system;
pub mod validate;
