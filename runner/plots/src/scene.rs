//! Mechanisms drawn to scale from a run: the points of a model (its `<P>_x`, `<P>_y` outputs
//! and points defined by expressions in `[animate.points]`), the links between them, the
//! paths (trails) of chosen points, the ground, and a frame that holds the motion or follows a
//! point. Animation frames and the handbook's configuration figures are drawn from it.

use std::collections::BTreeMap;
use std::ops::Range;

use fmi_importer::{Causality, Description, Kind, Variability, Variable};
use formulas::Formula;
use plotters::style::RGBColor;

use crate::figure::{self, Panel, Shape};
use crate::trace::{self, Trace};
use runner_workspace::experiment::{AnimateDefaults, PointsSpec, TrailSpec};

/// Colour of the links.
const LINK: RGBColor = RGBColor(52, 62, 88);

/// An expression of a run's variables and `t`, with its names bound to trace columns.
#[derive(Debug, Clone)]
struct Bound {
    formula: Formula,
}

impl Bound {
    fn parse(text: &str, description: &Description, what: &str) -> Result<Bound, String> {
        let formula = Formula::parse(text).map_err(|e| format!("[animate] {what} '{text}': {e}"))?;
        for name in &formula.names {
            if name != "t" {
                let v = description
                    .variable(name)
                    .ok_or_else(|| format!("[animate] {what} '{text}': {} has no variable '{name}'", description.model_name))?;
                if !v.kind.is_numeric() {
                    return Err(format!("[animate] {what} '{text}': '{name}' is a {}, not a number", v.kind));
                }
            }
        }
        Ok(Bound { formula })
    }

    /// True when every name it reads is a parameter or constant: the value never changes.
    fn is_constant(&self, description: &Description) -> bool {
        self.formula.names.iter().all(|n| {
            description.variable(n).is_some_and(|v| {
                matches!(v.causality, Causality::Parameter | Causality::CalculatedParameter | Causality::StructuralParameter)
                    || v.variability == Variability::Constant
            })
        })
    }

    /// Its value at every sample of `trace`.
    fn evaluate(&self, trace: &Trace) -> Result<Vec<f64>, String> {
        let columns: Vec<&[f64]> =
            self.formula.names.iter().map(|n| if n == "t" { Ok(trace.time.as_slice()) } else { trace.get(n) }).collect::<Result<_, _>>()?;
        let mut values = vec![0.0; columns.len()];
        Ok((0..trace.time.len())
            .map(|i| {
                for (v, c) in values.iter_mut().zip(&columns) {
                    *v = c[i];
                }
                self.formula.evaluate(&values)
            })
            .collect())
    }
}

/// A comparison `EXPR OP EXPR`.
#[derive(Debug, Clone)]
struct Condition {
    left: Bound,
    op: &'static str,
    right: Bound,
}

impl Condition {
    fn parse(text: &str, description: &Description) -> Result<Condition, String> {
        let ops = ["<=", ">=", "==", "!=", "<", ">"];
        let (at, op) = (0..text.len())
            .filter(|&i| text.is_char_boundary(i))
            .find_map(|i| ops.iter().find(|op| text[i..].starts_with(**op)).map(|op| (i, *op)))
            .ok_or_else(|| format!("[animate] condition '{text}' is not a comparison EXPR OP EXPR with OP one of < <= > >= == !="))?;
        let left = Bound::parse(&text[..at], description, "condition")?;
        let right = Bound::parse(&text[at + op.len()..], description, "condition")?;
        Ok(Condition { left, op, right })
    }

    fn evaluate(&self, trace: &Trace) -> Result<Vec<bool>, String> {
        let (a, b) = (self.left.evaluate(trace)?, self.right.evaluate(trace)?);
        Ok(a.iter()
            .zip(&b)
            .map(|(a, b)| match self.op {
                "<=" => a <= b,
                ">=" => a >= b,
                "==" => a == b,
                "!=" => a != b,
                "<" => a < b,
                _ => a > b,
            })
            .collect())
    }
}

