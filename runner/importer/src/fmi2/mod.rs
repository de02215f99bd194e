//! The FMI 2.0 binding: the description read into the importer's model, the binary's `fmi2*`
//! functions resolved once, and instances driven through them. It assumes nothing about who
//! exported the FMU beyond the standard.

mod component;
mod cosimulation;
mod description;
mod model_exchange;

use std::ffi::{c_char, c_int, c_void, CStr};
use std::path::Path;

use fmi_c::fmi2 as c;
use libloading::os::unix::{Library, Symbol, RTLD_LOCAL, RTLD_NOW};

pub use crate::exchange::MAX_EVENT_ITERATIONS;
pub use cosimulation::CoSimulation;
pub use description::describe;
pub(crate) use model_exchange::instantiate as instantiate_model_exchange;
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
        let functions = c::CallbackFunctions {
            logger: Some(c::logger_shim()),
            allocate_memory: Some(libc::calloc),
            free_memory: Some(libc::free),
            step_finished: None,
            component_environment: &*forwarder as *const c::LogForwarder as *mut c_void,
        };
        Box::new(Callbacks { functions, _forwarder: forwarder, log })
    }
}

/// The FMI 2.0 functions the importer calls, resolved once per loaded binary.
pub(crate) struct Api {
    pub(crate) instantiate: c::Instantiate,
    pub(crate) free_instance: c::FreeInstance,
    pub(crate) setup_experiment: c::SetupExperiment,
    pub(crate) enter_initialization_mode: c::EnterInitializationMode,
    pub(crate) exit_initialization_mode: c::ExitInitializationMode,
    pub(crate) terminate: c::Terminate,
    pub(crate) get_real: c::GetReal,
    pub(crate) get_integer: c::GetInteger,
    pub(crate) get_boolean: c::GetBoolean,
    pub(crate) set_real: c::SetReal,
    pub(crate) set_integer: c::SetInteger,
    pub(crate) set_boolean: c::SetBoolean,
    pub(crate) set_string: c::SetString,
    /// `fmi2GetString`, looked up leniently: the runner reads Strings only when asked to.
    pub(crate) get_string: Option<c::GetString>,
    pub(crate) do_step: Option<c::DoStep>,
    pub(crate) get_boolean_status: Option<c::GetBooleanStatus>,
    pub(crate) get_real_status: Option<c::GetRealStatus>,
    /// Co-Simulation: `fmi2SetRealInputDerivatives`, for FMUs that interpolate inputs (looked up
    /// leniently: an FMU that cannot interpolate need not export it usefully).
    pub(crate) set_real_input_derivatives: Option<c::SetRealInputDerivatives>,
    /// The Model Exchange functions, resolved when the binary is loaded for that interface.
    pub(crate) exchange: Option<ExchangeApi>,
}

/// The Model Exchange functions the importer calls.
#[derive(Clone, Copy)]
pub(crate) struct ExchangeApi {
    pub(crate) enter_event_mode: c::EnterEventMode,
    pub(crate) new_discrete_states: c::NewDiscreteStates,
    pub(crate) enter_continuous_time_mode: c::EnterContinuousTimeMode,
    pub(crate) completed_integrator_step: c::CompletedIntegratorStep,
    pub(crate) set_time: c::SetTime,
    pub(crate) set_continuous_states: c::SetContinuousStates,
    pub(crate) get_derivatives: c::GetDerivatives,
    pub(crate) get_event_indicators: c::GetEventIndicators,
    pub(crate) get_continuous_states: c::GetContinuousStates,
}

/// A loaded FMI 2.0 binary.
pub struct Binary {
    pub(crate) api: Api,
    // Kept open for the functions above; closed when the binary is dropped.
    _library: Library,
}

