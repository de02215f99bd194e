//! The byte format of serialized FMU states: a header (magic, format version, model tag,
//! payload length, CRC-32) before the postcard encoding of the core's state and the front
//! end's state-machine state, so a buffer of the wrong size, from another model, or corrupted
//! is refused instead of misread.

use serde::de::DeserializeOwned;
use serde::Serialize;

use super::State;
use crate::model::Model;

const MAGIC: &[u8; 4] = b"RFMS";
/// Version 2: the state-machine state is the front end's, after the core's state (version 1
/// had FMI 2.0's inside the core). Version 3: the core's Model Exchange fields and the Model
/// Exchange states of the state machine. Version 4: the solver's state holds its pending step
/// (the step across the communication point, its dense output and the point last handed out)
/// and the new solver settings (`max_step`, the stop time). Version 5: models may hold String
/// parameters (their text is in the model struct's encoding). Version 6: the inputs' polynomials
/// (`fmi2SetRealInputDerivatives`).
const FORMAT_VERSION: u16 = 6;
const HEADER_LEN: usize = 4 + 2 + 8 + 8 + 4;

/// Encodes `state` and the front end's `phase` with a header tying them to the model whose
/// GUID hashes to `model_tag`.
pub fn encode<M: Model, P: Serialize>(state: &State<M>, phase: &P, model_tag: u64) -> Result<Vec<u8>, String> {
    let payload = postcard::to_stdvec(&(state, phase)).map_err(|e| format!("the FMU state could not be serialized: {e}"))?;
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&model_tag.to_le_bytes());
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    Ok(out)
}

/// Decodes a buffer written by [`encode`] for the same model, explaining any refusal.
pub fn decode<M: Model, P: DeserializeOwned>(bytes: &[u8], model_tag: u64) -> Result<(State<M>, P), String> {
    if bytes.len() < HEADER_LEN || &bytes[..4] != MAGIC {
        return Err(format!("the buffer ({} bytes) is not a serialized FMU state of this toolkit", bytes.len()));
    }
    let version = u16::from_le_bytes([bytes[4], bytes[5]]);
    if version != FORMAT_VERSION {
        return Err(format!("the serialized FMU state has format version {version}; this FMU reads version {FORMAT_VERSION}"));
    }
    let tag = u64::from_le_bytes(bytes[6..14].try_into().expect("8 bytes"));
    if tag != model_tag {
        return Err("the serialized FMU state belongs to another model (or another version of this one)".to_owned());
    }
    let len = u64::from_le_bytes(bytes[14..22].try_into().expect("8 bytes"));
    let payload = &bytes[HEADER_LEN..];
    if len != payload.len() as u64 {
        return Err(format!("the serialized FMU state should have {} bytes but {} were given", HEADER_LEN as u64 + len, bytes.len()));
    }
    let crc = u32::from_le_bytes(bytes[22..26].try_into().expect("4 bytes"));
    if crc32fast::hash(payload) != crc {
        return Err("the serialized FMU state is corrupted (checksum mismatch)".to_owned());
    }
    postcard::from_bytes(payload).map_err(|e| format!("the serialized FMU state could not be decoded: {e}"))
}
