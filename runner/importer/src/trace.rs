//! Which FMI call the importer is in, and at what model time, for a supervisor that must say
//! where an FMU crashed or hung. The runner's worker processes point [`set_slot`] at memory they
//! share with their parent, which reads it after the worker died or was killed. Without a slot
//! (in-process runs) each call costs one load of a pointer that nobody writes.

use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU32, AtomicU64, Ordering};

/// An FMI function the importer calls (or the loading of the binary, which runs its
/// initializers). Codes are stable within one build, which is all a worker and its parent share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum Call {
    /// No call yet.
    None = 0,
    Load,
    Instantiate,
    SetupExperiment,
    SetReal,
    SetInteger,
    SetBoolean,
    SetString,
    EnterInitializationMode,
    ExitInitializationMode,
    GetReal,
    GetInteger,
    GetBoolean,
    DoStep,
    GetBooleanStatus,
    GetRealStatus,
    Terminate,
    FreeInstance,
    // FMI 2.0 Model Exchange.
    EnterEventMode,
    NewDiscreteStates,
    EnterContinuousTimeMode,
    CompletedIntegratorStep,
    SetTime,
    SetContinuousStates,
    GetDerivatives,
    GetEventIndicators,
    GetContinuousStates,
    // FMI 3.0.
    Fmi3Instantiate,
    Fmi3EnterConfigurationMode,
    Fmi3ExitConfigurationMode,
    Fmi3Set,
    Fmi3EnterInitializationMode,
    Fmi3ExitInitializationMode,
    Fmi3Get,
    Fmi3DoStep,
    Fmi3EnterEventMode,
    Fmi3UpdateDiscreteStates,
    Fmi3EnterStepMode,
    Fmi3Terminate,
    Fmi3FreeInstance,
    // FMI 3.0 Model Exchange.
    Fmi3InstantiateModelExchange,
    Fmi3EnterContinuousTimeMode,
    Fmi3CompletedIntegratorStep,
    Fmi3SetTime,
    Fmi3SetContinuousStates,
    Fmi3GetContinuousStateDerivatives,
    Fmi3GetEventIndicators,
    Fmi3GetContinuousStates,
    Fmi3GetNumberOfContinuousStates,
    // Last, so the numbers of the calls before stay as they were.
    GetString,
    GetDirectionalDerivative,
    Fmi3GetDirectionalDerivative,
    // Stepping (fmurunner.Simulation): reset and the FMU state, serialized and back.
    Reset,
    GetFmuState,
    SetFmuState,
    Fmi3Reset,
    Fmi3GetFmuState,
    Fmi3SetFmuState,
    // FMI 1.0 (its names carry the modelIdentifier as a prefix).
    Fmi1InstantiateModel,
    Fmi1InstantiateSlave,
    Fmi1Initialize,
    Fmi1InitializeSlave,
    Fmi1DoStep,
    Fmi1GetRealStatus,
    Fmi1EventUpdate,
    Fmi1CompletedIntegratorStep,
    Fmi1SetTime,
    Fmi1SetContinuousStates,
    Fmi1GetDerivatives,
    Fmi1GetEventIndicators,
    Fmi1GetContinuousStates,
    Fmi1Set,
    Fmi1Get,
    Fmi1Terminate,
    Fmi1TerminateSlave,
    Fmi1FreeModelInstance,
    Fmi1FreeSlaveInstance,
    Fmi1ResetSlave,
}

