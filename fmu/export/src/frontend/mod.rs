//! The FMI front end, written once for FMI 2.0 and 3.0: the instance over the model core and
//! its state-machine engine ([`Instance`]), the Model Exchange translation
//! (`model_exchange`), and the C boundary's generic bodies ([`ffi`]): the component box, the
//! FMU-state box and the unwinding guard every call passes.
//!
//! What differs between the versions is a [`Version`]: its states, its table of calls (C name,
//! interface, the states that allow it, and why these FMUs refuse it where they do), the names
//! its arguments and messages use, and the shape of its FMU states. Each version module
//! (`fmi2`, `fmi3`) holds only that table, its C signatures (thin `extern "C"` functions over
//! [`ffi`]), its modelDescription writer, and the few calls whose meaning differs between the
//! versions (FMI 2.0's step statuses; FMI 3.0's early return from a step).
//!
//! A call goes: C function (version module) → generic body ([`ffi`]: pointer and argument
//! checks, the guard) → [`Instance`] method (the state machine's verdict, then the core).

mod derivatives;
pub mod ffi;
mod instance;
mod model_exchange;

use std::fmt::Debug;

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

pub use instance::Instance;

use crate::core::Names;
use crate::model::Model;

/// The interface an instance was created for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Interface {
    ModelExchange,
    CoSimulation,
}

impl Interface {
    /// The standard's name, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Interface::ModelExchange => "Model Exchange",
            Interface::CoSimulation => "Co-Simulation",
        }
    }
}

/// How an instance was created: its interface and, for Co-Simulation, what the importer
/// allows (FMI 3.0's `eventModeUsed` and `earlyReturnAllowed`; always false in FMI 2.0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Setup {
    pub interface: Interface,
    pub event_mode_used: bool,
    pub early_return_allowed: bool,
}

impl Setup {
    /// An instance of `interface` with neither Event Mode nor early return (FMI 2.0's only kind).
    pub fn plain(interface: Interface) -> Setup {
        Setup { interface, event_mode_used: false, early_return_allowed: false }
    }
}

/// Every instance-level call of either version, by what it does: each [`Version`]'s table
/// gives its C name (`GetReal` is `fmi2GetReal` and `fmi3GetFloat64`), its interface and the
/// states that allow it. A call the version does not have is never made by it. A plain key
/// (one byte): the hot paths pass it around for free.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Call {
    SetDebugLogging,
    FreeInstance,
    /// FMI 2.0 only (FMI 3.0 passes the experiment to `fmi3EnterInitializationMode`).
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    /// The Real getter (FMI 3.0: Float64).
    GetReal,
    GetInteger,
    GetBoolean,
    GetString,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    // FMI 3.0's getters and setters of the types no variable of these FMUs has.
    GetFloat32,
    GetInt8,
    GetUInt8,
    GetInt16,
    GetUInt16,
    GetUInt32,
    GetInt64,
    GetUInt64,
    GetBinary,
    SetFloat32,
    SetInt8,
    SetUInt8,
    SetInt16,
    SetUInt16,
    SetUInt32,
    SetInt64,
    SetUInt64,
    SetBinary,
    GetFMUState,
    SetFMUState,
    FreeFMUState,
    SerializedFMUStateSize,
    SerializeFMUState,
    DeserializeFMUState,
    GetDirectionalDerivative,
    /// FMI 3.0 only.
    GetAdjointDerivative,
    /// FMI 2.0's `fmi2SetRealInputDerivatives`.
    SetInputDerivatives,
    GetOutputDerivatives,
    DoStep,
    // FMI 2.0's asynchronous Co-Simulation calls.
    CancelStep,
    GetStatus,
    GetRealStatus,
    GetIntegerStatus,
    GetBooleanStatus,
    GetStringStatus,
    EnterEventMode,
    /// FMI 2.0's `fmi2NewDiscreteStates`, FMI 3.0's `fmi3UpdateDiscreteStates`.
    UpdateDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    /// FMI 2.0's `fmi2GetDerivatives`, FMI 3.0's `fmi3GetContinuousStateDerivatives`.
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
    // FMI 3.0's own, from here on.
    GetNumberOfEventIndicators,
    GetNumberOfContinuousStates,
    EnterStepMode,
    GetNumberOfVariableDependencies,
    GetVariableDependencies,
    EnterConfigurationMode,
    ExitConfigurationMode,
    // The clock functions.
    GetClock,
    SetClock,
    GetIntervalDecimal,
    GetIntervalFraction,
    GetShiftDecimal,
    GetShiftFraction,
    SetIntervalDecimal,
    SetIntervalFraction,
    SetShiftDecimal,
    SetShiftFraction,
    EvaluateDiscreteStates,
    /// The last variant (the tables' test counts up to it).
    ActivateModelPartition,
}

