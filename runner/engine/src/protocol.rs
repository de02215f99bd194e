//! The messages between the runner and its worker processes: length-prefixed postcard frames
//! on a pipe each way. Both ends are the same binary, so the encoding needs no versioning; every
//! option a run takes travels as a field of these types (a new option is a new field, and the
//! worker rebuilds the same run from it).

use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use fmi_importer::{Description, Fmu, Interface, Value, Variable};
use serde::{de::DeserializeOwned, Deserialize, Serialize};

use crate::input::InputTable;
use crate::run::{Grid, Recording};
use crate::sweep::{PointResult, SweepSpec};

/// Largest frame accepted: far above any real message, it stops a corrupt length from
/// allocating gigabytes.
const MAX_FRAME: usize = 256 << 20;

/// Where the FMU comes from and how it is loaded: the one place both processes load it, so an
/// option of loading added here reaches the workers too.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FmuSource {
    /// The `.fmu` file.
    pub path: PathBuf,
    /// Where the supervisor unpacked it, for its workers to load from (it deletes it).
    pub unpacked: Option<PathBuf>,
    /// The interface to drive it through (`None`: Co-Simulation when it offers that).
    pub interface: Option<Interface>,
}

impl FmuSource {
    /// The FMU at `path`, through `interface`.
    pub fn new(path: &Path, interface: Option<Interface>) -> FmuSource {
        FmuSource { path: path.to_path_buf(), unpacked: None, interface }
    }

    /// Loads the FMU (running its binary's initializers): from the supervisor's copy when there is
    /// one, else unpacking it.
    pub fn load(&self) -> Result<Fmu, String> {
        match &self.unpacked {
            Some(dir) => Fmu::load_unpacked(&self.path, dir, self.interface),
            None => Fmu::load_as(&self.path, self.interface),
        }
    }

    /// Unpacks the FMU and reads its description without loading its binary (what a supervisor
    /// needs, so an FMU's initializers never run in it); returns the source its workers load,
    /// from that copy.
    pub fn open(&self) -> Result<(fmi_importer::Unpacked, FmuSource), String> {
        let unpacked = fmi_importer::Unpacked::open_as(&self.path, self.interface)?;
        let for_workers = FmuSource { unpacked: Some(unpacked.dir.path().to_path_buf()), ..self.clone() };
        Ok((unpacked, for_workers))
    }
}

/// A value as sent to a worker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum WireValue {
    Real(f64),
    Integer(i32),
    Int(i128),
    Boolean(bool),
    String(String),
    Binary(Vec<u8>),
    List(Vec<WireValue>),
}

impl From<&Value> for WireValue {
    fn from(v: &Value) -> WireValue {
        match v {
            Value::Real(x) => WireValue::Real(*x),
            Value::Integer(x) => WireValue::Integer(*x),
            Value::Int(x) => WireValue::Int(*x),
            Value::Boolean(x) => WireValue::Boolean(*x),
            Value::String(x) => WireValue::String(x.clone()),
            Value::Binary(x) => WireValue::Binary(x.clone()),
            Value::List(x) => WireValue::List(x.iter().map(WireValue::from).collect()),
        }
    }
}

impl From<WireValue> for Value {
    fn from(v: WireValue) -> Value {
        match v {
            WireValue::Real(x) => Value::Real(x),
            WireValue::Integer(x) => Value::Integer(x),
            WireValue::Int(x) => Value::Int(x),
            WireValue::Boolean(x) => Value::Boolean(x),
            WireValue::String(x) => Value::String(x),
            WireValue::Binary(x) => Value::Binary(x),
            WireValue::List(x) => Value::List(x.into_iter().map(Value::from).collect()),
        }
    }
}

/// One run (simulate, a run of a comparison): the arguments of [`crate::run::run_recording`]
/// by name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunJob {
    /// Instance name.
    pub name: String,
    pub grid: Grid,
    /// Variables set before initialization, in order.
    pub assignments: Vec<(String, WireValue)>,
    /// Variables sampled at every communication point, in order (an array's elements each).
    pub recorded: Vec<String>,
    /// Also sample at each event a step stops at ([`Recording::events`]).
    pub events: bool,
    /// Turns the FMU's debug logging on.
    pub debug_logging: bool,
    /// Inputs set before every step (`--input-file`), checked against the FMU where it runs.
    #[serde(default)]
    pub inputs: Option<InputTable>,
}

