//! Drives an [`Instance`] in-process by variable name, through the same code paths as the C
//! functions (minus pointer conversion): for model tests and the bare benchmarks.

use std::sync::{Arc, Mutex};

use crate::core::derivatives::{field_places, field_values, Evaluates, KeptLift, Known, Pass, Unknown};
use crate::core::Failure;
use crate::fmi2::state_machine::Interface;
use crate::fmi2::Instance;
use crate::logging::{Logger, Status};
use crate::model::{Access, BaseType, Causality, Model, Variability};
use crate::table::{Row, Slot, Table};

/// An instance plus the messages it logged.
pub struct Harness<M: Model> {
    pub instance: Instance<M>,
    messages: Arc<Mutex<Vec<String>>>,
}

/// Sampled outputs: `time[k]` and `values[j][k]` for the j-th requested name.
#[derive(Debug, Clone, Default)]
pub struct Trajectory {
    pub names: Vec<String>,
    pub time: Vec<f64>,
    pub values: Vec<Vec<f64>>,
}

impl Trajectory {
    /// The samples of output `name`.
    pub fn get(&self, name: &str) -> &[f64] {
        let j = self.names.iter().position(|n| n == name).unwrap_or_else(|| panic!("'{name}' was not recorded"));
        &self.values[j]
    }
}

fn describe(f: Failure) -> String {
    format!("{:?}: {}", f.status, f.message)
}

impl<M: Model> Default for Harness<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<M: Model> Harness<M> {
    /// A fresh Co-Simulation instance whose log (all categories, debug on) is kept for
    /// inspection.
    pub fn new() -> Harness<M> {
        Self::for_interface(Interface::CoSimulation)
    }

    /// A fresh Model Exchange instance, its log kept as by [`Harness::new`].
    pub fn model_exchange() -> Harness<M> {
        Self::for_interface(Interface::ModelExchange)
    }

