//! The messages between a supervisor and its workers: length-prefixed postcard frames on a pipe
//! each way, `Request`s to the worker and `Reply`s back.

use std::io::{Read, Write};

use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};

/// Largest frame accepted: far above any real message, it stops a corrupt length from
/// allocating gigabytes.
const MAX_FRAME: usize = 256 << 20;

/// What a supervisor asks a worker (`S`, `J`: the service's setup and job).
#[derive(Debug, Serialize, Deserialize)]
pub(crate) enum Request<S, J> {
    /// Prepare for the jobs that follow (answered [`Reply::Ready`] or [`Reply::Failed`]). A
    /// worker whose resident memory passes `retire_above` bytes after a job runs no more of
    /// them: it answers the jobs already sent with [`Reply::Skipped`] (a batch sends the next
    /// job before the last one ends, so that a worker never waits for it).
    Setup { setup: S, retire_above: Option<u64> },
    /// Run job `id`.
    Job { id: u64, job: J },
    /// Acknowledge, then exit; the worker may outlive the supervisor from now on.
    Release,
}

/// What a worker answers (`M`, `O`: the service's message and outcome).
#[derive(Debug, Serialize, Deserialize)]
pub(crate) enum Reply<M, O> {
    /// A line for the user (an FMU's log message). First, so that its encoding is the same
    /// whatever `M` and `O` are: a worker's log printer sends it without knowing them.
    Log(String),
    /// The setup succeeded.
    Ready,
    /// The setup failed; the worker exits.
    Failed(String),
    /// A message of the running job.
    Message(M),
    /// Job `id` ended with `outcome`; the worker's resident memory after it (bytes), and
    /// `tainted` when its process must run no more jobs (an FMU returned fmiFatal, after which
    /// the standard trusts no instance of it in this process).
    Done { id: u64, outcome: O, resident: u64, tainted: bool },
    /// Job `.0` was not run: the worker retired (memory, or tainted).
    Skipped(u64),
    /// The `Release` request is taken: the worker exits and no longer dies with the supervisor.
    Released,
}

/// Writes one frame.
pub fn send<T: Serialize>(out: &mut impl Write, message: &T) -> std::io::Result<()> {
    let bytes = postcard::to_stdvec(message).map_err(std::io::Error::other)?;
    let mut frame = Vec::with_capacity(4 + bytes.len());
    frame.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
    frame.extend_from_slice(&bytes);
    out.write_all(&frame)?;
    out.flush()
}

/// Reads one frame; `Ok(None)` at a clean end of the stream.
pub fn receive<T: DeserializeOwned>(input: &mut impl Read) -> std::io::Result<Option<T>> {
    let mut length = [0u8; 4];
    match input.read_exact(&mut length) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(e),
    }
    let length = u32::from_le_bytes(length) as usize;
    if length > MAX_FRAME {
        return Err(std::io::Error::other(format!("a message of {length} bytes is too long")));
    }
    let mut bytes = vec![0u8; length];
    input.read_exact(&mut bytes)?;
    postcard::from_bytes(&bytes).map(Some).map_err(std::io::Error::other)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_carry_floats_bit_for_bit_and_end_cleanly() {
        let weird = vec![f64::NAN, -0.0, f64::INFINITY, 1e-310, 0.1 + 0.2];
        let mut pipe = Vec::new();
        send(&mut pipe, &Reply::<(), Vec<f64>>::Done { id: 7, outcome: weird.clone(), resident: 1 << 40, tainted: true }).unwrap();
        send(&mut pipe, &Reply::<(), Vec<f64>>::Ready).unwrap();
        let mut input = &pipe[..];
        match receive::<Reply<(), Vec<f64>>>(&mut input).unwrap() {
            Some(Reply::Done { id: 7, outcome, resident, tainted: true }) => {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&outcome), bits(&weird));
                assert_eq!(resident, 1 << 40);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(receive::<Reply<(), Vec<f64>>>(&mut input).unwrap(), Some(Reply::Ready)));
        assert!(receive::<Reply<(), Vec<f64>>>(&mut input).unwrap().is_none(), "the end of the stream is not an error");
        let mut torn = &pipe[..pipe.len() - 1];
        let _ = receive::<Reply<(), Vec<f64>>>(&mut torn).unwrap();
        assert!(receive::<Reply<(), Vec<f64>>>(&mut torn).is_err(), "a frame cut short is an error");
    }

    /// A worker's log printer sends `Reply::<(), ()>::Log`; its supervisor reads it as the
    /// service's own replies.
    #[test]
    fn a_log_line_reads_the_same_whatever_the_service() {
        let mut pipe = Vec::new();
        send(&mut pipe, &Reply::<(), ()>::Log("[m] warning (logStatusWarning): é".into())).unwrap();
        match receive::<Reply<Vec<String>, (u8, f64)>>(&mut &pipe[..]).unwrap() {
            Some(Reply::Log(line)) => assert_eq!(line, "[m] warning (logStatusWarning): é"),
            other => panic!("{other:?}"),
        }
    }
}
