//! The FMI 3.0 binding: the description read into the importer's model, the binary's `fmi3*`
//! functions resolved once, and instances driven through them.

mod component;
mod cosimulation;
mod description;
mod model_exchange;

use std::ffi::{c_char, c_int, c_void};
use std::path::Path;

use fmi_c::fmi3 as c;
use fmi_c::Library;

pub use cosimulation::CoSimulation;
pub use description::describe;
pub(crate) use model_exchange::{instantiate as instantiate_model_exchange, state_structure};
pub use model_exchange::{Exchange3, ModelExchange};

use crate::fmi2::c_text;
use crate::logging::LogContext;
use crate::model::Interface;

/// FMI 3.0's platform folder for this machine.
pub const PLATFORM: &str = "x86_64-linux";

/// What an FMI 3.0 instance's `instanceEnvironment` points at: the logger of FMI 3.0 is not
/// told the instance's name, so the environment carries it.
pub(crate) struct Environment {
    pub(crate) name: String,
    pub(crate) log: LogContext,
}

/// `fmi3LogMessageCallback`.
pub(crate) unsafe extern "C" fn log_message(env: *mut c_void, status: c_int, category: *const c_char, message: *const c_char) {
    // This runs inside the FMU's call: it must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        if env.is_null() {
            return;
        }
        let env = &*(env as *const Environment);
        env.log.receive(&env.name, status, &c_text(category), &c_text(message));
    });
}

fmi_c::view! {
    /// The FMI 3.0 functions of both interfaces the importer calls.
    pub(crate) struct Common from c::Functions {
        free_instance: c::FreeInstance,
        enter_initialization_mode: c::EnterInitializationMode,
        exit_initialization_mode: c::ExitInitializationMode,
        enter_configuration_mode: c::EnterConfigurationMode,
        exit_configuration_mode: c::ExitConfigurationMode,
        enter_event_mode: c::EnterEventMode,
        update_discrete_states: c::UpdateDiscreteStates,
        terminate: c::Terminate,
        get_float32: c::GetFloat32,
        get_float64: c::GetFloat64,
        get_int8: c::GetInt8,
        get_uint8: c::GetUInt8,
        get_int16: c::GetInt16,
        get_uint16: c::GetUInt16,
        get_int32: c::GetInt32,
        get_uint32: c::GetUInt32,
        get_int64: c::GetInt64,
        get_uint64: c::GetUInt64,
        get_boolean: c::GetBoolean,
        get_string: c::GetString,
        get_binary: c::GetBinary,
        set_float32: c::SetFloat32,
        set_float64: c::SetFloat64,
        set_int8: c::SetInt8,
        set_uint8: c::SetUInt8,
        set_int16: c::SetInt16,
        set_uint16: c::SetUInt16,
        set_int32: c::SetInt32,
        set_uint32: c::SetUInt32,
        set_int64: c::SetInt64,
        set_uint64: c::SetUInt64,
        set_boolean: c::SetBoolean,
        set_string: c::SetString,
        set_binary: c::SetBinary,
    }
}

fmi_c::view! {
    /// The Co-Simulation functions the importer calls.
    pub(crate) struct CoSimulationApi from c::Functions {
        instantiate_co_simulation: c::InstantiateCoSimulation,
        enter_step_mode: c::EnterStepMode,
        do_step: c::DoStep,
    }
}

fmi_c::view! {
    /// The Model Exchange functions the importer calls.
    pub(crate) struct ModelExchangeApi from c::Functions {
        instantiate_model_exchange: c::InstantiateModelExchange,
        enter_continuous_time_mode: c::EnterContinuousTimeMode,
        completed_integrator_step: c::CompletedIntegratorStep,
        set_time: c::SetTime,
        set_continuous_states: c::SetContinuousStates,
        get_continuous_state_derivatives: c::GetContinuousStateDerivatives,
        get_event_indicators: c::GetEventIndicators,
        get_continuous_states: c::GetContinuousStates,
        get_number_of_continuous_states: c::GetNumberOfContinuousStates,
        get_number_of_event_indicators: c::GetNumberOfEventIndicators,
    }
}

/// The FMI 3.0 functions the importer calls: the common ones and those of the interface the
/// binary was loaded for.
pub(crate) struct Api {
    common: Common,
    /// The whole table, for the functions called only when an FMU has them.
    pub(crate) functions: c::Functions,
    pub(crate) co_simulation: Option<CoSimulationApi>,
    pub(crate) model_exchange: Option<ModelExchangeApi>,
}

impl std::ops::Deref for Api {
    type Target = Common;

    fn deref(&self) -> &Common {
        &self.common
    }
}

/// A loaded FMI 3.0 binary.
pub struct Binary {
    pub(crate) api: Api,
    // Kept open for the functions above; closed when the binary is dropped.
    _library: Library,
}

impl Binary {
    /// Loads the shared library at `path` and resolves the functions the runner calls: the
    /// common ones and those of `interface`.
    pub fn load(path: &Path, interface: Interface) -> Result<Binary, String> {
        // SAFETY: loading runs the library's initializers: the price of running any FMU.
        let library = unsafe { crate::open_binary(path) }?;
        let functions = c::Functions::resolve(&library);
        let co_simulation = interface == Interface::CoSimulation;
        let api = (|| {
            Ok(Api {
                common: Common::take(&functions)?,
                co_simulation: co_simulation.then(|| CoSimulationApi::take(&functions)).transpose()?,
                model_exchange: (!co_simulation).then(|| ModelExchangeApi::take(&functions)).transpose()?,
                functions,
            })
        })()
        .map_err(|name: &str| format!("the binary does not export the function {name} (FMI 3.0 requires it of a {interface} FMU)"))?;
        let get_version = functions.get_version.ok_or("the binary does not export the function fmi3GetVersion")?;
        // SAFETY: a static C string per the standard.
        let version = unsafe { c_text(get_version()).into_owned() };
        if !(version == "3.0" || version.starts_with("3.0.")) {
            return Err(format!("fmi3GetVersion returned {version:?}, not \"3.0\""));
        }
        Ok(Binary { api, _library: library })
    }
}