    fn for_interface(interface: Interface) -> Harness<M> {
        let messages = Arc::new(Mutex::new(Vec::new()));
        let sink = messages.clone();
        let logger = Logger::new(
            Some(Box::new(move |status: Status, category: &'static str, message: &str| {
                sink.lock().expect("log lock").push(format!("[{status:?}] {category}: {message}"));
            })),
            true,
        );
        Harness { instance: Instance::for_interface("harness", logger, interface), messages }
    }

    /// A fresh instance with `params` set by name, initialized at relative tolerance
    /// `tolerance` (`None`: the model's default): the start of most model tests.
    pub fn started(params: &[(&str, f64)], tolerance: Option<f64>) -> Result<Harness<M>, String> {
        let mut h = Harness::new();
        for (name, value) in params {
            h.set(name, *value)?;
        }
        h.initialize(tolerance)?;
        Ok(h)
    }

    /// Everything logged so far.
    pub fn messages(&self) -> Vec<String> {
        self.messages.lock().expect("log lock").clone()
    }

    fn vr(&self, name: &str) -> Result<(u32, BaseType), String> {
        let vr = self.instance.table().value_reference(name).ok_or_else(|| format!("no variable named '{name}'"))?;
        Ok((vr, self.instance.table().row(vr).expect("vr from table").base_type))
    }

    /// Lets the model read its resources from `dir`, as fmi2Instantiate does with the
    /// importer's fmuResourceLocation.
    pub fn load_resources(&mut self, dir: &std::path::Path) -> Result<(), String> {
        self.instance.load_resources(dir).map_err(|e| e.to_string())
    }

    /// Sets a variable by name; integers and booleans are given as numbers.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), String> {
        let (vr, ty) = self.vr(name)?;
        match ty {
            BaseType::Real => self.instance.set_real(&[vr], &[value]),
            BaseType::Integer => self.instance.set_integer(&[vr], &[value as i32]),
            BaseType::Boolean => self.instance.set_boolean(&[vr], &[value != 0.0]),
            BaseType::String => return Err(format!("'{name}' is a String variable: set it with set_string")),
        }
        .map_err(describe)
    }

    /// Sets a String variable by name.
    pub fn set_string(&mut self, name: &str, value: &str) -> Result<(), String> {
        let (vr, _) = self.vr(name)?;
        self.instance.set_string(&[vr], &[value]).map_err(describe)
    }

    /// Reads a String variable by name.
    pub fn get_string(&mut self, name: &str) -> Result<String, String> {
        let (vr, _) = self.vr(name)?;
        let texts = self.instance.get_string(&[vr]).map_err(describe)?;
        Ok(texts[0].to_str().expect("the toolkit hands out UTF-8").to_owned())
    }

    /// Reads a variable by name as a number.
    pub fn get(&mut self, name: &str) -> Result<f64, String> {
        let (vr, ty) = self.vr(name)?;
        match ty {
            BaseType::Real => {
                let mut v = [0.0];
                self.instance.get_real(&[vr], &mut v).map(|()| v[0])
            }
            BaseType::Integer => {
                let mut v = [0];
                self.instance.get_integer(&[vr], &mut v).map(|()| v[0] as f64)
            }
            BaseType::Boolean => {
                let mut v = [false];
                self.instance.get_boolean(&[vr], &mut v).map(|()| v[0] as i32 as f64)
            }
            BaseType::String => return Err(format!("'{name}' is a String variable: read it with get_string")),
        }
        .map_err(describe)
    }

    /// Setup (with `tolerance`, start 0, no stop time), enter and exit initialization.
    pub fn initialize(&mut self, tolerance: Option<f64>) -> Result<(), String> {
        self.instance.setup_experiment(tolerance, 0.0, None).map_err(describe)?;
        self.instance.enter_initialization_mode().map_err(describe)?;
        self.instance.exit_initialization_mode().map_err(describe)
    }

    /// One communication step of size `h` from the current time.
    pub fn step(&mut self, h: f64) -> Result<Status, String> {
        let t = self.instance.time();
        self.instance.do_step(t, h).map_err(describe)
    }

    /// Records `names` at t = 0 and after every step of `dt` until `stop` (or until the model
    /// ends the experiment early, recording that last point too).
    pub fn run(&mut self, stop: f64, dt: f64, names: &[&str]) -> Result<Trajectory, String> {
        let mut traj =
            Trajectory { names: names.iter().map(|s| s.to_string()).collect(), values: vec![Vec::new(); names.len()], time: Vec::new() };
        let n = (stop / dt).round() as usize;
        self.record(&mut traj)?;
        for k in 1..=n {
            // The grid is k*dt, not a running sum, so long runs do not drift.
            let target = if k == n { stop } else { k as f64 * dt };
            let t = self.instance.time();
            let status = self.instance.do_step(t, target - t).map_err(describe)?;
            self.record(&mut traj)?;
            if status == Status::Discard {
                break;
            }
        }
        Ok(traj)
    }

    fn record(&mut self, traj: &mut Trajectory) -> Result<(), String> {
        traj.time.push(self.instance.time());
        for j in 0..traj.names.len() {
            let v = self.get(&traj.names[j].clone())?;
            traj.values[j].push(v);
        }
        Ok(())
    }
}

/// A Jacobian of a model's equations: `values[i][j]` is the partial derivative of
/// `unknowns[i]` with respect to `knowns[j]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Jacobian {
    pub unknowns: Vec<&'static str>,
    pub knowns: Vec<&'static str>,
    pub values: Vec<Vec<f64>>,
}

impl Jacobian {
    /// The partial derivative of `unknown` with respect to `known`, by name.
    pub fn get(&self, unknown: &str, known: &str) -> f64 {
        let i = self.unknowns.iter().position(|n| *n == unknown).unwrap_or_else(|| panic!("'{unknown}' is no unknown"));
        let j = self.knowns.iter().position(|n| *n == known).unwrap_or_else(|| panic!("'{known}' is no known"));
        self.values[i][j]
    }

    /// The block of the unknowns and knowns named, in the order given.
    pub fn block(&self, unknowns: &[&str], knowns: &[&str]) -> Vec<Vec<f64>> {
        unknowns.iter().map(|u| knowns.iter().map(|k| self.get(u, k)).collect()).collect()
    }
}

/// The equations the derivative checks differentiate, at one point: continuous time (the
/// knowns time, the states and the Real inputs; the unknowns the state derivatives and the
/// continuous Real outputs) or initialization (the knowns the Real inputs and parameters; the
/// unknowns the states, their derivatives and the continuous Real outputs at the start).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    ContinuousTime,
    Initialization,
}

