//! The ME326 lab handbook as figures and numbers: every figure its "Discussion and
//! Deliverables" sections ask for (Ex. 1 to 6 and App. E), computed from this workspace's FMUs,
//! with `index.html` (each figure with its caption and the numbers a report quotes) and
//! `summary.json` (those numbers by key). Every number is computed at run time. This is the
//! lab's content: the runs go through the engine, the figures through the plots crate, and
//! `runner handbook` only builds the FMUs that are missing and puts the files in place.

use std::collections::BTreeMap;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use fmi_importer::{Fmu, Variable};
use formulas::{Formula, Metrics, References};
use plots::animation::{self, Animation};
use plots::figure::{self, Curve, Figure, Marker, Note, Panel, Style, VLine};
use plots::outputs::{self, Axis};
use plots::scene::Scene;
use plots::trace::{self, Event, Trace};
use plots::Format;
use rayon::prelude::*;
use runner_engine::run::{Grid, GridSettings};
use runner_engine::sweep::{parse_range, Plan};
use runner_engine::variables;
use runner_workspace::experiment::{self, Experiment, RunDefaults};
use runner_workspace::Located;
use solvers::Method;

/// One degree in radians.
const DEGREE: f64 = PI / 180.0;

/// The models the handbook uses.
pub const MODELS: [&str; 10] = [
    "second_order",
    "pendulum",
    "bumper",
    "quarter_car",
    "crank_slider",
    "offset_crank_slider",
    "crank_rocker",
    "double_rocker",
    "trebuchet",
    "inverted_crank_slider",
];

/// What the program that writes the handbook provides: how a finished file is put in place,
/// whether the user asked to stop, and progress.
pub trait Host: Sync {
    /// Writes the finished file `path` (atomically: a reader never sees half of it).
    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), String>;
    /// True once the user asked to stop: the exercises still to run are not started.
    fn interrupted(&self) -> bool;
    /// One more of the [`EXERCISES`] is done.
    fn exercise_done(&self);
}

/// How many exercises (sections of the page) the handbook computes.
pub const EXERCISES: usize = 8;

/// Options of the handbook build.
pub struct Options {
    /// The directory to write into (created if missing).
    pub out: PathBuf,
    /// Format of the figures (GIFs stay GIFs).
    pub format: Format,
    /// Worker threads (default: one per core).
    pub threads: Option<usize>,
}

/// A number a report quotes.
#[derive(Debug, Clone)]
pub struct Quoted {
    /// What it is, for the page.
    pub label: String,
    /// The value, SI.
    pub value: f64,
    /// Its unit on the page.
    pub unit: &'static str,
    /// Key in summary.json (`None`: page only).
    pub key: Option<String>,
}

/// A figure file and its caption.
#[derive(Debug, Clone)]
pub struct Entry {
    /// File name inside the output directory.
    pub file: String,
    /// Caption on the page.
    pub caption: String,
}

/// One exercise's part of the page.
#[derive(Debug, Clone, Default)]
pub struct Section {
    /// HTML anchor, e.g. `ex3`.
    pub id: &'static str,
    /// Heading.
    pub title: String,
    /// What was run, in a sentence or two.
    pub intro: String,
    /// Figures in page order.
    pub figures: Vec<Entry>,
    /// Numbers for the page's table (and summary.json, where keyed).
    pub numbers: Vec<Quoted>,
    /// Extra JSON values for summary.json (objects such as the trebuchet's release state).
    pub extra: Vec<(String, serde_json::Value)>,
}

/// What the handbook build produced.
pub struct Built {
    /// The page's sections, in handbook order.
    pub sections: Vec<Section>,
    /// Every file written.
    pub files: Vec<PathBuf>,
    /// How long it took (s).
    pub seconds: f64,
}

/// The FMUs of [`MODELS`] that `runner build` has not written yet.
pub fn missing_fmus() -> Vec<String> {
    let root = runner_workspace::root();
    MODELS.iter().filter(|m| !runner_workspace::fmu_path(&root, m).is_file()).map(|m| m.to_string()).collect()
}

/// The loaded FMUs, their files and their experiment files.
pub struct Models {
    loaded: BTreeMap<&'static str, (Fmu, Experiment)>,
    paths: BTreeMap<&'static str, PathBuf>,
}

impl Models {
    /// Loads every model of [`MODELS`]; a missing FMU is named, with the command that builds it.
    pub fn load() -> Result<Models, String> {
        let (mut loaded, mut paths) = (BTreeMap::new(), BTreeMap::new());
        for m in MODELS {
            let Located::Model { fmu, experiment, .. } = runner_workspace::locate(m)? else {
                return Err(format!("{m} is not a model of this workspace"));
            };
            if !fmu.is_file() {
                return Err(format!("{} is missing: build it with `runner build {m}`", fmu.display()));
            }
            loaded.insert(m, (Fmu::load(&fmu)?, experiment::read(&experiment)?));
            paths.insert(m, fmu);
        }
        Ok(Models { loaded, paths })
    }

    fn get(&self, id: &str) -> &(Fmu, Experiment) {
        &self.loaded[id]
    }
}

/// Where a section writes and how.
struct Context<'a> {
    models: &'a Models,
    dir: &'a Path,
    format: Format,
    threads: usize,
    host: &'a dyn Host,
}

/// A run's settings beyond the model's own defaults.
#[derive(Default, Clone)]
struct RunSpec<'s> {
    set: &'s [&'s str],
    stop_time: Option<f64>,
    output_interval: Option<f64>,
    tolerance: Option<f64>,
}

impl Context<'_> {
    fn fmu(&self, id: &str) -> &Fmu {
        &self.models.get(id).0
    }

    /// Runs model `id` with `spec`, recording its numeric outputs and `extra` variables.
    fn run(&self, id: &str, spec: &RunSpec, extra: &[&str]) -> Result<Trace, String> {
        let (fmu, experiment) = self.models.get(id);
        let md = &fmu.description;
        let settings =
            GridSettings { start_time: None, stop_time: spec.stop_time, output_interval: spec.output_interval, tolerance: spec.tolerance };
        let grid = Grid::choose(md, &[settings, experiment.simulate.grid()])?;
        let mut sets = experiment.simulate.set.clone();
        sets.extend(spec.set.iter().map(|s| s.to_string()));
        let assignments = variables::parse_sets(md, &sets)?;
        let mut recorded: Vec<&Variable> = md.outputs().filter(|v| v.kind.is_numeric()).collect();
        for name in extra {
            let v = variables::find(md, name)?;
            if !recorded.iter().any(|r| r.name == v.name) {
                recorded.push(v);
            }
        }
        Trace::record(fmu, id, &grid, &assignments, &recorded)
    }

    /// The start value of parameter `name` of `id`.
    fn parameter(&self, id: &str, name: &str) -> Result<f64, String> {
        let md = &self.fmu(id).description;
        variables::find(md, name)?
            .start
            .as_ref()
            .and_then(|s| s.as_number())
            .ok_or_else(|| format!("{id}: parameter '{name}' has no numeric start value"))
    }

    /// `variable` of `id` as an axis in its display unit.
    fn axis(&self, id: &str, variable: &str) -> Result<Axis, String> {
        let md = &self.fmu(id).description;
        Ok(Axis::of(md, variables::find(md, variable)?))
    }

    /// Writes `figure` as `<name>.<ext>` and returns its entry.
    fn figure(&self, name: &str, figure: &Figure, caption: impl Into<String>) -> Result<Entry, String> {
        let file = format!("{name}.{}", self.format.extension());
        let path = self.dir.join(&file);
        let bytes = plots::encode(figure, self.format).map_err(|e| format!("cannot draw {}: {e}", path.display()))?;
        self.host.write(&path, &bytes)?;
        Ok(Entry { file, caption: caption.into() })
    }

    /// Writes the animation of `motion` at `frames` as the GIF `file`, `title` on every frame.
    fn gif(
        &self,
        file: &str,
        animation: &Animation,
        motion: &plots::scene::Motion,
        frames: &[usize],
        title: &str,
    ) -> Result<animation::Written, String> {
        let width = animation.config.size.unwrap_or(animation::DEFAULT_SIZE);
        let host = self.host;
        let stop = &mut |_| if host.interrupted() { Err("interrupted".to_owned()) } else { Ok(()) };
        let (bytes, written) = animation::write_gif(Vec::new(), motion, frames, title, width, animation.timing.fps, stop)?;
        self.host.write(&self.dir.join(file), &bytes)?;
        Ok(written)
    }
}

