//! Looking variables up by name (with suggestions) and turning command-line text into values,
//! in SI or in a display unit the FMU declares (`120deg`, `10rpm`, `10lbf/in`).

use fmi_importer::{Causality, Description, Kind, Value, Variability, Variable};

/// A unit a Real variable can be given or shown in: its own unit (factor 1, offset 0) or one
/// of the display units the FMU declares for it, `display = factor * value + offset` (FMI 2.0).
#[derive(Debug, Clone, PartialEq)]
pub struct UnitConversion {
    /// The unit's name, e.g. `deg`.
    pub name: String,
    /// Display value per SI value.
    pub factor: f64,
    /// Display value of SI zero.
    pub offset: f64,
}

impl UnitConversion {
    /// A value in this unit from the SI value.
    pub fn from_si(&self, si: f64) -> f64 {
        self.factor * si + self.offset
    }

    /// The SI value of a value in this unit.
    pub fn to_si(&self, display: f64) -> f64 {
        (display - self.offset) / self.factor
    }
}

/// The units `variable` can be written in: its own unit first, then the display units its
/// unit's `UnitDefinitions` entry declares. Empty for a variable without a unit.
pub fn units_of(description: &Description, variable: &Variable) -> Vec<UnitConversion> {
    let Some(unit) = variable.unit.as_deref() else { return Vec::new() };
    let mut units = vec![UnitConversion { name: unit.to_owned(), factor: 1.0, offset: 0.0 }];
    if let Some(defined) = description.unit(unit) {
        // A display unit with a zero or non-finite factor cannot be converted back; skip it.
        let usable = defined.display_units.iter().filter(|d| d.factor.is_finite() && d.factor != 0.0 && d.offset.is_finite());
        units.extend(usable.map(|d| UnitConversion { name: d.name.clone(), factor: d.factor, offset: d.offset }));
    }
    units
}

/// The unit to show `variable` in: its declared `displayUnit` when the FMU defines it for the
/// variable's unit, else `None` (show SI).
pub fn display_unit_of(description: &Description, variable: &Variable) -> Option<UnitConversion> {
    let wanted = variable.display_unit.as_deref()?;
    units_of(description, variable).into_iter().skip(1).find(|u| u.name == wanted)
}

/// Splits `120deg`, `120 deg` or `-1.5e-3` into the number and the unit text after it (empty
/// when there is none): the longest leading part that reads as a number is the number.
fn split_number_and_unit(text: &str) -> Option<(f64, &str)> {
    text.char_indices()
        .map(|(i, c)| i + c.len_utf8())
        .rev()
        .find_map(|end| text[..end].trim().parse::<f64>().ok().map(|x| (x, text[end..].trim())))
}

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
        Kind::String => Err(format!(
            "'{}' is a String variable; a sweep varies numbers (give a String one value for every point with --set {}=TEXT)",
            variable.name, variable.name
        )),
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

/// Converts `text` to a value of `variable`'s type like [`parse_value`], and a Real given with
/// a unit (`120deg`, `10 rpm`) from that unit to SI. The unit must be the variable's own or a
/// display unit the FMU declares for it; any other is refused with the ones it may use.
pub fn parse_quantity(description: &Description, variable: &Variable, text: &str) -> Result<Value, String> {
    let text = text.trim();
    // Arrays take plain numbers (SI), element by element.
    if variable.kind != Kind::Real || variable.is_array() {
        return parse_value(variable, text);
    }
    let Some((number, unit)) = split_number_and_unit(text) else { return parse_value(variable, text) };
    if unit.is_empty() {
        return parse_value(variable, text);
    }
    let units = units_of(description, variable);
    let Some(conversion) = units.iter().find(|u| u.name == unit) else {
        return Err(match units.as_slice() {
            [] => format!("'{}' has no unit, so '{text}' cannot be converted: give a plain number", variable.name),
            [own] => format!(
                "'{}' is in {}, and the FMU declares no display unit for it, so '{unit}' cannot be converted: give {} or a plain number",
                variable.name, own.name, own.name
            ),
            _ => {
                let names: Vec<&str> = units.iter().map(|u| u.name.as_str()).collect();
                format!(
                    "'{}' cannot be given in '{unit}': the FMU declares {} for it (or a plain number, in {})",
                    variable.name,
                    names.join(", "),
                    names[0]
                )
            }
        });
    };
    if !number.is_finite() {
        return Err(format!("'{}' is a Real (a finite number), and '{text}' is not one", variable.name));
    }
    let si = conversion.to_si(number);
    if !si.is_finite() {
        return Err(format!("'{text}' is {si} in {}, not a finite number", units[0].name));
    }
    Ok(Value::Real(si))
}