/// The rows of the table that are knowns and unknowns of `equations`.
fn jacobian_rows<M: Model>(table: &Table<M>, equations: Stage) -> (Vec<usize>, Vec<usize>) {
    let known = |row: &Row<M>| match equations {
        Stage::ContinuousTime => {
            matches!(row.slot, Slot::Time | Slot::Model(Access::State(_))) || (row.causality == Causality::Input && row.field.is_some())
        }
        Stage::Initialization => matches!(row.causality, Causality::Input | Causality::Parameter) && row.field.is_some(),
    };
    let unknown = |row: &Row<M>| {
        matches!(row.slot, Slot::Derivative(_))
            || (row.causality == Causality::Output && row.variability == Variability::Continuous && row.field.is_some())
            || (equations == Stage::Initialization && matches!(row.slot, Slot::Model(Access::State(_))))
    };
    let pick = |f: &dyn Fn(&Row<M>) -> bool| table.rows.iter().enumerate().filter(|(_, r)| f(r)).map(|(i, _)| i).collect();
    (pick(&known), pick(&unknown))
}

/// The exact Jacobian of `equations` at time `t` and states `x` (continuous time; ignored at
/// initialization, where the states are unknowns) for `model`'s parameters and inputs: forward
/// passes in vector dual numbers ([`crate::core::derivatives::forward`]).
pub fn jacobian<M: Model>(model: &M, t: f64, x: &[f64], equations: Stage) -> Jacobian {
    let table = Table::<M>::new();
    let lifting = M::lifting().expect("the model is generic over its number type: it has exact derivatives");
    let (knowns, unknowns) = jacobian_rows(&table, equations);
    let seeds: Vec<Known> = knowns
        .iter()
        .map(|&i| match (&table.rows[i].slot, table.rows[i].field) {
            (Slot::Time, _) => Known::Time,
            (Slot::Model(Access::State(k)), _) => Known::State(*k),
            (_, Some(field)) => Known::Field(field),
            _ => unreachable!("knowns are time, states and real fields"),
        })
        .collect();
    let targets: Vec<(usize, Unknown)> = unknowns
        .iter()
        .map(|&i| match (&table.rows[i].slot, table.rows[i].field) {
            (Slot::Derivative(k), _) => Unknown::Derivative(*k),
            (Slot::Model(Access::State(k)), _) => Unknown::State(*k),
            (_, Some(field)) => Unknown::Field(field),
            _ => Unknown::Zero,
        })
        .enumerate()
        .collect();
    let mut values = Vec::new();
    field_values(&table.rows, &knowns, &field_places(&seeds), model, &mut values);
    let initialization = equations == Stage::Initialization;
    let pass = Pass {
        t,
        x,
        knowns: &seeds,
        fields: &field_places(&seeds),
        values: &values,
        seeded: 0..seeds.len(),
        unknowns: &targets,
        evaluates: Evaluates::of(&targets),
        initialization,
        version: 0,
    };
    let mut flat = vec![0.0; knowns.len() * unknowns.len()];
    (lifting.forward)(model, &pass, &mut KeptLift::default(), &mut flat).expect("the model's equations evaluate at this point");
    let values = flat.chunks(knowns.len().max(1)).take(unknowns.len()).map(<[f64]>::to_vec).collect();
    let name = |i: &usize| table.rows[*i].name;
    Jacobian { unknowns: unknowns.iter().map(name).collect(), knowns: knowns.iter().map(name).collect(), values }
}

/// The unknowns of `equations` (in [`jacobian`]'s order) computed in `f64` by the model's own
/// equations, for `model` (whose derived fields are refreshed) at (t, x).
fn evaluate<M: Model>(table: &Table<M>, unknowns: &[usize], model: &M, t: f64, x: &[f64], equations: Stage) -> Option<Vec<f64>> {
    let mut model = model.clone();
    crate::model::refresh(&mut model);
    let mut x = x.to_vec();
    if equations == Stage::Initialization {
        model.initial_state(&mut x).ok()?;
    }
    let mut dx = vec![0.0; M::N_STATES];
    model.derivatives(t, &x, &mut dx);
    model.outputs(t, &x);
    Some(
        unknowns
            .iter()
            .map(|&i| match &table.rows[i].slot {
                Slot::Derivative(k) => dx[*k],
                Slot::Model(Access::State(k)) => x[*k],
                Slot::Model(Access::Real { get, .. }) => get(&model),
                _ => 0.0,
            })
            .collect(),
    )
}