/// A number with its page label and optional summary key.
fn quoted(label: impl Into<String>, value: f64, unit: &'static str, key: Option<&str>) -> Quoted {
    Quoted { label: label.into(), value, unit, key: key.map(str::to_owned) }
}

/// The times at which `values` crosses zero upwards, linearly interpolated between samples.
pub fn upward_zero_crossings(time: &[f64], values: &[f64]) -> Vec<f64> {
    time.windows(2)
        .zip(values.windows(2))
        .filter(|(_, v)| v[0] < 0.0 && v[1] >= 0.0)
        .map(|(t, v)| t[0] + (t[1] - t[0]) * (-v[0]) / (v[1] - v[0]))
        .collect()
}

/// The mean period between successive upward zero crossings, if there are two or more.
pub fn period(time: &[f64], values: &[f64]) -> Option<f64> {
    let c = upward_zero_crossings(time, values);
    (c.len() >= 2).then(|| (c[c.len() - 1] - c[0]) / (c.len() - 1) as f64)
}

/// Model `id`'s closed forms (`models/<id>/references.toml`), the ones its Rust tests and
/// tests/fmpy evaluate too.
pub fn references(id: &str) -> Result<References, String> {
    References::from_file(&runner_workspace::root().join("models").join(id).join("references.toml"))
}

/// The exact period of a pendulum released from rest at `theta0`: references.toml's
/// 4 sqrt(L/g) K(sin²(theta0/2)).
pub fn pendulum_period_exact(length: f64, g: f64, theta0: f64) -> Result<f64, String> {
    references("pendulum")?.value("period", &[("L", length), ("g", g), ("theta0", theta0)])
}