impl Binary {
    /// Loads the shared library at `path` and resolves the functions the common ones and
    /// those of `interface`.
    pub fn load(path: &Path, interface: Interface) -> Result<Binary, String> {
        // SAFETY: loading runs the library's initializers: the price of running any FMU.
        // RTLD_LOCAL keeps two FMUs' fmi2* symbols apart.
        crate::trace::enter(crate::trace::Call::Load, f64::NAN);
        let library =
            unsafe { Library::open(Some(path), RTLD_NOW | RTLD_LOCAL) }.map_err(|e| format!("cannot load {}: {e}", path.display()))?;
        let api = Api::resolve(&library, interface).map_err(|e| format!("{e} (FMI 2.0 requires it of a {interface} FMU)"))?;
        // SAFETY: both return static C strings per the standard.
        let version = unsafe { c_text(symbol::<c::GetVersion>(&library, "fmi2GetVersion")?()).into_owned() };
        if version != "2.0" {
            return Err(format!("fmi2GetVersion returned {version:?}, not \"2.0\""));
        }
        let types = unsafe { c_text(symbol::<c::GetTypesPlatform>(&library, "fmi2GetTypesPlatform")?()).into_owned() };
        if types != "default" {
            return Err(format!("fmi2GetTypesPlatform returned {types:?}; only \"default\" types are supported"));
        }
        Ok(Binary { api, _library: library })
    }
}

/// The function `name` of `library` as the C signature `F`.
fn symbol<F: Copy>(library: &Library, name: &str) -> Result<F, String> {
    // SAFETY: the caller names a function whose C signature the FMI standard fixes as `F`.
    let found: Result<Symbol<F>, _> = unsafe { library.get(name.as_bytes()) };
    found.map(|s| *s).map_err(|_| format!("the binary does not export the function {name}"))
}

/// The function `name` when `needed`, else `None` without looking.
fn optional<F: Copy>(library: &Library, name: &str, needed: bool) -> Result<Option<F>, String> {
    if needed {
        symbol(library, name).map(Some)
    } else {
        Ok(None)
    }
}

impl Api {
    fn resolve(lib: &Library, interface: Interface) -> Result<Api, String> {
        let co_simulation = interface == Interface::CoSimulation;
        let exchange = if interface == Interface::ModelExchange {
            Some(ExchangeApi {
                enter_event_mode: symbol(lib, "fmi2EnterEventMode")?,
                new_discrete_states: symbol(lib, "fmi2NewDiscreteStates")?,
                enter_continuous_time_mode: symbol(lib, "fmi2EnterContinuousTimeMode")?,
                completed_integrator_step: symbol(lib, "fmi2CompletedIntegratorStep")?,
                set_time: symbol(lib, "fmi2SetTime")?,
                set_continuous_states: symbol(lib, "fmi2SetContinuousStates")?,
                get_derivatives: symbol(lib, "fmi2GetDerivatives")?,
                get_event_indicators: symbol(lib, "fmi2GetEventIndicators")?,
                get_continuous_states: symbol(lib, "fmi2GetContinuousStates")?,
            })
        } else {
            None
        };
        Ok(Api {
            exchange,
            instantiate: symbol(lib, "fmi2Instantiate")?,
            free_instance: symbol(lib, "fmi2FreeInstance")?,
            setup_experiment: symbol(lib, "fmi2SetupExperiment")?,
            enter_initialization_mode: symbol(lib, "fmi2EnterInitializationMode")?,
            exit_initialization_mode: symbol(lib, "fmi2ExitInitializationMode")?,
            terminate: symbol(lib, "fmi2Terminate")?,
            get_real: symbol(lib, "fmi2GetReal")?,
            get_integer: symbol(lib, "fmi2GetInteger")?,
            get_boolean: symbol(lib, "fmi2GetBoolean")?,
            set_real: symbol(lib, "fmi2SetReal")?,
            set_integer: symbol(lib, "fmi2SetInteger")?,
            set_boolean: symbol(lib, "fmi2SetBoolean")?,
            set_string: symbol(lib, "fmi2SetString")?,
            get_string: symbol(lib, "fmi2GetString").ok(),
            do_step: optional(lib, "fmi2DoStep", co_simulation)?,
            get_boolean_status: optional(lib, "fmi2GetBooleanStatus", co_simulation)?,
            get_real_status: optional(lib, "fmi2GetRealStatus", co_simulation)?,
            set_real_input_derivatives: optional(lib, "fmi2SetRealInputDerivatives", co_simulation).ok().flatten(),
        })
    }
}
