//! Every model's FMI entry points as tables of function pointers, FMI 2.0 and 3.0.
//!
//! Each model crate's `export_fmu!` makes its `#[no_mangle] extern "C"` functions forward to
//! the toolkit's generic front end (`fmu_export::frontend::ffi::get_real::<Fmi2, Model>`, ...)
//! or to a version's own bodies (`fmu_export::fmi2::ffi::do_step::<Model>`), one call each
//! (fmu/export/src/fmi2/ffi.rs `export_fmi2!`, fmi3/ffi.rs `export_fmi3!`). Several models
//! cannot be linked into one binary through those C names (the same symbol from two crates
//! resolves to one of them), so the tables below make the same calls as the macros, with the
//! same arguments, for each model: the code the `.so` runs, compiled into the fuzzer with its
//! sanitizer and coverage instrumentation. Only the one-line forwards themselves are not
//! exercised. If the macros change what a C function calls, this file is the one to follow.

use std::ffi::{c_char, c_int, c_void};

use fmu_export::fmi2::ffi as f2;
use fmu_export::fmi2::Fmi2 as V2;
use fmu_export::fmi3::ffi as f3;
use fmu_export::fmi3::Fmi3 as V3;
use fmu_export::frontend::ffi as fr;
use fmu_export::frontend::Call;
use fmu_export::Model;

pub use fmu_export::fmi2::ffi::{CallbackFunctions, EventInfo};
pub use fmu_export::fmi3::ffi::LogMessageCallback;

type C = *mut c_void;
type Vr = *const u32;

/// One model's FMI 2.0 functions (argument lists as in `fmi2Functions.h`).
#[allow(missing_docs)]
pub struct Fmi2 {
    pub instantiate: unsafe fn(*const c_char, c_int, *const c_char, *const c_char, *const CallbackFunctions, c_int, c_int) -> C,
    pub free_instance: unsafe fn(C),
    pub set_debug_logging: unsafe fn(C, c_int, usize, *const *const c_char) -> c_int,
    pub setup_experiment: unsafe fn(C, c_int, f64, f64, c_int, f64) -> c_int,
    pub enter_initialization_mode: unsafe fn(C) -> c_int,
    pub exit_initialization_mode: unsafe fn(C) -> c_int,
    pub terminate: unsafe fn(C) -> c_int,
    pub reset: unsafe fn(C) -> c_int,
    pub get_real: unsafe fn(C, Vr, usize, *mut f64) -> c_int,
    pub get_integer: unsafe fn(C, Vr, usize, *mut c_int) -> c_int,
    pub get_boolean: unsafe fn(C, Vr, usize, *mut c_int) -> c_int,
    pub get_string: unsafe fn(C, Vr, usize, *mut *const c_char) -> c_int,
    pub set_real: unsafe fn(C, Vr, usize, *const f64) -> c_int,
    pub set_integer: unsafe fn(C, Vr, usize, *const c_int) -> c_int,
    pub set_boolean: unsafe fn(C, Vr, usize, *const c_int) -> c_int,
    pub set_string: unsafe fn(C, Vr, usize, *const *const c_char) -> c_int,
    pub states: States,
    pub get_directional_derivative: unsafe fn(C, Vr, usize, Vr, usize, *const f64, *mut f64) -> c_int,
    pub set_real_input_derivatives: unsafe fn(C, Vr, usize, *const c_int, *const f64) -> c_int,
    pub get_real_output_derivatives: unsafe fn(C, Vr, usize, *const c_int, *mut f64) -> c_int,
    pub do_step: unsafe fn(C, f64, f64, c_int) -> c_int,
    pub cancel_step: unsafe fn(C) -> c_int,
    pub get_status: unsafe fn(C, c_int, *mut c_int) -> c_int,
    pub get_real_status: unsafe fn(C, c_int, *mut f64) -> c_int,
    pub get_integer_status: unsafe fn(C, c_int, *mut c_int) -> c_int,
    pub get_boolean_status: unsafe fn(C, c_int, *mut c_int) -> c_int,
    pub get_string_status: unsafe fn(C, c_int, *mut *const c_char) -> c_int,
    pub enter_event_mode: unsafe fn(C) -> c_int,
    pub new_discrete_states: unsafe fn(C, *mut EventInfo) -> c_int,
    pub enter_continuous_time_mode: unsafe fn(C) -> c_int,
    pub completed_integrator_step: unsafe fn(C, c_int, *mut c_int, *mut c_int) -> c_int,
    pub set_time: unsafe fn(C, f64) -> c_int,
    pub set_continuous_states: unsafe fn(C, *const f64, usize) -> c_int,
    pub get_derivatives: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_event_indicators: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_continuous_states: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_nominals_of_continuous_states: unsafe fn(C, *mut f64, usize) -> c_int,
}