/// The bumper's release time and its plate displacement x(t) in closed form (references.toml:
/// the overdamped contact solution until the release, then B x' + K x = 0).
struct BumperClosedForm {
    references: References,
    parameters: [(&'static str, f64); 4],
    t_release: f64,
}

impl BumperClosedForm {
    fn new(m: f64, k: f64, b: f64, v0: f64) -> Result<BumperClosedForm, String> {
        let disc = b * b - 4.0 * m * k;
        if disc <= 0.0 {
            return Err(format!("the bumper's closed form here is the overdamped one, and B^2 - 4MK = {disc} is not positive"));
        }
        let references = references("bumper")?;
        let parameters = [("M", m), ("K", k), ("B", b), ("V0", v0)];
        let t_release = references.value("t_release", &parameters)?;
        if !(t_release > 0.0 && t_release.is_finite()) {
            return Err("with these parameters the contact force never vanishes".into());
        }
        Ok(BumperClosedForm { references, parameters, t_release })
    }

    fn x(&self, t: f64) -> Result<f64, String> {
        let [m, k, b, v0] = self.parameters;
        let name = if t <= self.t_release { "x_contact" } else { "x_separated" };
        self.references.value(name, &[("t", t), m, k, b, v0])
    }
}

/// Max over samples of |a - b| relative to max |b|.
fn relative_error(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(f64::MIN_POSITIVE);
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| if (x - y).is_nan() { f64::INFINITY } else { m.max((x - y).abs() / scale) })
}

fn stacked(title: &str, panels: Vec<Panel>, height: u32) -> Figure {
    Figure::column(Some(title.to_owned()), panels, (900, height))
}

/// Ex. 1: u and q as two subplots; q' from the closed form and two numerical methods.
fn exercise_1(ctx: &Context) -> Result<Section, String> {
    let id = "second_order";
    let run = ctx.run(id, &RunSpec { output_interval: Some(0.01), ..RunSpec::default() }, &[])?;
    let (u, q) = (run.series("u")?, run.series("q")?);
    let mut s = Section { id: "ex1", title: "Exercise 1: 2q'' + 10q' + 12q = exp(-3t)".into(), ..Section::default() };
    s.intro = "q(0) = 2, q'(0) = 1; DOPRI5 (ode45's method) at the FMU's default tolerance, sampled every 10 ms.".into();
    let u_panel = Panel {
        y_label: "u(t) = exp(-3t)".into(),
        curves: vec![Curve { label: None, ..Curve::line("u", u, figure::color(0)) }],
        ..Panel::default()
    };
    let q_panel = Panel {
        x_label: "time (s)".into(),
        y_label: "q(t)".into(),
        curves: vec![Curve { label: None, ..Curve::line("q", q, figure::color(1)) }],
        ..Panel::default()
    };
    s.figures.push(ctx.figure(
        "ex1_input_and_response",
        &stacked("Ex. 1: input u(t) and response q(t)", vec![u_panel, q_panel], 300),
        "Ex. 1, plot 1: the input u(t) = exp(-3t) (top) and the response q(t) (bottom) on the same time scale.",
    )?);

    // The closed form is the one `runner compare` uses (experiment.toml [compare.reference]).
    let reference =
        ctx.models.get(id).1.compare.reference.get("q_dot").ok_or("second_order's experiment.toml has no [compare.reference] q_dot")?;
    let formula = Formula::parse(reference)?;
    if formula.names.iter().any(|n| n != "t") {
        return Err(format!("the q_dot reference '{reference}' must read only t"));
    }
    let exact: Vec<(f64, f64)> = (0..=1000).map(|i| i as f64 * 0.01).map(|t| (t, formula.evaluate(&[t]))).collect();
    let coarse = Some(0.2);
    let dopri = ctx.run(id, &RunSpec { output_interval: coarse, ..RunSpec::default() }, &[])?;
    let rk4 = ctx.run(id, &RunSpec { output_interval: coarse, set: &["solver=1", "fixed_step=0.05"], ..RunSpec::default() }, &[])?;
    let error = |t: &Trace| -> Result<f64, String> {
        let num = t.get("q_dot")?;
        let exact: Vec<f64> = t.time.iter().map(|&t| formula.evaluate(&[t])).collect();
        Ok(num.iter().zip(&exact).fold(0.0f64, |m, (a, b)| m.max((a - b).abs())))
    };
    let panel = Panel {
        x_label: "time (s)".into(),
        y_label: "q'(t)".into(),
        curves: vec![
            Curve { label: Some("closed form".into()), points: exact, color: figure::color(7), style: Style::Line(2) },
            Curve {
                label: Some("DOPRI5 (ode45's method)".into()),
                points: dopri.series("q_dot")?,
                color: figure::color(0),
                style: Style::Markers(Marker::Circle),
            },
            Curve {
                label: Some("RK4, fixed step 0.05 s".into()),
                points: rk4.series("q_dot")?,
                color: figure::color(3),
                style: Style::Markers(Marker::Cross),
            },
        ],
        ..Panel::default()
    };
    s.figures.push(ctx.figure(
        "ex1_rate_three_methods",
        &stacked("Ex. 1: q'(t), closed form and two numerical methods", vec![panel], 460),
        "Ex. 1, plot 2: q'(t) from the closed form (line) and from two numerical methods (symbols, every 0.2 s).",
    )?);
    s.numbers.push(quoted("largest |q' - q'_exact|, DOPRI5", error(&dopri)?, "", Some("second_order_q_dot_error_dopri5")));
    s.numbers.push(quoted("largest |q' - q'_exact|, RK4 at 0.05 s", error(&rk4)?, "", Some("second_order_q_dot_error_rk4")));
    Ok(s)
}

/// Ex. 2: the pendulum with forward Euler, as the handbook solves it.
fn exercise_2(ctx: &Context) -> Result<Section, String> {
    let id = "pendulum";
    const EULER_STEP: &str = "fixed_step=1e-5";
    let mut s = Section { id: "ex2", title: "Exercise 2: the simple pendulum, forward Euler".into(), ..Section::default() };
    s.intro = "Forward Euler (the handbook's EulerSolver) with a step of 0.01 ms, small enough that the swing neither grows nor decays visibly over 10 s; L = 0.75 m, m = 0.5 kg, released from rest.".into();
    let cases = [("15deg", "theta0 = 15°"), ("120deg", "theta0 = 120°")];
    let mut runs = Vec::new();
    for (value, _) in cases {
        let set = [format!("theta0={value}"), "solver=0".to_owned(), EULER_STEP.to_owned()];
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        runs.push(ctx.run(id, &RunSpec { set: &set, output_interval: Some(1e-3), ..RunSpec::default() }, &[])?);
    }
    let theta = ctx.axis(id, "theta")?;
    let omega = ctx.axis(id, "omega")?;
    let overlay: Vec<(Option<String>, &Trace, Vec<Event>)> =
        cases.iter().zip(&runs).map(|((_, label), t)| (Some(label.to_string()), t, vec![])).collect();
    let mut fig = outputs::figure("Ex. 2: theta for two release angles".into(), &overlay, std::slice::from_ref(&theta), None)?;
    fig.panels[0].curves.iter_mut().zip(cases).for_each(|(c, (_, label))| c.label = Some(label.to_string()));
    s.figures.push(ctx.figure("ex2_theta_15_and_120", &fig, "Ex. 2, plot 1: the angle for release angles of 15° and 120°, overlaid. The large swing is slower and flatter-topped: its period is longer than the small-angle one.")?);
    let single = [(None, &runs[1], vec![])];
    let fig = outputs::figure("Ex. 2: theta and theta' for theta0 = 120°".into(), &single, &[theta.clone(), omega.clone()], None)?;
    s.figures.push(ctx.figure("ex2_theta_and_rate_120", &fig, "Ex. 2, plot 2: the angle and the angular velocity for theta0 = 120°, as two subplots. Neither is sinusoidal: the angle's peaks are flattened and the velocity's are sharpened.")?);
    let phase: Vec<(Option<String>, &Trace, Vec<Event>)> =
        cases.iter().zip(&runs).map(|((_, label), t)| (Some(label.to_string()), t, vec![])).collect();
    let mut fig = outputs::figure("Ex. 2: phase portrait".into(), &phase, std::slice::from_ref(&omega), Some(&theta))?;
    fig.panels[0].curves.iter_mut().zip(cases).for_each(|(c, (_, label))| c.label = Some(label.to_string()));
    fig.panels[0].legend_lower = true;
    s.figures.push(ctx.figure("ex2_phase_portrait", &fig, "Ex. 2, plot 3: the phase portrait, angular velocity against angle. Each run is a closed curve, traced again every period: the energy is conserved (with friction the curve would spiral inwards).")?);

    let (length, g) = (ctx.parameter(id, "L")?, ctx.parameter(id, "g")?);
    let keys = ["pendulum_period_15deg_s", "pendulum_period_120deg_s"];
    for (((value, label), run), key) in cases.iter().zip(&runs).zip(keys) {
        let theta0 = run.get("theta")?[0];
        let t = period(&run.time, run.get("theta")?).ok_or_else(|| format!("the {value} run crosses zero fewer than twice"))?;
        s.numbers.push(quoted(format!("period, {label} (Euler, from zero crossings)"), t, "s", Some(key)));
        let exact = pendulum_period_exact(length, g, theta0)?;
        s.numbers.push(quoted(format!("period, {label}, exact (elliptic integral)"), exact, "s", Some(&key.replace("_s", "_exact_s"))));
        s.numbers.push(quoted(format!("period, {label}: Euler / exact - 1"), t / exact - 1.0, "relative", None));
        let energy = run.get("energy")?;
        let drift = (energy.last().copied().unwrap_or(f64::NAN) - energy[0]) / energy[0];
        s.numbers.push(quoted(format!("energy change over 10 s, {label} (Euler's drift)"), drift, "relative", None));
    }
    let small_angle = references(id)?.value("period_small_angle", &[("L", length), ("g", g)])?;
    s.numbers.push(quoted("small-angle period 2 pi sqrt(L/g)", small_angle, "s", Some("pendulum_period_small_angle_s")));
    Ok(s)
}

/// Ex. 3: the bumper against its closed form.
fn exercise_3(ctx: &Context) -> Result<Section, String> {
    let id = "bumper";
    let mut s = Section { id: "ex3", title: "Exercise 3: the massless bumper".into(), ..Section::default() };
    s.intro = "M = 1000 kg, K = 9850 N/m, B = 12500 N·s/m, V0 = 1 m/s; DOPRI5 at the FMU's default tolerance (1e-6, like ode45's), which locates the release as an event.".into();
    let released = ctx.run(id, &RunSpec::default(), &[])?;
    let attached = ctx.run(id, &RunSpec { set: &["attached=true"], ..RunSpec::default() }, &[])?;
    let (m, k, b, v0) = (ctx.parameter(id, "M")?, ctx.parameter(id, "K")?, ctx.parameter(id, "B")?, ctx.parameter(id, "V0")?);
    let closed_form = BumperClosedForm::new(m, k, b, v0)?;
    let t_r_exact = closed_form.t_release;
    let t_r = released.last("t_release")?;
    if t_r < 0.0 {
        return Err("the bumper FMU reports no release".into());
    }
    let analytic: Vec<(f64, f64)> =
        (0..=600).map(|i| i as f64 * 0.005).map(|t| closed_form.x(t).map(|x| (t, x))).collect::<Result<_, _>>()?;
    let numeric: Vec<(f64, f64)> = released.series("x")?.into_iter().step_by(50).collect();
    let exact_at: Vec<f64> = released.time.iter().map(|&t| closed_form.x(t)).collect::<Result<_, _>>()?;
    let x_error = relative_error(released.get("x")?, &exact_at);
    let release_line =
        |label: bool| VLine { x: t_r, label: label.then(|| format!("release, t_r = {} s", trace::short(t_r))), color: figure::color(3) };
    let panel = Panel {
        x_label: "time (s)".into(),
        y_label: "x (m)".into(),
        curves: vec![
            Curve { label: Some("closed form".into()), points: analytic, color: figure::color(7), style: Style::Line(2) },
            Curve {
                label: Some("FMU (DOPRI5), every 50 ms".into()),
                points: numeric,
                color: figure::color(0),
                style: Style::Markers(Marker::Circle),
            },
        ],
        vlines: vec![release_line(true)],
        ..Panel::default()
    };
    s.figures.push(ctx.figure(
        "ex3_numerical_vs_analytical",
        &stacked("Ex. 3: plate displacement, numerical over analytical", vec![panel], 460),
        "Ex. 3, plot 1: the plate's displacement from the FMU (symbols) over the closed-form solution (line), both regimes.",
    )?);

    let events = vec![Event { time: t_r, index: 0, text: format!("release, t_r = {} s", trace::short(t_r)) }];
    let axes: Vec<Axis> = ["x", "v", "a"].iter().map(|v| ctx.axis(id, v)).collect::<Result<_, _>>()?;
    let mut fig =
        outputs::figure("Ex. 3: plate position, velocity and acceleration".into(), &[(None, &released, events.clone())], &axes, None)?;
    fig.panels.iter_mut().zip(["x (m)", "x' (m/s)", "x'' (m/s²)"]).for_each(|(p, l)| p.y_label = l.into());
    for p in &mut fig.panels {
        for v in &mut p.vlines {
            v.label = v.label.as_ref().map(|_| events[0].text.clone());
        }
    }
    let a = released.get("a")?;
    let after = released.time.iter().position(|&t| t > t_r).ok_or("no sample after the release")?;
    let caption = format!(
        "Ex. 3, plot 2: x, x' and x'' of the plate, release marked. x and x' are continuous (at release the contact force K x + B x' is zero, so the massless plate's law B x' + K x = 0 takes over smoothly), but x'' jumps, from {} to {} m/s² between the samples around t_r: small on this scale.",
        trace::short(a[after - 1]),
        trace::short(a[after])
    );
    s.figures.push(ctx.figure("ex3_x_v_a", &fig, caption)?);

    let diff: Vec<(f64, f64)> =
        released.time.iter().zip(released.get("x")?.iter().zip(attached.get("x")?)).map(|(&t, (a, b))| (t, a - b)).collect();
    let both = Panel {
        y_label: "x (m)".into(),
        curves: vec![
            Curve::line("released (mass separates)", released.series("x")?, figure::color(0)),
            Curve { style: Style::Dashed(2), ..Curve::line("attached (mass fastened)", attached.series("x")?, figure::color(1)) },
        ],
        vlines: vec![release_line(true)],
        ..Panel::default()
    };
    let difference = Panel {
        x_label: "time (s)".into(),
        y_label: "x_released - x_attached (m)".into(),
        curves: vec![Curve { label: None, ..Curve::line("difference", diff, figure::color(2)) }],
        vlines: vec![release_line(false)],
        ..Panel::default()
    };
    s.figures.push(ctx.figure("ex3_released_vs_attached", &stacked("Ex. 3: released against attached", vec![both, difference], 300), "Ex. 3, plot 3: the plate when the mass releases and when it stays attached (top); the two decay at close rates (K/B = 0.79 /s against 0.85 /s), so the bottom panel shows their difference on its own scale.")?);
    s.numbers.push(quoted("t_r, numerical (the FMU's event)", t_r, "s", Some("bumper_t_release_s")));
    s.numbers.push(quoted("t_r, analytic: ln((K + B r2)/(K + B r1)) / (r1 - r2)", t_r_exact, "s", Some("bumper_t_release_analytic_s")));
    s.numbers.push(quoted("t_r numerical - analytic", t_r - t_r_exact, "s", Some("bumper_t_release_difference_s")));
    s.numbers.push(quoted("largest |x - x_exact| / max x", x_error, "relative", None));
    Ok(s)
}

/// One solver's cheapest setting that reaches the target error.
struct StepCount {
    setting: String,
    n_steps: f64,
    n_rhs: f64,
    error: f64,
}

/// Euler (steps from the output interval down by 4) and DOPRI5 (tolerances down by decades):
/// the cheapest setting of each that reaches `target` against `reference` on output `y`.
fn step_counts(ctx: &Context, id: &str, base: &[&str], reference: &[f64], y: &str, target: f64) -> Result<(StepCount, StepCount), String> {
    let interval = STEP_COUNT_INTERVAL;
    let count = |trace: &Trace, setting: String| -> Result<StepCount, String> {
        Ok(StepCount {
            setting,
            n_steps: trace.last("n_steps")?,
            n_rhs: trace.last("n_rhs")?,
            error: relative_error(trace.get(y)?, reference),
        })
    };
    let mut euler = None;
    for k in 0..9 {
        let h = interval / 4f64.powi(k);
        let mut set: Vec<String> = base.iter().map(|s| s.to_string()).collect();
        set.push(format!("solver={}", Method::Euler.code()));
        set.push(format!("fixed_step={h:e}"));
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        let run = ctx.run(id, &RunSpec { set: &set, output_interval: Some(interval), ..RunSpec::default() }, &[])?;
        let c = count(&run, format!("fixed step {} s", trace::short(h)))?;
        if c.error <= target {
            euler = Some(c);
            break;
        }
    }
    let mut dopri = None;
    for k in 3..=10 {
        let tolerance = 10f64.powi(-k);
        let mut set: Vec<String> = base.iter().map(|s| s.to_string()).collect();
        set.push(format!("solver={}", Method::Dopri5.code()));
        let set: Vec<&str> = set.iter().map(String::as_str).collect();
        let run =
            ctx.run(id, &RunSpec { set: &set, output_interval: Some(interval), tolerance: Some(tolerance), ..RunSpec::default() }, &[])?;
        let c = count(&run, format!("relative tolerance 1e-{k}"))?;
        if c.error <= target {
            dopri = Some(c);
            break;
        }
    }
    let missing = |what: &str| format!("{id}: no {what} setting tried reaches the error {target:e}");
    Ok((euler.ok_or_else(|| missing("Euler"))?, dopri.ok_or_else(|| missing("DOPRI5"))?))
}

/// Error both solvers must reach in Ex. 4's step-count comparison: 0.1 % of the output's peak,
/// where the curves lie on top of each other in a plot.
pub const STEP_COUNT_TARGET: f64 = 1e-3;

/// Output interval of the step-count runs (s): coarse enough that an adaptive solver's own step
/// choice, not the sampling, sets its count where the solver may step across samples, and fine
/// enough (10 samples per road period at 30 m/s) that the error is measured where it occurs.
pub const STEP_COUNT_INTERVAL: f64 = 0.01;

/// Ex. 4: the quarter car.
fn exercise_4(ctx: &Context) -> Result<Section, String> {
    let id = "quarter_car";
    let mut s = Section { id: "ex4", title: "Exercise 4: the quarter-car suspension".into(), ..Section::default() };
    s.intro = format!("Table 4.1's parameters on the road z_r = (1/25) sin(2 pi x_c / 3). Step counts: for each model the cheapest forward-Euler step (from the {} s output interval down by factors of 4) and DOPRI5 tolerance (from 1e-3 down by decades) whose largest error is within {} of the output's peak, the error measured against the closed form (Ex. 1) or DOPRI5 at rtol 1e-12 (Ex. 4); steps and right-hand-side evaluations are the FMUs' n_steps and n_rhs counters.", STEP_COUNT_INTERVAL, STEP_COUNT_TARGET);

    // Ex. 4 at 30 m/s: the reference, then both solvers' cheapest settings.
    let reference = ctx.run(
        id,
        &RunSpec {
            set: &["speed=30", "abs_tol=1e-14"],
            tolerance: Some(1e-12),
            output_interval: Some(STEP_COUNT_INTERVAL),
            ..RunSpec::default()
        },
        &[],
    )?;
    let (euler, dopri) = step_counts(ctx, id, &["speed=30"], reference.get("z_s")?, "z_s", STEP_COUNT_TARGET)?;
    let euler_step = euler.setting.trim_start_matches("fixed step ").trim_end_matches(" s").to_owned();
    let euler_set = ["speed=30".to_owned(), "solver=0".to_owned(), format!("fixed_step={euler_step}")];
    let euler_set: Vec<&str> = euler_set.iter().map(String::as_str).collect();
    let euler_run = ctx.run(id, &RunSpec { set: &euler_set, output_interval: Some(1e-3), ..RunSpec::default() }, &[])?;
    let dopri_run = ctx.run(id, &RunSpec { set: &["speed=30"], output_interval: Some(1e-3), ..RunSpec::default() }, &[])?;
    let mut panels = Vec::new();
    let first_second =
        |t: &Trace, v: &str| -> Result<Vec<(f64, f64)>, String> { Ok(t.series(v)?.into_iter().filter(|p| p.0 <= 1.0).collect()) };
    for (k, v) in ["z_s", "z_u"].iter().enumerate() {
        panels.push(Panel {
            y_label: format!("{v} (m)"),
            curves: vec![
                Curve {
                    label: (k == 0).then(|| "DOPRI5 (ode45's method), rtol 1e-6".into()),
                    ..Curve::line("", first_second(&dopri_run, v)?, figure::color(0))
                },
                Curve {
                    label: (k == 0).then(|| format!("forward Euler, step {euler_step} s")),
                    style: Style::Dashed(2),
                    ..Curve::line("", first_second(&euler_run, v)?, figure::color(1))
                },
            ],
            x_label: if k == 1 { "time (s)".into() } else { String::new() },
            ..Panel::default()
        });
    }
    let difference: Vec<(f64, f64)> =
        euler_run.time.iter().zip(euler_run.get("z_s")?.iter().zip(dopri_run.get("z_s")?)).map(|(&t, (e, d))| (t, e - d)).collect();
    let largest = difference.iter().fold(0.0f64, |m, p| m.max(p.1.abs()));
    panels.push(Panel {
        x_label: "time (s)".into(),
        y_label: "z_s Euler - DOPRI5 (m)".into(),
        curves: vec![Curve { label: None, ..Curve::line("", difference, figure::color(2)) }],
        ..Panel::default()
    });
    s.figures.push(ctx.figure("ex4_euler_vs_dopri5_30ms", &stacked("Ex. 4: Euler against DOPRI5 at 30 m/s", panels, 280), format!("Ex. 4, plot 1: sprung (top) and unsprung (middle) mass over the first second at 30 m/s from DOPRI5 and from forward Euler with the step that brings it within {} of the output's peak; the bottom panel is their difference over the whole 10 s run (largest {} m, against a peak z_s of {} m).", STEP_COUNT_TARGET, trace::short(largest), trace::short(dopri_run.get("z_s")?.iter().fold(0.0f64, |m, v| m.max(v.abs())))))?);

    // The transmissibility sweep of experiment.toml (speed 1 to 50 m/s).
    let (fmu, experiment) = ctx.models.get(id);
    let sweep = &experiment.sweep;
    let ranges = sweep.param.iter().map(|p| parse_range(p)).collect::<Result<Vec<_>, _>>()?;
    let metric_texts: Vec<String> = sweep.metric.clone();
    let metrics = Metrics::parse(&metric_texts)?;
    let grid = Grid::choose(&fmu.description, &[sweep.run().grid(), experiment.simulate.grid()])?;
    let fixed = variables::parse_sets(&fmu.description, &sweep.set)?;
    let plan = Plan::new(&fmu.description, &fmu.identifier, grid, fixed, ranges, metrics)?;
    let names: Vec<String> = plan.metrics.metrics.iter().map(|(n, _)| n.clone()).collect();
    let mut rows: Vec<(f64, Vec<f64>)> = Vec::new();
    let mut point = Vec::new();
    let host = ctx.host;
    plan.execute(fmu, ctx.threads, &|| host.interrupted(), |i, r| {
        plan.space.point(i, &mut point);
        match r.metrics {
            Some(m) => rows.push((point[0], m)),
            None => return Err(format!("quarter_car at speed {}: {}", point[0], r.status)),
        }
        Ok(())
    })?;
    if ctx.host.interrupted() {
        return Err("interrupted".into());
    }
    let column = |name: &str| -> Result<Vec<(f64, f64)>, String> {
        let j = names.iter().position(|n| n == name).ok_or_else(|| format!("quarter_car's [sweep] has no metric '{name}'"))?;
        Ok(rows.iter().map(|(x, m)| (*x, m[j])).collect())
    };
    let whole = column("transmissibility")?;
    let linearized = linearized_transmissibility(ctx, id, &whole)?;
    let (peak_speed, peak) = whole.iter().copied().fold((f64::NAN, f64::NEG_INFINITY), |best, p| if p.1 > best.1 { p } else { best });
    let mut curves =
        vec![Curve { style: Style::Line(2), ..Curve::line("max(z_s)/max(z_r) over the run (the handbook's)", whole, figure::color(0)) }];
    if let Ok(steady) = column("steady_state") {
        curves.push(Curve {
            style: Style::Dashed(2),
            ..Curve::line("amplitude ratio at the road frequency over the last 5 s (steady state)", steady, figure::color(1))
        });
    }
    curves.push(Curve {
        style: Style::Markers(Marker::Cross),
        ..Curve::line("|H(i w)| of the linearized model (runner linearize)", linearized, figure::color(2))
    });
    let panel = Panel {
        x_label: "speed (m/s)".into(),
        y_label: "transmissibility".into(),
        curves,
        notes: vec![Note {
            at: (peak_speed, peak),
            text: format!("peak {} at {} m/s", trace::short(peak), trace::short(peak_speed)),
            color: figure::color(3),
        }],
        ..Panel::default()
    };
    s.figures.push(ctx.figure("ex4_transmissibility", &stacked("Ex. 4: transmissibility against speed", vec![panel], 480), format!("Ex. 4, plot 2: transmissibility max(z_s)/max(z_r) against the car's speed ({} runs, rtol 1e-9, 1 ms samples), its peak marked. Above about 5 m/s the whole-run maximum is set by the start-up transient (the car starts at rest), so the steady-state ratio is drawn too (the amplitudes of z_s and z_r at the road frequency, fitted to the samples of the last 5 s), and over it the frequency response |Z_s/Z_r|(i w), w = 2 pi speed / wavelength, of the model linearized at rest (runner linearize, no simulation).", rows.len()))?);
    s.numbers.push(quoted("peak transmissibility", peak, "", Some("quarter_car_peak_transmissibility")));
    s.numbers.push(quoted("speed at the peak", peak_speed, "m/s", Some("quarter_car_peak_speed_m_s")));

    // Step counts on Ex. 1 (closed form) and Ex. 4.
    let ex1 = "second_order";
    let formula = Formula::parse(
        ctx.models.get(ex1).1.compare.reference.get("q").ok_or("second_order's experiment.toml has no [compare.reference] q")?,
    )?;
    let samples = (10.0 / STEP_COUNT_INTERVAL).round() as usize;
    let grid_times: Vec<f64> = (0..=samples).map(|i| i as f64 * STEP_COUNT_INTERVAL).collect();
    let q_exact: Vec<f64> = grid_times.iter().map(|&t| formula.evaluate(&[t])).collect();
    let (euler1, dopri1) = step_counts(ctx, ex1, &[], &q_exact, "q", STEP_COUNT_TARGET)?;
    let mut bars = Vec::new();
    let mut categories = Vec::new();
    let mut json = serde_json::Map::new();
    for (k, (name, key, e, d)) in
        [("Ex. 1 (second order)", "second_order", &euler1, &dopri1), ("Ex. 4 (quarter car, 30 m/s)", "quarter_car", &euler, &dopri)]
            .into_iter()
            .enumerate()
    {
        let x = k as f64 * 3.0;
        categories.push((x, name.to_owned()));
        bars.push((x - 0.55, e.n_steps.log10(), format!("Euler: {}", e.n_steps), figure::color(1)));
        bars.push((x + 0.55, d.n_steps.log10(), format!("DOPRI5: {}", d.n_steps), figure::color(0)));
        for (solver, shown, c) in [("euler", "forward Euler", e), ("dopri5", "DOPRI5", d)] {
            s.numbers.push(quoted(
                format!("{name}: {shown} steps ({}, error {})", c.setting, trace::short(c.error)),
                c.n_steps,
                "",
                Some(&format!("{key}_{solver}_steps")),
            ));
            json.insert(
                format!("{key}_{solver}"),
                serde_json::json!({"setting": c.setting, "n_steps": c.n_steps, "n_rhs": c.n_rhs, "error": c.error}),
            );
        }
        s.numbers.push(quoted(
            format!("{name}: Euler steps / DOPRI5 steps"),
            e.n_steps / d.n_steps,
            "",
            Some(&format!("{key}_euler_to_dopri5_steps")),
        ));
    }
    s.extra.push(("step_counts".into(), serde_json::Value::Object(json)));
    s.extra.push(("step_count_target_error".into(), serde_json::json!(STEP_COUNT_TARGET)));
    let mut panel = Panel {
        x_label: String::new(),
        y_label: "accepted steps (log scale)".into(),
        bars,
        bar_width: 1.0,
        bar_base: 0.0,
        x_categories: categories,
        log_y: true,
        ..Panel::default()
    };
    panel.x_range = Some(-1.5..4.5);
    s.figures.push(ctx.figure("ex4_step_counts", &stacked("Ex. 4: steps to the same accuracy", vec![panel], 460), format!("Ex. 4, discussion 1: accepted steps each solver needs to stay within {} of the output's peak (sampled every {} s), on Ex. 1's second-order system and on the fifth-order quarter car.", STEP_COUNT_TARGET, STEP_COUNT_INTERVAL))?);
    Ok(s)
}

/// A mechanism's animation settings, its run and its scene.
struct Mechanism {
    prepared: Animation,
    trace: Trace,
}

/// Model `id` as `runner animate` draws it, at its `[animate]` settings, and its run.
fn mechanism(ctx: &Context, id: &str) -> Result<Mechanism, String> {
    let fmu = Fmu::load(&ctx.models.paths[id])?;
    let prepared = Animation::new(fmu, &ctx.models.get(id).1, &RunDefaults::default(), None, None)?;
    let trace = prepared.record()?;
    Ok(Mechanism { prepared, trace })
}

/// Ex. 5A: each mechanism at its start, to scale.
fn exercise_5a(ctx: &Context) -> Result<Section, String> {
    let mut s = Section { id: "ex5a", title: "Exercise 5A: the four mechanisms".into(), ..Section::default() };
    s.intro = "The handbook's lengths, initial angles and speeds; the input link turns counter-clockwise.".into();
    let names = [
        ("crank_slider", "#1 crank-slider"),
        ("offset_crank_slider", "#2 offset crank-slider"),
        ("crank_rocker", "#3 crank-rocker"),
        ("double_rocker", "#4 double rocker"),
    ];
    let mut panels = Vec::new();
    for (id, title) in names {
        let md = &ctx.fmu(id).description;
        let config = ctx.models.get(id).1.animate.clone();
        let scene = Scene::new(md, &config)?;
        let grid =
            Grid::choose(md, &[GridSettings { start_time: None, stop_time: Some(0.01), output_interval: Some(0.01), tolerance: None }])?;
        let trace = Trace::record(ctx.fmu(id), id, &grid, &variables::parse_sets(md, &config.set)?, &scene.variables(md))?;
        let motion = scene.motion(&trace)?;
        let view = motion.bounds(|i| i == 0);
        let theta0 = ctx.parameter(id, "theta0")? / DEGREE;
        let mut panel = motion.panel(0, &view, Some(format!("{title}, theta = {}°", trace::short(theta0))));
        panel.shapes = motion.shapes(0, false, true);
        panel.corner_text = None;
        panels.push(panel);
    }
    let fig = Figure {
        title: Some("Ex. 5A: the mechanisms in their initial configurations, to scale".into()),
        panels,
        columns: 2,
        panel_size: (560, 440),
    };
    s.figures.push(ctx.figure("ex5a_initial_configurations", &fig, "Ex. 5A: each mechanism in its initial configuration, drawn to scale (equal axes, metres); ground pivots are squares, the slider's guide dashed.")?);
    Ok(s)
}

/// Ex. 5B: the crank-slider and the crank-rocker over two crank revolutions.
fn exercise_5b(ctx: &Context) -> Result<Section, String> {
    let mut s = Section { id: "ex5b", title: "Exercise 5B: planar mechanism simulation".into(), ..Section::default() };
    s.intro = "Mechanisms #1 and #3 over two crank revolutions (DOPRI5).".into();
    for (id, title) in [("crank_slider", "crank-slider (#1)"), ("crank_rocker", "crank-rocker (#3)")] {
        let m = mechanism(ctx, id)?;
        let md = &m.prepared.fmu.description;
        let axes: Vec<Axis> =
            ["v_A_x", "v_A_y", "v_B_x", "v_B_y"].iter().map(|v| Axis::of(md, md.variable(v).expect("checked by the run"))).collect();
        let recorded = ctx.run(id, &RunSpec { output_interval: Some(m.prepared.timing.interval), ..RunSpec::default() }, &[])?;
        let fig = outputs::figure(format!("Ex. 5B: velocities of A and B, {title}"), &[(None, &recorded, vec![])], &axes, None)?;
        s.figures.push(
            ctx.figure(
                &format!("ex5b_{id}_velocities"),
                &fig,
                format!("Ex. 5B, plot 1 ({title}): the horizontal and vertical velocities of A and B against time, as separate subplots."),
            )
            .map_err(|e| format!("{id}: {e}"))?,
        );
        let motion = m.prepared.scene.motion(&m.trace)?;
        let last = motion.len() - 1;
        let view = motion.bounds(|_| true);
        let fig = Figure {
            title: None,
            panels: vec![motion.panel(last, &view, Some(format!("Ex. 5B: {title}, final position and the paths of A and B")))],
            columns: 1,
            panel_size: (760, 600),
        };
        s.figures.push(ctx.figure(&format!("ex5b_{id}_paths"), &fig, format!("Ex. 5B, plot 2 ({title}): the mechanism in its final position, with the paths traced by A and B (the animation's last frame)."))?);
        let gif = format!("ex5b_{id}.gif");
        let frames = m.prepared.timing.frames(&m.trace.time);
        let written = ctx.gif(&gif, &m.prepared, &motion, &frames, &format!("{title}: two crank revolutions"))?;
        s.figures.push(Entry {
            file: gif,
            caption: format!(
                "Ex. 5B, the animated GIF ({title}): {} frames at {} fps, {} s of motion per second.",
                written.frames,
                trace::short(written.fps),
                trace::short(m.prepared.timing.frame_step * written.fps)
            ),
        });
        s.numbers.push(quoted(format!("{title}: GIF frames"), written.frames as f64, "", Some(&format!("{id}_gif_frames"))));
        s.numbers.push(quoted(
            format!("{title}: largest vector-loop gap |e|"),
            recorded.get("loop_residual")?.iter().fold(0.0f64, |a, b| a.max(b.abs())),
            "m",
            None,
        ));
    }
    Ok(s)
}

/// Ex. 6: the trebuchet.
fn exercise_6(ctx: &Context) -> Result<Section, String> {
    let id = "trebuchet";
    let mut s = Section { id: "ex6", title: "Exercise 6: the walking arm trebuchet".into(), ..Section::default() };
    s.intro = "Table 6.1's geometry and weights with the model's default starting angles and release angle (MODELS.md): falling about D, impact, swinging about A, and the projectile's flight until it lands.".into();
    let m = mechanism(ctx, id)?;
    let trace = &m.trace;
    let regime = trace.get("regime")?;
    let first = |r: f64| regime.iter().position(|&x| x >= r);
    let impact = first(2.0).ok_or("the trebuchet never reached the ground (no impact)")?;
    let release = first(4.0).ok_or("the trebuchet never released the projectile")?;
    let (t_impact, t_release, t_end) = (trace.last("t_impact")?, trace.last("t_release")?, *trace.time.last().unwrap_or(&0.0));
    let events = vec![
        Event { time: t_impact, index: impact, text: "impact: regime 2, then 3 (swinging about A)".into() },
        Event { time: t_release, index: release, text: "release: regime 4 (flight)".into() },
        Event { time: t_end, index: trace.time.len() - 1, text: "landing".into() },
    ];
    let md = &m.prepared.fmu.description;
    let speed = Axis::of(md, variables::find(md, "projectile_speed")?);
    let mut fig = outputs::figure("Ex. 6: projectile speed through the four regimes".into(), &[(None, trace, events)], &[speed], None)?;
    fig.panels[0].y_label = "projectile speed (m/s)".into();
    s.figures.push(ctx.figure("ex6_projectile_speed", &fig, "Ex. 6, plot 1: the projectile's speed through regime 1 (falling about D), the impact (regime 2, instantaneous), regime 3 (swinging about A) and regime 4 (flight).")?);

    let motion = m.prepared.scene.motion(trace)?;
    // The release configuration is the last sample before the projectile flies.
    let before_release = release.saturating_sub(1);
    let view = motion.bounds(|i| i <= before_release);
    let panels = [(0, "start"), (impact, "just after impact"), (before_release, "at release")]
        .iter()
        .map(|&(i, name)| {
            let mut p = motion.panel(i, &view, Some(format!("{name}, t = {} s", trace::short(trace.time[i]))));
            p.corner_text = None;
            p
        })
        .collect();
    let fig = Figure {
        title: Some("Ex. 6: start, impact and release configurations (same scale)".into()),
        panels,
        columns: 3,
        panel_size: (520, 470),
    };
    s.figures.push(ctx.figure("ex6_configurations", &fig, "Ex. 6, plot 2: the starting configuration, the first sample after A hits the ground, and the last sample before the projectile leaves the sling, to one scale, with the paths of the counterweight B and the projectile E so far.")?);
    let gif = "ex6_trebuchet.gif".to_owned();
    let frames = m.prepared.timing.frames(&trace.time);
    let written = ctx.gif(&gif, &m.prepared, &motion, &frames, "walking arm trebuchet")?;
    s.figures.push(Entry { file: gif, caption: format!("Ex. 6, the animated GIF: {} frames at {} fps, a quarter of real speed, with the trails of the counterweight (regimes 1 to 3) and the projectile; after release the frame keeps its scale and follows the projectile.", written.frames, trace::short(written.fps)) });

    let range = trace.last("range")?;
    let ideal = trace.last("range_ideal")?;
    let efficiency = trace.last("efficiency")?;
    s.numbers.push(quoted("range (landing x of the projectile)", range, "m", Some("trebuchet_range_m")));
    s.numbers.push(quoted(
        "ideal range: all initial potential energy to the projectile at 45°",
        ideal,
        "m",
        Some("trebuchet_range_ideal_m"),
    ));
    s.numbers.push(quoted(
        "efficiency: projectile kinetic energy at release / initial potential energy",
        efficiency,
        "",
        Some("trebuchet_efficiency"),
    ));
    s.numbers.push(quoted("range / ideal range", range / ideal, "", None));
    s.numbers.push(quoted("impact time", t_impact, "s", Some("trebuchet_t_impact_s")));
    s.numbers.push(quoted("release time", t_release, "s", Some("trebuchet_t_release_s")));
    s.numbers.push(quoted("landing time", t_end, "s", Some("trebuchet_t_land_s")));
    s.numbers.push(quoted("GIF frames", written.frames as f64, "", Some("trebuchet_gif_frames")));
    s.numbers.push(quoted("misfire (1: B touched the ground before release)", trace.last("misfire")?, "", Some("trebuchet_misfire")));
    // The state at release and the start, for checks that need nothing but physics.
    let at = |i: usize| -> Result<serde_json::Value, String> {
        let mut points = serde_json::Map::new();
        for p in ["A", "B", "C", "D", "E"] {
            points.insert(p.into(), serde_json::json!([trace.get(&format!("{p}_x"))?[i], trace.get(&format!("{p}_y"))?[i]]));
        }
        Ok(serde_json::Value::Object(points))
    };
    let flight = trace.time.iter().position(|&t| t > t_release).ok_or("no sample after release")?;
    s.extra.push(("trebuchet_initial_points_m".into(), at(0)?));
    s.extra.push((
        "trebuchet_first_flight_sample".into(),
        serde_json::json!({"t": trace.time[flight], "x": trace.get("x_p")?[flight], "y": trace.get("y_p")?[flight], "vx": trace.get("vx_p")?[flight], "vy": trace.get("vy_p")?[flight]}),
    ));
    s.extra.push(("trebuchet_projectile_speed_at_release_m_s".into(), serde_json::json!(trace.get("projectile_speed")?[flight])));
    s.extra.push(("trebuchet_animation".into(), serde_json::json!({"frame_step_s": m.prepared.timing.frame_step, "fps": written.fps, "output_interval_s": m.prepared.timing.interval})));
    Ok(s)
}

/// App. E: the inverted crank-slider's forces and input torque over one revolution.
fn appendix_e(ctx: &Context) -> Result<Section, String> {
    let id = "inverted_crank_slider";
    let mut s = Section { id: "appE", title: "Appendix E: the inverted crank-slider's kinetics".into(), ..Section::default() };
    s.intro = "The crank AB turns at a constant -60 rpm (clockwise, Fig. E.1); the joint forces and the input torque from E.23-E.24, over one revolution.".into();
    let omega = ctx.parameter(id, "omega")?;
    let revolution = 2.0 * PI / omega.abs();
    let run =
        ctx.run(id, &RunSpec { stop_time: Some(revolution), output_interval: Some(revolution / 720.0), ..RunSpec::default() }, &[])?;
    let theta = run.get("theta2")?;
    let turned: Vec<f64> = theta.iter().map(|t| (t - theta[0]).abs() / DEGREE).collect();
    let pairs =
        |name: &str| -> Result<Vec<(f64, f64)>, String> { Ok(turned.iter().copied().zip(run.get(name)?.iter().copied()).collect()) };
    let forces = ["F_Ax", "F_Ay", "F_Bx", "F_By", "F_C"];
    let curves =
        forces.iter().enumerate().map(|(k, f)| pairs(f).map(|p| Curve::line(*f, p, figure::color(k)))).collect::<Result<Vec<_>, _>>()?;
    let force_panel = Panel { y_label: "force (N)".into(), curves, x_range: Some(0.0..360.0), ..Panel::default() };
    let torque_panel = Panel {
        x_label: "crank angle turned |theta2 - theta2(0)| (deg)".into(),
        y_label: "T (N·m)".into(),
        curves: vec![Curve { label: None, ..Curve::line("T", pairs("T")?, figure::color(5)) }],
        x_range: Some(0.0..360.0),
        ..Panel::default()
    };
    s.figures.push(ctx.figure("appE_forces_and_torque", &stacked("App. E: joint forces and input torque over one revolution", vec![force_panel, torque_panel], 340), "App. E: the joint forces F_Ax, F_Ay (ground on the crank at A), F_Bx, F_By (link BD on the crank at B), the collar force F_C (top) and the input torque T (bottom) over one crank revolution.")?);
    let t = run.get("T")?;
    s.numbers.push(quoted(
        "largest |T| over a revolution",
        t.iter().fold(0.0f64, |a, b| a.max(b.abs())),
        "N·m",
        Some("inverted_crank_slider_max_torque_n_m"),
    ));
    Ok(s)
}

/// Escapes text for HTML.
fn html(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// A number for the page: 7 significant digits.
fn page_number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    if x.fract() == 0.0 && x.abs() < 1e9 {
        return format!("{x}");
    }
    let a = x.abs();
    if !(1e-3..1e6).contains(&a) {
        return format!("{x:.6e}");
    }
    let decimals = (6 - a.log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

/// The page: every section's figures with captions and its numbers.
fn page(sections: &[Section], seconds: f64) -> String {
    let mut out = String::from(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>ME326 lab handbook: figures and numbers</title>\n<style>\nbody { font-family: sans-serif; max-width: 1000px; margin: 2em auto; padding: 0 1em; color: #222; }\nfigure { margin: 1.5em 0; }\nfigure img { max-width: 100%; border: 1px solid #ddd; }\nfigcaption { font-size: 0.95em; color: #444; margin-top: 0.3em; }\ntable { border-collapse: collapse; margin: 1em 0; }\ntd, th { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; }\ntd.value { text-align: right; font-family: monospace; }\n#broken { display: none; color: #b00; font-weight: bold; }\nnav a { margin-right: 1em; }\n</style>\n</head>\n<body>\n<h1>ME326 lab handbook: figures and numbers</h1>\n",
    );
    out.push_str(&format!("<p>Every figure the handbook's Discussion and Deliverables sections ask for, computed from this project's FMUs by <code>runner handbook</code> in {seconds:.1} s. The numbers are also in <a href=\"summary.json\">summary.json</a>.</p>\n<p id=\"broken\"></p>\n<nav>"));
    for s in sections {
        out.push_str(&format!("<a href=\"#{}\">{}</a>", s.id, html(s.title.split(':').next().unwrap_or(&s.title))));
    }
    out.push_str("</nav>\n");
    for s in sections {
        out.push_str(&format!("<section id=\"{}\">\n<h2>{}</h2>\n<p>{}</p>\n", s.id, html(&s.title), html(&s.intro)));
        if !s.numbers.is_empty() {
            out.push_str("<table>\n<tr><th>quantity</th><th>value</th><th>unit</th></tr>\n");
            for n in &s.numbers {
                out.push_str(&format!(
                    "<tr><td>{}</td><td class=\"value\">{}</td><td>{}</td></tr>\n",
                    html(&n.label),
                    page_number(n.value),
                    html(n.unit)
                ));
            }
            out.push_str("</table>\n");
        }
        for f in &s.figures {
            out.push_str(&format!(
                "<figure>\n<img src=\"{0}\" alt=\"{1}\">\n<figcaption>{1} <a href=\"{0}\">{0}</a></figcaption>\n</figure>\n",
                html(&f.file),
                html(&f.caption)
            ));
        }
        out.push_str("</section>\n");
    }
    // Says so on the page if a figure fails to load (and tells a headless browser check).
    out.push_str("<script>\nwindow.addEventListener('load', function () {\n  var images = Array.prototype.slice.call(document.images);\n  var broken = images.filter(function (i) { return !i.complete || i.naturalWidth === 0; });\n  document.body.setAttribute('data-images', String(images.length));\n  document.body.setAttribute('data-broken-images', String(broken.length));\n  if (broken.length) {\n    var p = document.getElementById('broken');\n    p.style.display = 'block';\n    p.textContent = broken.length + ' figure(s) failed to load: ' + broken.map(function (i) { return i.getAttribute('src'); }).join(', ');\n  }\n});\n</script>\n</body>\n</html>\n");
    out
}

/// summary.json: every keyed number, then the extra values.
fn summary(sections: &[Section], seconds: f64) -> Result<String, String> {
    let mut map = serde_json::Map::new();
    for s in sections {
        for n in &s.numbers {
            if let Some(k) = &n.key {
                map.insert(k.clone(), serde_json::json!(n.value));
            }
        }
        for (k, v) in &s.extra {
            map.insert(k.clone(), v.clone());
        }
    }
    map.insert("build_seconds".into(), serde_json::json!(seconds));
    let mut text = serde_json::to_string_pretty(&serde_json::Value::Object(map)).map_err(|e| e.to_string())?;
    text.push('\n');
    Ok(text)
}

/// Computes every exercise and writes its figures, `index.html` and `summary.json` into
/// `options.out` through `host`. The FMUs must be built ([`missing_fmus`] says which are not).
pub fn write(options: &Options, host: &dyn Host) -> Result<Built, String> {
    let started = std::time::Instant::now();
    std::fs::create_dir_all(&options.out).map_err(|e| format!("cannot create {}: {e}", options.out.display()))?;
    let threads = options.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    if threads == 0 {
        return Err("--threads must be at least 1".into());
    }
    let models = Models::load()?;
    let ctx = Context { models: &models, dir: &options.out, format: options.format, threads: 1, host };
    type Task = fn(&Context) -> Result<Section, String>;
    // The slowest first, so two threads finish together.
    let tasks: [(&str, Task); EXERCISES] = [
        ("Ex. 6", exercise_6),
        ("Ex. 4", exercise_4),
        ("Ex. 5B", exercise_5b),
        ("Ex. 2", exercise_2),
        ("Ex. 3", exercise_3),
        ("Ex. 1", exercise_1),
        ("Ex. 5A", exercise_5a),
        ("App. E", appendix_e),
    ];
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("cannot start {threads} threads: {e}"))?;
    let results: Vec<Result<Section, String>> = pool.install(|| {
        tasks
            .par_iter()
            .map(|(name, task)| {
                if host.interrupted() {
                    return Err("interrupted".to_owned());
                }
                let r = task(&ctx).map_err(|e| format!("{name}: {e}"));
                host.exercise_done();
                r
            })
            .collect()
    });
    let mut sections = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let order = ["ex1", "ex2", "ex3", "ex4", "ex5a", "ex5b", "ex6", "appE"];
    sections.sort_by_key(|s| order.iter().position(|o| *o == s.id));
    let seconds = started.elapsed().as_secs_f64();
    host.write(&options.out.join("index.html"), page(&sections, seconds).as_bytes())?;
    host.write(&options.out.join("summary.json"), summary(&sections, seconds)?.as_bytes())?;
    let mut files: Vec<PathBuf> = sections.iter().flat_map(|s| s.figures.iter().map(|f| options.out.join(&f.file))).collect();
    files.push(options.out.join("index.html"));
    files.push(options.out.join("summary.json"));
    Ok(Built { sections, files, seconds })
}

/// |Z_s/Z_r|(i w) of quarter_car linearized at rest, at the road frequency w = 2 pi speed /
/// wavelength of each speed of `speeds` (the sweep's): the road enters as its rate
/// z_r_dot_ext, so Z_s/Z_r is the ratio of the responses of z_s and z_r to it.
fn linearized_transmissibility(ctx: &Context, id: &str, speeds: &[(f64, f64)]) -> Result<Vec<(f64, f64)>, String> {
    use runner_engine::linear::{self, Request};
    let fmu = Fmu::load_as(&ctx.models.paths[id], Some(fmi_importer::Interface::ModelExchange))?;
    let (_, experiment) = ctx.models.get(id);
    let grid = Grid::choose(&fmu.description, &[experiment.simulate.grid()])?;
    let request = Request {
        name: id,
        grid: &grid,
        assignments: &[],
        at: None,
        prefer: fmi_importer::exchange::JacobianSource::DirectionalDerivatives,
    };
    let model = linear::linearize(&fmu, &request)?;
    let wavelength = match fmu.description.variable("road_wavelength").and_then(|v| v.start.as_ref()) {
        Some(fmi_importer::model::Start::Real(x)) => *x,
        _ => return Err("quarter_car has no Real start value for road_wavelength".to_owned()),
    };
    let omegas: Vec<f64> = speeds.iter().map(|(speed, _)| 2.0 * PI * speed / wavelength).collect();
    let input = model.input("z_r_dot_ext")?;
    let body = model.frequency_response(input, model.output("z_s")?, &omegas)?;
    let road = model.frequency_response(input, model.output("z_r")?, &omegas)?;
    Ok(speeds.iter().zip(body.iter().zip(&road)).map(|((speed, _), (b, r))| (*speed, b.norm() / r.norm())).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AGM period against the series T = T0 (1 + theta0^2/16 + 11 theta0^4/3072 + ...),
    /// which is accurate to 1e-7 at 15°, and against the tabulated K(sin 60°) = 2.1565156.
    #[test]
    fn the_exact_pendulum_period_matches_the_series_and_the_table() {
        let t0 = 2.0 * PI * (0.75f64 / 9.81).sqrt();
        let a = 15f64.to_radians();
        let series = t0 * (1.0 + a * a / 16.0 + 11.0 * a.powi(4) / 3072.0);
        assert!((pendulum_period_exact(0.75, 9.81, a).unwrap() / series - 1.0).abs() < 1e-6);
        let k = 2.156_515_647_5;
        let t = 4.0 * (0.75f64 / 9.81).sqrt() * k;
        assert!((pendulum_period_exact(0.75, 9.81, 120f64.to_radians()).unwrap() / t - 1.0).abs() < 1e-9);
    }

    /// The release time makes the contact force K x + B x' vanish, and only there.
    #[test]
    fn the_bumper_releases_where_the_contact_force_vanishes() {
        let (m, k, b, v0) = (1000.0, 9850.0, 12500.0, 1.0);
        let closed_form = BumperClosedForm::new(m, k, b, v0).unwrap();
        let t_r = closed_form.t_release;
        let h = 1e-6;
        // The contact solution alone (x_contact), differentiated numerically here.
        let contact = |t: f64| closed_form.references.value("x_contact", &[("t", t), ("M", m), ("K", k), ("B", b), ("V0", v0)]).unwrap();
        let force = |t: f64| k * contact(t) + b * (contact(t + h) - contact(t - h)) / (2.0 * h);
        assert!(force(t_r).abs() < 1e-4, "{}", force(t_r));
        assert!(force(t_r * 0.9) > 0.0 && force(t_r * 1.1) < 0.0);
        assert_eq!(closed_form.x(t_r).unwrap(), contact(t_r));
        assert!(BumperClosedForm::new(1000.0, 9850.0, 100.0, 1.0).is_err(), "underdamped is refused, not guessed");
    }

    #[test]
    fn periods_come_from_interpolated_zero_crossings() {
        let time: Vec<f64> = (0..=2000).map(|i| i as f64 * 0.01).collect();
        let values: Vec<f64> = time.iter().map(|t| (2.0 * PI * t / 1.7 + 0.3).sin()).collect();
        assert!((period(&time, &values).unwrap() - 1.7).abs() < 1e-6);
    }
}