/// Where a point comes from.
#[derive(Debug, Clone)]
enum Place {
    /// The FMU's outputs `<P>_x`, `<P>_y`.
    Outputs(String, String),
    /// `[animate.points]` expressions; `fixed` when they read parameters only.
    Defined(Bound, Bound, bool),
}

/// A mechanism as the `[animate]` section describes it, resolved against an FMU.
#[derive(Debug, Clone)]
pub struct Scene {
    names: Vec<String>,
    places: Vec<Place>,
    links: Vec<(Vec<usize>, Option<Condition>)>,
    trails: Vec<(usize, Option<Condition>)>,
    levels: Vec<Bound>,
    follow: Option<(usize, Option<Condition>)>,
    show: Vec<String>,
    /// Points drawn as dots when there are neither links nor trails.
    loose: Vec<usize>,
}

/// The point names `P` of `description`'s Real output pairs `P_x`, `P_y` that are positions:
/// the same unit, and not a rate (no `/` in it; `v_A_x` in m/s is a velocity).
pub fn output_points(description: &Description) -> Vec<String> {
    let outputs: BTreeMap<&str, &Variable> = description.outputs().filter(|v| v.kind == Kind::Real).map(|v| (v.name.as_str(), v)).collect();
    description
        .outputs()
        .filter_map(|v| {
            let point = v.name.strip_suffix("_x")?;
            let y = outputs.get(format!("{point}_y").as_str())?;
            let unit_ok = v.unit == y.unit && !v.unit.as_deref().unwrap_or("").contains('/');
            (v.kind == Kind::Real && !point.is_empty() && unit_ok).then(|| point.to_owned())
        })
        .collect()
}

impl Scene {
    /// Resolves `config` against `description`: every point named must be an output pair or
    /// defined in `[animate.points]`, every expression must read variables the FMU has.
    pub fn new(description: &Description, config: &AnimateDefaults) -> Result<Scene, String> {
        let found = output_points(description);
        let mut scene = Scene {
            names: Vec::new(),
            places: Vec::new(),
            links: Vec::new(),
            trails: Vec::new(),
            levels: Vec::new(),
            follow: None,
            show: Vec::new(),
            loose: Vec::new(),
        };
        for (name, [x, y]) in &config.points {
            let bx = Bound::parse(&x.text(), description, &format!("point {name} x"))?;
            let by = Bound::parse(&y.text(), description, &format!("point {name} y"))?;
            let fixed = bx.is_constant(description) && by.is_constant(description);
            scene.names.push(name.clone());
            scene.places.push(Place::Defined(bx, by, fixed));
        }
        let index = |scene: &mut Scene, name: &str| -> Result<usize, String> {
            if let Some(i) = scene.names.iter().position(|n| n == name) {
                return Ok(i);
            }
            if found.iter().any(|p| p == name) {
                scene.names.push(name.to_owned());
                scene.places.push(Place::Outputs(format!("{name}_x"), format!("{name}_y")));
                return Ok(scene.names.len() - 1);
            }
            Err(format!(
                "[animate] names the point '{name}', but {} has no outputs {name}_x and {name}_y and [animate.points] does not define it (points it outputs: {})",
                description.model_name,
                if found.is_empty() { "none".to_owned() } else { found.join(", ") }
            ))
        };
        let condition = |text: &Option<String>| text.as_deref().map(|t| Condition::parse(t, description)).transpose();
        for link in &config.links {
            let (points, when) = match link {
                PointsSpec::Always(p) => (p, None),
                PointsSpec::When(w) => (&w.points, Some(w.when.clone())),
            };
            if points.len() < 2 {
                return Err(format!("[animate] a link needs two or more points, not {points:?}"));
            }
            let ids = points.iter().map(|p| index(&mut scene, p)).collect::<Result<Vec<_>, _>>()?;
            let when = condition(&when)?;
            scene.links.push((ids, when));
        }
        for trail in &config.trails {
            let (point, when) = match trail {
                TrailSpec::Always(p) => (p, None),
                TrailSpec::When(w) => (&w.point, Some(w.when.clone())),
            };
            let id = index(&mut scene, point)?;
            let when = condition(&when)?;
            scene.trails.push((id, when));
        }
        if let Some(f) = &config.follow {
            let id = index(&mut scene, &f.point)?;
            scene.follow = Some((id, condition(&f.when)?));
        }
        for level in &config.levels {
            scene.levels.push(Bound::parse(&level.text(), description, "level")?);
        }
        for name in &config.show {
            trace::numeric_variable(description, name)?;
            scene.show.push(name.clone());
        }
        if scene.links.is_empty() && scene.trails.is_empty() {
            if found.is_empty() && config.points.is_empty() {
                return Err(format!(
                    "{} has no point coordinates to animate: no Real outputs <P>_x and <P>_y (in a length unit) and no [animate.points]",
                    description.model_name
                ));
            }
            for name in &found {
                let id = index(&mut scene, name)?;
                scene.trails.push((id, None));
            }
            scene.loose = (0..scene.names.len()).collect();
        }
        Ok(scene)
    }

