//! The one place that knows units: SI base-unit exponents of every unit a model may declare,
//! and the handbook's display units (deg, rpm, in, lbf, ...) as FMI `DisplayUnit` conversions.

/// Exponents of the SI base units (and rad) that make up a unit, as FMI's `BaseUnit` writes them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct BaseUnit {
    pub kg: i32,
    pub m: i32,
    pub s: i32,
    pub rad: i32,
}

/// A display unit: `value_in_display_unit = factor * value_in_si + offset` (FMI 2.0 convention).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DisplayUnit {
    pub name: &'static str,
    pub factor: f64,
    pub offset: f64,
}

/// A unit a model may declare.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UnitDef {
    pub name: &'static str,
    /// What the unit measures, as Modelica's SI types name it (`Angle` for rad): the name of
    /// the FMI 3.0 type that declares it.
    pub quantity: &'static str,
    pub base: BaseUnit,
    pub display_units: &'static [DisplayUnit],
}

/// One inch in metres (exact by definition).
pub const INCH: f64 = 0.0254;
/// One foot in metres (exact by definition).
pub const FOOT: f64 = 0.3048;
/// One pound-force in newtons (exact by definition: 0.45359237 kg x 9.80665 m/s^2).
pub const LBF: f64 = 4.448_221_615_260_5;
/// One ounce-force in newtons.
pub const OZF: f64 = LBF / 16.0;
/// One degree in radians.
pub const DEGREE: f64 = std::f64::consts::PI / 180.0;
/// One revolution per minute in rad/s.
pub const RPM: f64 = 2.0 * std::f64::consts::PI / 60.0;

const fn b(kg: i32, m: i32, s: i32, rad: i32) -> BaseUnit {
    BaseUnit { kg, m, s, rad }
}

const fn d(name: &'static str, si_per_display: f64) -> DisplayUnit {
    DisplayUnit { name, factor: 1.0 / si_per_display, offset: 0.0 }
}

/// Every unit known to the toolkit.
pub const UNITS: &[UnitDef] = &[
    UnitDef { name: "1", quantity: "Dimensionless", base: b(0, 0, 0, 0), display_units: &[] },
    UnitDef { name: "s", quantity: "Time", base: b(0, 0, 1, 0), display_units: &[d("ms", 1e-3)] },
    UnitDef { name: "m", quantity: "Length", base: b(0, 1, 0, 0), display_units: &[d("mm", 1e-3), d("in", INCH)] },
    UnitDef { name: "m/s", quantity: "Velocity", base: b(0, 1, -1, 0), display_units: &[d("mm/s", 1e-3), d("in/s", INCH)] },
    UnitDef { name: "m/s2", quantity: "Acceleration", base: b(0, 1, -2, 0), display_units: &[d("mm/s2", 1e-3), d("in/s2", INCH)] },
    UnitDef { name: "kg", quantity: "Mass", base: b(1, 0, 0, 0), display_units: &[d("lbf.s2/in", LBF / INCH)] },
    UnitDef { name: "kg.m2", quantity: "MomentOfInertia", base: b(1, 2, 0, 0), display_units: &[] },
    UnitDef { name: "N", quantity: "Force", base: b(1, 1, -2, 0), display_units: &[d("lbf", LBF), d("ozf", OZF)] },
    UnitDef {
        name: "N/m",
        quantity: "TranslationalSpringConstant",
        base: b(1, 0, -2, 0),
        display_units: &[d("lbf/in", LBF / INCH), d("lbf/ft", LBF / FOOT)],
    },
    UnitDef { name: "N.s/m", quantity: "TranslationalDampingConstant", base: b(1, 0, -1, 0), display_units: &[d("lbf.s/in", LBF / INCH)] },
    UnitDef { name: "N.m", quantity: "Torque", base: b(1, 2, -2, 0), display_units: &[d("lbf.in", LBF * INCH), d("ozf.in", OZF * INCH)] },
    UnitDef { name: "N.m.s/rad", quantity: "RotationalDampingConstant", base: b(1, 2, -1, -1), display_units: &[] },
    UnitDef { name: "J", quantity: "Energy", base: b(1, 2, -2, 0), display_units: &[] },
    UnitDef { name: "W", quantity: "Power", base: b(1, 2, -3, 0), display_units: &[] },
    UnitDef { name: "rad", quantity: "Angle", base: b(0, 0, 0, 1), display_units: &[d("deg", DEGREE)] },
    UnitDef { name: "rad/s", quantity: "AngularVelocity", base: b(0, 0, -1, 1), display_units: &[d("rpm", RPM), d("deg/s", DEGREE)] },
    UnitDef { name: "rad/s2", quantity: "AngularAcceleration", base: b(0, 0, -2, 1), display_units: &[d("deg/s2", DEGREE)] },
    UnitDef { name: "m/s3", quantity: "Jerk", base: b(0, 1, -3, 0), display_units: &[] },
    UnitDef { name: "N/m2", quantity: "Pressure", base: b(1, -1, -2, 0), display_units: &[] },
    UnitDef { name: "1/s", quantity: "Rate", base: b(0, 0, -1, 0), display_units: &[] },
];

