#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::RPM;
use fmu_export::ModelInfo;
use linkages::{FourBarParameters, FourBarPreset};

/// Ex. 5A #3: the crank-rocker's dimensions and identity on the shared four-bar.
#[derive(Debug, Clone)]
pub struct CrankRocker;

/// This FMU's model: the shared equations (crate `linkages`) with this preset.
pub type FourBar = linkages::FourBar<CrankRocker>;

impl FourBarPreset for CrankRocker {
    fn parameters() -> FourBarParameters {
        FourBarParameters {
            l_oa: 0.100,
            l_ab: 0.180,
            l_bc: 0.500,
            l_co: 0.560,
            theta_co: 0.0,
            theta0: 135f64.to_radians(),
            omega: 5.0 * RPM,
            branch: 1,
        }
    }

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "crank_rocker",
            description: "ME326 Ex. 5 mechanism #3: crank-rocker four-bar driven at constant speed, vector-loop kinematics",
            // Two revolutions at 5 rpm.
            stop_time: 24.0,
            tolerance: 1e-6,
            output_interval: 1e-2,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(FourBar);

#[cfg(test)]
mod tests {
    use super::*;
    use fmu_export::harness::Harness;
    use fmu_export::table::Table;
    #[allow(unused_imports)]
    use fmu_export::{Equations, Model};
    use formulas::References;
    use std::f64::consts::PI;

    /// Entry `name` of references.toml at the input angle `th` for the parameters of `p`: the
    /// four-bar's closed form by the law of cosines, independent of the vector loop
    /// (models/linkages/references/four_bar.toml, shared with the double rocker; tests/fmpy
    /// evaluates it too).
    fn reference(name: &str, p: &FourBar, th: f64) -> f64 {
        let mut values = Table::<FourBar>::new().parameter_values(p);
        values.push(("theta", th));
        References::of_model(env!("CARGO_MANIFEST_DIR")).and_then(|r| r.value(name, &values)).expect("a reference of the parameters")
    }

    /// The closed form's (theta3, theta4) at the input angle `th`, on the branch of `p`.
    pub(crate) fn closed_form(p: &FourBar, th: f64) -> (f64, f64) {
        (reference("theta3", p, th), reference("theta4", p, th))
    }

    pub(crate) fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Time derivatives of the closed form by central differences in theta (step 3e-4 rad):
    /// truncation h^2 f(3)/6 and h^2 f(4)/12 ~ 1e-8, rounding 4 eps pi / h^2 ~ 2e-8 for the
    /// second derivative; bounds 5e-8 (first) and 2e-7 (second) rad/s, rad/s2.
    pub(crate) fn fd(p: &FourBar, th: f64) -> [f64; 4] {
        let h = 3e-4;
        let (p0, m, c) = (closed_form(p, th + h), closed_form(p, th - h), closed_form(p, th));
        let w = p.omega;
        let d1 = |a: f64, b: f64| wrap(a - b) / (2.0 * h) * w;
        let d2 = |a: f64, b: f64, c: f64| (wrap(a - c) - wrap(c - b)) / (h * h) * w * w;
        [d1(p0.0, m.0), d1(p0.1, m.1), d2(p0.0, m.0, c.0), d2(p0.1, m.1, c.1)]
    }

    pub(crate) const NAMES: [&str; 17] = [
        "theta",
        "theta3",
        "theta4",
        "theta3_dot",
        "theta4_dot",
        "theta3_ddot",
        "theta4_ddot",
        "A_x",
        "A_y",
        "B_x",
        "B_y",
        "v_A_x",
        "v_A_y",
        "v_B_x",
        "v_B_y",
        "loop_residual",
        "n_steps",
    ];

    fn harness(params: &[(&str, f64)]) -> Harness<FourBar> {
        Harness::started(params, None).unwrap()
    }

