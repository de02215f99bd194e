//! Closed-form references as data: a table of named [`Formula`]s (a model's
//! `references.toml`), where a name that is another entry of the table stands for that entry's
//! value and every other name (`t`, a parameter) is given by the caller. The model's Rust tests,
//! `runner handbook` and the Python tests (tests/fmpy/closed_form.py, same rules) all evaluate
//! the same text, so each closed form is written once. An entry may also be a matrix (an array
//! of rows of formulas), e.g. a linear system whose exact solution is its matrix exponential.
//! A file may take the entries of others (`include = ["../linkages/references/four_bar.toml"]`,
//! paths relative to it), so models that share a mechanism share its closed forms.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::metrics::{Formula, CONSTANTS};

/// A table of named formulas that may use each other.
#[derive(Debug, Clone)]
pub struct References {
    formulas: BTreeMap<String, Formula>,
    matrices: BTreeMap<String, Vec<Vec<Formula>>>,
}

impl References {
    /// Parses every `name = "formula"` pair, refusing a formula that does not parse and a
    /// cycle of entries that use each other.
    pub fn new<'a>(entries: impl IntoIterator<Item = (&'a str, &'a str)>) -> Result<References, String> {
        let mut formulas = BTreeMap::new();
        for (name, text) in entries {
            if CONSTANTS.iter().any(|(c, _)| *c == name) {
                return Err(format!("reference {name} = {text}: '{name}' is a constant of the formulas, not a name for an entry"));
            }
            let formula = Formula::parse(text).map_err(|e| format!("reference {name} = {text}: {e}"))?;
            formulas.insert(name.to_owned(), formula);
        }
        let references = References { formulas, matrices: BTreeMap::new() };
        for name in references.formulas.keys() {
            references.check_acyclic(name, &mut Vec::new())?;
        }
        Ok(references)
    }

    /// Reads a `references.toml`: top-level `name = "formula"` pairs and `name = [[...], ...]`
    /// matrices of formulas (every row as long as the first). A text with `include` needs its
    /// file's place: [`References::from_file`].
    pub fn from_toml(text: &str) -> Result<References, String> {
        let table: toml::Table = text.parse().map_err(|e| format!("references: {e}"))?;
        if table.contains_key(INCLUDE) {
            return Err(format!("references: '{INCLUDE}' names files relative to this one: read it with References::from_file"));
        }
        References::from_tables(vec![("references".into(), table)])
    }

    /// Reads the references.toml at `path` and the files its `include` names (relative to it,
    /// and theirs in turn); an entry given in two of them, or a file that includes itself, is
    /// refused naming the files.
    pub fn from_file(path: &Path) -> Result<References, String> {
        let mut tables = Vec::new();
        read_with_includes(path, &mut Vec::new(), &mut tables)?;
        References::from_tables(tables)
    }

    /// The references.toml of the model crate at `dir` (its tests pass
    /// `env!("CARGO_MANIFEST_DIR")`), read once per process: tests evaluate entries at every
    /// sample of a run.
    pub fn of_model(dir: &str) -> Result<&'static References, String> {
        static READ: Mutex<BTreeMap<String, &'static References>> = Mutex::new(BTreeMap::new());
        let mut read = READ.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        if let Some(references) = read.get(dir) {
            return Ok(references);
        }
        let references: &'static References = Box::leak(Box::new(References::from_file(&Path::new(dir).join("references.toml"))?));
        read.insert(dir.to_owned(), references);
        Ok(references)
    }

    /// The entries of `tables` (each with the file it came from, for messages), which must not
    /// share a name.
    fn from_tables(tables: Vec<(String, toml::Table)>) -> Result<References, String> {
        let mut origin: BTreeMap<&str, &str> = BTreeMap::new();
        let mut entries = Vec::new();
        let mut matrices = BTreeMap::new();
        for (file, table) in &tables {
            for (name, value) in table.iter().filter(|(name, _)| *name != INCLUDE) {
                if let Some(first) = origin.insert(name, file) {
                    return Err(format!("reference {name} is given twice: in {first} and in {file}"));
                }
                if let Some(rows) = value.as_array() {
                    matrices.insert(name.clone(), matrix(name, rows)?);
                    continue;
                }
                let text =
                    value.as_str().ok_or_else(|| format!("reference {name} is neither a formula (a string) nor a matrix of them"))?;
                entries.push((name.as_str(), text));
            }
        }
        let mut references = References::new(entries)?;
        references.matrices = matrices;
        Ok(references)
    }

    fn check_acyclic(&self, name: &str, path: &mut Vec<String>) -> Result<(), String> {
        if path.iter().any(|p| p == name) {
            path.push(name.to_owned());
            return Err(format!("references use each other in a cycle: {}", path.join(" -> ")));
        }
        let Some(formula) = self.formulas.get(name) else { return Ok(()) };
        path.push(name.to_owned());
        for used in &formula.names {
            self.check_acyclic(used, path)?;
        }
        path.pop();
        Ok(())
    }

    /// Matrix entry `name`, each element evaluated as [`References::value`] evaluates an entry.
    pub fn matrix(&self, name: &str, values: &[(&str, f64)]) -> Result<Vec<Vec<f64>>, String> {
        let rows = self.matrices.get(name).ok_or_else(|| format!("there is no matrix reference '{name}'"))?;
        let mut known = BTreeMap::new();
        rows.iter().map(|row| row.iter().map(|f| self.evaluate(name, f, values, &mut known)).collect()).collect()
    }

    /// The names of the entries.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.formulas.keys().map(String::as_str)
    }

    /// The names of the matrix entries.
    pub fn matrix_names(&self) -> impl Iterator<Item = &str> {
        self.matrices.keys().map(String::as_str)
    }

    /// The names entry `name` needs from the caller (directly or through other entries), in
    /// order of first use.
    pub fn inputs(&self, name: &str) -> Result<Vec<String>, String> {
        let formula = self.formulas.get(name).ok_or_else(|| format!("there is no reference '{name}'"))?;
        let mut out = Vec::new();
        for used in &formula.names {
            let more = if self.formulas.contains_key(used) { self.inputs(used)? } else { vec![used.clone()] };
            for m in more {
                if !out.contains(&m) {
                    out.push(m);
                }
            }
        }
        Ok(out)
    }

    /// The value of entry `name` given the values of its inputs, or a message naming what is
    /// missing.
    pub fn value(&self, name: &str, values: &[(&str, f64)]) -> Result<f64, String> {
        self.entry(name, values, &mut BTreeMap::new())
    }

    /// Entry `name`, or its value in `known` if an entry evaluated earlier in the same call
    /// already used it (each entry is evaluated once per call, as numbers do not change).
    fn entry<'r>(&'r self, name: &str, values: &[(&str, f64)], known: &mut BTreeMap<&'r str, f64>) -> Result<f64, String> {
        if let Some(value) = known.get(name) {
            return Ok(*value);
        }
        let (key, formula) = self.formulas.get_key_value(name).ok_or_else(|| format!("there is no reference '{name}'"))?;
        let value = self.evaluate(name, formula, values, known)?;
        known.insert(key, value);
        Ok(value)
    }

    /// `formula` (of entry `name`, for messages) with the entries it uses evaluated first.
    fn evaluate<'r>(
        &'r self,
        name: &str,
        formula: &Formula,
        values: &[(&str, f64)],
        known: &mut BTreeMap<&'r str, f64>,
    ) -> Result<f64, String> {
        let mut args = Vec::with_capacity(formula.names.len());
        for used in &formula.names {
            let value = if self.formulas.contains_key(used) {
                self.entry(used, values, known)?
            } else {
                values
                    .iter()
                    .find(|(n, _)| n == used)
                    .map(|(_, v)| *v)
                    .ok_or_else(|| format!("reference {name} = {} reads '{used}', which was not given", formula.text))?
            };
            args.push(value);
        }
        Ok(formula.evaluate(&args))
    }
}