    /// The variables a run must record for this scene.
    pub fn variables<'a>(&self, description: &'a Description) -> Vec<&'a Variable> {
        let mut names: Vec<String> = Vec::new();
        let mut add = |n: &str| {
            if n != "t" && !names.iter().any(|m| m == n) {
                names.push(n.to_owned());
            }
        };
        for place in &self.places {
            match place {
                Place::Outputs(x, y) => {
                    add(x);
                    add(y);
                }
                Place::Defined(x, y, _) => x.formula.names.iter().chain(&y.formula.names).for_each(|n| add(n)),
            }
        }
        let conditions = self.links.iter().filter_map(|l| l.1.as_ref()).chain(self.trails.iter().filter_map(|t| t.1.as_ref()));
        for c in conditions.chain(self.follow.iter().filter_map(|f| f.1.as_ref())) {
            c.left.formula.names.iter().chain(&c.right.formula.names).for_each(|n| add(n));
        }
        for l in &self.levels {
            l.formula.names.iter().for_each(|n| add(n));
        }
        self.show.iter().for_each(|n| add(n));
        names.iter().filter_map(|n| description.variable(n)).collect()
    }

    /// The scene's motion in `trace` (recorded with at least [`Scene::variables`]).
    pub fn motion<'s>(&'s self, trace: &'s Trace) -> Result<Motion<'s>, String> {
        let mut positions = Vec::new();
        for place in &self.places {
            let (x, y): (Vec<f64>, Vec<f64>) = match place {
                Place::Outputs(x, y) => (trace.get(x)?.to_vec(), trace.get(y)?.to_vec()),
                Place::Defined(x, y, _) => (x.evaluate(trace)?, y.evaluate(trace)?),
            };
            positions.push(x.into_iter().zip(y).collect::<Vec<_>>());
        }
        let always = || vec![true; trace.time.len()];
        let shown = |c: &Option<Condition>| c.as_ref().map_or_else(|| Ok(always()), |c| c.evaluate(trace));
        let links = self.links.iter().map(|(_, c)| shown(c)).collect::<Result<Vec<_>, _>>()?;
        let trails = self.trails.iter().map(|(_, c)| shown(c)).collect::<Result<Vec<_>, _>>()?;
        let following = match &self.follow {
            Some((_, c)) => shown(c)?,
            None => vec![false; trace.time.len()],
        };
        let levels =
            self.levels.iter().map(|l| l.evaluate(trace).map(|v| v.first().copied().unwrap_or(f64::NAN))).collect::<Result<_, _>>()?;
        Ok(Motion { scene: self, trace, positions, links, trails, following, levels })
    }
}

