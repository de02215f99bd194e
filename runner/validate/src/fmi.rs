//! The words both FMI versions share, as the probes use them: the version (the FMI C
//! interface's [`Fmi`], with the [`Version`] words the probes use), the interface an instance
//! is made for (the C interface's), the states of the standard's state machines, the variable
//! types the probes exchange, the operations of the C API ([`Op`], each version names them its
//! own way) and the status an FMU returned ([`Code`], any int, named by the C interface's
//! [`Status`]).

use std::ffi::c_int;

pub(crate) use fmi_c::{FmiVersion as Fmi, Interface, Status};

/// What the probes say of a version besides its functions: its words and its rules where the
/// two standards differ.
pub(crate) trait Version: Copy {
    /// The prefix of its C names (`fmi2`, `fmi3`).
    fn prefix(self) -> &'static str;
    /// The standard's name of a C status value (`fmi2Error`, `fmi3OK`), also for values it does
    /// not define.
    fn status_name(self, code: c_int) -> &'static str;
    /// The queries without an instance and the text the version fixes for each.
    fn identity(self) -> &'static [(Op, &'static str)];
    /// What the FMU gets to check its description with: the GUID (FMI 2.0) or the
    /// instantiationToken (FMI 3.0).
    fn token(self) -> &'static str;
    /// The instance argument of the C functions, for messages.
    fn instance_type(self) -> &'static str;
    /// What the standard calls the instance handle in its prose (`component`, `instance`).
    fn instance_word(self) -> &'static str;
    /// The C type of a saved FMU state, as the standard spells it (`FMUstate`, `FMUState`).
    fn fmu_state_word(self) -> &'static str;
    /// Where the standard requires Error for a wrong value reference.
    fn wrong_value_reference_section(self) -> &'static str;
    /// The capability flag of FMU state, as the description spells it.
    fn fmu_state_flag(self, serialized: bool) -> &'static str;
    /// The flag of the discrete update that asks for another one.
    fn again_flag(self) -> &'static str;
    /// Where an instance goes after a call returned Error: FMI 2.0 has an Error state, FMI 3.0
    /// puts it in Terminated (FMI 3.0.2 section 2.3.1: "If any function called in super state
    /// FMUStateSettable returns fmi3Error, the FMU enters state Terminated").
    fn state_after_error(self) -> State;
}

impl Version for Fmi {
    fn prefix(self) -> &'static str {
        match self {
            Fmi::Fmi1 => "fmi",
            Fmi::Fmi2 => "fmi2",
            Fmi::Fmi3 => "fmi3",
        }
    }

    fn status_name(self, code: c_int) -> &'static str {
        match self {
            Fmi::Fmi1 => fmi_c::fmi1::status_name(code),
            Fmi::Fmi2 => fmi_c::fmi2::status_name(code),
            Fmi::Fmi3 => fmi_c::fmi3::status_name(code),
        }
    }

    fn identity(self) -> &'static [(Op, &'static str)] {
        match self {
            Fmi::Fmi2 => &[(Op::GetVersion, "2.0"), (Op::GetTypesPlatform, "default")],
            Fmi::Fmi3 => &[(Op::GetVersion, "3.0")],
            Fmi::Fmi1 => &[(Op::GetVersion, "1.0")],
        }
    }

    fn token(self) -> &'static str {
        match self {
            Fmi::Fmi2 | Fmi::Fmi1 => "GUID",
            Fmi::Fmi3 => "instantiationToken",
        }
    }

    fn instance_type(self) -> &'static str {
        match self {
            Fmi::Fmi1 => "fmiComponent",
            Fmi::Fmi2 => "fmi2Component",
            Fmi::Fmi3 => "fmi3Instance",
        }
    }

    fn instance_word(self) -> &'static str {
        match self {
            Fmi::Fmi2 | Fmi::Fmi1 => "component",
            Fmi::Fmi3 => "instance",
        }
    }

    fn fmu_state_word(self) -> &'static str {
        match self {
            Fmi::Fmi2 | Fmi::Fmi1 => "FMUstate",
            Fmi::Fmi3 => "FMUState",
        }
    }

    fn wrong_value_reference_section(self) -> &'static str {
        match self {
            Fmi::Fmi2 | Fmi::Fmi1 => "section 2.1.7",
            Fmi::Fmi3 => "section 2.2.3",
        }
    }

    fn fmu_state_flag(self, serialized: bool) -> &'static str {
        match (self, serialized) {
            (Fmi::Fmi2 | Fmi::Fmi1, false) => "canGetAndSetFMUstate",
            (Fmi::Fmi2 | Fmi::Fmi1, true) => "canSerializeFMUstate",
            (Fmi::Fmi3, false) => "canGetAndSetFMUState",
            (Fmi::Fmi3, true) => "canSerializeFMUState",
        }
    }

    fn again_flag(self) -> &'static str {
        match self {
            Fmi::Fmi1 => "iterationConverged = false",
            Fmi::Fmi2 => "newDiscreteStatesNeeded",
            Fmi::Fmi3 => "discreteStatesNeedUpdate",
        }
    }

    fn state_after_error(self) -> State {
        match self {
            Fmi::Fmi2 | Fmi::Fmi1 => State::Error,
            Fmi::Fmi3 => State::Terminated,
        }
    }
}