const ALL: [Call; 78] = [
    Call::None,
    Call::Load,
    Call::Instantiate,
    Call::SetupExperiment,
    Call::SetReal,
    Call::SetInteger,
    Call::SetBoolean,
    Call::SetString,
    Call::EnterInitializationMode,
    Call::ExitInitializationMode,
    Call::GetReal,
    Call::GetInteger,
    Call::GetBoolean,
    Call::DoStep,
    Call::GetBooleanStatus,
    Call::GetRealStatus,
    Call::Terminate,
    Call::FreeInstance,
    Call::EnterEventMode,
    Call::NewDiscreteStates,
    Call::EnterContinuousTimeMode,
    Call::CompletedIntegratorStep,
    Call::SetTime,
    Call::SetContinuousStates,
    Call::GetDerivatives,
    Call::GetEventIndicators,
    Call::GetContinuousStates,
    Call::Fmi3Instantiate,
    Call::Fmi3EnterConfigurationMode,
    Call::Fmi3ExitConfigurationMode,
    Call::Fmi3Set,
    Call::Fmi3EnterInitializationMode,
    Call::Fmi3ExitInitializationMode,
    Call::Fmi3Get,
    Call::Fmi3DoStep,
    Call::Fmi3EnterEventMode,
    Call::Fmi3UpdateDiscreteStates,
    Call::Fmi3EnterStepMode,
    Call::Fmi3Terminate,
    Call::Fmi3FreeInstance,
    Call::Fmi3InstantiateModelExchange,
    Call::Fmi3EnterContinuousTimeMode,
    Call::Fmi3CompletedIntegratorStep,
    Call::Fmi3SetTime,
    Call::Fmi3SetContinuousStates,
    Call::Fmi3GetContinuousStateDerivatives,
    Call::Fmi3GetEventIndicators,
    Call::Fmi3GetContinuousStates,
    Call::Fmi3GetNumberOfContinuousStates,
    Call::GetString,
    Call::GetDirectionalDerivative,
    Call::Fmi3GetDirectionalDerivative,
    Call::Reset,
    Call::GetFmuState,
    Call::SetFmuState,
    Call::Fmi3Reset,
    Call::Fmi3GetFmuState,
    Call::Fmi3SetFmuState,
    Call::Fmi1InstantiateModel,
    Call::Fmi1InstantiateSlave,
    Call::Fmi1Initialize,
    Call::Fmi1InitializeSlave,
    Call::Fmi1DoStep,
    Call::Fmi1GetRealStatus,
    Call::Fmi1EventUpdate,
    Call::Fmi1CompletedIntegratorStep,
    Call::Fmi1SetTime,
    Call::Fmi1SetContinuousStates,
    Call::Fmi1GetDerivatives,
    Call::Fmi1GetEventIndicators,
    Call::Fmi1GetContinuousStates,
    Call::Fmi1Set,
    Call::Fmi1Get,
    Call::Fmi1Terminate,
    Call::Fmi1TerminateSlave,
    Call::Fmi1FreeModelInstance,
    Call::Fmi1FreeSlaveInstance,
    Call::Fmi1ResetSlave,
];