/// A scene evaluated over a run: where every point is at every sample, and which links and
/// trails are shown.
pub struct Motion<'s> {
    scene: &'s Scene,
    trace: &'s Trace,
    positions: Vec<Vec<(f64, f64)>>,
    links: Vec<Vec<bool>>,
    trails: Vec<Vec<bool>>,
    following: Vec<bool>,
    levels: Vec<f64>,
}

/// A view: the x and y ranges drawn.
pub type View = (Range<f64>, Range<f64>);

/// A motion as plain data, for a drawing made elsewhere (`runner serve`'s page draws it on a
/// canvas): the points at every sample, and per sample which links and trails are shown.
#[derive(Debug, Clone)]
pub struct Geometry {
    /// Point names.
    pub names: Vec<String>,
    /// Per point: fixed (a pivot defined by parameters only).
    pub fixed: Vec<bool>,
    /// `positions[p][i]`: point `p` at sample `i` (m).
    pub positions: Vec<Vec<(f64, f64)>>,
    /// Each link's points, and whether it is shown at each sample.
    pub links: Vec<(Vec<usize>, Vec<bool>)>,
    /// Each trail's point, and whether it is drawn at each sample.
    pub trails: Vec<(usize, Vec<bool>)>,
    /// Heights of the ground lines (m).
    pub levels: Vec<f64>,
    /// The view of every sample (see [`Motion::views`]).
    pub views: Vec<View>,
    /// The time stamp of every sample (see [`Motion::stamp`]).
    pub stamps: Vec<String>,
}