/// The FMU-state functions, alike in both versions (serialized bytes as `u8`), with their C names
/// (get, set, free, size, serialize, deserialize).
#[allow(missing_docs)]
pub struct States {
    pub names: [&'static str; 6],
    pub get: unsafe fn(C, *mut C) -> c_int,
    pub set: unsafe fn(C, C) -> c_int,
    pub free: unsafe fn(C, *mut C) -> c_int,
    pub size: unsafe fn(C, C, *mut usize) -> c_int,
    pub serialize: unsafe fn(C, C, *mut u8, usize) -> c_int,
    pub deserialize: unsafe fn(C, *const u8, usize, *mut C) -> c_int,
}

/// `fmi3GetDirectionalDerivative`, `fmi3GetAdjointDerivative`: the instance, the unknowns and
/// knowns with their numbers, the seed and the sensitivity with theirs.
pub type Sensitivity3 = unsafe fn(C, Vr, usize, Vr, usize, *const f64, usize, *mut f64, usize) -> c_int;

/// A function of FMI 3.0 that these FMUs refuse whatever its arguments (clocks, configuration
/// mode, types no variable has, ...): the toolkit checks the state and logs the reason.
#[allow(missing_docs)]
pub struct Refused3 {
    pub name: &'static str,
    pub call: unsafe fn(C) -> c_int,
}

/// One model's FMI 3.0 functions (argument lists as in `fmi3Functions.h`).
#[allow(missing_docs)]
pub struct Fmi3 {
    pub instantiate_model_exchange:
        unsafe fn(*const c_char, *const c_char, *const c_char, bool, *mut c_void, Option<LogMessageCallback>) -> C,
    #[allow(clippy::type_complexity)]
    pub instantiate_co_simulation:
        unsafe fn(*const c_char, *const c_char, *const c_char, bool, bool, bool, *mut c_void, Option<LogMessageCallback>) -> C,
    pub free_instance: unsafe fn(C),
    pub set_debug_logging: unsafe fn(C, bool, usize, *const *const c_char) -> c_int,
    pub enter_initialization_mode: unsafe fn(C, bool, f64, f64, bool, f64) -> c_int,
    pub exit_initialization_mode: unsafe fn(C) -> c_int,
    pub enter_event_mode: unsafe fn(C) -> c_int,
    pub terminate: unsafe fn(C) -> c_int,
    pub reset: unsafe fn(C) -> c_int,
    pub get_float64: unsafe fn(C, Vr, usize, *mut f64, usize) -> c_int,
    pub get_int32: unsafe fn(C, Vr, usize, *mut i32, usize) -> c_int,
    pub get_boolean: unsafe fn(C, Vr, usize, *mut bool, usize) -> c_int,
    pub get_string: unsafe fn(C, Vr, usize, *mut *const c_char, usize) -> c_int,
    pub set_float64: unsafe fn(C, Vr, usize, *const f64, usize) -> c_int,
    pub set_int32: unsafe fn(C, Vr, usize, *const i32, usize) -> c_int,
    pub set_boolean: unsafe fn(C, Vr, usize, *const u8, usize) -> c_int,
    pub set_string: unsafe fn(C, Vr, usize, *const *const c_char, usize) -> c_int,
    pub states: States,
    pub get_directional_derivative: Sensitivity3,
    pub get_adjoint_derivative: Sensitivity3,
    pub get_output_derivatives: unsafe fn(C, Vr, usize, *const i32, *mut f64, usize) -> c_int,
    pub update_discrete_states: unsafe fn(C, *mut bool, *mut bool, *mut bool, *mut bool, *mut bool, *mut f64) -> c_int,
    pub enter_continuous_time_mode: unsafe fn(C) -> c_int,
    pub completed_integrator_step: unsafe fn(C, bool, *mut bool, *mut bool) -> c_int,
    pub set_time: unsafe fn(C, f64) -> c_int,
    pub set_continuous_states: unsafe fn(C, *const f64, usize) -> c_int,
    pub get_continuous_state_derivatives: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_event_indicators: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_continuous_states: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_nominals_of_continuous_states: unsafe fn(C, *mut f64, usize) -> c_int,
    pub get_number_of_event_indicators: unsafe fn(C, *mut usize) -> c_int,
    pub get_number_of_continuous_states: unsafe fn(C, *mut usize) -> c_int,
    pub enter_step_mode: unsafe fn(C) -> c_int,
    pub do_step: unsafe fn(C, f64, f64, bool, *mut bool, *mut bool, *mut bool, *mut f64) -> c_int,
    pub refused: Vec<Refused3>,
}

/// One model: its identifier, its GUID (FMI 2.0's GUID and FMI 3.0's instantiation token),
/// its number of variables and states, and both versions' functions.
pub struct Fmu {
    /// The model identifier (`second_order`).
    pub name: &'static str,
    /// The GUID / instantiation token the binary checks.
    pub guid: &'static str,
    /// The number of variables (value references 0..n_variables, FMI 2.0 and 3.0 alike).
    pub n_variables: u32,
    /// The number of continuous states.
    pub n_states: usize,
    /// FMI 2.0.
    pub fmi2: Fmi2,
    /// FMI 3.0.
    pub fmi3: Fmi3,
}

fn fmi2<M: Model>() -> Fmi2 {
    Fmi2 {
        instantiate: f2::instantiate::<M>,
        free_instance: fr::free_instance::<V2, M>,
        set_debug_logging: |c, on, n, cats| unsafe { fr::set_debug_logging::<V2, M>(c, on != 0, n, cats) },
        setup_experiment: f2::setup_experiment::<M>,
        enter_initialization_mode: |c| unsafe { fr::simple::<V2, M>(c, Call::EnterInitializationMode, |i| i.enter_initialization_mode()) },
        exit_initialization_mode: |c| unsafe { fr::simple::<V2, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()) },
        terminate: |c| unsafe { fr::simple::<V2, M>(c, Call::Terminate, |i| i.terminate()) },
        reset: |c| unsafe { fr::simple::<V2, M>(c, Call::Reset, |i| i.reset()) },
        get_real: |c, vr, n, v| unsafe { fr::get_real::<V2, M>(c, vr, n, v, n) },
        get_integer: |c, vr, n, v| unsafe { fr::get_integer::<V2, M>(c, vr, n, v, n) },
        get_boolean: |c, vr, n, v| unsafe { fr::get_boolean::<V2, M, c_int>(c, vr, n, v, n) },
        get_string: |c, vr, n, v| unsafe { fr::get_string::<V2, M>(c, vr, n, v, n) },
        set_real: |c, vr, n, v| unsafe { fr::set_real::<V2, M>(c, vr, n, v, n) },
        set_integer: |c, vr, n, v| unsafe { fr::set_integer::<V2, M>(c, vr, n, v, n) },
        set_boolean: |c, vr, n, v| unsafe { fr::set_boolean::<V2, M, c_int>(c, vr, n, v, n) },
        set_string: |c, vr, n, v| unsafe { fr::set_string::<V2, M>(c, vr, n, v, n) },
        states: States {
            names: [
                "fmi2GetFMUstate",
                "fmi2SetFMUstate",
                "fmi2FreeFMUstate",
                "fmi2SerializedFMUstateSize",
                "fmi2SerializeFMUstate",
                "fmi2DeSerializeFMUstate",
            ],
            get: fr::get_fmu_state::<V2, M>,
            set: fr::set_fmu_state::<V2, M>,
            free: fr::free_fmu_state::<V2, M>,
            size: fr::serialized_fmu_state_size::<V2, M>,
            serialize: fr::serialize_fmu_state::<V2, M>,
            deserialize: fr::deserialize_fmu_state::<V2, M>,
        },
        get_directional_derivative: |c, unknowns, n_unknowns, knowns, n_knowns, seed, sensitivity| unsafe {
            let call = Call::GetDirectionalDerivative;
            fr::get_sensitivity::<V2, M>(c, call, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_knowns), (sensitivity, n_unknowns))
        },
        set_real_input_derivatives: fr::set_input_derivatives::<V2, M>,
        get_real_output_derivatives: |c, vr, n, order, v| unsafe { fr::get_output_derivatives::<V2, M>(c, vr, n, order, v, n) },
        do_step: f2::do_step::<M>,
        cancel_step: |c| unsafe { fr::simple::<V2, M>(c, Call::CancelStep, |i| i.check(Call::CancelStep)) },
        get_status: f2::get_status::<M>,
        get_real_status: f2::get_real_status::<M>,
        get_integer_status: f2::get_integer_status::<M>,
        get_boolean_status: f2::get_boolean_status::<M>,
        get_string_status: f2::get_string_status::<M>,
        enter_event_mode: |c| unsafe { fr::simple::<V2, M>(c, Call::EnterEventMode, |i| i.enter_event_mode()) },
        new_discrete_states: f2::new_discrete_states::<M>,
        enter_continuous_time_mode: |c| unsafe {
            fr::simple::<V2, M>(c, Call::EnterContinuousTimeMode, |i| i.enter_continuous_time_mode())
        },
        completed_integrator_step: |c, _no_set_prior, enter, terminate| unsafe {
            fr::completed_integrator_step::<V2, M, c_int>(c, enter, terminate)
        },
        set_time: fr::set_time::<V2, M>,
        set_continuous_states: fr::set_continuous_states::<V2, M>,
        get_derivatives: fr::get_derivatives::<V2, M>,
        get_event_indicators: fr::get_event_indicators::<V2, M>,
        get_continuous_states: fr::get_continuous_states::<V2, M>,
        get_nominals_of_continuous_states: fr::get_nominals_of_continuous_states::<V2, M>,
    }
}

