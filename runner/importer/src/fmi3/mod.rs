//! The FMI 3.0 binding: the description read into the importer's model, the binary's `fmi3*`
//! functions resolved once, and instances driven through them.

mod component;
mod cosimulation;
mod description;
mod model_exchange;

use std::ffi::{c_char, c_int, c_void};
use std::path::Path;

use fmi_c::fmi3 as c;
use libloading::os::unix::{Library, Symbol, RTLD_LOCAL, RTLD_NOW};

pub use cosimulation::CoSimulation;
pub use description::describe;
pub(crate) use model_exchange::instantiate as instantiate_model_exchange;
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

/// The function `name` of `library` as the C signature `F`.
fn symbol<F: Copy>(library: &Library, name: &str) -> Result<F, String> {
    // SAFETY: the caller names a function whose C signature the FMI standard fixes as `F`.
    let found: Result<Symbol<F>, _> = unsafe { library.get(name.as_bytes()) };
    found.map(|s| *s).map_err(|_| format!("the binary does not export the function {name}"))
}

macro_rules! api {
    ($(#[$doc:meta])* $api:ident { $($field:ident: $ty:ident = $name:literal,)+ }) => {
        $(#[$doc])*
        #[derive(Clone, Copy)]
        pub(crate) struct $api {
            $(pub(crate) $field: c::$ty,)+
        }

        impl $api {
            fn resolve(lib: &Library) -> Result<$api, String> {
                Ok($api { $($field: symbol(lib, $name)?,)+ })
            }
        }
    };
}

api! {
    /// The FMI 3.0 functions of both interfaces the importer calls, resolved once per loaded binary.
    Common {
        free_instance: FreeInstance = "fmi3FreeInstance",
        enter_initialization_mode: EnterInitializationMode = "fmi3EnterInitializationMode",
        exit_initialization_mode: ExitInitializationMode = "fmi3ExitInitializationMode",
        enter_configuration_mode: EnterConfigurationMode = "fmi3EnterConfigurationMode",
        exit_configuration_mode: ExitConfigurationMode = "fmi3ExitConfigurationMode",
        enter_event_mode: EnterEventMode = "fmi3EnterEventMode",
        update_discrete_states: UpdateDiscreteStates = "fmi3UpdateDiscreteStates",
        terminate: Terminate = "fmi3Terminate",
        get_float32: GetFloat32 = "fmi3GetFloat32",
        get_float64: GetFloat64 = "fmi3GetFloat64",
        get_int8: GetInt8 = "fmi3GetInt8",
        get_uint8: GetUInt8 = "fmi3GetUInt8",
        get_int16: GetInt16 = "fmi3GetInt16",
        get_uint16: GetUInt16 = "fmi3GetUInt16",
        get_int32: GetInt32 = "fmi3GetInt32",
        get_uint32: GetUInt32 = "fmi3GetUInt32",
        get_int64: GetInt64 = "fmi3GetInt64",
        get_uint64: GetUInt64 = "fmi3GetUInt64",
        get_boolean: GetBoolean = "fmi3GetBoolean",
        get_string: GetString = "fmi3GetString",
        get_binary: GetBinary = "fmi3GetBinary",
        set_float32: SetFloat32 = "fmi3SetFloat32",
        set_float64: SetFloat64 = "fmi3SetFloat64",
        set_int8: SetInt8 = "fmi3SetInt8",
        set_uint8: SetUInt8 = "fmi3SetUInt8",
        set_int16: SetInt16 = "fmi3SetInt16",
        set_uint16: SetUInt16 = "fmi3SetUInt16",
        set_int32: SetInt32 = "fmi3SetInt32",
        set_uint32: SetUInt32 = "fmi3SetUInt32",
        set_int64: SetInt64 = "fmi3SetInt64",
        set_uint64: SetUInt64 = "fmi3SetUInt64",
        set_boolean: SetBoolean = "fmi3SetBoolean",
        set_string: SetString = "fmi3SetString",
        set_binary: SetBinary = "fmi3SetBinary",
    }
}

api! {
    /// The Co-Simulation functions the importer calls.
    CoSimulationApi {
        instantiate: InstantiateCoSimulation = "fmi3InstantiateCoSimulation",
        enter_step_mode: EnterStepMode = "fmi3EnterStepMode",
        do_step: DoStep = "fmi3DoStep",
    }
}

api! {
    /// The Model Exchange functions the importer calls.
    ModelExchangeApi {
        instantiate: InstantiateModelExchange = "fmi3InstantiateModelExchange",
        enter_continuous_time_mode: EnterContinuousTimeMode = "fmi3EnterContinuousTimeMode",
        completed_integrator_step: CompletedIntegratorStep = "fmi3CompletedIntegratorStep",
        set_time: SetTime = "fmi3SetTime",
        set_continuous_states: SetContinuousStates = "fmi3SetContinuousStates",
        get_continuous_state_derivatives: GetContinuousStateDerivatives = "fmi3GetContinuousStateDerivatives",
        get_event_indicators: GetEventIndicators = "fmi3GetEventIndicators",
        get_continuous_states: GetContinuousStates = "fmi3GetContinuousStates",
        get_number_of_continuous_states: GetNumberOfContinuousStates = "fmi3GetNumberOfContinuousStates",
        get_number_of_event_indicators: GetNumberOfEventIndicators = "fmi3GetNumberOfEventIndicators",
    }
}

/// The FMI 3.0 functions the importer calls: the common ones and those of the interface the
/// binary was loaded for.
pub(crate) struct Api {
    common: Common,
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
        let library =
            unsafe { Library::open(Some(path), RTLD_NOW | RTLD_LOCAL) }.map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        let resolve = || -> Result<Api, String> {
            let co_simulation = interface == Interface::CoSimulation;
            Ok(Api {
                common: Common::resolve(&library)?,
                co_simulation: co_simulation.then(|| CoSimulationApi::resolve(&library)).transpose()?,
                model_exchange: (!co_simulation).then(|| ModelExchangeApi::resolve(&library)).transpose()?,
            })
        };
        let api = resolve().map_err(|e| format!("{e} (FMI 3.0 requires it of a {interface} FMU)"))?;
        // SAFETY: a static C string per the standard.
        let version = unsafe { c_text(symbol::<c::GetVersion>(&library, "fmi3GetVersion")?()).into_owned() };
        if !(version == "3.0" || version.starts_with("3.0.")) {
            return Err(format!("fmi3GetVersion returned {version:?}, not \"3.0\""));
        }
        Ok(Binary { api, _library: library })
    }
}