/// A state of an instance, the states of both versions and both interfaces in one list (each
/// version's state table says which it has).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum State {
    Instantiated,
    InitializationMode,
    /// FMI 2.0 Co-Simulation between steps.
    StepComplete,
    /// FMI 2.0 Co-Simulation after a step returned fmi2Discard.
    StepFailed,
    /// FMI 3.0 Co-Simulation between steps.
    StepMode,
    EventMode,
    ContinuousTimeMode,
    Terminated,
    /// FMI 2.0 after a call returned fmi2Error.
    Error,
    /// After FreeInstance (or Fatal): no call may follow.
    Gone,
}

impl State {
    const ALL: [State; 9] = [
        State::Instantiated,
        State::InitializationMode,
        State::StepComplete,
        State::StepFailed,
        State::StepMode,
        State::EventMode,
        State::ContinuousTimeMode,
        State::Terminated,
        State::Error,
    ];

    /// The standard's name.
    pub(crate) fn name(self) -> &'static str {
        match self {
            State::Instantiated => "Instantiated",
            State::InitializationMode => "InitializationMode",
            State::StepComplete => "StepComplete",
            State::StepFailed => "StepFailed",
            State::StepMode => "StepMode",
            State::EventMode => "EventMode",
            State::ContinuousTimeMode => "ContinuousTimeMode",
            State::Terminated => "Terminated",
            State::Error => "Error",
            State::Gone => "freed",
        }
    }

    /// The state the standard's `name` names.
    pub(crate) fn from_name(name: &str) -> Option<State> {
        State::ALL.into_iter().find(|s| s.name() == name)
    }
}

/// The variable types the probes exchange: FMI 2.0's four (Enumeration exchanged as Integer),
/// and FMI 3.0's scalar Float64, Int32, Boolean and String.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Type {
    Real,
    Integer,
    Boolean,
    String,
}

impl Type {
    pub(crate) const ALL: [Type; 4] = [Type::Real, Type::Integer, Type::Boolean, Type::String];
}

/// An operation of the C API, whatever its name in a version (each version's table names it:
/// `Get(Real)` is fmi2GetReal and fmi3GetFloat64).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) enum Op {
    GetTypesPlatform,
    GetVersion,
    SetDebugLogging,
    Instantiate,
    FreeInstance,
    SetupExperiment,
    EnterInitializationMode,
    ExitInitializationMode,
    Terminate,
    Reset,
    Get(Type),
    Set(Type),
    GetFmuState,
    SetFmuState,
    FreeFmuState,
    SerializedFmuStateSize,
    SerializeFmuState,
    DeserializeFmuState,
    GetDirectionalDerivative,
    EnterEventMode,
    /// fmi2NewDiscreteStates, fmi3UpdateDiscreteStates.
    UpdateDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    /// fmi2GetDerivatives, fmi3GetContinuousStateDerivatives.
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    GetNominalsOfContinuousStates,
    GetNumberOfEventIndicators,
    GetNumberOfContinuousStates,
    SetInputDerivatives,
    GetOutputDerivatives,
    EnterStepMode,
    DoStep,
    CancelStep,
    /// fmi2GetStatus (`None`) and fmi2Get<Type>Status.
    Status(Option<Type>),
}

