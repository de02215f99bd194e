//! `fmurunner._engine.Stepper`: the engine's stepping ([`runner_engine::stepping`]) for Python,
//! in this process or in a worker process; `fmurunner.Simulation` is its documented face.
//! Values cross as Python objects: floats, ints, bools, strs, bytes, and numpy arrays for
//! arrays and for several numbers read at once.

use std::ffi::c_int;
use std::path::Path;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64};
use std::sync::{Arc, Mutex, MutexGuard, TryLockError};
use std::time::{Duration, Instant};

use fmi_importer::{Description, Interface, Solver, Unpacked};
use numpy::npyffi::{NPY_ARRAY_C_CONTIGUOUS, NPY_ARRAY_OWNDATA, NPY_ARRAY_WRITEABLE, NPY_TYPES};
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyByteArray, PyBytes, PyFloat, PyInt, PyList, PyString, PyTuple};
use runner_engine::isolated;
use runner_engine::request::{FmuSource, WireValue};
use runner_engine::run::SolverOptionNames;
use runner_engine::stepping::{Given, IsolatedStepper, Pacing, Selection, StepSettings, Stepped, ValueKind, Values};
use runner_engine::variables;
use runner_sandbox::WorkerCommand;

use crate::err;

/// How a step ended, as Python sees it. Immutable to Python; the stepper refills the one it
/// returned last when nobody holds it any more (see [`step_result`]), hence atomics.
#[pyclass(frozen, freelist = 8, module = "fmurunner._engine", name = "StepResult")]
pub struct StepResult {
    /// The bits of the time reached.
    time: AtomicU64,
    complete: AtomicBool,
    events: AtomicU32,
}

#[pymethods]
impl StepResult {
    /// The time reached (s).
    #[getter]
    fn time(&self) -> f64 {
        f64::from_bits(self.time.load(Relaxed))
    }

    /// True when the step reached the end asked for; False when the FMU returned early at an
    /// event (FMI 3.0), handled, at ``time``.
    #[getter]
    fn complete(&self) -> bool {
        self.complete.load(Relaxed)
    }

    /// Events handled during the step.
    #[getter]
    fn events(&self) -> u32 {
        self.events.load(Relaxed)
    }

    fn __repr__(&self) -> String {
        let complete = if self.complete() { "True" } else { "False" };
        format!("StepResult(time={:?}, complete={complete}, events={})", self.time(), self.events())
    }
}

impl From<Stepped> for StepResult {
    fn from(s: Stepped) -> StepResult {
        StepResult { time: AtomicU64::new(s.time.to_bits()), complete: AtomicBool::new(s.complete), events: AtomicU32::new(s.events) }
    }
}

/// True when `kept` is the only reference to the object: nobody else holds it.
fn unshared<T>(kept: &Bound<'_, T>) -> bool {
    // SAFETY: a live object's reference count, read with the GIL held.
    unsafe { pyo3::ffi::Py_REFCNT(kept.as_ptr()) == 1 }
}

/// `stepped` for Python: the result returned last (`kept`) refilled when nobody holds it any
/// more, as CPython's `zip` reuses its result tuple, else a new one, kept. A loop that drops each
/// result makes none; a result held keeps its values.
fn step_result<'py>(py: Python<'py>, kept: &mut Option<Py<StepResult>>, stepped: Stepped) -> PyResult<Bound<'py, StepResult>> {
    if let Some(result) = kept {
        let result = result.bind(py);
        if unshared(result) {
            let r = result.get();
            r.time.store(stepped.time.to_bits(), Relaxed);
            r.complete.store(stepped.complete, Relaxed);
            r.events.store(stepped.events, Relaxed);
            return Ok(result.clone());
        }
    }
    let result = Bound::new(py, StepResult::from(stepped))?;
    *kept = Some(result.clone().unbind());
    Ok(result)
}