impl Call {
    /// The C function's name (`fmi2DoStep`), or what is happening.
    pub fn name(self) -> &'static str {
        match self {
            Call::None => "no FMI call yet",
            Call::Load => "loading the FMU's binary",
            Call::Instantiate => "fmi2Instantiate",
            Call::SetupExperiment => "fmi2SetupExperiment",
            Call::SetReal => "fmi2SetReal",
            Call::SetInteger => "fmi2SetInteger",
            Call::SetBoolean => "fmi2SetBoolean",
            Call::SetString => "fmi2SetString",
            Call::EnterInitializationMode => "fmi2EnterInitializationMode",
            Call::ExitInitializationMode => "fmi2ExitInitializationMode",
            Call::GetReal => "fmi2GetReal",
            Call::GetInteger => "fmi2GetInteger",
            Call::GetBoolean => "fmi2GetBoolean",
            Call::DoStep => "fmi2DoStep",
            Call::GetBooleanStatus => "fmi2GetBooleanStatus",
            Call::GetRealStatus => "fmi2GetRealStatus",
            Call::Terminate => "fmi2Terminate",
            Call::FreeInstance => "fmi2FreeInstance",
            Call::EnterEventMode => "fmi2EnterEventMode",
            Call::NewDiscreteStates => "fmi2NewDiscreteStates",
            Call::EnterContinuousTimeMode => "fmi2EnterContinuousTimeMode",
            Call::CompletedIntegratorStep => "fmi2CompletedIntegratorStep",
            Call::SetTime => "fmi2SetTime",
            Call::SetContinuousStates => "fmi2SetContinuousStates",
            Call::GetDerivatives => "fmi2GetDerivatives",
            Call::GetEventIndicators => "fmi2GetEventIndicators",
            Call::GetContinuousStates => "fmi2GetContinuousStates",
            Call::Fmi3Instantiate => "fmi3InstantiateCoSimulation",
            Call::Fmi3EnterConfigurationMode => "fmi3EnterConfigurationMode",
            Call::Fmi3ExitConfigurationMode => "fmi3ExitConfigurationMode",
            Call::Fmi3Set => "fmi3Set (a value)",
            Call::Fmi3EnterInitializationMode => "fmi3EnterInitializationMode",
            Call::Fmi3ExitInitializationMode => "fmi3ExitInitializationMode",
            Call::Fmi3Get => "fmi3Get (the outputs)",
            Call::Fmi3DoStep => "fmi3DoStep",
            Call::Fmi3EnterEventMode => "fmi3EnterEventMode",
            Call::Fmi3UpdateDiscreteStates => "fmi3UpdateDiscreteStates",
            Call::Fmi3EnterStepMode => "fmi3EnterStepMode",
            Call::Fmi3Terminate => "fmi3Terminate",
            Call::Fmi3FreeInstance => "fmi3FreeInstance",
            Call::Fmi3InstantiateModelExchange => "fmi3InstantiateModelExchange",
            Call::Fmi3EnterContinuousTimeMode => "fmi3EnterContinuousTimeMode",
            Call::Fmi3CompletedIntegratorStep => "fmi3CompletedIntegratorStep",
            Call::Fmi3SetTime => "fmi3SetTime",
            Call::Fmi3SetContinuousStates => "fmi3SetContinuousStates",
            Call::Fmi3GetContinuousStateDerivatives => "fmi3GetContinuousStateDerivatives",
            Call::Fmi3GetEventIndicators => "fmi3GetEventIndicators",
            Call::Fmi3GetContinuousStates => "fmi3GetContinuousStates",
            Call::Fmi3GetNumberOfContinuousStates => "fmi3GetNumberOfContinuousStates (and EventIndicators)",
            Call::GetString => "fmi2GetString",
            Call::GetDirectionalDerivative => "fmi2GetDirectionalDerivative",
            Call::Fmi3GetDirectionalDerivative => "fmi3GetDirectionalDerivative",
            Call::Reset => "fmi2Reset",
            Call::GetFmuState => "fmi2GetFMUstate (and its serialization)",
            Call::SetFmuState => "fmi2SetFMUstate (from a serialized state)",
            Call::Fmi3Reset => "fmi3Reset",
            Call::Fmi3GetFmuState => "fmi3GetFMUState (and its serialization)",
            Call::Fmi3SetFmuState => "fmi3SetFMUState (from a serialized state)",
            Call::Fmi1InstantiateModel => "fmiInstantiateModel",
            Call::Fmi1InstantiateSlave => "fmiInstantiateSlave",
            Call::Fmi1Initialize => "fmiInitialize",
            Call::Fmi1InitializeSlave => "fmiInitializeSlave",
            Call::Fmi1DoStep => "fmiDoStep",
            Call::Fmi1GetRealStatus => "fmiGetRealStatus",
            Call::Fmi1EventUpdate => "fmiEventUpdate",
            Call::Fmi1CompletedIntegratorStep => "fmiCompletedIntegratorStep",
            Call::Fmi1SetTime => "fmiSetTime",
            Call::Fmi1SetContinuousStates => "fmiSetContinuousStates",
            Call::Fmi1GetDerivatives => "fmiGetDerivatives",
            Call::Fmi1GetEventIndicators => "fmiGetEventIndicators",
            Call::Fmi1GetContinuousStates => "fmiGetContinuousStates",
            Call::Fmi1Set => "fmiSetReal/Integer/Boolean/String",
            Call::Fmi1Get => "fmiGetReal/Integer/Boolean/String",
            Call::Fmi1Terminate => "fmiTerminate",
            Call::Fmi1TerminateSlave => "fmiTerminateSlave",
            Call::Fmi1FreeModelInstance => "fmiFreeModelInstance",
            Call::Fmi1FreeSlaveInstance => "fmiFreeSlaveInstance",
            Call::Fmi1ResetSlave => "fmiResetSlave",
        }
    }

    /// The call of code `code` (as stored in a [`CallSlot`]).
    pub fn from_code(code: u32) -> Option<Call> {
        ALL.get(code as usize).copied()
    }
}