/// One call in a version's table.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Row {
    /// The C name, for messages.
    pub name: &'static str,
    /// The interface the call belongs to; `None` for the calls both share.
    pub interface: Option<Interface>,
    /// The states that allow it, one bit each ([`MachineState::bit`]).
    pub allowed: u16,
    /// Why these FMUs refuse the call even where the state machine allows it (the capability
    /// flag their modelDescription.xml declares); `None` for the calls they serve.
    pub refused: Option<&'static str>,
}

impl Row {
    /// A call these FMUs serve.
    pub const fn serves(name: &'static str, interface: Option<Interface>, allowed: u16) -> Row {
        Row { name, interface, allowed, refused: None }
    }

    /// A call these FMUs refuse for `why`, once the state machine allows it.
    pub const fn refuses(name: &'static str, interface: Option<Interface>, allowed: u16, why: &'static str) -> Row {
        Row { name, interface, allowed, refused: Some(why) }
    }

    /// The row of a call the version does not have (never made by it).
    pub const ABSENT: Row = Row { name: "(no such function in this FMI version)", interface: None, allowed: 0, refused: None };
}

/// The names a version gives the arguments the generic bodies check, for messages (and the
/// `logCalls` traces).
#[derive(Debug, Clone, Copy)]
pub struct Words {
    /// The value-reference array of the getters and setters (`vr[]`, `valueReferences[]`).
    pub vrs: &'static str,
    /// Their value array (`value[]`, `values[]`).
    pub values: &'static str,
    /// The number of continuous states (`nx`, `nContinuousStates`).
    pub n_states: &'static str,
    /// The number of event indicators (`ni`, `nEventIndicators`).
    pub n_indicators: &'static str,
    /// The arrays of the Model Exchange calls.
    pub states: &'static str,
    pub derivatives: &'static str,
    pub indicators: &'static str,
    pub nominals: &'static str,
    /// The FMU-state argument (`FMUstate`, `FMUState`).
    pub fmu_state: &'static str,
    /// What names the instance's build at instantiation (`GUID`, `instantiationToken`).
    pub token: &'static str,
    /// The directional derivative's arrays, unknowns' and knowns' value references, seed and
    /// sensitivity (`vUnknown_ref[]`, `vKnown_ref[]`, `dvKnown[]`, `dvUnknown[]`; FMI 3.0:
    /// `unknowns[]`, `knowns[]`, `seed[]`, `sensitivity[]`), and the numbers of unknowns and
    /// knowns (`nUnknown`, `nUnknowns`).
    pub unknowns: &'static str,
    pub knowns: &'static str,
    pub seed: &'static str,
    pub sensitivity: &'static str,
    pub n_unknowns: &'static str,
    pub n_knowns: &'static str,
}

/// A version's state-machine state.
pub trait MachineState: Copy + Eq + Debug + Send + 'static {
    /// The standard's name of the state, for messages.
    fn name(self) -> &'static str;
    /// The interface whose state machine has the state; `None` for the states both share.
    fn interface(self) -> Option<Interface>;
    /// The state's bit in [`Row::allowed`].
    fn bit(self) -> u16;
}

/// What differs between FMI 2.0 and 3.0, for the one front end: data, and the shape of an FMU
/// state. Implemented by `fmi2::Fmi2` and `fmi3::Fmi3`.
pub trait Version: Sized + 'static {
    /// The state machine's states, as the standard names them; FMU states record them in this
    /// version's numbering.
    type State: MachineState;
    /// What an FMU state keeps of the state machine (beside the core's state).
    type Saved: Clone + Serialize + DeserializeOwned + Send + 'static;

    /// The names the core's messages use.
    const NAMES: Names;
    /// The names of the arguments.
    const WORDS: Words;
    /// The tag of this version's component boxes (a pointer of the other version, or none of
    /// ours, is refused).
    const COMPONENT_MAGIC: u64;
    /// FMI 3.0 makes the event indicators Float64 variables after the table's rows.
    const INDICATOR_VARIABLES: bool;

    /// The states the engine moves between (Co-Simulation's stepping state is FMI 2.0's
    /// StepComplete and FMI 3.0's Step Mode).
    const INSTANTIATED: Self::State;
    const INITIALIZATION_MODE: Self::State;
    const STEP_MODE: Self::State;
    const EVENT_MODE: Self::State;
    const CONTINUOUS_TIME_MODE: Self::State;
    const TERMINATED: Self::State;
    const ERROR: Self::State;

    /// The call's row of this version's table.
    fn row(call: Call) -> Row;
    /// The call's C name.
    #[inline(always)]
    fn name(call: Call) -> &'static str {
        Self::row(call).name
    }
    /// The tag of model `M`'s FMU states in this version, in memory and serialized.
    fn state_tag<M: Model>() -> u64;
    /// What an FMU state keeps of the machine: its state and the event a step stopped at.
    fn save(state: Self::State, pending_event: &Option<Vec<bool>>) -> Self::Saved;
    /// The state and pending event of a saved machine.
    fn restore(saved: &Self::Saved) -> (Self::State, Option<Vec<bool>>);
}