/// `numbers` as a float64 array: the array returned last for this selection (`kept`) refilled
/// when nobody holds it any more and it is still what it was made as (one dimension of
/// `numbers.len()`, float64, contiguous, writeable, its own data), as [`step_result`] does; else
/// a new one, kept.
fn numbers_array<'py>(py: Python<'py>, kept: &mut Option<Py<PyArray1<f64>>>, numbers: &[f64]) -> Bound<'py, PyArray1<f64>> {
    if let Some(array) = kept {
        let array = array.bind(py);
        if unshared(array) {
            // SAFETY: the array object is alive (held by `kept`); its fields are read as numpy lays them out.
            let (flags, double) = unsafe {
                let raw = &*array.as_array_ptr();
                (raw.fields.flags, (*raw.fields.descr).fields.type_num == NPY_TYPES::NPY_DOUBLE as c_int)
            };
            let own = NPY_ARRAY_OWNDATA | NPY_ARRAY_WRITEABLE | NPY_ARRAY_C_CONTIGUOUS;
            if double && flags & own == own && array.ndim() == 1 && array.len() == numbers.len() {
                // SAFETY: nothing else refers to the array (its only reference is `kept`), so no
                // view or borrow of its data exists; it is contiguous float64 of this length.
                if let Ok(data) = unsafe { array.as_slice_mut() } {
                    data.copy_from_slice(numbers);
                    return array.clone();
                }
            }
        }
    }
    let array = PyArray1::from_slice(py, numbers);
    *kept = Some(array.clone().unbind());
    array
}

/// The variables read last in this process: a loop reads the same names again and again.
struct LastRead {
    /// The str objects of the names as they were given: the same objects (a loop's literals, a
    /// list made once) are recognized by identity, without comparing text.
    given: Vec<Py<PyString>>,
    selection: Selection,
    /// The array a numeric selection was last returned in.
    array: Option<Py<PyArray1<f64>>>,
}

/// Steps in this process quicker than this run without releasing the GIL: releasing and taking
/// it back costs about as much as such a step, and other threads wait far less than Python's own
/// switch interval (5 ms).
const QUICK_STEP: Duration = Duration::from_micros(50);

/// One step in this many is timed while steps are quick (reading the clock twice costs a fifth
/// of what a step adds to the FMU's own work): steps that turn slow hold the GIL for at most this
/// many of them.
const TIMED_EVERY: u8 = 8;

/// Whether steps in this process keep the GIL.
#[derive(Default)]
struct Quickness {
    /// The last step timed was quicker than [`QUICK_STEP`].
    quick: bool,
    /// Steps still to run untimed (holding the GIL) before the next is timed.
    untimed: u8,
}

/// Where the instance lives.
enum Backend {
    /// In this process.
    Local {
        stepper: Box<runner_engine::stepping::Stepper>,
        last: Option<LastRead>,
        /// Whether its steps keep the GIL.
        quick: Quickness,
        /// The result of the last step.
        result: Option<Py<StepResult>>,
    },
    /// In a worker process; the unpacked FMU it loads is kept here (deleted with it).
    Isolated {
        stepper: IsolatedStepper,
        _unpacked: Box<Unpacked>,
        description: Box<Description>,
    },
    Closed,
}

/// A stepped simulation: `fmurunner.Simulation` is its subclass, whose stepping calls are these
/// methods themselves (no Python function in between). Their docstrings are the ones users read.
#[pyclass(frozen, subclass, module = "fmurunner._engine")]
pub struct Stepper {
    backend: Mutex<Backend>,
}

/// The integrator's options as `simulate`, `sweep` and `Simulation` spell them.
const OPTION_NAMES: SolverOptionNames = SolverOptionNames {
    fixed_step: "fixed_step=",
    abs_tolerance: "abs_tolerance=",
    all: "the solver options (solver=, fixed_step=, abs_tolerance=)",
    to_model_exchange: "give interface='model-exchange'",
};

/// The runner's integrator from the options `solver`, `fixed_step` and `abs_tolerance` of
/// `simulate`, `sweep` and `Simulation`, checked by the engine and refused by their names.
pub(crate) fn solver_of(name: Option<&str>, fixed_step: Option<f64>, abs_tolerance: Option<f64>) -> PyResult<Solver> {
    runner_engine::run::solver_of(name, fixed_step, abs_tolerance, OPTION_NAMES).map_err(err)
}

pub(crate) fn interface_of(name: Option<&str>) -> PyResult<Option<Interface>> {
    name.map(|n| {
        let spelled = n.replace('_', "-").to_ascii_lowercase();
        Interface::from_name(&spelled).ok_or_else(|| err(format!("'{n}' is not an interface: use 'co-simulation' or 'model-exchange'")))
    })
    .transpose()
}

