//! An instance's state saved as bytes and restored, for stepping from outside (`fmurunner`'s
//! `Simulation.get_state()`): the FMU's own serialized state (`fmi2SerializeFMUstate`,
//! `fmi3SerializeFMUState`) with what the runner keeps beside it, the time reached and, for
//! Model Exchange, the next time event. The bytes name the FMU (its GUID or instantiation token,
//! and its model name) and the interface, so a state is never handed to an instance it was not
//! taken from. `runner simulate --final-fmu-state-file` writes these bytes to a file, and
//! `--initial-fmu-state-file` reads them back.

use crate::model::Interface;

/// The first bytes of a saved state: a file type and its version (2: with the model name).
const MAGIC: &[u8; 10] = b"FMURSTATE\x02";

/// The FMU a state belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Identity<'a> {
    /// Its GUID (FMI 2.0) or instantiation token (FMI 3.0).
    pub token: &'a str,
    /// Its modelName.
    pub model_name: &'a str,
    /// The interface the state was taken through.
    pub interface: Interface,
}

impl Identity<'_> {
    /// The FMU of `description` run through `interface`.
    pub fn of(description: &crate::Description, interface: Interface) -> Identity<'_> {
        Identity { token: &description.instantiation_token, model_name: &description.model_name, interface }
    }
}

/// Largest FMU state the importer takes (a corrupt size must not allocate gigabytes).
pub const MAX_STATE_BYTES: usize = 1 << 30;

/// An instance's state as the importer saves it.
#[derive(Debug, Clone, PartialEq)]
pub struct SavedState {
    /// The time the instance had reached.
    pub time: f64,
    /// Model Exchange: the next time event the FMU announced, if any.
    pub next_event_time: Option<f64>,
    /// The FMU's own serialized state.
    pub fmu: Vec<u8>,
}

impl SavedState {
    /// The state as bytes, naming the FMU it was taken from.
    pub fn to_bytes(&self, identity: Identity) -> Vec<u8> {
        let (token, name) = (identity.token.as_bytes(), identity.model_name.as_bytes());
        let mut out = Vec::with_capacity(MAGIC.len() + 41 + token.len() + name.len() + self.fmu.len());
        out.extend_from_slice(MAGIC);
        out.push(interface_code(identity.interface));
        for text in [token, name] {
            out.extend_from_slice(&(text.len() as u64).to_le_bytes());
            out.extend_from_slice(text);
        }
        out.extend_from_slice(&self.time.to_le_bytes());
        out.extend_from_slice(&self.next_event_time.unwrap_or(f64::NAN).to_le_bytes());
        out.extend_from_slice(&(self.fmu.len() as u64).to_le_bytes());
        out.extend_from_slice(&self.fmu);
        out
    }

