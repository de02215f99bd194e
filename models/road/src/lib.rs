#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use std::f64::consts::PI;
use std::path::{Component, Path, PathBuf};

use fmu_export::{Equations, Model, ModelError, ModelInfo, Scalar, StateVector, Variables};
use serde::{Deserialize, Serialize};

/// The road elevation z_r and rate z_r' under a wheel moving at `speed` along a profile.
#[derive(Debug, Clone, Serialize, Deserialize, Variables)]
#[variables(states = State)]
pub struct Road<T = f64> {
    /// Horizontal speed of the wheel along the road
    #[parameter(unit = "m/s", finite)]
    pub speed: T,
    /// Profile: 0 the Ex. 4 sinusoid, 1 one half-cosine bump, 2 the measured profile of the file `table`
    #[parameter(one_of(0, 1, 2))]
    pub profile: i32,
    /// Profile 2's table file (CSV, header x,z, x and z in m): a relative name is read from the FMU's resources/ folder, an absolute path or a file: URI as it is
    #[parameter]
    pub table: String,
    /// Amplitude a of the sinusoid z = a sin(2 pi x / wavelength)
    #[parameter(unit = "m", finite)]
    pub amplitude: T,
    /// Wavelength of the sinusoid
    #[parameter(unit = "m", positive)]
    pub wavelength: T,
    /// Height of the bump
    #[parameter(unit = "m", finite)]
    pub bump_height: T,
    /// Length of the bump along the road
    #[parameter(unit = "m", positive)]
    pub bump_length: T,
    /// Where the bump starts along the road
    #[parameter(unit = "m", finite)]
    pub bump_start: T,
    /// Road elevation under the wheel
    #[output(unit = "m")]
    pub z_r: T,
    /// Road rate z_r' = speed * dz/dx
    #[output(unit = "m/s")]
    pub z_r_dot: T,
    /// The FMU's resources folder, as the importer gave it at instantiation (`None`: it gave
    /// none).
    resource_dir: Option<PathBuf>,
    /// The measured profile, read from the file `table` names when initialization needs it.
    measured: Table,
    /// The file `measured` was read from (initialization may run more than once).
    measured_from: Option<PathBuf>,
}

/// The state vector.
#[derive(StateVector)]
pub struct State<T = f64> {
    /// Position of the wheel along the road
    #[state(unit = "m")]
    pub x: T,
}

impl Default for Road {
    fn default() -> Self {
        Road {
            speed: 30.0,
            profile: 0,
            amplitude: 0.04,
            wavelength: 3.0,
            bump_height: 0.05,
            bump_length: 1.0,
            bump_start: 5.0,
            z_r: 0.0,
            z_r_dot: 0.0,
            table: TABLE_FILE.to_owned(),
            resource_dir: None,
            measured: Table::default(),
            measured_from: None,
        }
    }
}

/// A measured profile: rows (x, z), x strictly increasing, linear between rows.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Table {
    pub x: Vec<f64>,
    pub z: Vec<f64>,
}

/// The default of `table`: the sample profile shipped in the FMU's resources.
pub const TABLE_FILE: &str = "profile.csv";