/// `NAME=VALUE` texts as the start values of a stepper over `description`.
fn start_values(description: &Description, sets: &[String]) -> PyResult<Vec<(String, WireValue)>> {
    let parsed = variables::parse_sets(description, sets).map_err(err)?;
    Ok(parsed.iter().map(|(v, x)| (v.name.clone(), WireValue::from(x))).collect())
}

/// A Python value as a [`Given`]; a numpy scalar or array as the Python value or list its
/// `tolist()` gives.
fn given(value: &Bound<'_, PyAny>) -> PyResult<Given> {
    if value.is_instance_of::<PyBool>() {
        return Ok(Given::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyInt>() {
        return value.extract::<i128>().map(Given::Integer).map_err(|_| err(format!("{value} is too large an integer")));
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(Given::Real(value.extract()?));
    }
    if let Ok(text) = value.cast::<PyString>() {
        return Ok(Given::Text(text.to_str()?.to_owned()));
    }
    if value.is_instance_of::<PyBytes>() || value.is_instance_of::<PyByteArray>() {
        return Ok(Given::Bytes(value.extract()?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        return value.try_iter()?.map(|item| given(&item?)).collect::<PyResult<Vec<_>>>().map(Given::List);
    }
    let kind = value.get_type();
    if kind.module().is_ok_and(|m| m.to_str().is_ok_and(|m| m == "numpy")) {
        if let Ok(plain) = value.call_method0("tolist") {
            if !plain.is(value) {
                return given(&plain);
            }
        }
    }
    let type_name = kind.name().map(|n| n.to_string()).unwrap_or_else(|_| "?".to_owned());
    Err(err(format!("a value of type {type_name} cannot be set: give a number, a bool, a str (a number with a unit: '120deg'), bytes, or a list for an array")))
}

/// Column `c`'s value as a Python object of `kind`.
fn python_value<'py>(py: Python<'py>, kind: ValueKind, values: &Values, c: usize) -> PyResult<Bound<'py, PyAny>> {
    let text = || values.texts.iter().find(|(k, _)| *k == c).map(|(_, t)| t.as_str());
    let x = values.numbers[c];
    Ok(match kind {
        ValueKind::Float => PyFloat::new(py, x).into_any(),
        ValueKind::Bool => PyBool::new(py, x != 0.0).to_owned().into_any(),
        ValueKind::Int => match text() {
            Some(t) => {
                t.parse::<i128>().map_err(|_| err(format!("the FMU's integer {t:?} does not read as one")))?.into_pyobject(py)?.into_any()
            }
            None => (x as i64).into_pyobject(py)?.into_any(),
        },
        ValueKind::Text => PyString::new(py, text().unwrap_or_default()).into_any(),
        ValueKind::Bytes => {
            let hex = text().unwrap_or_default();
            let bytes = fmi_importer::model::parse_hex(hex).map_err(|_| err(format!("the FMU's binary {hex:?} does not read as bytes")))?;
            PyBytes::new(py, &bytes).into_any()
        }
    })
}

/// The values read for `shapes` as Python receives them: one name gives its value (a numpy
/// array for an array); several give a float64 numpy array when all are numeric scalars (the
/// array in `kept` refilled when it may be, see [`numbers_array`]), else a list of their values.
fn python_values<'py>(
    py: Python<'py>,
    shapes: &[(ValueKind, Option<usize>)],
    values: &Values,
    one: bool,
    kept: &mut Option<Py<PyArray1<f64>>>,
) -> PyResult<Bound<'py, PyAny>> {
    let scalars = shapes.iter().all(|(_, n)| n.is_none());
    let numeric =
        shapes.iter().all(|(k, _)| matches!(k, ValueKind::Float | ValueKind::Bool) || *k == ValueKind::Int) && values.texts.is_empty();
    if !one && scalars && numeric {
        return Ok(numbers_array(py, kept, &values.numbers).into_any());
    }
    let mut items = Vec::with_capacity(shapes.len());
    let mut c = 0;
    for &(kind, size) in shapes {
        match size {
            None => {
                items.push(python_value(py, kind, values, c)?);
                c += 1;
            }
            Some(n) => {
                let column = &values.numbers[c..c + n];
                let has_text = values.texts.iter().any(|(k, _)| (c..c + n).contains(k));
                let item = match kind {
                    ValueKind::Float => PyArray1::from_slice(py, column).into_any(),
                    ValueKind::Bool => PyArray1::from_iter(py, column.iter().map(|&x| x != 0.0)).into_any(),
                    ValueKind::Int if !has_text => PyArray1::from_iter(py, column.iter().map(|&x| x as i64)).into_any(),
                    _ => PyList::new(py, (c..c + n).map(|k| python_value(py, kind, values, k)).collect::<PyResult<Vec<_>>>()?)?.into_any(),
                };
                items.push(item);
                c += n;
            }
        }
    }
    if one {
        return Ok(items.pop().expect("one name"));
    }
    Ok(PyList::new(py, items)?.into_any())
}

