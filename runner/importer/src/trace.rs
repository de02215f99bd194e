//! Which FMI call the importer is in, and at what model time, for a supervisor that must say
//! where an FMU crashed or hung. The runner's worker processes point [`set_slot`] at memory they
//! share with their parent, which reads it after the worker died or was killed. Without a slot
//! (in-process runs) each call costs one load of a pointer that nobody writes.

use std::sync::atomic::{AtomicPtr, AtomicU32, AtomicU64, Ordering};

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
}

const ALL: [Call; 18] = [
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
        }
    }

    /// The call of code `code` (as stored in a [`CallSlot`]).
    pub fn from_code(code: u32) -> Option<Call> {
        ALL.get(code as usize).copied()
    }
}

/// The last call entered and the model time then (f64 bits; NaN before the time is known).
#[repr(C)]
pub struct CallSlot {
    pub call: AtomicU32,
    pub time: AtomicU64,
}

impl CallSlot {
    /// The call and time recorded last (`None` for the time while it is unknown).
    pub fn read(&self) -> (Call, Option<f64>) {
        let call = Call::from_code(self.call.load(Ordering::Relaxed)).unwrap_or(Call::None);
        let time = f64::from_bits(self.time.load(Ordering::Relaxed));
        (call, Some(time).filter(|t| t.is_finite()))
    }

    /// Forgets the last call (a new run starts).
    pub fn clear(&self) {
        self.call.store(Call::None as u32, Ordering::Relaxed);
        self.time.store(f64::NAN.to_bits(), Ordering::Relaxed);
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