/// The FMI 3.0 functions `export_fmi3!` binds to `frontend::ffi::refuse` (whatever their
/// arguments, which it does not read): every type no variable has, binaries, clocks, variable
/// dependencies, Configuration Mode, Scheduled Execution's calls.
macro_rules! refused3 {
    ($m:ty; $($name:literal $call:ident)*) => {
        vec![$(Refused3 { name: $name, call: |c| unsafe { fr::refuse::<V3, $m>(c, Call::$call) } },)*]
    };
}

fn fmi3<M: Model>() -> Fmi3 {
    let refused = refused3![M;
        "fmi3GetFloat32" GetFloat32 "fmi3GetInt8" GetInt8 "fmi3GetUInt8" GetUInt8 "fmi3GetInt16" GetInt16
        "fmi3GetUInt16" GetUInt16 "fmi3GetUInt32" GetUInt32 "fmi3GetInt64" GetInt64 "fmi3GetUInt64" GetUInt64
        "fmi3SetFloat32" SetFloat32 "fmi3SetInt8" SetInt8 "fmi3SetUInt8" SetUInt8 "fmi3SetInt16" SetInt16
        "fmi3SetUInt16" SetUInt16 "fmi3SetUInt32" SetUInt32 "fmi3SetInt64" SetInt64 "fmi3SetUInt64" SetUInt64
        "fmi3GetBinary" GetBinary "fmi3SetBinary" SetBinary "fmi3GetClock" GetClock "fmi3SetClock" SetClock
        "fmi3GetNumberOfVariableDependencies" GetNumberOfVariableDependencies
        "fmi3GetVariableDependencies" GetVariableDependencies
        "fmi3EnterConfigurationMode" EnterConfigurationMode "fmi3ExitConfigurationMode" ExitConfigurationMode
        "fmi3GetIntervalDecimal" GetIntervalDecimal "fmi3GetIntervalFraction" GetIntervalFraction
        "fmi3GetShiftDecimal" GetShiftDecimal "fmi3GetShiftFraction" GetShiftFraction
        "fmi3SetIntervalDecimal" SetIntervalDecimal "fmi3SetIntervalFraction" SetIntervalFraction
        "fmi3SetShiftDecimal" SetShiftDecimal "fmi3SetShiftFraction" SetShiftFraction
        "fmi3EvaluateDiscreteStates" EvaluateDiscreteStates "fmi3ActivateModelPartition" ActivateModelPartition
    ];
    Fmi3 {
        instantiate_model_exchange: f3::instantiate_model_exchange::<M>,
        instantiate_co_simulation: f3::instantiate_co_simulation::<M>,
        free_instance: fr::free_instance::<V3, M>,
        set_debug_logging: fr::set_debug_logging::<V3, M>,
        enter_initialization_mode: f3::enter_initialization_mode::<M>,
        exit_initialization_mode: |c| unsafe { fr::simple::<V3, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()) },
        enter_event_mode: |c| unsafe { fr::simple::<V3, M>(c, Call::EnterEventMode, |i| i.enter_event_mode()) },
        terminate: |c| unsafe { fr::simple::<V3, M>(c, Call::Terminate, |i| i.terminate()) },
        reset: |c| unsafe { fr::simple::<V3, M>(c, Call::Reset, |i| i.reset()) },
        get_float64: fr::get_real::<V3, M>,
        get_int32: fr::get_integer::<V3, M>,
        get_boolean: fr::get_boolean::<V3, M, bool>,
        get_string: fr::get_string::<V3, M>,
        set_float64: fr::set_real::<V3, M>,
        set_int32: fr::set_integer::<V3, M>,
        set_boolean: fr::set_boolean::<V3, M, u8>,
        set_string: fr::set_string::<V3, M>,
        states: States {
            names: [
                "fmi3GetFMUState",
                "fmi3SetFMUState",
                "fmi3FreeFMUState",
                "fmi3SerializedFMUStateSize",
                "fmi3SerializeFMUState",
                "fmi3DeserializeFMUState",
            ],
            get: fr::get_fmu_state::<V3, M>,
            set: fr::set_fmu_state::<V3, M>,
            free: fr::free_fmu_state::<V3, M>,
            size: fr::serialized_fmu_state_size::<V3, M>,
            serialize: fr::serialize_fmu_state::<V3, M>,
            deserialize: fr::deserialize_fmu_state::<V3, M>,
        },
        get_directional_derivative: |c, unknowns, n_unknowns, knowns, n_knowns, seed, n_seed, sensitivity, n_sensitivity| unsafe {
            let call = Call::GetDirectionalDerivative;
            fr::get_sensitivity::<V3, M>(c, call, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_seed), (sensitivity, n_sensitivity))
        },
        get_adjoint_derivative: |c, unknowns, n_unknowns, knowns, n_knowns, seed, n_seed, sensitivity, n_sensitivity| unsafe {
            let call = Call::GetAdjointDerivative;
            fr::get_sensitivity::<V3, M>(c, call, (unknowns, n_unknowns), (knowns, n_knowns), (seed, n_seed), (sensitivity, n_sensitivity))
        },
        get_output_derivatives: fr::get_output_derivatives::<V3, M>,
        update_discrete_states: f3::update_discrete_states::<M>,
        enter_continuous_time_mode: |c| unsafe {
            fr::simple::<V3, M>(c, Call::EnterContinuousTimeMode, |i| i.enter_continuous_time_mode())
        },
        completed_integrator_step: |c, _no_set_prior, enter, terminate| unsafe {
            fr::completed_integrator_step::<V3, M, bool>(c, enter, terminate)
        },
        set_time: fr::set_time::<V3, M>,
        set_continuous_states: fr::set_continuous_states::<V3, M>,
        get_continuous_state_derivatives: fr::get_derivatives::<V3, M>,
        get_event_indicators: fr::get_event_indicators::<V3, M>,
        get_continuous_states: fr::get_continuous_states::<V3, M>,
        get_nominals_of_continuous_states: fr::get_nominals_of_continuous_states::<V3, M>,
        get_number_of_event_indicators: f3::get_number_of_event_indicators::<M>,
        get_number_of_continuous_states: f3::get_number_of_continuous_states::<M>,
        enter_step_mode: |c| unsafe { fr::simple::<V3, M>(c, Call::EnterStepMode, |i| i.enter_step_mode()) },
        do_step: f3::do_step::<M>,
        refused,
    }
}

