//! The public variable catalogue (`MODELS.md` at the workspace root): hand-written conventions
//! and, for each model, an entry generated from its variable table between two marker lines.
//! Each model's tests call [`check`], which fails when the committed entry differs from the
//! table; with `UPDATE_CATALOGUE=1` in the environment it rewrites the entry instead (adding
//! it at the end when the model has none yet), so `UPDATE_CATALOGUE=1 cargo test --workspace
//! catalogue` regenerates the whole file. The rows every FMU adds to its model's (solver
//! controls, `time`, `der(<state>)`) are one more generated entry, `conventions`, checked by
//! this crate's tests.

use std::path::{Path, PathBuf};

use crate::model::{Access, BaseType, Causality, Model, Variability};
use crate::table::{self, Row, Start};
use crate::units;
use solvers::controls::CONTROLS;
use solvers::Method;

/// The file name of the catalogue, at the workspace root.
pub const FILE: &str = "MODELS.md";

/// The command that regenerates every entry.
pub const UPDATE_COMMAND: &str = "UPDATE_CATALOGUE=1 cargo test --workspace catalogue";

/// The first line of model `id`'s entry.
pub fn begin_marker(id: &str) -> String {
    format!("<!-- catalogue {id}: generated from the model's variable table by `{UPDATE_COMMAND}`; do not edit -->")
}

/// The last line of model `id`'s entry.
pub fn end_marker(id: &str) -> String {
    format!("<!-- end of catalogue {id} -->")
}

/// A table cell: `|` escaped, nothing when empty.
fn cell(text: &str) -> String {
    text.replace('|', "\\|")
}

/// A converted number as people write it: the shortest form of `value` rounded to 10
/// significant digits (15.000000000000002 deg reads 15).
fn short(value: f64) -> String {
    let rounded: f64 = format!("{value:.9e}").parse().unwrap_or(value);
    format!("{rounded}")
}

