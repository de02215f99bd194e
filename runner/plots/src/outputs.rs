//! A run's variables against time (or against another variable, a phase portrait) as a
//! figure: one panel per variable in its display unit, several runs overlaid, events marked as
//! vertical lines (or as points against another variable). `runner simulate --plot` and the
//! handbook draw with it.

use fmi_importer::{Description, Variable};
use runner_engine::variables::{self, UnitConversion};

use crate::figure::{self, Curve, Figure, Note, Panel, VLine};
use crate::trace::{self, Event, Trace};

/// A variable as plotted: its column name, the unit it is shown in and the conversion.
#[derive(Debug, Clone)]
pub struct Axis {
    /// The variable's name (its column in a trace).
    pub name: String,
    /// The axis label: the name and the unit shown.
    pub label: String,
    /// From SI to the unit shown, when that is a display unit.
    pub conversion: Option<UnitConversion>,
}

impl Axis {
    /// `variable` in its display unit when the FMU declares one, else in its own unit.
    pub fn of(description: &Description, variable: &Variable) -> Axis {
        let conversion = variables::display_unit_of(description, variable);
        let unit = conversion.as_ref().map(|c| c.name.clone()).or_else(|| variable.unit.clone());
        let label = match unit {
            Some(u) if u != "1" => format!("{} ({u})", variable.name),
            _ => variable.name.clone(),
        };
        Axis { name: variable.name.clone(), label, conversion }
    }

    /// A value of this variable, in the unit shown.
    pub fn show(&self, si: f64) -> f64 {
        self.conversion.as_ref().map_or(si, |c| c.from_si(si))
    }

    /// The column of this variable in `trace`, converted.
    pub fn values(&self, trace: &Trace) -> Result<Vec<f64>, String> {
        Ok(trace.get(&self.name)?.iter().map(|&v| self.show(v)).collect())
    }
}

/// Panels per column before the figure gets another column.
const ROWS_PER_COLUMN: usize = 6;

/// Builds the figure of `runs` (one trace per case): one panel per y axis, all sharing the x
/// axis (time, or `x`), events as vertical lines (or marked points against `x`).
pub fn figure(title: String, runs: &[(Option<String>, &Trace, Vec<Event>)], ys: &[Axis], x: Option<&Axis>) -> Result<Figure, String> {
    let xs: Vec<Vec<f64>> = runs.iter().map(|(_, t, _)| x.map_or(Ok(t.time.clone()), |a| a.values(t))).collect::<Result<_, _>>()?;
    let x_values = xs.iter().flatten().copied();
    let x_range = if x.is_some() { figure::padded_range(x_values) } else { figure::exact_range(x_values) };
    let x_label = x.map_or("time (s)".to_owned(), |a| a.label.clone());
    let columns = ys.len().div_ceil(ROWS_PER_COLUMN).max(1);
    let rows = ys.len().div_ceil(columns);
    let mut panels = Vec::new();
    for (k, y) in ys.iter().enumerate() {
        let mut panel = Panel { y_label: y.label.clone(), x_range: Some(x_range.clone()), ..Panel::default() };
        // Only the bottom panel of each column names the shared axis.
        let bottom = k / columns == rows - 1 || k + columns >= ys.len();
        panel.x_label = if bottom { x_label.clone() } else { String::new() };
        for (i, ((label, run, events), run_x)) in runs.iter().zip(&xs).enumerate() {
            let values = y.values(run)?;
            let color = figure::color(if runs.len() > 1 { i } else { 0 });
            let mut curve = Curve::line(
                label.clone().unwrap_or_else(|| y.name.clone()),
                run_x.iter().copied().zip(values.iter().copied()).collect(),
                color,
            );
            // One legend for the overlaid runs, in the first panel; a single run needs none.
            if runs.len() == 1 || k > 0 {
                curve.label = None;
            }
            panel.curves.push(curve);
            let event_color = if runs.len() > 1 { color } else { figure::color(3) };
            for e in events {
                match x {
                    None => panel.vlines.push(VLine {
                        x: e.time,
                        label: (k == 0).then(|| format!("{} (t = {} s)", e.text, trace::short(e.time))),
                        color: event_color,
                    }),
                    Some(_) => panel.notes.push(Note {
                        at: (run_x[e.index], values[e.index]),
                        text: if k == 0 { e.text.clone() } else { String::new() },
                        color: event_color,
                    }),
                }
            }
        }
        panels.push(panel);
    }
    let width = if columns == 1 { 900 } else { 620 };
    let height = if ys.len() == 1 { 460 } else { 210 };
    Ok(Figure { title: Some(title), panels, columns, panel_size: (width, height) })
}