impl Stepper {
    fn lock(&self) -> PyResult<MutexGuard<'_, Backend>> {
        match self.backend.try_lock() {
            Ok(guard) => Ok(guard),
            Err(TryLockError::WouldBlock) => {
                Err(err("the simulation is in use by another thread: a Simulation takes one call at a time".to_owned()))
            }
            Err(TryLockError::Poisoned(poisoned)) => Ok(poisoned.into_inner()),
        }
    }

    /// A step or an advance: `local` on an instance in this process, `isolated` on one in a
    /// worker process.
    fn stepping<'py>(
        &self,
        py: Python<'py>,
        local: impl FnOnce(&mut runner_engine::stepping::Stepper) -> Result<Stepped, String> + Send,
        isolated: impl FnOnce(&mut IsolatedStepper) -> Result<Stepped, String> + Send,
    ) -> PyResult<Bound<'py, StepResult>> {
        let mut guard = self.lock()?;
        match &mut *guard {
            Backend::Local { stepper, quick, result, .. } => {
                let stepped = local_step(py, stepper, quick, local).map_err(err)?;
                step_result(py, result, stepped)
            }
            Backend::Isolated { stepper, .. } => Bound::new(py, StepResult::from(py.detach(|| isolated(stepper)).map_err(err)?)),
            Backend::Closed => Err(closed()),
        }
    }
}

fn closed() -> PyErr {
    err("the simulation is closed".to_owned())
}

/// Whether item `given` of a `get` argument is the name `known` that `*object` was given as:
/// the same object, or a str of the same text (which is then kept, to be recognized by identity).
fn same_name(given: &Bound<'_, PyAny>, object: &mut Py<PyString>, known: &str) -> bool {
    if given.as_ptr() == object.as_ptr() {
        return true;
    }
    match given.cast::<PyString>() {
        Ok(name) if name.to_str().is_ok_and(|n| n == known) => {
            *object = name.clone().unbind();
            true
        }
        _ => false,
    }
}

/// Whether a `get` argument names exactly the variables `last` read (and then whether it is one
/// str), looked at without copying: a str, or a list or tuple of strs.
fn same_names<'py>(names: &Bound<'py, PyAny>, last: &mut LastRead) -> Option<bool> {
    let LastRead { given, selection, .. } = last;
    let known = &selection.names;
    if names.is_instance_of::<PyString>() {
        return (known.len() == 1 && same_name(names, &mut given[0], &known[0])).then_some(true);
    }
    let same = |len: usize, item: &dyn Fn(usize) -> Option<Bound<'py, PyAny>>, given: &mut [Py<PyString>]| {
        len == known.len() && (0..len).all(|k| item(k).is_some_and(|item| same_name(&item, &mut given[k], &known[k])))
    };
    if let Ok(list) = names.cast::<PyList>() {
        return same(list.len(), &|k| list.get_item(k).ok(), given).then_some(false);
    }
    if let Ok(tuple) = names.cast::<PyTuple>() {
        return same(tuple.len(), &|k| tuple.get_item(k).ok(), given).then_some(false);
    }
    None
}

/// The names of a `get` argument, a str or a sequence of strs: their str objects, their texts,
/// and whether it was one str.
fn names_of(names: &Bound<'_, PyAny>) -> PyResult<(Vec<Py<PyString>>, Vec<String>, bool)> {
    if let Ok(name) = names.cast::<PyString>() {
        return Ok((vec![name.clone().unbind()], vec![name.to_str()?.to_owned()], true));
    }
    let items = names.try_iter().map_err(|_| err(format!("get() takes a variable name or a list of names, not {names}")))?;
    let (mut objects, mut texts) = (Vec::new(), Vec::new());
    for item in items {
        let item = item?;
        let name = item.cast::<PyString>().map_err(|_| err(format!("get(): {item} is not a variable name (a str)")))?;
        texts.push(name.to_str()?.to_owned());
        objects.push(name.clone().unbind());
    }
    Ok((objects, texts, false))
}

