//! The FMI 1.0 binding: the description read into the importer's model, the binary's
//! `<modelIdentifier>_fmi*` functions resolved once, and instances driven through them:
//! Co-Simulation (`fmiDoStep`) and Model Exchange, which the runner's integrator drives through
//! the integration the versions share ([`crate::exchange`]).

mod component;
mod cosimulation;
mod description;
mod model_exchange;

use std::ffi::{c_char, c_int};
use std::path::Path;
use std::sync::{Arc, Mutex, Once};

use fmi_c::fmi1 as c;
use fmi_c::Library;

pub use cosimulation::CoSimulation;
pub use description::describe;
pub(crate) use model_exchange::instantiate as instantiate_model_exchange;
pub use model_exchange::{Exchange1, ModelExchange};

use crate::fmi2::c_text;
use crate::logging::LogContext;
use crate::model::Interface;

/// FMI 1.0's platform folder for this machine.
pub const PLATFORM: &str = "linux64";

fmi_c::view! {
    /// The FMI 1.0 functions the importer calls of either interface.
    pub(crate) struct Common from c::Functions {
        get_version: c::GetVersion,
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
    pub(crate) struct SlaveApi from c::Functions {
        get_types_platform: c::GetTypesPlatform,
        instantiate_slave: c::InstantiateSlave,
        initialize_slave: c::InitializeSlave,
        terminate_slave: c::TerminateSlave,
        free_slave_instance: c::FreeSlaveInstance,
        do_step: c::DoStep,
    }
}

fmi_c::view! {
    /// The Model Exchange functions the importer calls.
    pub(crate) struct ModelApi from c::Functions {
        get_model_types_platform: c::GetModelTypesPlatform,
        instantiate_model: c::InstantiateModel,
        free_model_instance: c::FreeModelInstance,
        set_time: c::SetTime,
        set_continuous_states: c::SetContinuousStates,
        completed_integrator_step: c::CompletedIntegratorStep,
        initialize: c::Initialize,
        get_derivatives: c::GetDerivatives,
        get_event_indicators: c::GetEventIndicators,
        event_update: c::EventUpdate,
        get_continuous_states: c::GetContinuousStates,
        terminate: c::Terminate,
    }
}

/// The FMI 1.0 functions the importer calls, checked present when the binary was loaded, and
/// the whole table for those it calls only when the FMU has them (`fmiGetString`, ...).
pub(crate) struct Api {
    pub(crate) common: Common,
    pub(crate) functions: c::Functions,
    pub(crate) slave: Option<SlaveApi>,
    pub(crate) model: Option<ModelApi>,
}

/// A loaded FMI 1.0 binary.
pub struct Binary {
    pub(crate) api: Api,
    // Kept open for the functions above; closed when the binary is dropped.
    _library: Library,
}

impl Binary {
    /// Loads the shared library at `path` and resolves its functions under the prefix
    /// `identifier`: those the importer calls of `interface` must be there.
    pub fn load(path: &Path, interface: Interface, identifier: &str) -> Result<Binary, String> {
        crate::trace::enter(crate::trace::Call::Load, f64::NAN);
        // SAFETY: loading runs the library's initializers: the price of running any FMU.
        let library = unsafe { crate::open_binary(path) }?;
        let functions = c::Functions::resolve_prefixed(&library, identifier);
        let missing =
            |name: &str| format!("the binary does not export the function {identifier}_{name} (FMI 1.0 requires it of a {interface} FMU)");
        let api = Api {
            common: Common::take(&functions).map_err(missing)?,
            slave: (interface == Interface::CoSimulation).then(|| SlaveApi::take(&functions)).transpose().map_err(missing)?,
            model: (interface == Interface::ModelExchange).then(|| ModelApi::take(&functions)).transpose().map_err(missing)?,
            functions,
        };
        // SAFETY: both return static C strings per the standard.
        let version = unsafe { c_text((api.common.get_version)()).into_owned() };
        if version != "1.0" {
            return Err(format!("{identifier}_fmiGetVersion returned {version:?}, not \"1.0\""));
        }
        // SAFETY: as fmiGetVersion.
        let types = match (&api.slave, &api.model) {
            (Some(slave), _) => Some(("fmiGetTypesPlatform", unsafe { c_text((slave.get_types_platform)()).into_owned() })),
            (None, Some(model)) => Some(("fmiGetModelTypesPlatform", unsafe { c_text((model.get_model_types_platform)()).into_owned() })),
            (None, None) => None,
        };
        if let Some((name, types)) = types.filter(|(_, types)| types != "standard32") {
            return Err(format!("{identifier}_{name} returned {types:?}; only the \"standard32\" types are supported"));
        }
        INSTALL_SINK.call_once(|| c::set_log_sink(sink));
        Ok(Binary { api, _library: library })
    }
}

/// One live instance's log: its component (null while it is being instantiated) and name.
struct Registered {
    component: usize,
    name: String,
    log: Arc<LogContext>,
}

/// Every live FMI 1.0 instance of the process: FMI 1.0's logger gets only the FMU's component
/// and instance name, so the log a message belongs to is looked up here.
static REGISTRY: Mutex<Vec<Registered>> = Mutex::new(Vec::new());

static INSTALL_SINK: Once = Once::new();

/// Receives every message an FMI 1.0 FMU logs, formatted by the C shim, and hands it to its
/// instance's log (by component, else by instance name: messages during instantiation come
/// before the component is known).
unsafe extern "C" fn sink(component: c::Component, instance: *const c_char, status: c_int, category: *const c_char, text: *const c_char) {
    // This runs inside the FMU's call: it must not unwind into C.
    let _ = std::panic::catch_unwind(|| {
        let (instance, category, text) = (c_text(instance), c_text(category), c_text(text));
        let log = REGISTRY.lock().ok().and_then(|registry| {
            let address = component as usize;
            let by_component = registry.iter().rev().find(|r| address != 0 && r.component == address);
            let by_name = || registry.iter().rev().find(|r| r.name == instance);
            by_component.or_else(by_name).map(|r| Arc::clone(&r.log))
        });
        match log {
            Some(log) => log.receive(&instance, status, &category, &text),
            None => crate::logging::print_line(&format!("[{instance}] {} ({category}): {text}", crate::logging::level(status))),
        }
    });
}

/// An instance's place in [`REGISTRY`], removed when dropped.
pub(crate) struct Registration {
    log: Arc<LogContext>,
}

impl Registration {
    /// Registers the log of the instance `name` about to be instantiated.
    pub(crate) fn new(name: &str) -> Registration {
        let log = Arc::new(LogContext::default());
        if let Ok(mut registry) = REGISTRY.lock() {
            registry.push(Registered { component: 0, name: name.to_owned(), log: Arc::clone(&log) });
        }
        Registration { log }
    }

    /// The instance's log.
    pub(crate) fn log(&self) -> &LogContext {
        &self.log
    }

    /// The FMU made the instance `component`.
    pub(crate) fn instantiated(&self, component: c::Component) {
        if let Ok(mut registry) = REGISTRY.lock() {
            if let Some(r) = registry.iter_mut().find(|r| Arc::ptr_eq(&r.log, &self.log)) {
                r.component = component as usize;
            }
        }
    }
}

impl Drop for Registration {
    fn drop(&mut self) {
        if let Ok(mut registry) = REGISTRY.lock() {
            registry.retain(|r| !Arc::ptr_eq(&r.log, &self.log));
        }
    }
}