fn fmu<M: Model>() -> Fmu {
    let info = M::info();
    Fmu {
        name: info.identifier,
        guid: fmu_export::table::guid::<M>(),
        n_variables: fmu_export::table::Table::<M>::new().rows.len() as u32,
        n_states: M::N_STATES,
        fmi2: fmi2::<M>(),
        fmi3: fmi3::<M>(),
    }
}

/// Every model of `models/` (the crates `runner build` exports) that this build takes (its
/// features: every one by default, five in the smoke build), in a fixed order: a fuzz input
/// names a model by its index here.
pub fn all() -> Vec<Fmu> {
    let mut fmus = Vec::new();
    #[cfg(feature = "bumper")]
    fmus.push(fmu::<bumper::Bumper>());
    #[cfg(feature = "crank_rocker")]
    fmus.push(fmu::<crank_rocker::FourBar>());
    #[cfg(feature = "crank_slider")]
    fmus.push(fmu::<crank_slider::CrankSlider>());
    #[cfg(feature = "double_rocker")]
    fmus.push(fmu::<double_rocker::FourBar>());
    #[cfg(feature = "inverted_crank_slider")]
    fmus.push(fmu::<inverted_crank_slider::InvertedCrankSlider>());
    #[cfg(feature = "mass_spring_damper")]
    fmus.push(fmu::<mass_spring_damper::MassSpringDamper>());
    #[cfg(feature = "offset_crank_slider")]
    fmus.push(fmu::<offset_crank_slider::OffsetCrankSlider>());
    #[cfg(feature = "pendulum")]
    fmus.push(fmu::<pendulum::Pendulum>());
    #[cfg(feature = "quarter_car")]
    fmus.push(fmu::<quarter_car::QuarterCar>());
    #[cfg(feature = "road")]
    fmus.push(fmu::<road::Road>());
    #[cfg(feature = "second_order")]
    fmus.push(fmu::<second_order::SecondOrder>());
    #[cfg(feature = "trebuchet")]
    fmus.push(fmu::<trebuchet::Trebuchet>());
    fmus
}