impl Table {
    /// Reads a profile from CSV text (`x,z` header, `#` comments); errors name the line.
    pub fn parse(text: &str, file: &str) -> Result<Table, String> {
        let mut table = Table::default();
        let mut header = false;
        for (n, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let at = |what: String| format!("{file}, line {}: {what}", n + 1);
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if !header {
                if cells != ["x", "z"] {
                    return Err(at(format!("the header must be 'x,z', not '{line}'")));
                }
                header = true;
                continue;
            }
            if cells.len() != 2 {
                return Err(at(format!("a row has two numbers, x and z; found '{line}'")));
            }
            let number = |cell: &str| {
                cell.parse::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| at(format!("'{cell}' is not a finite number")))
            };
            let (x, z) = (number(cells[0])?, number(cells[1])?);
            if let Some(&last) = table.x.last() {
                if x <= last {
                    return Err(at(format!("x must increase from row to row: {x} after {last}")));
                }
            }
            table.x.push(x);
            table.z.push(z);
        }
        if table.x.len() < 2 {
            return Err(format!("{file}: a profile needs the header 'x,z' and at least two rows"));
        }
        Ok(table)
    }

    /// z(x) and dz/dx: linear between rows (at a row, the slope after it), the end values and
    /// zero slope outside; a flat road for an empty table (none was loaded: initialization
    /// refuses profile 2 then, but the toolkit's dependency probing evaluates outputs anyway).
    pub fn at<T: Scalar>(&self, x: T) -> (T, T) {
        let (xs, zs) = (&self.x, &self.z);
        let n = xs.len();
        let at = x.value();
        if n == 0 {
            return (T::zero(), T::zero());
        }
        if at < xs[0] {
            return (T::from(zs[0]), T::zero());
        }
        if at >= xs[n - 1] {
            return (T::from(zs[n - 1]), T::zero());
        }
        let i = xs.partition_point(|&xi| xi <= at) - 1;
        let slope = (zs[i + 1] - zs[i]) / (xs[i + 1] - xs[i]);
        ((x - xs[i]) * slope + zs[i], T::from(slope))
    }
}

impl<T: Scalar> Road<T> {
    /// z(x) and dz/dx of the chosen profile.
    pub fn profile_at(&self, x: T) -> (T, T) {
        match self.profile {
            0 => {
                let k = T::from(2.0 * PI) / self.wavelength;
                let (s, c) = (k * x).sin_cos();
                (self.amplitude * s, self.amplitude * k * c)
            }
            1 => {
                let u = x - self.bump_start;
                // Half-open, as the edges' indicators fire on reaching zero: at an edge's event
                // the profile (and its derivatives) are already those of the side ahead.
                if !(u >= T::zero() && u < self.bump_length) {
                    return (T::zero(), T::zero());
                }
                let k = T::from(2.0 * PI) / self.bump_length;
                let (s, c) = (k * u).sin_cos();
                (self.bump_height * 0.5 * (T::one() - c), self.bump_height * 0.5 * k * s)
            }
            _ => self.measured.at(x),
        }
    }
}

impl<T> Road<T> {
    /// The file `table` names: a relative name inside the resources folder (without `..`, so
    /// it stays there), an absolute path, or a `file:` URI (decoded as `fmuResourceLocation`
    /// is).
    pub fn table_path(&self) -> Result<PathBuf, ModelError> {
        let name = self.table.as_str();
        if name.trim().is_empty() {
            return Err(ModelError("profile 2 needs a table file, but the parameter table is empty".to_owned()));
        }
        if name.starts_with("file:") {
            return fmu_export::fmi2::ffi::resource_dir(name)
                .ok_or_else(|| ModelError(format!("table = '{name}' is not a file URI of a local absolute path (file:///dir/file.csv)")));
        }
        let path = Path::new(name);
        if path.is_absolute() {
            return Ok(path.to_owned());
        }
        if path.components().any(|c| matches!(c, Component::ParentDir)) {
            return Err(ModelError(format!(
                "table = '{name}': a relative name is a file in the FMU's resources/ folder and cannot contain '..'; give an absolute path for a file elsewhere"
            )));
        }
        match &self.resource_dir {
            Some(dir) => Ok(dir.join(path)),
            None => Err(ModelError(format!(
                "profile 2 reads table = '{name}' from the FMU's resources/ folder, but the importer gave no resource location (give an absolute path instead)"
            ))),
        }
    }

    /// Reads the measured profile from the file `table` names, unless it was read from that
    /// file already; errors name the file (and the line, for what is in it).
    fn load_measured(&mut self) -> Result<(), ModelError> {
        let path = self.table_path()?;
        if self.measured_from.as_ref() == Some(&path) {
            return Ok(());
        }
        let shown =
            if path.as_os_str() == self.table.as_str() { self.table.clone() } else { format!("{} ({})", self.table, path.display()) };
        let text = std::fs::read_to_string(&path).map_err(|e| ModelError(format!("cannot read the profile table {shown}: {e}")))?;
        self.measured = Table::parse(&text, &self.table).map_err(ModelError)?;
        self.measured_from = Some(path);
        Ok(())
    }
}