impl Op {
    /// The get or set of a variable type: (type, true for a get).
    pub(crate) fn access(self) -> Option<(Type, bool)> {
        match self {
            Op::Get(t) => Some((t, true)),
            Op::Set(t) => Some((t, false)),
            _ => None,
        }
    }

    /// The calls about an FMU state the instance saved.
    pub(crate) fn takes_fmu_state(self) -> bool {
        matches!(self, Op::SetFmuState | Op::FreeFmuState | Op::SerializedFmuStateSize | Op::SerializeFmuState | Op::DeserializeFmuState)
    }
}

/// A status code as returned, including values the standard does not define, and the version
/// that names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Code {
    pub status: c_int,
    pub fmi: Fmi,
}

impl Code {
    const OK: c_int = Status::Ok as c_int;
    const WARNING: c_int = Status::Warning as c_int;
    const DISCARD: c_int = Status::Discard as c_int;
    const ERROR: c_int = Status::Error as c_int;
    const FATAL: c_int = Status::Fatal as c_int;
    /// The function is not exported, so it was not called.
    const MISSING: c_int = -1000;

    /// What a call of `fmi` returned.
    pub(crate) fn new(fmi: Fmi, status: c_int) -> Code {
        Code { status, fmi }
    }

    /// OK, as a call that returns nothing is taken to have answered.
    pub(crate) fn ok_of(fmi: Fmi) -> Code {
        Code::new(fmi, Code::OK)
    }

    /// Error, as a NULL from an instantiation is taken.
    pub(crate) fn error_of(fmi: Fmi) -> Code {
        Code::new(fmi, Code::ERROR)
    }

    /// The code of a function the binary does not export.
    pub(crate) fn missing(fmi: Fmi) -> Code {
        Code::new(fmi, Code::MISSING)
    }

    /// OK or Warning: the call succeeded.
    pub(crate) fn ok(self) -> bool {
        self.status == Code::OK || self.status == Code::WARNING
    }

    pub(crate) fn is_discard(self) -> bool {
        self.status == Code::DISCARD
    }

    pub(crate) fn is_error(self) -> bool {
        self.status == Code::ERROR
    }

    pub(crate) fn is_fatal(self) -> bool {
        self.status == Code::FATAL
    }

    /// The function is not exported (nothing was called).
    pub(crate) fn is_missing(self) -> bool {
        self.status == Code::MISSING
    }

    /// The standard's name.
    pub(crate) fn name(self) -> &'static str {
        if self.is_missing() {
            "nothing (the function is not exported)"
        } else {
            self.fmi.status_name(self.status)
        }
    }
}

/// What a call returned, with what the FMU logged during it.
#[derive(Debug)]
pub(crate) struct Outcome<T> {
    pub code: Code,
    pub value: T,
    pub log: Option<String>,
}

impl<T> Outcome<T> {
    /// The outcome without its value.
    pub(crate) fn unit(self) -> Outcome<()> {
        Outcome { code: self.code, value: (), log: self.log }
    }
}

/// A list of numbers as a record or message shows it.
pub(crate) fn numbers(values: &[f64]) -> String {
    let mut text: Vec<String> = values.iter().take(6).map(|v| v.to_string()).collect();
    if values.len() > 6 {
        text.push(format!("... ({} values)", values.len()));
    }
    text.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_are_named_by_their_version() {
        assert_eq!(Code::error_of(Fmi::Fmi2).name(), "fmi2Error");
        assert_eq!(Code::new(Fmi::Fmi3, 1).name(), "fmi3Warning");
        assert!(Code::new(Fmi::Fmi3, 1).ok() && !Code::new(Fmi::Fmi3, 2).ok());
        assert_eq!(Code::new(Fmi::Fmi2, 77).name(), "an unknown fmi2Status");
        assert!(Code::missing(Fmi::Fmi2).is_missing() && !Code::missing(Fmi::Fmi2).ok());
        assert_eq!(Code::missing(Fmi::Fmi3).name(), "nothing (the function is not exported)");
    }

    #[test]
    fn states_and_arguments_read_back() {
        for s in State::ALL {
            assert_eq!(State::from_name(s.name()), Some(s));
        }
        assert_eq!(State::from_name("freed"), None, "no probe starts in a freed instance");
        assert_eq!(numbers(&[1.0, 2.5]), "1, 2.5");
        assert_eq!(numbers(&[0.0; 8]), "0, 0, 0, 0, 0, 0, ... (8 values)");
    }
}