/// The Jacobian of [`jacobian`] by central differences of the model's own `f64` equations:
/// known j moved by ±h_j, h_j = 1e-5 max(|v_j|, 1). `None` where the model refuses a moved
/// parameter.
pub fn difference_jacobian<M: Model>(model: &M, t: f64, x: &[f64], equations: Stage) -> Option<Jacobian> {
    differences(model, t, x, equations).map(|d| d.central)
}

/// Central differences of [`jacobian`]'s unknowns, with the unknowns' values and the gaps
/// between the forward and the backward difference at steps h and h/2.
struct Differences {
    central: Jacobian,
    /// The central differences at h/2.
    central_half: Vec<Vec<f64>>,
    /// (f(v + h) - f(v)) / h - (f(v) - f(v - h)) / h: h f'' where f is smooth, the jump of the
    /// slope at a kink.
    gap: Vec<Vec<f64>>,
    /// The same at h/2: half of `gap` where f is smooth, as large at a kink.
    gap_half: Vec<Vec<f64>>,
    values: Vec<f64>,
}

fn differences<M: Model>(model: &M, t: f64, x: &[f64], equations: Stage) -> Option<Differences> {
    let table = Table::<M>::new();
    let (knowns, unknowns) = jacobian_rows(&table, equations);
    let base = evaluate(&table, &unknowns, model, t, x, equations)?;
    let zeros = || vec![vec![0.0; knowns.len()]; unknowns.len()];
    let (mut central, mut central_half, mut gap, mut gap_half) = (zeros(), zeros(), zeros(), zeros());
    for (j, &known) in knowns.iter().enumerate() {
        let row = &table.rows[known];
        let moved = |sign: f64| -> Option<(f64, Vec<f64>)> {
            let (step, sign) = (sign.abs(), sign.signum());
            let (mut t, mut x, mut model) = (t, x.to_vec(), model.clone());
            let v = match &row.slot {
                Slot::Time => &mut t,
                Slot::Model(Access::State(k)) => &mut x[*k],
                _ => &mut 0.0,
            };
            let value = match &row.slot {
                Slot::Model(Access::Real { get, .. }) => get(&model),
                _ => *v,
            };
            let h = step * 1e-5 * value.abs().max(1.0);
            match &row.slot {
                Slot::Model(Access::Real { set: Some(set), .. }) => set(&mut model, value + sign * h),
                _ => *v = value + sign * h,
            }
            Some((h, evaluate(&table, &unknowns, &model, t, &x, equations)?))
        };
        let ((h, plus), (_, minus)) = (moved(1.0)?, moved(-1.0)?);
        let ((h2, plus2), (_, minus2)) = (moved(0.5)?, moved(-0.5)?);
        for i in 0..unknowns.len() {
            central[i][j] = (plus[i] - minus[i]) / (2.0 * h);
            central_half[i][j] = (plus2[i] - minus2[i]) / (2.0 * h2);
            gap[i][j] = (plus[i] - 2.0 * base[i] + minus[i]) / h;
            gap_half[i][j] = (plus2[i] - 2.0 * base[i] + minus2[i]) / h2;
        }
    }
    let name = |i: &usize| table.rows[*i].name;
    let central = Jacobian { unknowns: unknowns.iter().map(name).collect(), knowns: knowns.iter().map(name).collect(), values: central };
    Some(Differences { central, central_half, gap, gap_half, values: base })
}

/// What [`check_derivatives`] compared.
#[derive(Debug, Clone, Default)]
pub struct DerivativeCheck {
    /// Points compared (continuous time along the run, and initialization).
    pub points: usize,
    /// Jacobian entries compared, and those of them that are not zero.
    pub entries: usize,
    pub nonzero: usize,
    /// Entries left out at a kink of the f64 function (see [`check_derivatives`]).
    pub kinks: usize,
    /// The largest |exact - difference| over its bound.
    pub worst: f64,
    /// Columns of d(der x)/dx by the implicit solver's path found equal to the general
    /// path's, to the bit ([`crate::core::derivatives::check_solver_block`]).
    pub solver_columns: usize,
}