/// Parses `--set NAME=VALUE` items into checked variable-value pairs; a value may carry a
/// unit the FMU declares for the variable (see [`parse_quantity`]).
pub fn parse_sets<'a>(description: &'a Description, sets: &[String]) -> Result<Vec<(&'a Variable, Value)>, String> {
    sets.iter()
        .map(|s| {
            let (name, value) = split_assignment(s, "--set")?;
            let variable = find(description, name)?;
            check_settable(variable)?;
            Ok((variable, parse_quantity(description, variable, value)?))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use fmi_importer::model::{DisplayUnit, FmiVersion, Unit};

    /// A description with the units of the handbook's models, as `runner build` declares them
    /// (display = factor * SI), plus a temperature with an offset, which none of ours has.
    fn description() -> Description {
        let unit = |name: &str, display: &[(&str, f64, f64)]| Unit {
            name: name.into(),
            display_units: display.iter().map(|&(n, factor, offset)| DisplayUnit { name: n.into(), factor, offset }).collect(),
        };
        let real = |name: &str, unit: Option<&str>, display: Option<&str>| Variable {
            name: name.into(),
            value_reference: 0,
            description: None,
            kind: Kind::Real,
            causality: Causality::Parameter,
            variability: Variability::Fixed,
            unit: unit.map(str::to_owned),
            display_unit: display.map(str::to_owned),
            start: None,
            dimensions: Vec::new(),
        };
        let pi = std::f64::consts::PI;
        Description {
            fmi_version: FmiVersion::Fmi2,
            fmi_version_text: "2.0".into(),
            model_name: "units".into(),
            description: None,
            instantiation_token: String::new(),
            generation_tool: None,
            co_simulation: None,
            model_exchange: None,
            default_experiment: None,
            units: vec![
                unit("rad", &[("deg", 180.0 / pi, 0.0)]),
                unit("rad/s", &[("rpm", 60.0 / (2.0 * pi), 0.0), ("deg/s", 180.0 / pi, 0.0)]),
                unit("N/m", &[("lbf/in", 0.0254 / 4.4482216152605, 0.0), ("lbf/ft", 0.3048 / 4.4482216152605, 0.0)]),
                unit("K", &[("degC", 1.0, -273.15)]),
                unit("m", &[]),
            ],
            variables: vec![
                real("theta0", Some("rad"), Some("deg")),
                real("omega", Some("rad/s"), Some("rpm")),
                real("k", Some("N/m"), None),
                real("T", Some("K"), Some("degC")),
                real("L", Some("m"), None),
                real("a2", None, None),
                real("w", Some("furlong"), None),
            ],
            number_of_continuous_states: 0,
            number_of_event_indicators: 0,
        }
    }

    fn si(d: &Description, name: &str, text: &str) -> Result<f64, String> {
        match parse_quantity(d, d.variable(name).unwrap(), text)? {
            Value::Real(x) => Ok(x),
            other => panic!("{other:?}"),
        }
    }

    /// Expected SI values from the unit definitions (1 lbf = 4.4482216152605 N, 1 in = 0.0254 m,
    /// exact), worked out by hand; relative 1e-15 is a few roundings of the factor's inverse.
    #[test]
    fn values_with_a_declared_unit_are_converted_to_si() {
        let d = description();
        let close = |a: f64, b: f64| (a - b).abs() <= 1e-15 * b.abs().max(1.0);
        assert!(close(si(&d, "theta0", "120deg").unwrap(), 2.0 * std::f64::consts::PI / 3.0));
        assert!(close(si(&d, "theta0", " 15 deg ").unwrap(), std::f64::consts::PI / 12.0));
        assert!(close(si(&d, "omega", "10rpm").unwrap(), std::f64::consts::PI / 3.0));
        assert!(close(si(&d, "k", "10lbf/in").unwrap(), 1_751.268_352_464_763_7));
        assert!(close(si(&d, "k", "0.7lbf/ft").unwrap(), 0.7 * 4.4482216152605 / 0.3048));
        assert!(close(si(&d, "T", "20degC").unwrap(), 293.15), "the offset is undone");
        assert_eq!(si(&d, "theta0", "2rad").unwrap(), 2.0, "the variable's own unit");
        assert_eq!(si(&d, "theta0", "-1.5e-1").unwrap(), -0.15, "a plain number is SI, as before");
        assert_eq!(si(&d, "L", "1e-3m").unwrap(), 1e-3, "an exponent is part of the number, not a unit");
    }

    #[test]
    fn an_undeclared_unit_is_refused_with_the_declared_ones() {
        let d = description();
        let err = si(&d, "omega", "10rad").unwrap_err();
        assert!(err.contains("'omega' cannot be given in 'rad'") && err.contains("rad/s, rpm, deg/s"), "{err}");
        let err = si(&d, "L", "3in").unwrap_err();
        assert!(err.contains("'L' is in m") && err.contains("declares no display unit"), "{err}");
        let err = si(&d, "a2", "3kg").unwrap_err();
        assert!(err.contains("'a2' has no unit"), "{err}");
        let err = si(&d, "w", "3furlong").unwrap();
        assert_eq!(err, 3.0, "a unit without a definition is still the variable's own");
        assert!(si(&d, "theta0", "deg").unwrap_err().contains("not one"), "no number");
        assert!(si(&d, "theta0", "infdeg").unwrap_err().contains("finite"));
    }

    #[test]
    fn the_display_unit_of_a_variable_comes_from_its_unit_definition() {
        let d = description();
        let theta = display_unit_of(&d, d.variable("theta0").unwrap()).unwrap();
        assert_eq!(theta.name, "deg");
        assert!((theta.from_si(std::f64::consts::PI) - 180.0).abs() < 1e-12);
        assert!(display_unit_of(&d, d.variable("k").unwrap()).is_none(), "no displayUnit attribute");
        assert_eq!(units_of(&d, d.variable("a2").unwrap()), vec![]);
    }

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