/// The last call entered and the model time then (f64 bits; NaN before the time is known), and
/// the part of a larger run those calls were for ([`set_context`]: a system's component).
#[repr(C)]
pub struct CallSlot {
    pub call: AtomicU32,
    pub time: AtomicU64,
    pub context: AtomicU32,
}

impl CallSlot {
    /// The call and time recorded last (`None` for the time while it is unknown).
    pub fn read(&self) -> (Call, Option<f64>) {
        let call = Call::from_code(self.call.load(Ordering::Relaxed)).unwrap_or(Call::None);
        let time = f64::from_bits(self.time.load(Ordering::Relaxed));
        (call, Some(time).filter(|t| t.is_finite()))
    }

    /// The context recorded last (0: none).
    pub fn context(&self) -> u32 {
        self.context.load(Ordering::Relaxed)
    }

    /// Forgets the last call and context (a new run starts).
    pub fn clear(&self) {
        self.call.store(Call::None as u32, Ordering::Relaxed);
        self.time.store(f64::NAN.to_bits(), Ordering::Relaxed);
        self.context.store(0, Ordering::Relaxed);
    }
}

static SLOT: AtomicPtr<CallSlot> = AtomicPtr::new(std::ptr::null_mut());

/// Records every later FMI call of this process in `slot`.
pub fn set_slot(slot: &'static CallSlot) {
    SLOT.store(slot as *const CallSlot as *mut CallSlot, Ordering::Release);
}

/// Notes that `call` starts at model time `time` (NaN if none).
#[inline]
pub(crate) fn enter(call: Call, time: f64) {
    let slot = SLOT.load(Ordering::Relaxed);
    if !slot.is_null() {
        // SAFETY: set_slot only takes slots that live for the rest of the process.
        let slot = unsafe { &*slot };
        slot.call.store(call as u32, Ordering::Relaxed);
        slot.time.store(time.to_bits(), Ordering::Relaxed);
    }
}

/// Notes that the calls from now on are made for part `context` of a larger run, which only
/// its caller can name: a system's master sets its component's index plus one before it drives
/// that component, so a worker that dies in an FMI call is reported with the component (0: no
/// part). Without a slot it costs what `enter` does, a load and a test: on quarter_car_road
/// (two components, six calls a step) 45 instructions a step, 1.3 % of the FMUs' own step.
#[inline]
pub fn set_context(context: u32) {
    let slot = SLOT.load(Ordering::Relaxed);
    if !slot.is_null() {
        // SAFETY: set_slot only takes slots that live for the rest of the process.
        unsafe { &*slot }.context.store(context, Ordering::Relaxed);
    }
}

/// Set when a call of any FMU in this process returned fmiFatal.
static FATAL: AtomicBool = AtomicBool::new(false);

/// Notes that a call returned fmiFatal: the standard then trusts no instance of the FMU in this
/// process ("the model computations are irreparably corrupted for all FMU instances").
#[cold]
pub(crate) fn note_fatal() {
    FATAL.store(true, Ordering::Relaxed);
}

/// True once any FMU call of this process returned fmiFatal: a worker process then runs no
/// more jobs.
pub fn fatal_seen() -> bool {
    FATAL.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_read_back_as_their_call() {
        for (i, call) in ALL.iter().enumerate() {
            assert_eq!(*call as u32, i as u32, "ALL is in code order");
            assert_eq!(Call::from_code(i as u32), Some(*call));
        }
        assert_eq!(Call::from_code(ALL.len() as u32), None);
    }
}