/// Checks model `M`'s exact derivatives against central differences of its own `f64`
/// equations: in continuous time at up to 200 points along its default experiment (through
/// every regime the run visits) and at initialization for its default parameters.
///
/// The exact value is compared with the central difference at h_j/2, h_j = 1e-5 max(|v_j|, 1).
/// That errs by its truncation, h_j^2 |f'''| / 24, and its rounding, about eps |f_i| / h_j
/// (or eps times the size of the terms of a quantity that cancels to near zero, such as a
/// loop-closure gap: up to 1e2 in these models' SI units). The truncation is estimated from
/// the differences themselves: the central difference at h_j errs four times as much, so their
/// gap is three times the error at h_j/2. The rounding is bounded by 1e-6 s_ij + 1e-8, with
/// s_ij = |J_ij| + |f_i| / max(|v_j|, 1) (eps |f_i| / h_j is 2e-11 |f_i| / max(|v_j|, 1), and
/// eps 1e2 / h_j is 4e-9). The bound is the sum: it widens near a singular configuration
/// (a linkage's limit position, where third derivatives are huge) and stays 1e-6 of the scale
/// elsewhere, while an error in a derivative term is of the order of s_ij itself. The check
/// fails naming the entry that exceeds it. Both sides differentiate the equations of the
/// regime the model is in at the point (its discrete state stays as it is), so a point after
/// an event checks the new regime's equations. Where the function has a kink at the point
/// itself (the length |e| of a loop-closure gap that the projection has made zero) no
/// derivative exists to compare: the forward and backward differences then disagree by the
/// jump of the slope at any step, where for a smooth function they disagree by h f'', half as
/// much at half the step. Entries whose disagreement exceeds the bound and does not shrink
/// below 3/4 at h/2 are counted as `kinks`; the check fails if they are more than a tenth.
pub fn check_derivatives<M: Model>() -> Result<DerivativeCheck, String> {
    let table = Table::<M>::new();
    let mut defaults = M::default();
    crate::model::refresh(&mut defaults);
    let mut points: Vec<(M, f64, Vec<f64>, Stage)> = vec![(defaults.clone(), 0.0, vec![0.0; M::N_STATES], Stage::Initialization)];
    for s in crate::structure::trajectory(&defaults) {
        points.push((s.model, s.t, s.x, Stage::ContinuousTime));
    }
    let mut report = DerivativeCheck::default();
    for (model, t, x, equations) in &points {
        let exact = jacobian(model, *t, x, *equations);
        let Some(d) = differences(model, *t, x, *equations) else { continue };
        let (knowns, unknowns) = jacobian_rows(&table, *equations);
        report.points += 1;
        for (i, &unknown) in unknowns.iter().enumerate() {
            for (j, &known) in knowns.iter().enumerate() {
                let scale_j = match &table.rows[known].slot {
                    Slot::Time => t.abs(),
                    Slot::Model(Access::State(k)) => x[*k].abs(),
                    Slot::Model(Access::Real { get, .. }) => get(model).abs(),
                    _ => 0.0,
                }
                .max(1.0);
                let (a, c_full, c) = (exact.values[i][j], d.central.values[i][j], d.central_half[i][j]);
                let bound = 1e-6 * (a.abs() + d.values[i].abs() / scale_j) + 1e-8 + (c_full - c).abs();
                report.entries += 1;
                let (g, g_half) = (d.gap[i][j].abs(), d.gap_half[i][j].abs());
                if g > bound && g_half > 0.75 * g {
                    report.kinks += 1;
                    continue;
                }
                report.nonzero += usize::from(a != 0.0);
                report.worst = report.worst.max((a - c).abs() / bound);
                // A NaN on either side fails too.
                let within = (a - c).abs() <= bound;
                if !within {
                    return Err(format!(
                        "{equations:?} at t = {t}: d {} / d {} = {a:e} exactly, {c:e} by central differences (bound {bound:e})",
                        table.rows[unknown].name, table.rows[known].name
                    ));
                }
            }
        }
    }
    // About 20 of the run's points: each is a new instance, and the paths' agreement does not
    // depend on where (beyond the regime, which the run's points visit).
    let continuous: Vec<_> = points.iter().filter(|p| p.3 == Stage::ContinuousTime).collect();
    let every = continuous.len().div_ceil(20).max(1);
    let solver_points: Vec<(M, f64, Vec<f64>)> = continuous.iter().step_by(every).map(|(m, t, x, _)| (m.clone(), *t, x.clone())).collect();
    report.solver_columns = crate::core::derivatives::check_solver_block(&solver_points)?;
    if report.kinks * 10 > report.entries {
        return Err(format!("{} of {} entries are at kinks: too few derivatives were compared", report.kinks, report.entries));
    }
    if report.nonzero == 0 {
        return Err("no nonzero derivative was compared: the check would prove nothing".to_owned());
    }
    Ok(report)
}