impl<T: Scalar> Equations<T> for Road<T> {
    fn initial_state(&mut self, x: &mut [T]) -> Result<(), ModelError> {
        if self.profile == 2 {
            self.load_measured()?;
        }
        State { x: T::zero() }.store(x);
        Ok(())
    }

    #[inline]
    fn derivatives(&self, _t: T, _x: &[T], dx: &mut [T]) {
        State { x: self.speed }.store(dx);
    }

    fn outputs(&mut self, _t: T, x: &[T]) {
        let (z, slope) = self.profile_at(State::load(x).x);
        self.z_r = z;
        self.z_r_dot = self.speed * slope;
    }
}

impl Model for Road {
    const N_STATES: usize = State::LEN;
    /// The bump's two edges (profile 1).
    const N_EVENT_INDICATORS: usize = 2;

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "road",
            description: "The road under a wheel (Ex. 4 as a system): z_r and z_r' of a sinusoid, a bump or a measured profile at a speed",
            stop_time: 10.0,
            tolerance: 1e-6,
            output_interval: 1e-3,
            documentation: include_str!("../derivation.md"),
        }
    }

    /// The bump's edges, where z_r'' jumps, as state events: x - s and x - (s + l) change sign
    /// there, so a solver restarts at them and an FMI 3.0 importer that allows early return
    /// sees them. The other profiles have none (constants).
    fn event_indicators(&self, _t: f64, x: &[f64], z: &mut [f64]) {
        if self.profile == 1 {
            let x = State::load(x).x;
            z[0] = x - self.bump_start;
            z[1] = x - (self.bump_start + self.bump_length);
        } else {
            z.fill(1.0);
        }
    }

    /// Only remembers where the resources are: the table is read when profile 2 is used.
    fn resources(&mut self, dir: &Path) -> Result<(), ModelError> {
        self.resource_dir = Some(dir.to_owned());
        Ok(())
    }
}

