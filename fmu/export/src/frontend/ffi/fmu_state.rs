//! FMU states: what the importer's FMU-state pointer points at, and the six calls that take,
//! restore, free and (de)serialize it.

use std::ffi::{c_int, c_void};

use super::{ok, slice, slice_mut, with_instance};
use crate::core::{snapshot, CallResult, Failure, State};
use crate::frontend::{Call, Version};
use crate::logging::Status;
use crate::model::Model;

/// What an FMU-state pointer points at: the tag of the model's states in this version (a
/// state of the other version, or of another model, is refused instead of misread), then the
/// core's state and the state machine's.
// repr(C): the tag first, as in `Component`.
#[repr(C)]
pub struct StateBox<V: Version, M: Model> {
    pub(super) magic: u64,
    saved: (State<M>, V::Saved),
}

/// The FMU state box `state` points at, when it is one of this model's in this version.
unsafe fn state_box<'a, V: Version, M: Model>(state: *mut c_void, call: Call) -> CallResult<&'a mut StateBox<V, M>> {
    let b = state as *mut StateBox<V, M>;
    if b.is_null() {
        return Err(Failure::error(format!("{}: the FMU state is NULL", V::name(call))));
    }
    if (*b).magic != V::state_tag::<M>() {
        return Err(Failure::error(format!(
            "{}: the FMU state was not made by this model's {}, or was already freed",
            V::name(call),
            V::name(Call::GetFMUState)
        )));
    }
    Ok(&mut *b)
}

/// Stores `saved` in a new box (`*state` NULL) or in the one `*state` points at.
unsafe fn store_state<V: Version, M: Model>(state: *mut *mut c_void, saved: (State<M>, V::Saved), call: Call) -> CallResult<Status> {
    if (*state).is_null() {
        *state = Box::into_raw(Box::new(StateBox::<V, M> { magic: V::state_tag::<M>(), saved })) as *mut c_void;
    } else {
        state_box::<V, M>(*state, call)?.saved = saved;
    }
    Ok(Status::Ok)
}

/// Refuses a NULL pointer where the FMU state is to be stored.
unsafe fn state_pointer<V: Version>(state: *mut *mut c_void, call: Call) -> CallResult {
    if state.is_null() {
        return Err(Failure::error(format!("{}: the {} pointer is NULL", V::name(call), V::WORDS.fmu_state)));
    }
    Ok(())
}

/// `GetFMUState`: a new state, or the one `*state` points at overwritten.
pub unsafe fn get_fmu_state<V: Version, M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    let call = Call::GetFMUState;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        state_pointer::<V>(state, call)?;
        let saved = inst.get_fmu_state()?;
        store_state::<V, M>(state, saved, call)
    })
}

/// `SetFMUState`.
pub unsafe fn set_fmu_state<V: Version, M: Model>(c: *mut c_void, state: *mut c_void) -> c_int {
    let call = Call::SetFMUState;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        let b = state_box::<V, M>(state, call)?;
        ok(inst.set_fmu_state(&b.saved))
    })
}

/// `FreeFMUState`: frees and sets `*state` to NULL (a NULL state is a no-op).
pub unsafe fn free_fmu_state<V: Version, M: Model>(c: *mut c_void, state: *mut *mut c_void) -> c_int {
    let call = Call::FreeFMUState;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        if state.is_null() || (*state).is_null() {
            return Ok(Status::Ok);
        }
        let b = state_box::<V, M>(*state, call)?;
        b.magic = 0;
        drop(Box::from_raw(b as *mut StateBox<V, M>));
        *state = std::ptr::null_mut();
        Ok(Status::Ok)
    })
}

/// The bytes of a boxed state, tagged with the model's tag in this version.
fn encode<V: Version, M: Model>(b: &StateBox<V, M>) -> CallResult<Vec<u8>> {
    snapshot::encode(&b.saved.0, &b.saved.1, V::state_tag::<M>()).map_err(Failure::error)
}

/// `SerializedFMUStateSize`.
pub unsafe fn serialized_fmu_state_size<V: Version, M: Model>(c: *mut c_void, state: *mut c_void, size: *mut usize) -> c_int {
    let call = Call::SerializedFMUStateSize;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        if size.is_null() {
            return Err(Failure::error(format!("{}: size is NULL", V::name(call))));
        }
        *size = encode(state_box::<V, M>(state, call)?)?.len();
        Ok(Status::Ok)
    })
}

/// `SerializeFMUState`: `size` must be what `SerializedFMUStateSize` returned.
pub unsafe fn serialize_fmu_state<V: Version, M: Model>(c: *mut c_void, state: *mut c_void, buffer: *mut u8, size: usize) -> c_int {
    let call = Call::SerializeFMUState;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        let bytes = encode(state_box::<V, M>(state, call)?)?;
        if size != bytes.len() {
            return Err(Failure::error(format!(
                "{}: the buffer has {size} bytes but the state needs {} (ask {})",
                V::name(call),
                bytes.len(),
                V::name(Call::SerializedFMUStateSize)
            )));
        }
        let out = slice_mut(buffer, size, V::name(call), "serializedState[]")?;
        out.copy_from_slice(&bytes);
        Ok(Status::Ok)
    })
}

/// `DeserializeFMUState`: refuses buffers of the wrong size, model, version or checksum.
pub unsafe fn deserialize_fmu_state<V: Version, M: Model>(
    c: *mut c_void,
    buffer: *const u8,
    size: usize,
    state: *mut *mut c_void,
) -> c_int {
    let call = Call::DeserializeFMUState;
    with_instance::<V, M>(c, call, |inst| {
        inst.check(call)?;
        state_pointer::<V>(state, call)?;
        let bytes = slice(buffer, size, V::name(call), "serializedState[]")?;
        let saved =
            snapshot::decode::<M, V::Saved>(bytes, V::state_tag::<M>()).map_err(|e| Failure::error(format!("{}: {e}", V::name(call))))?;
        store_state::<V, M>(state, saved, call)
    })
}