impl RunJob {
    /// A job for `assignments` and `recording`, of variables of the FMU being run.
    pub fn new(name: &str, grid: Grid, assignments: &[(&Variable, Value)], recording: &Recording, debug_logging: bool) -> RunJob {
        RunJob {
            name: name.to_owned(),
            grid,
            assignments: assignments.iter().map(|(v, x)| (v.name.clone(), WireValue::from(x))).collect(),
            recorded: recording.variables.iter().map(|v| v.name.clone()).collect(),
            events: recording.events,
            debug_logging,
            inputs: None,
        }
    }

    /// The job with `inputs` set before every step.
    pub fn with_inputs(self, inputs: Option<InputTable>) -> RunJob {
        RunJob { inputs, ..self }
    }

    /// The job's assignments and recording, looked up in `description`: the same on both sides
    /// of the pipe, arrays sized alike.
    #[allow(clippy::type_complexity)]
    pub fn resolve<'a>(&self, description: &'a Description) -> Result<(Vec<(&'a Variable, Value)>, Recording<'a>), String> {
        let find = |name: &str| description.variable(name).ok_or_else(|| format!("the FMU has no variable '{name}'"));
        let assignments: Vec<_> =
            self.assignments.iter().map(|(n, v)| Ok((find(n)?, Value::from(v.clone())))).collect::<Result<_, String>>()?;
        let recorded: Vec<&Variable> = self.recorded.iter().map(|n| find(n)).collect::<Result<_, String>>()?;
        let mut recording = Recording::new(description, &recorded, &assignments)?;
        recording.events = self.events;
        Ok((assignments, recording))
    }
}

/// How a worker's run ended: [`crate::run::Outcome`] on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunEnd {
    pub ended_early: Option<String>,
    pub counters: Option<(u64, u64)>,
}

/// What the runner asks a worker; `Load` comes first.
#[derive(Debug, Serialize, Deserialize)]
pub enum Request {
    /// Load the FMU (once per worker).
    Load(FmuSource),
    /// Prepare this sweep's plan, for the `Point`s that follow. A worker whose resident memory
    /// passes `retire_above` bytes after a point runs no more of them: it answers the `Point`s
    /// already sent with [`Reply::Skipped`] (the runner sends the next point before the last one
    /// ends, so that a worker never waits for it).
    Sweep { spec: SweepSpec, retire_above: Option<u64> },
    /// Run point `.0` of the sweep.
    Point(u64),
    /// Run this and stream its samples.
    Run(RunJob),
    /// Acknowledge, then exit; the worker may outlive the runner from now on.
    Release,
}

/// What a worker answers.
#[derive(Debug, Serialize, Deserialize)]
pub enum Reply {
    /// The `Load` or `Sweep` request succeeded.
    Ready,
    /// The `Load` or `Sweep` request failed; the worker exits.
    Failed(String),
    /// A line for the user (an FMU's log message, a note).
    Log(String),
    /// A sweep point's result, and the worker's resident memory after it (bytes).
    Point { index: u64, result: PointResult, resident: u64 },
    /// Point `.0` was not run: the worker retired (its memory passed `retire_above`).
    Skipped(u64),
    /// Samples of the running job: `t` then the recorded values, repeated; and per sample, in
    /// order, the texts of the columns whose numbers do not give them (`Reader::needs_text`).
    Samples { values: Vec<f64>, texts: Vec<String> },
    /// The run ended, or the error that ended it.
    RunDone { result: Result<RunEnd, String>, resident: u64 },
    /// The `Release` request is taken: the worker exits and no longer dies with the runner.
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
        let weird = [f64::NAN, -0.0, f64::INFINITY, 1e-310, 0.1 + 0.2];
        let result = PointResult { metrics: Some(weird.to_vec()), status: "ok, \"quoted\"\nline".into() };
        let mut pipe = Vec::new();
        send(&mut pipe, &Reply::Point { index: 7, result: result.clone(), resident: 1 << 40 }).unwrap();
        send(&mut pipe, &Reply::Ready).unwrap();
        let mut input = &pipe[..];
        match receive::<Reply>(&mut input).unwrap() {
            Some(Reply::Point { index: 7, result: got, resident }) => {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(got.metrics.as_ref().unwrap()), bits(&weird));
                assert_eq!((got.status, resident), (result.status, 1 << 40));
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(receive::<Reply>(&mut input).unwrap(), Some(Reply::Ready)));
        assert!(receive::<Reply>(&mut input).unwrap().is_none(), "the end of the stream is not an error");
        let mut torn = &pipe[..pipe.len() - 1];
        let _ = receive::<Reply>(&mut torn).unwrap();
        assert!(receive::<Reply>(&mut torn).is_err(), "a frame cut short is an error");
    }
}