/// The FMI version whose C functions [`c_api_step`] drives.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    Fmi2,
    Fmi3,
}

/// What [`c_api_step`] saw.
#[derive(Debug, Clone)]
pub struct CApiStep {
    /// The status of fmi2DoStep / fmi3DoStep (0 OK, 3 Error, ...).
    pub status: i32,
    /// How long that one call took.
    pub took: std::time::Duration,
    /// Every message the instance logged, as "status: message".
    pub messages: Vec<String>,
    /// The continuous states read with fmi2GetReal / fmi3GetFloat64 after the step (all
    /// `None` when the read failed).
    pub states: Vec<Option<f64>>,
    /// The status of fmi2Reset / fmi3Reset after the step (the instance is freed after it).
    pub reset_status: i32,
}

/// Messages of one instance, reached through its component environment pointer.
type LogSink = Mutex<Vec<String>>;

/// Reads only the fixed arguments: our FMUs pass preformatted messages (with `%` escaped).
extern "C" fn record_fmi2(
    env: *mut std::ffi::c_void,
    _name: *const std::ffi::c_char,
    status: i32,
    _cat: *const std::ffi::c_char,
    msg: *const std::ffi::c_char,
) {
    // SAFETY: `env` is the `LogSink` c_api_step passed, alive until the instance is freed;
    // `msg` a NUL-terminated string from the FMU.
    let (sink, msg) = unsafe { (&*(env as *const LogSink), std::ffi::CStr::from_ptr(msg).to_string_lossy()) };
    sink.lock().expect("log lock").push(format!("{status}: {msg}"));
}

unsafe extern "C" fn record_fmi3(env: *mut std::ffi::c_void, status: i32, _cat: *const std::ffi::c_char, msg: *const std::ffi::c_char) {
    record_fmi2(env, std::ptr::null(), status, std::ptr::null(), msg)
}

