//! Drives an [`Instance`] in-process by variable name, through the same code paths as the C
//! functions (minus pointer conversion): for model tests and the bare benchmarks.

use std::sync::{Arc, Mutex};

use crate::core::Failure;
use crate::fmi2::state_machine::Interface;
use crate::fmi2::Instance;
use crate::logging::{Logger, Status};
use crate::model::{BaseType, Model};

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
