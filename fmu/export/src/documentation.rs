//! The `documentation/index.html` of an FMU: the model's derivation (Markdown from the model
//! crate) and its variable table, generated from the same source as the binary and the XML.

use crate::model::{Causality, Model, Variability};
use crate::table::{ranges, Table};

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn causality(c: Causality) -> &'static str {
    match c {
        Causality::Parameter => "parameter",
        Causality::CalculatedParameter => "calculatedParameter",
        Causality::Input => "input",
        Causality::Output => "output",
        Causality::Local => "local",
        Causality::Independent => "independent",
    }
}

fn variability(v: Variability) -> &'static str {
    match v {
        Variability::Constant => "constant",
        Variability::Fixed => "fixed",
        Variability::Tunable => "tunable",
        Variability::Discrete => "discrete",
        Variability::Continuous => "continuous",
    }
}

/// Renders the complete HTML page of model `M`.
pub fn index_html<M: Model>() -> String {
    let info = M::info();
    let mut derivation = String::new();
    let parser = pulldown_cmark::Parser::new_ext(info.documentation, pulldown_cmark::Options::ENABLE_TABLES);
    pulldown_cmark::html::push_html(&mut derivation, parser);

    let model = M::default();
    let mut rows = String::new();
    for (vr, (row, range)) in Table::<M>::new().rows.iter().zip(ranges::<M>()).enumerate() {
        let start = row.start(&model).map(|s| s.to_string()).unwrap_or_default();
        rows.push_str(&format!(
            "<tr><td><code>{}</code></td><td>{vr}</td><td>{}</td><td>{}</td><td>{:?}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
            escape(row.name),
            causality(row.causality),
            variability(row.variability),
            row.base_type,
            escape(row.unit.unwrap_or("")),
            escape(row.display_unit.unwrap_or("")),
            escape(&start),
            escape(&range.to_string()),
            escape(row.description),
        ));
    }
    format!(
        r#"<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{id}: {desc}</title>
<style>
body {{ font-family: sans-serif; max-width: 60em; margin: 2em auto; line-height: 1.45; padding: 0 1em; }}
table {{ border-collapse: collapse; font-size: 0.9em; }}
td, th {{ border: 1px solid #bbb; padding: 0.2em 0.5em; text-align: left; vertical-align: top; }}
pre, code {{ background: #f4f4f4; }}
pre {{ padding: 0.5em; overflow-x: auto; }}
</style>
</head>
<body>
<h1><code>{id}</code></h1>
<p>{desc}</p>
{derivation}
<h2>Variables</h2>
<p>All values are SI; display units are the handbook's. Value references number the variables in this order.</p>
<table>
<tr><th>name</th><th>vr</th><th>causality</th><th>variability</th><th>type</th><th>unit</th><th>display unit</th><th>start</th><th>range</th><th>description</th></tr>
{rows}</table>
<h2>Simulation</h2>
<p>Default experiment: stop time {stop} s, relative tolerance {tol}, output interval {dt} s.
The solver is chosen with <code>solver</code>: 0 forward Euler, 1 classical RK4, 2 adaptive Dormand&ndash;Prince 5(4) (the method of MATLAB's <code>ode45</code>, the default),
3 Bogacki&ndash;Shampine 3(2) (<code>ode23</code>'s), 4 Dormand&ndash;Prince 8(5,3) (DOP853).
Euler and RK4 use <code>fixed_step</code>; a communication interval that is not a multiple of it ends with a shorter step.
The adaptive methods use the relative tolerance of <code>fmi2SetupExperiment</code> and <code>abs_tol</code>, and take the steps their error control chooses,
across communication points: the values at a communication point come from the dense output of the step that covers it, and integration goes on from that step's end.
The step is thrown away and integration restarts from the communication point when an input, a parameter or a state is set to a new value, or an FMU state is restored
(which brings back the step it captured, so a rollback continues bit for bit). No step goes past an event, nor past the stop time.
<code>max_step</code> (s, 0 = unlimited, the default) bounds the adaptive steps, as <code>ode45</code>'s MaxStep. Inputs are held constant over each communication step.
<code>n_steps</code> and <code>n_rhs</code> count accepted steps and right-hand-side evaluations.</p>
<p>The same binary is a Model Exchange FMU: there the importer's solver integrates the states through
<code>fmi2GetDerivatives</code> (the <code>der(x)</code> variables) and locates the zeros of the event indicators, the FMU's event
handling runs in event mode, a model with constraints projects its drift at step events, and <code>n_steps</code> and
<code>n_rhs</code> count the importer's completed steps and derivative evaluations; the solver controls are not used.</p>
</body>
</html>
"#,
        id = escape(info.identifier),
        desc = escape(info.description),
        stop = info.stop_time,
        tol = info.tolerance,
        dt = info.output_interval,
    )
}