/// One Co-Simulation communication step from t = 0 over `h`, through model `M`'s FMI 2.0 or
/// 3.0 C functions (the generic bodies its `export_fmu!` forwards to, so the same code as the
/// `.so`): instantiated with logging on, the Real and Integer variables `params` set by name,
/// initialized at the model's default tolerance without a stop time, then the step. Afterwards
/// what an importer may still do after an fmiError: read the states, fmiReset, and free the
/// instance.
pub fn c_api_step<M: Model>(version: FmiVersion, params: &[(&str, f64)], h: f64) -> Result<CApiStep, String> {
    use crate::fmi2::{ffi as f2, Fmi2};
    use crate::fmi3::{ffi as f3, Fmi3};
    use crate::frontend::ffi as fr;
    use crate::frontend::Call;

    let table = Table::<M>::new();
    let sink: Box<LogSink> = Box::new(Mutex::new(Vec::new()));
    let env = &*sink as *const LogSink as *mut std::ffi::c_void;
    let token = std::ffi::CString::new(crate::table::guid::<M>()).expect("no NUL in a GUID");
    let mut set = Vec::new();
    for (name, value) in params {
        let vr = table.value_reference(name).ok_or_else(|| format!("no variable named '{name}'"))?;
        set.push((vr, table.row(vr).expect("vr from table").base_type, *value));
    }
    let state_vrs: Vec<u32> = (0..M::N_STATES)
        .map(|k| {
            let row = table.rows.iter().position(|r| matches!(r.slot, Slot::Model(Access::State(j)) if j == k));
            row.expect("every state has a variable") as u32
        })
        .collect();
    let mut states = vec![None; M::N_STATES];
    // SAFETY: every pointer passed lives until the call returns; `sink` outlives the instance.
    let (status, took, reset_status) = unsafe {
        match version {
            FmiVersion::Fmi2 => {
                // On x86-64 System V a variadic call with only the fixed arguments matches this
                // non-variadic callee (as in tests/panic_boundary.rs).
                let logger: f2::LoggerFn = std::mem::transmute(record_fmi2 as extern "C" fn(_, _, _, _, _));
                let callbacks = f2::CallbackFunctions {
                    logger: Some(logger),
                    allocate_memory: None,
                    free_memory: None,
                    step_finished: None,
                    component_environment: env,
                };
                let c =
                    f2::instantiate::<M>(c"bounded".as_ptr(), f2::FMI2_COSIMULATION, token.as_ptr(), std::ptr::null(), &callbacks, 0, 1);
                if c.is_null() {
                    return Err(format!("fmi2Instantiate refused: {:?}", sink.lock().expect("log lock")));
                }
                let mut ok = true;
                for &(vr, ty, value) in &set {
                    ok &= match ty {
                        BaseType::Integer => fr::set_integer::<Fmi2, M>(c, &vr, 1, &(value as i32), 1),
                        _ => fr::set_real::<Fmi2, M>(c, &vr, 1, &value, 1),
                    } == 0;
                }
                ok &= f2::setup_experiment::<M>(c, 0, 0.0, 0.0, 0, 0.0) == 0;
                ok &= fr::simple::<Fmi2, M>(c, Call::EnterInitializationMode, |i| i.enter_initialization_mode()) == 0;
                ok &= fr::simple::<Fmi2, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()) == 0;
                if !ok {
                    fr::free_instance::<Fmi2, M>(c);
                    return Err(format!("setting up the instance failed: {:?}", sink.lock().expect("log lock")));
                }
                let started = std::time::Instant::now();
                let status = f2::do_step::<M>(c, 0.0, h, 1);
                let took = started.elapsed();
                for (vr, out) in state_vrs.iter().zip(&mut states) {
                    let mut v = f64::NAN;
                    *out = (fr::get_real::<Fmi2, M>(c, vr, 1, &mut v, 1) == 0).then_some(v);
                }
                let reset = fr::simple::<Fmi2, M>(c, Call::Reset, |i| i.reset());
                fr::free_instance::<Fmi2, M>(c);
                (status, took, reset)
            }
            FmiVersion::Fmi3 => {
                let c = f3::instantiate_co_simulation::<M>(
                    c"bounded".as_ptr(),
                    token.as_ptr(),
                    std::ptr::null(),
                    true,
                    false,
                    false,
                    env,
                    Some(record_fmi3),
                );
                if c.is_null() {
                    return Err(format!("fmi3InstantiateCoSimulation refused: {:?}", sink.lock().expect("log lock")));
                }
                let mut ok = true;
                for &(vr, ty, value) in &set {
                    ok &= match ty {
                        BaseType::Integer => fr::set_integer::<Fmi3, M>(c, &vr, 1, &(value as i32), 1),
                        _ => fr::set_real::<Fmi3, M>(c, &vr, 1, &value, 1),
                    } == 0;
                }
                ok &= f3::enter_initialization_mode::<M>(c, false, 0.0, 0.0, false, 0.0) == 0;
                ok &= fr::simple::<Fmi3, M>(c, Call::ExitInitializationMode, |i| i.exit_initialization_mode()) == 0;
                if !ok {
                    fr::free_instance::<Fmi3, M>(c);
                    return Err(format!("setting up the instance failed: {:?}", sink.lock().expect("log lock")));
                }
                let (mut event, mut terminate, mut early, mut last) = (false, false, false, 0.0);
                let started = std::time::Instant::now();
                let status = f3::do_step::<M>(c, 0.0, h, true, &mut event, &mut terminate, &mut early, &mut last);
                let took = started.elapsed();
                for (vr, out) in state_vrs.iter().zip(&mut states) {
                    let mut v = f64::NAN;
                    *out = (fr::get_real::<Fmi3, M>(c, vr, 1, &mut v, 1) == 0).then_some(v);
                }
                let reset = fr::simple::<Fmi3, M>(c, Call::Reset, |i| i.reset());
                fr::free_instance::<Fmi3, M>(c);
                (status, took, reset)
            }
        }
    };
    let messages = sink.lock().expect("log lock").clone();
    Ok(CApiStep { status, took, messages, states, reset_status })
}
