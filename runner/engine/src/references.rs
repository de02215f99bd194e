//! Closed-form references as data: a table of named [`Formula`]s (a model's
//! `references.toml`), where a name that is another entry of the table stands for that entry's
//! value and every other name (`t`, a parameter) is given by the caller. The model's Rust tests,
//! `runner handbook` and the Python tests (tests/fmpy/closed_form.py, same rules) all evaluate
//! the same text, so each closed form is written once. An entry may also be a matrix (an array
//! of rows of formulas), e.g. a linear system whose exact solution is its matrix exponential.

use std::collections::BTreeMap;

use crate::metrics::Formula;

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
    /// matrices of formulas (every row as long as the first).
    pub fn from_toml(text: &str) -> Result<References, String> {
        let table: toml::Table = text.parse().map_err(|e| format!("references: {e}"))?;
        let mut entries = Vec::new();
        let mut matrices = BTreeMap::new();
        for (name, value) in &table {
            if let Some(rows) = value.as_array() {
                matrices.insert(name.clone(), matrix(name, rows)?);
                continue;
            }
            let text = value.as_str().ok_or_else(|| format!("reference {name} is neither a formula (a string) nor a matrix of them"))?;
            entries.push((name.as_str(), text));
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
        rows.iter().map(|row| row.iter().map(|f| self.evaluate(name, f, values)).collect()).collect()
    }

    /// The names of the entries.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.formulas.keys().map(String::as_str)
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
        let formula = self.formulas.get(name).ok_or_else(|| format!("there is no reference '{name}'"))?;
        self.evaluate(name, formula, values)
    }

    /// `formula` (of entry `name`, for messages) with the entries it uses evaluated first.
    fn evaluate(&self, name: &str, formula: &Formula, values: &[(&str, f64)]) -> Result<f64, String> {
        let mut args = Vec::with_capacity(formula.names.len());
        for used in &formula.names {
            let value = if self.formulas.contains_key(used) {
                self.value(used, values)?
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
    }

    /// Matrix elements use the scalar entries like any formula.
    #[test]
    fn matrices_are_evaluated_element_by_element() {
        let r = References::from_toml("w = \"2*x\"\nf = [[\"0\", \"1\"], [\"-w^2\", \"x\"]]\n").unwrap();
        assert_eq!(r.matrix("f", &[("x", 3.0)]), Ok(vec![vec![0.0, 1.0], vec![-36.0, 3.0]]));
        assert!(r.matrix("g", &[]).unwrap_err().contains("no matrix reference 'g'"));
    }
}