    /// Reads bytes of [`SavedState::to_bytes`], checking that they are a state of the FMU
    /// `identity` (the same GUID or instantiation token and model name, through the same
    /// interface).
    pub fn from_bytes(bytes: &[u8], identity: Identity) -> Result<SavedState, String> {
        let mut rest = bytes;
        let mut take = |n: usize, what: &str| -> Result<&[u8], String> {
            if rest.len() < n {
                return Err(format!("not a saved state: the bytes end before its {what}"));
            }
            let (head, tail) = rest.split_at(n);
            rest = tail;
            Ok(head)
        };
        let u64_at = |b: &[u8]| u64::from_le_bytes(b.try_into().expect("8 bytes"));
        let f64_at = |b: &[u8]| f64::from_le_bytes(b.try_into().expect("8 bytes"));
        let magic = take(MAGIC.len(), "header")?;
        if magic[..MAGIC.len() - 1] == MAGIC[..MAGIC.len() - 1] && magic != MAGIC {
            return Err(format!(
                "a saved state of format {}, which this runner does not read (it reads {}): save it again",
                magic[MAGIC.len() - 1],
                MAGIC[MAGIC.len() - 1]
            ));
        }
        if magic != MAGIC {
            return Err("not a saved state (get_state() and --final-fmu-state-file write one)".to_owned());
        }
        let saved_interface = take(1, "interface")?[0];
        let mut text = |what: &str| -> Result<String, String> {
            let len = usize::try_from(u64_at(take(8, &format!("{what}'s length"))?)).unwrap_or(usize::MAX);
            if len > bytes.len() {
                return Err(format!("not a saved state: its {what}'s length is past its end"));
            }
            Ok(String::from_utf8_lossy(take(len, what)?).into_owned())
        };
        let saved_token = text("GUID")?;
        let saved_name = text("model name")?;
        if saved_token != identity.token || saved_name != identity.model_name {
            return Err(format!(
                "the state was saved from another FMU: model {saved_name:?} with GUID or instantiation token {saved_token:?}, not model {:?} with {:?}",
                identity.model_name, identity.token
            ));
        }
        if saved_interface != interface_code(identity.interface) {
            return Err(format!(
                "the state was saved from this FMU run as {}, not as {}",
                interface_name(saved_interface),
                identity.interface
            ));
        }
        let time = f64_at(take(8, "time")?);
        let next = f64_at(take(8, "next time event")?);
        let fmu_len = usize::try_from(u64_at(take(8, "FMU state's length")?)).unwrap_or(usize::MAX);
        if fmu_len > MAX_STATE_BYTES {
            return Err(format!("not a saved state: an FMU state of {fmu_len} bytes"));
        }
        let fmu = take(fmu_len, "FMU state")?.to_vec();
        if !rest.is_empty() {
            return Err(format!("not a saved state: {} bytes follow its end", rest.len()));
        }
        if !time.is_finite() {
            return Err(format!("not a saved state: its time is {time}"));
        }
        Ok(SavedState { time, next_event_time: Some(next).filter(|t| !t.is_nan()), fmu })
    }
}

fn interface_code(interface: Interface) -> u8 {
    match interface {
        Interface::CoSimulation => 1,
        Interface::ModelExchange => 2,
    }
}

fn interface_name(code: u8) -> String {
    match code {
        1 => Interface::CoSimulation.to_string(),
        2 => Interface::ModelExchange.to_string(),
        _ => format!("interface {code}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What to_bytes writes, from_bytes reads back bit for bit; a state of another FMU, of the
    /// other interface, or cut short is refused with the reason.
    #[test]
    fn a_state_reads_back_and_names_its_fmu() {
        let me = Identity { token: "{guid}", model_name: "m", interface: Interface::ModelExchange };
        let state = SavedState { time: 0.1 + 0.2, next_event_time: Some(1.5), fmu: vec![1, 2, 3, 0, 255] };
        let bytes = state.to_bytes(me);
        assert_eq!(SavedState::from_bytes(&bytes, me).unwrap(), state);
        let cs = Identity { token: "g", model_name: "m", interface: Interface::CoSimulation };
        let none = SavedState { next_event_time: None, ..state.clone() };
        assert_eq!(SavedState::from_bytes(&none.to_bytes(cs), cs).unwrap(), none);
        let other = SavedState::from_bytes(&bytes, Identity { token: "{other}", ..me }).unwrap_err();
        assert!(other.contains("another FMU") && other.contains("{guid}"), "{other}");
        let renamed = SavedState::from_bytes(&bytes, Identity { model_name: "n", ..me }).unwrap_err();
        assert!(renamed.contains("model \"m\"") && renamed.contains("not model \"n\""), "{renamed}");
        let interface = SavedState::from_bytes(&bytes, Identity { interface: Interface::CoSimulation, ..me }).unwrap_err();
        assert!(interface.contains("ModelExchange") || interface.contains("Model Exchange"), "{interface}");
        let cut = SavedState::from_bytes(&bytes[..bytes.len() - 1], me).unwrap_err();
        assert!(cut.contains("end before its FMU state"), "{cut}");
        assert!(SavedState::from_bytes(b"hello", cs).unwrap_err().contains("not a saved state"));
        let mut old = bytes.clone();
        old[MAGIC.len() - 1] = 1;
        assert!(SavedState::from_bytes(&old, me).unwrap_err().contains("format 1"));
        let mut long = bytes.clone();
        long.push(0);
        assert!(SavedState::from_bytes(&long, me).unwrap_err().contains("1 bytes follow"));
    }
}
