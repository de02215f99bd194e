//! Looking variables up by name (with suggestions) and turning command-line text into values.

use fmi_importer::{Causality, Description, Kind, Value, Variability, Variable};

/// Edit distance between two names: insertions, deletions, substitutions and swaps of two
/// neighbouring characters (the commonest typo) each count one.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let (a, b): (Vec<char>, Vec<char>) = (a.chars().collect(), b.chars().collect());
    let mut d = vec![vec![0usize; b.len() + 1]; a.len() + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = (a[i - 1] != b[j - 1]) as usize;
            d[i][j] = (d[i - 1][j] + 1).min(d[i][j - 1] + 1).min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                d[i][j] = d[i][j].min(d[i - 2][j - 2] + 1);
            }
        }
    }
    d[a.len()][b.len()]
}

/// The variable called `name`, or an error naming up to three close names.
pub fn find<'a>(description: &'a Description, name: &str) -> Result<&'a Variable, String> {
    if let Some(v) = description.variable(name) {
        return Ok(v);
    }
    // Close means: same name ignoring case, or at most a third of the name's characters changed.
    let limit = (name.chars().count() / 3).max(1);
    let mut close: Vec<(usize, &str)> = description
        .variables
        .iter()
        .map(|v| {
            let d = if v.name.eq_ignore_ascii_case(name) { 0 } else { edit_distance(name, &v.name) };
            (d, v.name.as_str())
        })
        .filter(|&(d, _)| d <= limit)
        .collect();
    close.sort();
    let mut message = format!("the model {} has no variable '{name}'", description.model_name);
    if close.is_empty() {
        message.push_str("; `runner info` lists its variables");
    } else {
        let names: Vec<String> = close.iter().take(3).map(|(_, n)| format!("'{n}'")).collect();
        message.push_str(&format!("; did you mean {}?", names.join(" or ")));
    }
    Err(message)
}

/// Checks that `variable` may be set before initialization: a parameter or an input, not constant.
pub fn check_settable(variable: &Variable) -> Result<(), String> {
    let settable = matches!(variable.causality, Causality::Parameter | Causality::StructuralParameter | Causality::Input)
        && variable.variability != Variability::Constant;
    if settable {
        Ok(())
    } else {
        Err(format!("'{}' is {} ({}); only parameters and inputs can be set", variable.name, variable.causality, variable.variability))
    }
}

/// Converts `text` to a value of `variable`'s type; for an array, whitespace-separated
/// element values (row-major; one value sets every element).
pub fn parse_value(variable: &Variable, text: &str) -> Result<Value, String> {
    let text = text.trim();
    if variable.is_array() && variable.kind != Kind::String {
        let items = text.split_whitespace().map(|item| parse_element(variable, item)).collect::<Result<Vec<_>, _>>()?;
        if items.is_empty() {
            return Err(format!("'{}' is an array: give its element values separated by spaces", variable.name));
        }
        return Ok(Value::List(items));
    }
    parse_element(variable, text)
}

/// Converts `text` to one value of `variable`'s element type.
fn parse_element(variable: &Variable, text: &str) -> Result<Value, String> {
    let bad = |what: &str| format!("'{}' is {what}, and '{text}' is not one", variable.name, what = what);
    match variable.kind {
        Kind::Real => text.parse::<f64>().ok().filter(|v| v.is_finite()).map(Value::Real).ok_or_else(|| bad("a Real (a finite number)")),
        Kind::Float32 => text
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && v.abs() <= f32::MAX as f64)
            .map(Value::Real)
            .ok_or_else(|| bad("a Float32 (a finite number within single precision)")),
        Kind::Integer | Kind::Enumeration => text.parse::<i32>().map(Value::Integer).map_err(|_| bad("an Integer")),
        kind @ (Kind::Int8 | Kind::UInt8 | Kind::Int16 | Kind::UInt16 | Kind::UInt32 | Kind::Int64 | Kind::UInt64) => {
            let (lo, hi) = kind.integer_range().expect("an integer type");
            text.parse::<i128>()
                .ok()
                .filter(|v| (lo..=hi).contains(v))
                .map(Value::Int)
                .ok_or_else(|| bad(&format!("an {kind} (a whole number from {lo} to {hi})")))
        }
        Kind::Boolean => match text {
            "true" | "1" => Ok(Value::Boolean(true)),
            "false" | "0" => Ok(Value::Boolean(false)),
            _ => Err(bad("a Boolean (true/false/1/0)")),
        },
        Kind::String => Ok(Value::String(text.to_owned())),
        Kind::Binary => {
            fmi_importer::model::parse_hex(text).map(Value::Binary).map_err(|_| bad("a Binary (hexadecimal bytes, e.g. 666f6f)"))
        }
        Kind::Clock => Err(format!("'{}' is a Clock; clocks cannot be set", variable.name)),
    }
}

/// Converts a number from a sweep range to `variable`'s type (integers must be whole).
pub fn number_value(variable: &Variable, x: f64) -> Result<Value, String> {
    match variable.kind {
        _ if variable.is_array() => Err(format!("'{}' is an array; a sweep sets scalars", variable.name)),
        Kind::Real | Kind::Float32 => Ok(Value::Real(x)),
        Kind::Integer | Kind::Enumeration if x.fract() == 0.0 && x.abs() <= i32::MAX as f64 => Ok(Value::Integer(x as i32)),
        Kind::Boolean if x == 0.0 || x == 1.0 => Ok(Value::Boolean(x == 1.0)),
        kind => match kind.integer_range() {
            Some((lo, hi)) if x.fract() == 0.0 && x >= lo as f64 && x <= hi as f64 => Ok(Value::Int(x as i128)),
            _ => Err(format!("'{}' is {kind}; {x} is not a value of that type", variable.name)),
        },
    }
}

/// Splits `NAME=VALUE`.
pub fn split_assignment<'s>(text: &'s str, what: &str) -> Result<(&'s str, &'s str), String> {
    match text.split_once('=') {
        Some((name, value)) if !name.trim().is_empty() => Ok((name.trim(), value.trim())),
        _ => Err(format!("{what} '{text}' is not of the form NAME=VALUE")),
    }
}

/// Parses `--set NAME=VALUE` items into checked variable-value pairs.
pub fn parse_sets<'a>(description: &'a Description, sets: &[String]) -> Result<Vec<(&'a Variable, Value)>, String> {
    sets.iter()
        .map(|s| {
            let (name, value) = split_assignment(s, "--set")?;
            let variable = find(description, name)?;
            check_settable(variable)?;
            Ok((variable, parse_value(variable, value)?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::edit_distance;

    #[test]
    fn edit_distance_counts_single_character_edits() {
        assert_eq!(edit_distance("speed", "speed"), 0);
        assert_eq!(edit_distance("sped", "speed"), 1);
        assert_eq!(edit_distance("z_s", "z_u"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("x_mni", "x_min"), 1, "a swap is one edit");
    }
}