impl Motion<'_> {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.trace.time.len()
    }

    /// True when the run has no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The position of point `name` at sample `i`.
    pub fn position(&self, name: &str, i: usize) -> Option<(f64, f64)> {
        self.scene.names.iter().position(|n| n == name).map(|p| self.positions[p][i])
    }

    /// Indices of the points drawn (in links, trails or loose).
    fn drawn_points(&self) -> Vec<usize> {
        let mut ids: Vec<usize> = self.scene.links.iter().flat_map(|l| l.0.iter().copied()).collect();
        ids.extend(self.scene.trails.iter().map(|t| t.0));
        ids.extend(self.scene.loose.iter().copied());
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// The smallest box holding every drawn point at the samples `i` for which `pick(i)`.
    pub fn bounds(&self, pick: impl Fn(usize) -> bool) -> View {
        let ids = self.drawn_points();
        let points: Vec<(f64, f64)> = (0..self.len())
            .filter(|&i| pick(i))
            .flat_map(|i| ids.iter().map(move |&p| (p, i)))
            .map(|(p, i)| self.positions[p][i])
            .collect();
        let mut x = figure::exact_range(points.iter().map(|p| p.0));
        let mut y = figure::exact_range(points.iter().map(|p| p.1));
        // Room for the joints and labels, and a minimum size for a point that never moves.
        let pad = 0.08 * (x.end - x.start).max(y.end - y.start).max(1e-3);
        x = (x.start - pad)..(x.end + pad);
        y = (y.start - pad)..(y.end + pad);
        (x, y)
    }

    /// The view of every frame `frames` (sample indices, in order): one box holding the whole
    /// motion, or, with `follow`, the box of the motion before following, moved so that the
    /// followed point stays in its middle 60 % while the condition holds.
    pub fn views(&self, frames: &[usize]) -> Vec<View> {
        let Some((point, _)) = &self.scene.follow else {
            let all = self.bounds(|_| true);
            return vec![all; frames.len()];
        };
        let base = if self.following.iter().all(|&f| f) { self.bounds(|i| i == 0) } else { self.bounds(|i| !self.following[i]) };
        let (w, h) = (base.0.end - base.0.start, base.1.end - base.1.start);
        let (mut cx, mut cy) = ((base.0.start + base.0.end) / 2.0, (base.1.start + base.1.end) / 2.0);
        frames
            .iter()
            .map(|&i| {
                if self.following[i] {
                    let (px, py) = self.positions[*point][i];
                    if px.is_finite() && py.is_finite() {
                        cx = cx.clamp(px - 0.3 * w, px + 0.3 * w);
                        cy = cy.clamp(py - 0.3 * h, py + 0.3 * h);
                    }
                }
                ((cx - w / 2.0)..(cx + w / 2.0), (cy - h / 2.0)..(cy + h / 2.0))
            })
            .collect()
    }

    /// What is drawn at sample `i`: ground lines, trails up to `i`, links, joints, labels.
    pub fn shapes(&self, i: usize, with_trails: bool, with_labels: bool) -> Vec<Shape> {
        let scene = self.scene;
        let mut shapes: Vec<Shape> = self.levels.iter().filter(|l| l.is_finite()).map(|&y| Shape::Level { y }).collect();
        if with_trails {
            for (k, (p, _)) in scene.trails.iter().enumerate() {
                let points = (0..=i).map(|j| if self.trails[k][j] { self.positions[*p][j] } else { (f64::NAN, f64::NAN) }).collect();
                shapes.push(Shape::Polyline { points, color: figure::color(k), width: 2 });
            }
        }
        for (k, (ids, _)) in scene.links.iter().enumerate() {
            if self.links[k][i] {
                shapes.push(Shape::Polyline { points: ids.iter().map(|&p| self.positions[p][i]).collect(), color: LINK, width: 5 });
            }
        }
        let fixed = |p: usize| matches!(scene.places[p], Place::Defined(_, _, true));
        let in_links: Vec<usize> =
            scene.links.iter().enumerate().filter(|(k, _)| self.links[*k][i]).flat_map(|(_, l)| l.0.iter().copied()).collect();
        for &p in &in_links {
            let at = self.positions[p][i];
            shapes.push(if fixed(p) {
                Shape::Pivot { at, size: 6 }
            } else {
                Shape::Dot { at, radius: 5, fill: RGBColor(255, 255, 255), outline: LINK }
            });
        }
        for (k, (p, _)) in scene.trails.iter().enumerate() {
            if self.trails[k][i] || in_links.contains(p) {
                shapes.push(Shape::Dot { at: self.positions[*p][i], radius: 6, fill: figure::color(k), outline: LINK });
            }
        }
        if with_labels {
            for p in self.drawn_points() {
                let shown = in_links.contains(&p) || scene.trails.iter().enumerate().any(|(k, t)| t.0 == p && self.trails[k][i]);
                if shown {
                    shapes.push(Shape::Label { at: self.positions[p][i], text: scene.names[p].clone(), offset: (13, -13) });
                }
            }
        }
        shapes
    }

    /// The whole motion as plain data.
    pub fn geometry(&self) -> Geometry {
        let scene = self.scene;
        let samples: Vec<usize> = (0..self.len()).collect();
        Geometry {
            names: scene.names.clone(),
            fixed: scene.places.iter().map(|p| matches!(p, Place::Defined(_, _, true))).collect(),
            positions: self.positions.clone(),
            links: scene.links.iter().zip(&self.links).map(|((ids, _), shown)| (ids.clone(), shown.clone())).collect(),
            trails: scene.trails.iter().zip(&self.trails).map(|((p, _), shown)| (*p, shown.clone())).collect(),
            levels: self.levels.clone(),
            views: self.views(&samples),
            stamps: samples.iter().map(|&i| self.stamp(i)).collect(),
        }
    }

    /// The time stamp of sample `i`: `t = 0.700 s`, with the values of `[animate] show`.
    pub fn stamp(&self, i: usize) -> String {
        let mut text = format!("t = {:.3} s", self.trace.time[i]);
        for name in &self.scene.show {
            if let Some(c) = self.trace.column(name) {
                text.push_str(&format!("   {name} = {}", trace::short(c[i])));
            }
        }
        text
    }

    /// A panel showing sample `i` in `view`, to scale.
    pub fn panel(&self, i: usize, view: &View, title: Option<String>) -> Panel {
        Panel {
            title,
            x_label: "x (m)".into(),
            y_label: "y (m)".into(),
            shapes: self.shapes(i, true, true),
            x_range: Some(view.0.clone()),
            y_range: Some(view.1.clone()),
            equal_scales: true,
            corner_text: Some(self.stamp(i)),
            ..Panel::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::FmiVersion;

    fn var(name: &str, causality: Causality, unit: &str) -> Variable {
        Variable {
            name: name.into(),
            value_reference: 0,
            description: None,
            kind: Kind::Real,
            causality,
            variability: if causality == Causality::Parameter { Variability::Fixed } else { Variability::Continuous },
            unit: Some(unit.into()),
            display_unit: None,
            start: None,
            dimensions: Vec::new(),
        }
    }

    fn crank() -> Description {
        Description {
            fmi_version: FmiVersion::Fmi2,
            fmi_version_text: "2.0".into(),
            model_name: "crank".into(),
            description: None,
            instantiation_token: String::new(),
            generation_tool: None,
            co_simulation: None,
            model_exchange: None,
            default_experiment: None,
            units: vec![],
            variables: vec![
                var("l", Causality::Parameter, "m"),
                var("A_x", Causality::Output, "m"),
                var("A_y", Causality::Output, "m"),
                var("v_A_x", Causality::Output, "m/s"),
                var("v_A_y", Causality::Output, "m/s"),
            ],
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        }
    }

    #[test]
    fn points_are_position_pairs_not_velocities() {
        assert_eq!(output_points(&crank()), vec!["A".to_owned()]);
    }

    fn config(text: &str) -> AnimateDefaults {
        #[derive(serde::Deserialize)]
        struct File {
            animate: AnimateDefaults,
        }
        toml::from_str::<File>(text).unwrap().animate
    }

    /// A crank of length l about O: the link O-A is drawn, O is a fixed pivot (it reads only a
    /// parameter), and the frame holds the whole circle.
    #[test]
    fn a_crank_is_drawn_with_its_pivot_and_its_frame_holds_the_motion() {
        let d = crank();
        let scene =
            Scene::new(&d, &config("[animate]\npoints = { O = [0, \"0*l\"] }\nlinks = [[\"O\", \"A\"]]\ntrails = [\"A\"]\n")).unwrap();
        let names: Vec<&str> = scene.variables(&d).iter().map(|v| v.name.as_str()).collect();
        assert_eq!(names, ["l", "A_x", "A_y"]);
        let n = 100;
        let angle = |i: usize| i as f64 / (n - 1) as f64 * std::f64::consts::TAU;
        let trace = Trace {
            names: vec!["l".into(), "A_x".into(), "A_y".into()],
            time: (0..n).map(|i| i as f64).collect(),
            columns: vec![vec![0.1; n], (0..n).map(|i| 0.1 * angle(i).cos()).collect(), (0..n).map(|i| 0.1 * angle(i).sin()).collect()],
            ended_early: None,
        };
        let motion = scene.motion(&trace).unwrap();
        let shapes = motion.shapes(n - 1, true, true);
        assert!(shapes.iter().any(|s| matches!(s, Shape::Pivot { at, .. } if *at == (0.0, 0.0))), "O is a pivot");
        assert!(shapes.iter().any(|s| matches!(s, Shape::Polyline { width: 5, points, .. } if points.len() == 2)), "the link");
        assert!(shapes.iter().any(|s| matches!(s, Shape::Polyline { width: 2, points, .. } if points.len() == n)), "the whole trail");
        let (x, y) = &motion.views(&[0, n - 1])[1];
        assert!(x.start < -0.1 && x.end > 0.1 && y.start < -0.1 && y.end > 0.1, "{x:?} {y:?}");
    }

    /// The geometry `runner serve`'s page draws from is the motion the GIF is drawn from: the
    /// same positions, links, trails, views and stamps, sample by sample.
    #[test]
    fn the_geometry_is_the_motion_as_data() {
        let d = crank();
        let scene = Scene::new(
            &d,
            &config(
                "[animate]\npoints = { O = [0, \"0*l\"] }\nlinks = [[\"O\", \"A\"]]\ntrails = [{ point = \"A\", when = \"t >= 2\" }]\n",
            ),
        )
        .unwrap();
        let n = 5;
        let trace = Trace {
            names: vec!["l".into(), "A_x".into(), "A_y".into()],
            time: (0..n).map(|i| i as f64).collect(),
            columns: vec![vec![0.1; n], (0..n).map(|i| 0.1 * i as f64).collect(), vec![0.05; n]],
            ended_early: None,
        };
        let motion = scene.motion(&trace).unwrap();
        let g = motion.geometry();
        assert_eq!(g.names, ["O", "A"]);
        assert_eq!(g.fixed, [true, false], "O reads a parameter only");
        for i in 0..n {
            assert_eq!(g.positions[0][i], motion.position("O", i).unwrap());
            assert_eq!(g.positions[1][i], motion.position("A", i).unwrap());
            assert_eq!(g.stamps[i], motion.stamp(i));
        }
        assert_eq!(g.links, [(vec![0, 1], vec![true; n])]);
        assert_eq!(g.trails, [(1, vec![false, false, true, true, true])]);
        assert_eq!(g.views, motion.views(&[0, 1, 2, 3, 4]));
        assert!(g.levels.is_empty());
    }

    #[test]
    fn an_unknown_point_or_name_is_refused_with_what_there_is() {
        let d = crank();
        let err = Scene::new(&d, &config("[animate]\nlinks = [[\"O\", \"A\"]]\n")).unwrap_err();
        assert!(err.contains("'O'") && err.contains("points it outputs: A"), "{err}");
        let err = Scene::new(&d, &config("[animate]\ntrails = [{ point = \"A\", when = \"regime < 4\" }]\n")).unwrap_err();
        assert!(err.contains("no variable 'regime'"), "{err}");
        let err = Scene::new(&d, &config("[animate]\ntrails = [{ point = \"A\", when = \"A_x\" }]\n")).unwrap_err();
        assert!(err.contains("not a comparison"), "{err}");
    }

    /// Following: the frame keeps its size and moves with the point once the condition holds.
    #[test]
    fn a_followed_point_stays_in_view() {
        let d = crank();
        let scene = Scene::new(&d, &config("[animate]\ntrails = [\"A\"]\nfollow = { point = \"A\", when = \"t >= 10\" }\n")).unwrap();
        let n = 30;
        let trace = Trace {
            names: vec!["A_x".into(), "A_y".into()],
            time: (0..n).map(|i| i as f64).collect(),
            columns: vec![(0..n).map(|i| if i < 10 { (i % 2) as f64 } else { (i - 9) as f64 * 3.0 }).collect(), vec![0.0; n]],
            ended_early: None,
        };
        let motion = scene.motion(&trace).unwrap();
        let frames: Vec<usize> = (0..n).collect();
        let views = motion.views(&frames);
        let width = |v: &View| v.0.end - v.0.start;
        for (i, v) in views.iter().enumerate() {
            assert!((width(v) - width(&views[0])).abs() < 1e-12, "the scale never changes");
            let x = trace.columns[0][i];
            assert!(v.0.start <= x && x <= v.0.end, "frame {i}: {x} in {v:?}");
        }
        assert!(views[n - 1].0.start > 50.0, "the frame moved along: {:?}", views[n - 1]);
    }
}