/// Looks a unit up by name.
pub fn unit(name: &str) -> Option<&'static UnitDef> {
    UNITS.iter().find(|u| u.name == name)
}

/// The unit of the time derivative of a quantity in `unit_name` (its base units over a second):
/// the first such unit known, `None` if there is none.
pub fn rate_of(unit_name: &str) -> Option<&'static str> {
    let base = unit(unit_name)?.base;
    let rate = BaseUnit { s: base.s - 1, ..base };
    UNITS.iter().find(|u| u.base == rate).map(|u| u.name)
}

/// Looks a display unit of `unit_name` up by name.
pub fn display_unit(unit_name: &str, display_name: &str) -> Option<&'static DisplayUnit> {
    unit(unit_name)?.display_units.iter().find(|d| d.name == display_name)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The handbook's prelab values (Ex. 4) converted by hand: k = 10 lbf/in = 1751.268 N/m,
    /// m = 2 lbf.s2/in = 350.254 kg; a wrong factor direction would be off by orders of magnitude.
    #[test]
    fn display_factors_convert_si_to_handbook_units() {
        let k_si = 10.0 * LBF / INCH;
        assert!((k_si - 1_751.268_352_464_76).abs() < 1e-9);
        let du = display_unit("N/m", "lbf/in").unwrap();
        assert!((du.factor * k_si - 10.0).abs() < 1e-12);
        let deg = display_unit("rad", "deg").unwrap();
        assert!((deg.factor * std::f64::consts::PI - 180.0).abs() < 1e-12);
        let rpm = display_unit("rad/s", "rpm").unwrap();
        assert!((rpm.factor * (2.0 * std::f64::consts::PI) - 60.0).abs() < 1e-12);
    }

    /// The derivative units of the states the models declare.
    #[test]
    fn rates_divide_by_a_second() {
        assert_eq!(rate_of("m"), Some("m/s"));
        assert_eq!(rate_of("m/s"), Some("m/s2"));
        assert_eq!(rate_of("rad"), Some("rad/s"));
        assert_eq!(rate_of("rad/s"), Some("rad/s2"));
        assert_eq!(rate_of("m/s2"), Some("m/s3"));
        assert_eq!(rate_of("N"), None);
        assert_eq!(rate_of("nope"), None);
    }

    #[test]
    fn unit_names_are_unique_and_display_names_unique_within_unit() {
        for (i, u) in UNITS.iter().enumerate() {
            assert!(UNITS[i + 1..].iter().all(|v| v.name != u.name), "duplicate unit {}", u.name);
            assert!(UNITS[i + 1..].iter().all(|v| v.quantity != u.quantity), "two units measure {}", u.quantity);
            for (j, du) in u.display_units.iter().enumerate() {
                assert!(u.display_units[j + 1..].iter().all(|e| e.name != du.name));
                assert!(du.factor.is_finite() && du.factor > 0.0);
            }
        }
    }
}