fn causality(c: Causality, access_is_state: bool) -> &'static str {
    match (c, access_is_state) {
        (Causality::Output, true) => "output (state)",
        (Causality::Parameter, _) => "parameter",
        (Causality::CalculatedParameter, _) => "calculated parameter",
        (Causality::Input, _) => "input",
        (Causality::Output, false) => "output",
        (Causality::Local, _) => "local",
        (Causality::Independent, _) => "independent",
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

/// The identifier of the entry that describes the rows every FMU adds after its model's own.
pub const CONVENTIONS: &str = "conventions";

/// The entry of the rows every FMU adds after its model's own, marker lines included: the
/// solver controls, then the Model Exchange variables `time` and `der(<state>)`, as the
/// variable table appends them (so the model's value references never move), and the codes
/// of `solver`.
pub fn conventions() -> String {
    // The rows exactly as `Table` builds them; `()` stands in for the model, which no row reads.
    let mut rows: Vec<Row<()>> = CONTROLS.iter().map(|&c| Row::from_control(c)).collect();
    rows.push(Row::time());
    let state = Row { name: "<state>", ..Row::time() };
    // A leak of two short strings per call: a Row's strings are `&'static`, and this runs in tests.
    let label: &'static (String, String) = Box::leak(Box::new(table::derivative_label(state.name)));
    let mut derivative = Row::derivative(0, &state, label);
    derivative.unit = Some("(unit of the state)/s");
    derivative.description = "Time derivative of the state named in the parentheses: one row per state, in state order";
    rows.push(derivative);
    let mut out = begin_marker(CONVENTIONS);
    out.push_str(
        "\nAfter its own variables every FMU declares these, in this order (value references continue the model's). \
         The Model Exchange interface reads `time` and the `der(<state>)` rows; the solver controls are the FMU's own \
         integrator, which Co-Simulation uses.\n\n",
    );
    out.push_str("| variable | causality | variability | type | unit | start | description |\n");
    out.push_str("|---|---|---|---|---|---|---|\n");
    for row in &rows {
        let start = match (&row.slot, row.base_type) {
            (table::Slot::Control(c), BaseType::Integer) => c.default_value().map(|v| format!("{}", v as i64)),
            // 0 reads as 0 (max_step: unlimited), the others as the code writes them (1e-3).
            (table::Slot::Control(c), _) => c.default_value().map(|v| if v == 0.0 { "0".to_owned() } else { format!("{v:e}") }),
            _ => None,
        };
        out.push_str(&format!(
            "| `{}` | {} | {} | {:?} | {} | {} | {} |\n",
            row.name,
            causality(row.causality, false),
            variability(row.variability),
            row.base_type,
            cell(row.unit.unwrap_or("")),
            cell(&start.unwrap_or_default()),
            cell(row.description),
        ));
    }
    let codes: Vec<String> = Method::ALL.iter().map(|m| format!("`{}` = {} (`{}`)", m.code(), m.title(), m.name())).collect();
    out.push_str(&format!("\n`solver` codes: {}.\n", codes.join(", ")));
    out.push_str(&end_marker(CONVENTIONS));
    out
}

/// The entry of model `M`, marker lines included: its identity and default experiment, then
/// one row per variable of its own table (the solver controls every FMU adds are described
/// once, in the hand-written part), in value-reference order.
pub fn entry<M: Model>() -> String {
    let info = M::info();
    let defaults = M::default();
    let mut out = begin_marker(info.identifier);
    out.push_str(&format!(
        "\n`{}`: {}. Default experiment: stop time {} s, relative tolerance {:e}, output interval {} s.\n\n",
        info.identifier, info.description, info.stop_time, info.tolerance, info.output_interval
    ));
    out.push_str("| variable | causality | variability | type | unit | display unit | start | range | description |\n");
    out.push_str("|---|---|---|---|---|---|---|---|---|\n");
    for v in M::variables() {
        let is_state = matches!(v.access, Access::State(_));
        let needs_start = matches!(v.causality, Causality::Parameter | Causality::Input);
        let start = match (needs_start, &v.access) {
            (false, _) | (_, Access::State(_)) => String::new(),
            (true, Access::Real { get, .. }) => {
                let value = get(&defaults);
                // Exact in SI (what fmi2SetReal takes), rounded in the handbook's unit.
                match v.unit.zip(v.display_unit).and_then(|(u, d)| units::display_unit(u, d)) {
                    Some(du) => format!("{value} ({} {})", short(du.factor * value + du.offset), du.name),
                    None => format!("{value}"),
                }
            }
            (true, Access::Integer { get, .. }) => Start::Integer(get(&defaults)).to_string(),
            (true, Access::Boolean { get, .. }) => Start::Boolean(get(&defaults)).to_string(),
            (true, Access::String { get, .. }) => Start::String(get(&defaults).to_owned()).to_string(),
        };
        out.push_str(&format!(
            "| `{}` | {} | {} | {:?} | {} | {} | {} | {} | {} |\n",
            v.name,
            causality(v.causality, is_state),
            variability(v.variability),
            v.base_type(),
            cell(v.unit.unwrap_or("")),
            cell(v.display_unit.unwrap_or("")),
            cell(&start),
            cell(&v.range.to_string()),
            cell(v.description),
        ));
    }
    out.push_str(&end_marker(info.identifier));
    out
}

/// Where model `id`'s entry is in `text`: the byte range from its first marker to the end of
/// its last, or `None` when it has none.
pub fn find(text: &str, id: &str) -> Option<std::ops::Range<usize>> {
    let begin = text.find(&begin_marker(id))?;
    let end_marker = end_marker(id);
    let end = text[begin..].find(&end_marker)? + begin + end_marker.len();
    Some(begin..end)
}

/// The identifiers of every entry in `text`, in order.
pub fn entries(text: &str) -> Vec<String> {
    text.lines().filter_map(|l| l.strip_prefix("<!-- catalogue ")?.split(':').next().map(str::to_owned)).collect()
}

/// `text` with model `id`'s entry replaced by `entry`, or the entry added in a section of its
/// own at the end.
pub fn with_entry(text: &str, id: &str, entry: &str) -> String {
    match find(text, id) {
        Some(range) => format!("{}{entry}{}", &text[..range.start], &text[range.end..]),
        None => format!("{}\n## {id}\n\n{entry}\n", text.trim_end_matches('\n').to_owned() + "\n"),
    }
}

/// The catalogue file of the workspace holding the crate at `manifest_dir`.
pub fn path(manifest_dir: &str) -> PathBuf {
    Path::new(manifest_dir).ancestors().map(|p| p.join(FILE)).find(|p| p.is_file()).unwrap_or_else(|| Path::new(manifest_dir).join(FILE))
}

/// Fails (a test's panic) when the catalogue's entry for `M` is not what its table gives, or
/// rewrites the entry with `UPDATE_CATALOGUE=1`. `manifest_dir` is the calling model crate's
/// `env!("CARGO_MANIFEST_DIR")`.
pub fn check<M: Model>(manifest_dir: &str) {
    check_entry(manifest_dir, M::info().identifier, &entry::<M>());
}

/// [`check`] for any entry `id` whose current text is `entry`.
fn check_entry(manifest_dir: &str, id: &str, entry: &str) {
    let file = path(manifest_dir);
    let text = std::fs::read_to_string(&file).unwrap_or_else(|e| panic!("cannot read the catalogue {}: {e}", file.display()));
    let update = std::env::var("UPDATE_CATALOGUE").is_ok_and(|v| !v.is_empty() && v != "0");
    if update {
        let updated = with_entry(&text, id, entry);
        if updated != text {
            std::fs::write(&file, updated).unwrap_or_else(|e| panic!("cannot write {}: {e}", file.display()));
        }
        return;
    }
    match find(&text, id) {
        None => panic!("{} has no entry for {id}: run `{UPDATE_COMMAND}` to add it", file.display()),
        Some(range) if text[range.clone()] != *entry => {
            let committed: Vec<&str> = text[range].lines().collect();
            let first = entry.lines().zip(&committed).position(|(a, b)| a != *b).unwrap_or(committed.len().min(entry.lines().count()));
            panic!(
                "the entry for {id} in {} is stale (from line {} of the entry: {:?} but the table gives {:?}): run `{UPDATE_COMMAND}`",
                file.display(),
                first + 1,
                committed.get(first).copied().unwrap_or("(end of entry)"),
                entry.lines().nth(first).unwrap_or("(end of entry)")
            )
        }
        Some(_) => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// MODELS.md's `conventions` entry is the one the solver controls and the table give.
    #[test]
    fn conventions_entry_is_current() {
        check_entry(env!("CARGO_MANIFEST_DIR"), CONVENTIONS, &conventions());
    }

    /// The generated conventions name every control, both Model Exchange rows and every code.
    #[test]
    fn conventions_list_every_control_and_solver_code() {
        let text = conventions();
        for c in CONTROLS {
            assert!(text.contains(&format!("| `{}` |", c.name())), "{} missing", c.name());
        }
        assert!(text.contains("| `time` | independent |") && text.contains("| `der(<state>)` | local |"), "{text}");
        for m in Method::ALL {
            assert!(text.contains(&format!("`{}` = {}", m.code(), m.title())), "{text}");
        }
    }

    const TEXT: &str =
        "# Catalogue\n\nconventions\n\n## a\n\nnotes on a\n\n<!-- catalogue a: x -->\nold\n<!-- end of catalogue a -->\n\n## b\n";

    /// An entry is replaced between its markers, text around it untouched; a missing one is
    /// added at the end under its own heading; entries are listed by identifier.
    #[test]
    fn entries_are_replaced_in_place_or_added_at_the_end() {
        let a = format!("{}\nnew\n{}", begin_marker("a"), end_marker("a"));
        let text = TEXT.replace("<!-- catalogue a: x -->", &begin_marker("a"));
        let replaced = with_entry(&text, "a", &a);
        assert_eq!(replaced, text.replace("old", "new"));
        assert_eq!(with_entry(&replaced, "a", &a), replaced);
        let added = with_entry(&replaced, "c", "C");
        assert!(added.starts_with(&replaced) && added.ends_with("\n## c\n\nC\n"), "{added:?}");
        assert_eq!(entries(&added), ["a"]);
        assert_eq!(entries(&with_entry(&added, "c", &format!("{}\n{}", begin_marker("c"), end_marker("c")))), ["a", "c"]);
    }

    #[test]
    fn numbers_read_as_written() {
        assert_eq!(short(15.000000000000002), "15");
        assert_eq!(short(0.2617993877991494), "0.2617993878");
        assert_eq!(short(-1.0), "-1");
        assert_eq!(cell("gap |e|"), "gap \\|e\\|");
    }
}