/// The key of a references.toml that lists the files whose entries it takes too.
const INCLUDE: &str = "include";

/// Reads `path` into `tables`, then the files it includes; `stack` is the chain of files
/// including each other, to refuse a cycle.
fn read_with_includes(path: &Path, stack: &mut Vec<PathBuf>, tables: &mut Vec<(String, toml::Table)>) -> Result<(), String> {
    let shown = path.display().to_string();
    if stack.iter().any(|p| p == path) {
        let chain: Vec<String> = stack.iter().chain([&path.to_path_buf()]).map(|p| p.display().to_string()).collect();
        return Err(format!("references include each other in a cycle: {}", chain.join(" -> ")));
    }
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {shown}: {e}"))?;
    let table: toml::Table = text.parse().map_err(|e| format!("{shown}: {e}"))?;
    let includes: Vec<PathBuf> = match table.get(INCLUDE) {
        None => Vec::new(),
        Some(value) => {
            let not_paths = || format!("{shown}: '{INCLUDE}' must be an array of file paths (relative to this file)");
            let list = value.as_array().ok_or_else(not_paths)?;
            let dir = path.parent().unwrap_or(Path::new("."));
            list.iter().map(|p| p.as_str().map(|p| dir.join(p)).ok_or_else(not_paths)).collect::<Result<_, _>>()?
        }
    };
    tables.push((shown, table));
    stack.push(path.to_path_buf());
    for included in &includes {
        read_with_includes(included, stack, tables)?;
    }
    stack.pop();
    Ok(())
}

