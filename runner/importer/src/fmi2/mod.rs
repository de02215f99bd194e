//! The FMI 2.0 binding: the description read into the importer's model, the binary's `fmi2*`
//! functions resolved once, and instances driven through them. It assumes nothing about who
//! exported the FMU beyond the standard.

mod component;
pub(crate) mod cosimulation;
mod description;
mod model_exchange;

use std::ffi::{c_char, c_int, c_void, CStr};
use std::path::Path;

use fmi_c::fmi2 as c;
use fmi_c::Library;

pub use crate::exchange::MAX_EVENT_ITERATIONS;
pub use cosimulation::CoSimulation;
pub use description::describe;
pub(crate) use model_exchange::{instantiate as instantiate_model_exchange, state_structure};
pub use model_exchange::{Exchange2, ModelExchange};

use crate::logging::LogContext;
use crate::model::Interface;

/// FMI 2.0's platform folder for this machine.
pub const PLATFORM: &str = "linux64";

pub(crate) unsafe fn c_text<'a>(p: *const c_char) -> std::borrow::Cow<'a, str> {
    if p.is_null() {
        "".into()
    } else {
        CStr::from_ptr(p).to_string_lossy()
    }
}

/// Receives every message an FMI 2.0 FMU logs, already formatted by the C shim.
unsafe extern "C" fn forward(context: *mut c_void, instance: *const c_char, status: c_int, category: *const c_char, text: *const c_char) {
    // This runs inside the FMU's call: it must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        if context.is_null() {
            return;
        }
        let context = &*(context as *const LogContext);
        context.receive(&c_text(instance), status, &c_text(category), &c_text(text));
    });
}

/// The logger callbacks of one instance; they must stay at a fixed address while it lives.
pub(crate) struct Callbacks {
    pub(crate) functions: c::CallbackFunctions,
    _forwarder: Box<c::LogForwarder>,
    pub(crate) log: Box<LogContext>,
}

impl Callbacks {
    pub(crate) fn new() -> Box<Callbacks> {
        let log = Box::new(LogContext::default());
        let forwarder = Box::new(c::LogForwarder { forward, context: &*log as *const LogContext as *mut c_void });
        let functions = c::CallbackFunctions::forwarding_to(&forwarder);
        Box::new(Callbacks { functions, _forwarder: forwarder, log })
    }
}

fmi_c::view! {
    /// The FMI 2.0 functions the importer calls of either interface.
    pub(crate) struct Common from c::Functions {
        instantiate: c::Instantiate,
        free_instance: c::FreeInstance,
        setup_experiment: c::SetupExperiment,
        enter_initialization_mode: c::EnterInitializationMode,
        exit_initialization_mode: c::ExitInitializationMode,
        terminate: c::Terminate,
        get_real: c::GetReal,
        get_integer: c::GetInteger,
        get_boolean: c::GetBoolean,
        set_real: c::SetReal,
        set_integer: c::SetInteger,
        set_boolean: c::SetBoolean,
        set_string: c::SetString,
    }
}

fmi_c::view! {
    /// The Co-Simulation functions the importer calls.
    pub(crate) struct CoSimulationApi from c::Functions {
        do_step: c::DoStep,
        get_boolean_status: c::GetBooleanStatus,
        get_real_status: c::GetRealStatus,
    }
}

fmi_c::view! {
    /// The Model Exchange functions the importer calls.
    pub(crate) struct ExchangeApi from c::Functions {
        enter_event_mode: c::EnterEventMode,
        new_discrete_states: c::NewDiscreteStates,
        enter_continuous_time_mode: c::EnterContinuousTimeMode,
        completed_integrator_step: c::CompletedIntegratorStep,
        set_time: c::SetTime,
        set_continuous_states: c::SetContinuousStates,
        get_derivatives: c::GetDerivatives,
        get_event_indicators: c::GetEventIndicators,
        get_continuous_states: c::GetContinuousStates,
    }
}

/// The FMI 2.0 functions the importer calls: the common ones and those of the interface the
/// binary was loaded for, checked present when it was loaded; and the whole table, for the
/// functions it calls only when an FMU has them (`fmi2GetString`, `fmi2SetRealInputDerivatives`).
pub(crate) struct Api {
    common: Common,
    pub(crate) functions: c::Functions,
    pub(crate) co_simulation: Option<CoSimulationApi>,
    pub(crate) exchange: Option<ExchangeApi>,
}

impl std::ops::Deref for Api {
    type Target = Common;

    fn deref(&self) -> &Common {
        &self.common
    }
}

/// A loaded FMI 2.0 binary.
pub struct Binary {
    pub(crate) api: Api,
    // Kept open for the functions above; closed when the binary is dropped.
    _library: Library,
}

impl Binary {
    /// Loads the shared library at `path` and resolves its functions: those the importer calls
    /// of either interface and of `interface` must be there.
    pub fn load(path: &Path, interface: Interface) -> Result<Binary, String> {
        crate::trace::enter(crate::trace::Call::Load, f64::NAN);
        // SAFETY: loading runs the library's initializers: the price of running any FMU.
        let library = unsafe { crate::open_binary(path) }?;
        let functions = c::Functions::resolve(&library);
        let missing = |name: &str| format!("the binary does not export the function {name} (FMI 2.0 requires it of a {interface} FMU)");
        let api = Api {
            exchange: (interface == Interface::ModelExchange).then(|| ExchangeApi::take(&functions)).transpose().map_err(missing)?,
            common: Common::take(&functions).map_err(missing)?,
            co_simulation: (interface == Interface::CoSimulation)
                .then(|| CoSimulationApi::take(&functions))
                .transpose()
                .map_err(missing)?,
            functions,
        };
        let (Some(get_version), Some(get_types_platform)) = (functions.get_version, functions.get_types_platform) else {
            let name = if functions.get_version.is_none() { "fmi2GetVersion" } else { "fmi2GetTypesPlatform" };
            return Err(format!("the binary does not export the function {name}"));
        };
        // SAFETY: both return static C strings per the standard.
        let version = unsafe { c_text(get_version()).into_owned() };
        if version != "2.0" {
            return Err(format!("fmi2GetVersion returned {version:?}, not \"2.0\""));
        }
        let types = unsafe { c_text(get_types_platform()).into_owned() };
        if types != "default" {
            return Err(format!("fmi2GetTypesPlatform returned {types:?}; only \"default\" types are supported"));
        }
        Ok(Binary { api, _library: library })
    }
}