    /// Both branches over two revolutions (2401 points, default tolerance) against the law-of-
    /// cosines closed form: angles projected at every point agree to rounding (bound 1e-12
    /// rad); rates and accelerations within the finite-difference bounds of `fd`. A, B and
    /// A's velocity against the closed form too (bound 1e-12 m, m/s), B's velocity against
    /// l_BC theta4' (-sin, cos)(theta4) with the differenced rate (l_BC times the rate bound).
    /// The loop gap stays below 1e-9 m.
    #[test]
    fn motion_matches_the_closed_form_on_both_branches() {
        for br in [1.0, -1.0] {
            let p = FourBar { branch: br as i32, ..FourBar::default() };
            let mut h = harness(&[("branch", br)]);
            let tr = h.run(24.0, 0.01, &NAMES).unwrap();
            assert_eq!(tr.time.len(), 2401);
            let mut err = [0.0f64; 4];
            for k in 0..tr.time.len() {
                let g = |n: &str| tr.get(n)[k];
                let th = p.theta0 + p.omega * tr.time[k];
                assert!((g("theta") - th).abs() < 1e-12);
                let (t3, t4) = closed_form(&p, th);
                let d = fd(&p, th);
                err[0] = err[0].max(wrap(g("theta3") - t3).abs()).max(wrap(g("theta4") - t4).abs());
                err[1] = err[1].max((g("theta3_dot") - d[0]).abs()).max((g("theta4_dot") - d[1]).abs());
                err[2] = err[2].max((g("theta3_ddot") - d[2]).abs()).max((g("theta4_ddot") - d[3]).abs());
                err[3] = err[3].max(g("loop_residual"));
                for point in ["A_x", "A_y", "B_x", "B_y", "v_A_x", "v_A_y"] {
                    assert!((g(point) - reference(point, &p, th)).abs() < 1e-12, "{point} at t = {}", tr.time[k]);
                }
                assert!((g("v_B_x") + p.l_bc * d[1] * t4.sin()).abs() < 3e-8 && (g("v_B_y") - p.l_bc * d[1] * t4.cos()).abs() < 3e-8);
                // The branch: B stays left (+1) or right (-1) of A->C.
                let cross = (p.l_co - g("A_x")) * (g("B_y") - g("A_y")) + g("A_y") * (g("B_x") - g("A_x"));
                assert!(br * cross > 0.0);
            }
            eprintln!(
                "branch {br}: max |angle err| {:.2e} rad, rates {:.2e} rad/s, accelerations {:.2e} rad/s2, loop_residual {:.2e} m",
                err[0], err[1], err[2], err[3]
            );
            assert!(err[0] < 1e-12 && err[1] < 5e-8 && err[2] < 2e-7 && err[3] < 1e-9, "{err:?}");
        }
    }

    /// A crank-rocker is periodic in the input angle: after one revolution (12 s at 5 rpm) the
    /// whole state is back at its start (positions and rates projected, so to rounding: 1e-12).
    #[test]
    fn returns_to_the_start_after_one_revolution() {
        let mut h = harness(&[]);
        let names = ["theta3", "theta4", "theta3_dot", "theta4_dot", "theta3_ddot", "theta4_ddot", "B_x", "B_y"];
        let start: Vec<f64> = names.iter().map(|n| h.get(n).unwrap()).collect();
        h.run(12.0, 0.05, &names).unwrap();
        for (n, s) in names.iter().zip(&start) {
            let v = h.get(n).unwrap();
            let diff = if n.ends_with("3") || n.ends_with("4") { wrap(v - s) } else { v - s };
            eprintln!("{n}: start {s:.15} after one revolution {v:.15}");
            assert!(diff.abs() < 1e-12, "{n}: {s} -> {v}");
        }
    }

    #[test]
    fn impossible_assembly_is_refused_naming_the_parameters() {
        let mut h = Harness::<FourBar>::new();
        h.set("l_CO", 1.0).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(
            err.contains("theta0 = 135.0000 deg") && err.contains("l_CO = 1 m") && err.contains("l_BC") && err.contains("theta_CO"),
            "{err}"
        );
        let mut h = Harness::<FourBar>::new();
        h.set("branch", 2.0).unwrap();
        assert!(h.initialize(None).unwrap_err().contains("parameter branch"));
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<FourBar>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<FourBar>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<FourBar>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