/// Parses matrix entry `name`: rows of formula strings, all of one length.
fn matrix(name: &str, rows: &[toml::Value]) -> Result<Vec<Vec<Formula>>, String> {
    let mut out: Vec<Vec<Formula>> = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let row = row.as_array().ok_or_else(|| format!("matrix reference {name}: row {} is not an array", i + 1))?;
        let parsed = row
            .iter()
            .map(|cell| {
                let text = cell.as_str().ok_or_else(|| format!("matrix reference {name}: row {} holds a non-formula", i + 1))?;
                Formula::parse(text).map_err(|e| format!("matrix reference {name}, row {}: {text}: {e}", i + 1))
            })
            .collect::<Result<Vec<_>, String>>()?;
        if out.first().is_some_and(|first| first.len() != parsed.len()) {
            return Err(format!("matrix reference {name}: row {} has {} entries, row 1 has {}", i + 1, parsed.len(), out[0].len()));
        }
        out.push(parsed);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Entries use each other in any order; the caller gives only the leaves.
    #[test]
    fn entries_use_each_other() {
        let r = References::from_toml("y = \"2*x + c\"\nx = \"t^2\"\n").unwrap();
        assert_eq!(r.value("y", &[("t", 3.0), ("c", 1.0)]), Ok(19.0));
        assert_eq!(r.inputs("y").unwrap(), ["t", "c"]);
        assert_eq!(r.names().collect::<Vec<_>>(), ["x", "y"]);
        let missing = r.value("y", &[("t", 3.0)]).unwrap_err();
        assert!(missing.contains("reads 'c'"), "{missing}");
        assert!(r.value("z", &[]).unwrap_err().contains("no reference 'z'"));
    }

    #[test]
    fn cycles_and_bad_entries_are_refused() {
        let cycle = References::from_toml("a = \"b + 1\"\nb = \"2*a\"\n").unwrap_err();
        assert!(cycle.contains("cycle: a -> b -> a"), "{cycle}");
        assert!(References::from_toml("a = \"1 +\"\n").unwrap_err().contains("reference a = 1 +"));
        assert!(References::from_toml("a = 1.5\n").unwrap_err().contains("neither a formula"));
        assert!(References::from_toml("a = [[\"1\", \"2\"], [\"3\"]]\n").unwrap_err().contains("row 2 has 1 entries, row 1 has 2"));
        let pi = References::from_toml("pi = \"3.14\"\n").unwrap_err();
        assert!(pi.contains("'pi' is a constant of the formulas"), "{pi}");
        assert!(References::from_toml("include = [\"x.toml\"]\n").unwrap_err().contains("read it with References::from_file"));
    }

    /// A file takes the entries of the files it includes (relative to it, transitively); a
    /// name given twice and a cycle of includes are refused naming the files.
    #[test]
    fn files_include_others() {
        let dir = std::env::temp_dir().join(format!("references-include-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("shared")).unwrap();
        let write = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
        write("shared/loop.toml", "include = [\"more.toml\"]\nx = \"l*cos(theta)\"\n");
        write("shared/more.toml", "y = \"l*sin(theta)\"\n");
        write("references.toml", "include = [\"shared/loop.toml\"]\nr = \"hypot(x, y)\"\nl = \"2\"\n");
        let r = References::of_model(dir.to_str().unwrap()).unwrap();
        assert!(std::ptr::eq(r, References::of_model(dir.to_str().unwrap()).unwrap()), "read once");
        assert_eq!(r.names().collect::<Vec<_>>(), ["l", "r", "x", "y"]);
        assert_eq!(r.inputs("r").unwrap(), ["theta"], "l is an entry of the including file");
        assert!((r.value("r", &[("theta", 0.7)]).unwrap() - 2.0).abs() < 1e-15);
        write("twice.toml", "include = [\"shared/loop.toml\"]\ny = \"0\"\n");
        let e = References::from_file(&dir.join("twice.toml")).unwrap_err();
        assert!(e.contains("reference y is given twice") && e.contains("twice.toml") && e.contains("more.toml"), "{e}");
        write("cycle.toml", "include = [\"cycle.toml\"]\n");
        let e = References::from_file(&dir.join("cycle.toml")).unwrap_err();
        assert!(e.contains("include each other in a cycle"), "{e}");
        write("bad.toml", "include = \"shared/loop.toml\"\n");
        assert!(References::from_file(&dir.join("bad.toml")).unwrap_err().contains("must be an array of file paths"));
        write("missing.toml", "include = [\"nowhere.toml\"]\n");
        assert!(References::from_file(&dir.join("missing.toml")).unwrap_err().contains("cannot read"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// Matrix elements use the scalar entries like any formula.
    #[test]
    fn matrices_are_evaluated_element_by_element() {
        let r = References::from_toml("w = \"2*x\"\nf = [[\"0\", \"1\"], [\"-w^2\", \"x\"]]\n").unwrap();
        assert_eq!(r.matrix("f", &[("x", 3.0)]), Ok(vec![vec![0.0, 1.0], vec![-36.0, 3.0]]));
        assert_eq!(r.matrix_names().collect::<Vec<_>>(), ["f"]);
        assert!(r.matrix("g", &[]).unwrap_err().contains("no matrix reference 'g'"));
    }
}