fmu_export::export_fmu!(Road);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;

    const SHIPPED: &str = include_str!("../resources/profile.csv");

    /// The FMU's resources folder as the crate ships it.
    fn resources_dir() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("resources")
    }

    fn run(params: &[(&str, f64)], with_resources: bool) -> fmu_export::harness::Trajectory {
        let mut h = Harness::<Road>::new();
        if with_resources {
            h.load_resources(&resources_dir()).unwrap();
        }
        for (name, value) in params {
            h.set(name, *value).unwrap();
        }
        h.initialize(None).unwrap();
        h.run(10.0, 1e-3, &["x", "z_r", "z_r_dot"]).unwrap()
    }

    /// The sinusoid against its closed form at x = v t: z = a sin(k v t), z' = a k v cos(k v t).
    /// DOPRI5 integrates x' = v exactly but for rounding, which adds up over the steps: after n
    /// steps x is off by at most n ulps of x, which moves z by a k times that and z' by a k^2 v
    /// times that (the bounds below, with a factor 2 for the rounding of the closed form itself).
    #[test]
    fn sinusoid_matches_the_closed_form() {
        let traj = run(&[("speed", 30.0)], false);
        let (a, k, v) = (0.04, 2.0 * PI / 3.0, 30.0);
        let (x, z, dz) = (traj.get("x"), traj.get("z_r"), traj.get("z_r_dot"));
        let mut worst: f64 = 0.0;
        for (i, &t) in traj.time.iter().enumerate() {
            let drift = 2.0 * (i as f64 + 1.0) * f64::EPSILON * (v * t).max(1.0);
            assert!((x[i] - v * t).abs() <= drift, "x at {t}: {}", x[i] - v * t);
            assert!((z[i] - a * (k * v * t).sin()).abs() <= a * k * drift + 1e-16, "z_r at {t}");
            assert!((dz[i] - a * k * v * (k * v * t).cos()).abs() <= a * k * k * v * drift + 1e-15, "z_r_dot at {t}");
            worst = worst.max((x[i] - v * t).abs());
        }
        assert!(worst < 1e-9, "x drifted by {worst:e} m over 10 s");
    }

    /// The bump at 2 m/s: zero before 5 m (t < 2.5 s) and after 6 m (t > 3 s), the half
    /// cosine in between with its top h at the middle (t = 2.75 s), and z' the derivative of z:
    /// central differences of the sampled z (h = 1 ms) are off by z''' h^2 / 6 = (h_b / 2)
    /// (2 pi v / l)^3 h^2 / 6, 1e-5, inside the bump; at its two ends z'' jumps from 0 to
    /// (h_b / 2)(2 pi v / l)^2 = 3.9 m/s2, and the difference is off by a quarter of that times h.
    #[test]
    fn bump_matches_the_closed_form_and_its_rate_is_the_derivative() {
        let traj = run(&[("speed", 2.0), ("profile", 1.0)], false);
        let (z, dz) = (traj.get("z_r"), traj.get("z_r_dot"));
        for (i, &t) in traj.time.iter().enumerate() {
            let u = 2.0 * t - 5.0;
            let expect = if (0.0..=1.0).contains(&u) { 0.025 * (1.0 - (2.0 * PI * u).cos()) } else { 0.0 };
            assert!((z[i] - expect).abs() < 1e-12, "z_r at {t}: {} against {expect}", z[i]);
            if i > 0 && i + 1 < z.len() {
                let central = (z[i + 1] - z[i - 1]) / 2e-3;
                let at_an_end = (t - 2.5).abs() < 1.5e-3 || (t - 3.0).abs() < 1.5e-3;
                let bound = if at_an_end { 0.25 * 3.95 * 1e-3 + 1e-5 } else { 2e-5 };
                assert!((dz[i] - central).abs() < bound, "z_r_dot at {t}: {} against {central}", dz[i]);
            }
        }
        let top = z.iter().cloned().fold(f64::MIN, f64::max);
        assert!((top - 0.05).abs() < 1e-12);
    }

    /// The shipped table at 1 m/s: z at each row's x is the row's z, linear between rows.
    #[test]
    fn measured_profile_interpolates_the_table() {
        let table = Table::parse(SHIPPED, TABLE_FILE).unwrap();
        let traj = run(&[("speed", 1.0), ("profile", 2.0)], true);
        for (x, z) in table.x.iter().zip(&table.z) {
            let i = (x * 1000.0).round() as usize;
            if i < traj.time.len() {
                assert!((traj.get("z_r")[i] - z).abs() < 1e-12, "z at x = {x}");
            }
        }
        // Midway in the ramp 4..4.1 m the slope is 0.2, times 1 m/s.
        let i = 4050;
        assert!((traj.get("z_r")[i] - 0.01).abs() < 1e-12 && (traj.get("z_r_dot")[i] - 0.2).abs() < 1e-9);
        assert_eq!(table.at(-1.0), (0.0, 0.0));
        assert_eq!(table.at(25.0), (0.02, 0.0));
    }

    #[test]
    fn bad_tables_are_explained() {
        let err = |t: &str| Table::parse(t, "p.csv").unwrap_err();
        assert!(err("x,y\n0,0\n1,1\n").contains("p.csv, line 1: the header must be 'x,z'"));
        assert!(err("x,z\n0,0\n1,abc\n").contains("line 3: 'abc' is not a finite number"));
        assert!(err("x,z\n0,0\n0,1\n").contains("line 3: x must increase"));
        assert!(err("x,z\n0,0,1\n").contains("line 2: a row has two numbers"));
        assert!(err("x,z\n0,0\n").contains("at least two rows"));
        // Through initialization, as an importer meets them: the file named, and the line.
        let dir = tempfile::tempdir().unwrap();
        let init = |table: Option<&str>, resources: Option<&Path>| {
            let mut h = Harness::<Road>::new();
            if let Some(dir) = resources {
                h.load_resources(dir).unwrap();
            }
            h.set("profile", 2.0).unwrap();
            if let Some(table) = table {
                h.set_string("table", table).unwrap();
            }
            h.initialize(None).map(|()| h)
        };
        let missing = init(None, Some(dir.path())).err().unwrap();
        assert!(missing.contains("cannot read the profile table profile.csv (") && missing.contains("No such file"), "{missing}");
        std::fs::write(dir.path().join("bad.csv"), "x,z\n1,0\n0,1\n").unwrap();
        let bad = init(Some("bad.csv"), Some(dir.path())).err().unwrap();
        assert!(bad.contains("bad.csv, line 3: x must increase"), "{bad}");
        assert!(init(Some(""), Some(dir.path())).err().unwrap().contains("the parameter table is empty"));
        assert!(init(Some("../profile.csv"), Some(dir.path())).err().unwrap().contains("cannot contain '..'"));
        assert!(init(Some("file://host/x.csv"), Some(dir.path())).err().unwrap().contains("is not a file URI of a local absolute path"));
        let none = init(None, None).err().unwrap();
        assert!(none.contains("the importer gave no resource location"), "{none}");
        // The sinusoid needs no file: a bad table is not read then.
        let mut h = Harness::<Road>::new();
        h.set_string("table", "nowhere.csv").unwrap();
        h.initialize(None).unwrap();
    }

    /// `table` names the file: the second shipped sample by its name, the same file by
    /// absolute path and by file URI, and a file outside the resources; each interpolated
    /// linearly between its rows (checked at the rows and midway between them, from the file
    /// itself).
    #[test]
    fn the_table_parameter_names_the_profile_file() {
        let run_with = |table: &str, resources: bool| {
            let mut h = Harness::<Road>::new();
            if resources {
                h.load_resources(&resources_dir()).unwrap();
            }
            h.set("speed", 1.0).unwrap();
            h.set("profile", 2.0).unwrap();
            h.set_string("table", table).unwrap();
            h.initialize(None).unwrap();
            assert_eq!(h.get_string("table").unwrap(), table);
            h.run(10.0, 1e-3, &["z_r", "z_r_dot"]).unwrap()
        };
        let bump = resources_dir().join("speed_bump.csv");
        let by_name = run_with("speed_bump.csv", true);
        let table = Table::parse(&std::fs::read_to_string(&bump).unwrap(), "speed_bump.csv").unwrap();
        for k in 0..table.x.len() - 1 {
            let (x0, x1, z0, z1) = (table.x[k], table.x[k + 1], table.z[k], table.z[k + 1]);
            for (x, z) in [(x0, z0), (0.5 * (x0 + x1), 0.5 * (z0 + z1))] {
                let i = (x * 1000.0).round() as usize;
                if i < by_name.time.len() {
                    // x = t exactly at 1 m/s up to DOPRI5's rounding (see the sinusoid test).
                    assert!((by_name.get("z_r")[i] - z).abs() < 1e-12, "z at x = {x}");
                }
            }
        }
        // The ramp up: slope 0.07 / 0.3 at 1 m/s.
        assert!((by_name.get("z_r_dot")[3150] - 0.07 / 0.3).abs() < 1e-12);
        let absolute = run_with(bump.to_str().unwrap(), false);
        let uri = run_with(&format!("file://{}", bump.display()), false);
        assert_eq!(by_name.get("z_r"), absolute.get("z_r"));
        assert_eq!(by_name.get("z_r"), uri.get("z_r"));
        // The default names the shipped profile.csv: the same run as before the parameter.
        let default = run(&[("speed", 1.0), ("profile", 2.0)], true);
        let named = run_with(TABLE_FILE, true);
        assert_eq!(default.get("z_r"), named.get("z_r"));
    }

    /// `table` is a fixed parameter: refused after initialization, with the standard's rule.
    #[test]
    fn the_table_is_fixed_after_initialization() {
        let mut h = Harness::<Road>::new();
        h.load_resources(&resources_dir()).unwrap();
        h.initialize(None).unwrap();
        let err = h.set_string("table", "speed_bump.csv").unwrap_err();
        assert!(err.contains("parameter 'table' is fixed and can be set only before fmi2ExitInitializationMode"), "{err}");
    }

    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<Road>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<Road>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