/// Steps the instance in this process with `f`: holding the GIL when the last step timed was
/// quicker than [`QUICK_STEP`] and no real-time pacing sleeps, else with the GIL released.
fn local_step(
    py: Python<'_>,
    stepper: &mut runner_engine::stepping::Stepper,
    quick: &mut Quickness,
    f: impl FnOnce(&mut runner_engine::stepping::Stepper) -> Result<Stepped, String> + Send,
) -> Result<Stepped, String> {
    let hold = quick.quick && stepper.pacing.is_none();
    if hold && quick.untimed > 0 {
        quick.untimed -= 1;
        return f(stepper);
    }
    let clock = Instant::now();
    let stepped = if hold { f(stepper) } else { py.detach(|| f(stepper)) };
    quick.quick = clock.elapsed() < QUICK_STEP;
    quick.untimed = TIMED_EVERY - 1;
    stepped
}

#[pymethods]
impl Stepper {
    /// Opens the FMU at `path` and initializes an instance: in this process, or with `worker`
    /// (program, arguments) in a worker process of the sandbox.
    #[new]
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (path, sets, interface=None, start_time=None, stop_time=None, tolerance=None, solver=None, realtime=None, worker=None, timeout=None, worker_memory=None, name=None))]
    fn new(
        py: Python<'_>,
        path: &str,
        sets: Vec<String>,
        interface: Option<&str>,
        start_time: Option<f64>,
        stop_time: Option<f64>,
        tolerance: Option<f64>,
        solver: Option<&str>,
        realtime: Option<f64>,
        worker: Option<(String, Vec<String>)>,
        timeout: Option<f64>,
        worker_memory: Option<u64>,
        name: Option<String>,
    ) -> PyResult<Stepper> {
        let interface = interface_of(interface)?;
        let solver_given = solver.is_some();
        let solver = solver_of(solver, None, None)?;
        let pacing = realtime.map(Pacing::new).transpose().map_err(err)?;
        let mut settings = StepSettings::new(name.as_deref().unwrap_or("fmurunner"));
        settings.start_time = start_time;
        settings.stop_time = stop_time;
        settings.tolerance = tolerance;
        settings.solver = solver;
        let source = FmuSource::new(Path::new(path), interface);
        let backend = match worker {
            None => {
                if timeout.is_some() || worker_memory.is_some() {
                    return Err(err("timeout and worker_memory limit a worker process: give isolated=True".to_owned()));
                }
                let stepper = py
                    .detach(|| -> Result<_, String> {
                        let fmu = source.load()?;
                        check_solver(&fmu.description, &fmu.identifier, fmu.interface, solver_given)?;
                        settings.start_values = start_values(&fmu.description, &sets).map_err(|e| e.to_string())?;
                        let mut stepper = runner_engine::stepping::Stepper::open(Arc::new(fmu), settings)?;
                        stepper.pacing = pacing;
                        Ok(stepper)
                    })
                    .map_err(err)?;
                Backend::Local { stepper: Box::new(stepper), last: None, quick: Quickness::default(), result: None }
            }
            Some((program, args)) => {
                let timeout = runner_sandbox::timeout("timeout", timeout).map_err(err)?;
                let memory = worker_memory.unwrap_or_else(|| runner_sandbox::default_memory_mib(1));
                let command = WorkerCommand { program: program.into(), args: args.into_iter().map(Into::into).collect(), env: Vec::new() };
                let config = isolated::config(command, timeout, memory).map_err(err)?;
                let (stepper, unpacked) = py
                    .detach(|| -> Result<_, String> {
                        let (unpacked, for_worker) = source.open()?;
                        check_solver(&unpacked.description, &unpacked.identifier, unpacked.interface, solver_given)?;
                        settings.start_values = start_values(&unpacked.description, &sets).map_err(|e| e.to_string())?;
                        let mut stepper = IsolatedStepper::open(config, for_worker, settings)?;
                        stepper.pacing = pacing;
                        Ok((stepper, unpacked))
                    })
                    .map_err(err)?;
                let description = Box::new(unpacked.description.clone());
                Backend::Isolated { stepper, _unpacked: Box::new(unpacked), description }
            }
        };
        Ok(Stepper { backend: Mutex::new(backend) })
    }

    /// The simulated time reached (s).
    #[getter]
    fn time(&self) -> PyResult<f64> {
        match &*self.lock()? {
            Backend::Local { stepper, .. } => Ok(stepper.time()),
            Backend::Isolated { stepper, .. } => Ok(stepper.time()),
            Backend::Closed => Err(closed()),
        }
    }

    /// Advances the simulation by one communication step of ``dt`` seconds.
    ///
    /// Returns how far it got: ``result.time`` is the time reached; ``result.complete`` is
    /// False when an FMI 3.0 FMU returned early at an event (handled, at ``result.time``; step
    /// again for the rest); ``result.events`` counts the events handled.
    fn step<'py>(&self, py: Python<'py>, dt: f64) -> PyResult<Bound<'py, StepResult>> {
        self.stepping(py, |s| s.step(dt), |s| s.step(dt))
    }

    /// Advances the simulation to time ``t`` (one step, continued through every event an FMI
    /// 3.0 FMU returns early at). Returns as :meth:`step` does, ``complete`` True.
    fn advance_to<'py>(&self, py: Python<'py>, t: f64) -> PyResult<Bound<'py, StepResult>> {
        self.stepping(py, |s| s.advance_to(t), |s| s.advance_to(t))
    }

    /// The current value of a variable, or of several.
    ///
    /// ``get("x")`` gives a float (Real), int (integer types, Enumeration), bool, str or bytes
    /// (FMI 3.0 Binary); an array variable gives a numpy array (a list for Strings and
    /// Binaries). ``get(["x", "v"])`` gives a float64 numpy array when every name is a numeric
    /// scalar (Booleans as 0.0/1.0), else a list of their values. Values are in SI units.
    /// Reading the same names again, as a loop does, reuses their lookup.
    fn get<'py>(&self, py: Python<'py>, names: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let mut guard = self.lock()?;
        match &mut *guard {
            Backend::Local { stepper, last, .. } => {
                let one = match last.as_mut().and_then(|last| same_names(names, last)) {
                    Some(one) => one,
                    None => {
                        let (given, texts, one) = names_of(names)?;
                        let refs: Vec<&str> = texts.iter().map(String::as_str).collect();
                        *last = Some(LastRead { given, selection: stepper.select(&refs).map_err(err)?, array: None });
                        one
                    }
                };
                let LastRead { selection, array, .. } = last.as_mut().expect("selected above");
                stepper.read(selection).map_err(err)?;
                python_values(py, &selection.shapes, &selection.values, one, array)
            }
            Backend::Isolated { stepper, .. } => {
                let (_, names, one) = names_of(names)?;
                let (values, shapes) = py.detach(|| stepper.get(names)).map_err(err)?;
                python_values(py, &shapes, &values, one, &mut None)
            }
            Backend::Closed => Err(closed()),
        }
    }

    /// Sets an input or a tunable parameter to ``value``: a number in SI units, or text with a
    /// unit the FMU declares for the variable (``sim.set("theta", "120deg")``); a bool, str or
    /// bytes for those types; a list or numpy array for an array variable. Fixed parameters are
    /// set with ``start_values`` (or :meth:`reset`).
    fn set(&self, py: Python<'_>, name: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let given = given(value)?;
        let mut guard = self.lock()?;
        match &mut *guard {
            Backend::Local { stepper, .. } => stepper.set(name, &given).map_err(err),
            Backend::Isolated { stepper, .. } => py.detach(|| stepper.set(name, given)).map_err(err),
            Backend::Closed => Err(closed()),
        }
    }

    /// The simulation's state as bytes: the FMU's serialized state (``fmi2SerializeFMUstate``,
    /// ``fmi3SerializeFMUState``) and the time reached. :meth:`set_state` goes back to it, in
    /// this or another ``Simulation`` of the same FMU. The FMU must declare
    /// ``canGetAndSetFMUstate`` and ``canSerializeFMUstate``.
    fn get_state<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let mut guard = self.lock()?;
        let backend: &mut Backend = &mut guard;
        let bytes = py
            .detach(|| match backend {
                Backend::Local { stepper, .. } => stepper.get_state(),
                Backend::Isolated { stepper, .. } => stepper.get_state(),
                Backend::Closed => Err("the simulation is closed".to_owned()),
            })
            .map_err(err)?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Goes back to a state :meth:`get_state` returned (time included).
    fn set_state(&self, py: Python<'_>, state: &Bound<'_, PyAny>) -> PyResult<()> {
        let bytes: Vec<u8> = if state.is_instance_of::<PyBytes>() || state.is_instance_of::<PyByteArray>() {
            state.extract()?
        } else {
            return Err(err(format!("set_state() takes the bytes get_state() returned, not {}", state.get_type().name()?)));
        };
        let mut guard = self.lock()?;
        let backend: &mut Backend = &mut guard;
        py.detach(|| match backend {
            Backend::Local { stepper, .. } => stepper.set_state(&bytes),
            Backend::Isolated { stepper, .. } => stepper.set_state(bytes),
            Backend::Closed => Err("the simulation is closed".to_owned()),
        })
        .map_err(err)
    }

    /// Back to the start with the same instance; `sets` (`NAME=VALUE`) replace the start values
    /// (`Simulation.reset` takes them as a dict).
    #[pyo3(name = "_reset", signature = (sets=None))]
    fn reset(&self, py: Python<'_>, sets: Option<Vec<String>>) -> PyResult<()> {
        let mut guard = self.lock()?;
        let backend: &mut Backend = &mut guard;
        let values = match (&*backend, &sets) {
            (_, None) => None,
            (Backend::Local { stepper, .. }, Some(sets)) => Some(start_values(stepper.description(), sets)?),
            (Backend::Isolated { description, .. }, Some(sets)) => Some(start_values(description, sets)?),
            (Backend::Closed, _) => return Err(closed()),
        };
        py.detach(|| match backend {
            Backend::Local { stepper, .. } => stepper.reset(values),
            Backend::Isolated { stepper, .. } => stepper.reset(values),
            Backend::Closed => Err("the simulation is closed".to_owned()),
        })
        .map_err(err)
    }

    /// Frees the FMU instance (and lets its worker go). Later calls raise RunnerError; closing
    /// twice is allowed.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        let mut guard = self.lock()?;
        let mut backend = std::mem::replace(&mut *guard, Backend::Closed);
        if let Backend::Local { last, result, .. } = &mut backend {
            // Python objects are let go of while attached.
            (*last, *result) = (None, None);
        }
        py.detach(move || drop(backend));
        Ok(())
    }

    /// True once :meth:`close` was called.
    #[getter]
    fn closed(&self) -> PyResult<bool> {
        Ok(matches!(&*self.lock()?, Backend::Closed))
    }

    /// (overruns, worst lateness in seconds) of real-time pacing; `None` without pacing.
    #[getter(_pacing)]
    fn pacing(&self) -> PyResult<Option<(u64, f64)>> {
        let guard = self.lock()?;
        let pacing = match &*guard {
            Backend::Local { stepper, .. } => stepper.pacing.as_ref(),
            Backend::Isolated { stepper, .. } => stepper.pacing.as_ref(),
            Backend::Closed => return Err(closed()),
        };
        Ok(pacing.map(|p| (p.overruns, p.worst_lateness)))
    }
}

/// Refuses the integrator's options (`given`: one of them was) for an FMU that runs as
/// Co-Simulation, where they would do nothing.
pub(crate) fn check_solver(description: &Description, identifier: &str, interface: Interface, given: bool) -> Result<(), String> {
    runner_engine::run::refuse_solver_under_co_simulation(given, description, identifier, interface, OPTION_NAMES)
}

/// Serves a worker process of the sandbox: `kind` is `sweep` (runs and sweep points) or `step`
/// (a stepped simulation). Only a supervisor starts this (fmurunner/_worker.py).
#[pyfunction]
pub fn serve_worker(py: Python<'_>, kind: &str) -> PyResult<()> {
    let serve = match kind {
        "sweep" => isolated::serve,
        "step" => runner_engine::stepping::serve,
        _ => return Err(err(format!("no worker of kind '{kind}': use sweep or step"))),
    };
    py.detach(serve).map_err(err)
}