/// True when `V`'s table allows `call` in `state` (for an instance of the call's interface).
#[inline(always)]
pub fn is_allowed_in<V: Version>(call: Call, state: V::State) -> bool {
    V::row(call).allowed & state.bit() != 0
}

/// The name of event indicator `k`'s variable (FMI 3.0 declares the indicators as variables).
pub fn event_indicator_name(k: usize) -> String {
    format!("event_indicator_{k}")
}

/// What `fmi2NewDiscreteStates` and `fmi3UpdateDiscreteStates` tell the importer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiscreteUpdate {
    /// `newDiscreteStatesNeeded`, `discreteStatesNeedUpdate`: never, one update settles every
    /// event of these models.
    pub discrete_states_need_update: bool,
    pub terminate_simulation: bool,
    pub nominals_of_continuous_states_changed: bool,
    pub values_of_continuous_states_changed: bool,
    /// `nextEventTimeDefined` and `nextEventTime`: these models have no time events.
    pub next_event_time: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fmi2::Fmi2;
    use crate::fmi3::Fmi3;

    /// Every call: `Call` is `repr(u8)` with the default discriminants, 0 to its last variant's.
    fn all() -> impl Iterator<Item = Call> {
        // SAFETY: every value in the range is the discriminant of a variant.
        (0..=Call::ActivateModelPartition as u8).map(|i| unsafe { std::mem::transmute::<u8, Call>(i) })
    }

    /// Checks version `V`'s table against the standard's lists of its functions by interface
    /// (`fmi_c`, written from the standard's headers): every function with an instance has
    /// exactly one row, of the list's interface, and every row names one of the version's
    /// functions (or is absent from the version). A wrong name would log refusals under another
    /// function's name; a wrong interface would let an instance of one interface make the other's
    /// calls.
    fn table_covers<V: Version>(lists: &[(&[&str], Option<Interface>)]) {
        let no_instance = |name: &str| name.ends_with("GetVersion") || name.ends_with("GetTypesPlatform") || name.contains("Instantiate");
        let mut names = Vec::new();
        for (functions, interface) in lists {
            for &function in functions.iter().filter(|f| !no_instance(f)) {
                let rows: Vec<Row> = all().map(V::row).filter(|r| r.name == function).collect();
                assert_eq!(rows.len(), 1, "{function}: one row");
                assert_eq!(rows[0].interface, *interface, "{function}'s interface");
                names.push(function);
            }
        }
        for call in all() {
            let row = V::row(call);
            assert!(row == Row::ABSENT || names.contains(&row.name), "{call:?}'s row names {}, not a function of the version", row.name);
        }
    }

    #[test]
    fn the_tables_cover_every_function_of_each_version() {
        use fmi_c::{fmi2, fmi3};
        let (me, cs) = (Some(Interface::ModelExchange), Some(Interface::CoSimulation));
        table_covers::<Fmi2>(&[
            (&fmi2::COMMON_FUNCTIONS, None),
            (&fmi2::MODEL_EXCHANGE_FUNCTIONS, me),
            (&fmi2::CO_SIMULATION_FUNCTIONS, cs),
        ]);
        table_covers::<Fmi3>(&[
            (&fmi3::COMMON_FUNCTIONS, None),
            (&fmi3::MODEL_EXCHANGE_FUNCTIONS, me),
            (&fmi3::CO_SIMULATION_FUNCTIONS, cs),
            (&fmi3::SCHEDULED_EXECUTION_FUNCTIONS, None),
        ]);
    }

    /// The calls these FMUs refuse say why with the capability their description declares, and
    /// the calls they serve have no reason to refuse.
    #[test]
    fn refused_calls_name_their_reason() {
        assert!(Fmi3::row(Call::GetClock).refused.is_some() && Fmi3::row(Call::GetFloat32).refused.is_some());
        for call in [
            Call::GetReal,
            Call::DoStep,
            Call::GetDerivatives,
            Call::GetFMUState,
            Call::GetDirectionalDerivative,
            Call::GetOutputDerivatives,
        ] {
            assert_eq!((Fmi2::row(call).refused, Fmi3::row(call).refused), (None, None), "{call:?}");
        }
        assert_eq!(Fmi3::row(Call::GetAdjointDerivative).refused, None);
        assert_eq!(Fmi2::row(Call::SetInputDerivatives).refused, None);
    }
}
