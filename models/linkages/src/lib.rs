//! The vector-loop models shared by the lab's linkage FMUs. The crank-rocker and the double
//! rocker are the same four-bar, and the crank-slider is the offset crank-slider with
//! y_OC = 0: each FMU crate supplies only a preset (its defaults and identity), its derivation
//! and its tests, so the equations exist once.
#![deny(unsafe_code)]

pub mod four_bar;
pub mod slider_crank;

pub use four_bar::FourBar;
pub use slider_crank::SliderCrank;

use fmu_export::nalgebra::Vector2;
use fmu_export::{ModelInfo, Scalar};

/// Position and velocity of the crank pin A of an input link of length `l_oa` at angle
/// `theta` turning at `omega`: (A, v_A).
pub fn crank_point<T: Scalar>(l_oa: T, theta: T, omega: T) -> (Vector2<T>, Vector2<T>) {
    let (s, c) = theta.sin_cos();
    (Vector2::new(l_oa * c, l_oa * s), Vector2::new(-l_oa * omega * s, l_oa * omega * c))
}

/// Default parameters of a four-bar FMU.
#[derive(Debug, Clone, Copy)]
pub struct FourBarParameters {
    pub l_oa: f64,
    pub l_ab: f64,
    pub l_bc: f64,
    pub l_co: f64,
    pub theta_co: f64,
    pub theta0: f64,
    pub omega: f64,
    pub branch: i32,
}

/// What makes a four-bar FMU itself: its defaults and its identity.
pub trait FourBarPreset: Clone + std::fmt::Debug + Send + 'static {
    /// The FMU's default parameters.
    fn parameters() -> FourBarParameters;
    /// Identifier, description, default experiment and documentation.
    fn info() -> ModelInfo;
}

/// Default parameters of a slider-crank FMU.
#[derive(Debug, Clone, Copy)]
pub struct SliderCrankParameters {
    pub l_oa: f64,
    pub l_ab: f64,
    pub y_oc: f64,
    pub theta0: f64,
    pub omega: f64,
    pub branch: i32,
}

/// What makes a slider-crank FMU itself: its defaults, identity and whether y_OC is a parameter.
pub trait SliderCrankPreset: Clone + std::fmt::Debug + Send + 'static {
    /// True when the slider's line height y_OC is a settable parameter (offset crank-slider).
    const HAS_OFFSET: bool;
    /// The FMU's default parameters.
    fn parameters() -> SliderCrankParameters;
    /// Identifier, description, default experiment and documentation.
    fn info() -> ModelInfo;
}
