#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::RPM;
use fmu_export::ModelInfo;
use linkages::{FourBarParameters, FourBarPreset};

/// Ex. 5A #4: the double rocker's dimensions and identity on the shared four-bar.
#[derive(Debug, Clone)]
pub struct DoubleRocker;

/// This FMU's model: the shared equations (crate `linkages`) with this preset.
pub type FourBar = linkages::FourBar<DoubleRocker>;

impl FourBarPreset for DoubleRocker {
    fn parameters() -> FourBarParameters {
        FourBarParameters {
            l_oa: 0.400,
            l_ab: 0.100,
            l_bc: 0.410,
            l_co: 0.190,
            // C straight above O: assembles at theta0 = 150 deg (derivation.md).
            theta_co: 90f64.to_radians(),
            theta0: 150f64.to_radians(),
            omega: 8.0 * RPM,
            branch: 1,
        }
    }

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "double_rocker",
            description: "ME326 Ex. 5 mechanism #4: double-rocker four-bar driven at constant speed, vector-loop kinematics; stops at its limit position",
            // The input rocker cannot turn fully: it reaches its limit position at
            // theta = 204.90 deg, t = 1.144 s; the run stops (fmi2Discard, terminated) the
            // margin |sin(theta4 - theta3)| = 0.05 before it, at 204.86 deg, t = 1.1429 s.
            // 2 s covers that; derivation.md explains the choice.
            stop_time: 2.0,
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
    use fmu_export::logging::Status;
    use fmu_export::table::Table;
    #[allow(unused_imports)]
    use fmu_export::{Equations, Model};
    use formulas::References;
    use std::f64::consts::PI;

    /// Entry `name` of references.toml at the input angle `th` for the parameters of `p`: the
    /// four-bar's closed form by the law of cosines, independent of the vector loop
    /// (models/linkages/references/four_bar.toml, shared with the crank-rocker), and the limit
    /// position; tests/fmpy evaluates them too.
    fn reference(name: &str, p: &FourBar, th: f64) -> f64 {
        let mut values = Table::<FourBar>::new().parameter_values(p);
        values.push(("theta", th));
        References::of_model(env!("CARGO_MANIFEST_DIR")).and_then(|r| r.value(name, &values)).expect("a reference of the parameters")
    }

    /// The closed form's (theta3, theta4) at the input angle `th`, on the branch of `p`.
    fn closed_form(p: &FourBar, th: f64) -> (f64, f64) {
        (reference("theta3", p, th), reference("theta4", p, th))
    }

    fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Time derivatives of the closed form by fourth-order central differences in theta
    /// (five points, step h = 1e-3 rad): truncation ~h^4 f(5)/30 and h^4 f(6)/90 ~ 1e-12 f(5),
    /// rounding ~eps pi / h ~ 1e-12 (first) and eps pi / h^2 ~ 1e-9 (second derivative).
    /// (Second-order differences were tried: their h^2 f(3)/6 ~ 6e-8 is too coarse here.)
    fn fd(p: &FourBar, th: f64) -> [f64; 4] {
        let h = 1e-3;
        let c = closed_form(p, th);
        let at = |k: f64| closed_form(p, th + k * h);
        let (p1, p2, m1, m2) = (at(1.0), at(2.0), at(-1.0), at(-2.0));
        let w = p.omega;
        // Differences relative to the centre value, wrapped, so branch cuts of atan2 do not matter.
        let der = |f: fn((f64, f64)) -> f64| {
            let r = |v: (f64, f64)| wrap(f(v) - f(c));
            let d1 = (-r(p2) + 8.0 * r(p1) - 8.0 * r(m1) + r(m2)) / (12.0 * h) * w;
            let d2 = (-r(p2) + 16.0 * r(p1) + 16.0 * r(m1) - r(m2)) / (12.0 * h * h) * w * w;
            (d1, d2)
        };
        let (a1, a2) = der(|v| v.0);
        let (b1, b2) = der(|v| v.1);
        [a1, b1, a2, b2]
    }

    const NAMES: [&str; 16] = [
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
    ];

    /// Both branches on a 1 ms grid up to the limit position: every projected point against
    /// the law-of-cosines closed form (finite there, angles to 1e-11 rad: rounding amplified by the
    /// conditioning 1/|sin(theta4 - theta3)| near the limit), rates and accelerations
    /// against its finite differences where |sin(theta4 - theta3)| > 0.5: the derivatives of
    /// the closed form grow like powers of 1/sin near the limit and so does fd()'s truncation
    /// (measured at sin = 0.5: 1.3e-8 rad/s and 2e-7 rad/s2, at sin = 1: 4e-12 and 1e-9;
    /// bounds 5e-8 and 5e-7).
    /// Then the stop: Discard and terminated, the message names the limit and the angle,
    /// the last point (located event) the margin |sin(theta4 - theta3)| = 0.05 short of the
    /// exact limit angle (references.toml's theta_limit, |AC| = l_AB + l_BC: theta = 90 +
    /// 114.901 = 204.901 deg; its theta_stop, 204.858 deg), all outputs
    /// finite, loop gap below 1e-9 m, and B never changes side of A->C.
    #[test]
    fn motion_matches_the_closed_form_and_stops_at_the_limit() {
        for br in [1.0, -1.0] {
            let p = FourBar { branch: br as i32, ..FourBar::default() };
            let mut h = Harness::<FourBar>::new();
            h.set("branch", br).unwrap();
            h.initialize(None).unwrap();
            let tr = h.run(2.0, 1e-3, &NAMES).unwrap();
            assert_eq!(h.instance.do_step_status().unwrap(), Status::Discard);
            assert!(h.instance.terminated().unwrap());
            let n = tr.time.len();
            let mut err = [0.0f64; 3];
            for k in 0..n {
                let g = |n: &str| tr.get(n)[k];
                let th = p.theta0 + p.omega * tr.time[k];
                assert!((g("theta") - th).abs() < 1e-12);
                for (j, name) in NAMES.iter().enumerate() {
                    assert!(tr.values[j][k].is_finite(), "{name}");
                }
                assert!(g("loop_residual") < 1e-9);
                let (cx, cy) = (p.l_co * p.theta_co.cos(), p.l_co * p.theta_co.sin());
                let cross = (cx - g("A_x")) * (g("B_y") - g("A_y")) - (cy - g("A_y")) * (g("B_x") - g("A_x"));
                assert!(br * cross > 0.0, "branch jump at t = {}", tr.time[k]);
                if k == n - 1 {
                    break;
                }
                let (t3, t4) = closed_form(&p, th);
                assert!(t3.is_finite() && t4.is_finite(), "the closed form assembles before the limit, t = {}", tr.time[k]);
                err[0] = err[0].max(wrap(g("theta3") - t3).abs()).max(wrap(g("theta4") - t4).abs());
                if (t4 - t3).sin().abs() > 0.5 {
                    let d = fd(&p, th);
                    err[1] = err[1].max((g("theta3_dot") - d[0]).abs()).max((g("theta4_dot") - d[1]).abs());
                    err[2] = err[2].max((g("theta3_ddot") - d[2]).abs()).max((g("theta4_ddot") - d[3]).abs());
                }
            }
            let th_end = *tr.get("theta").last().unwrap();
            let limit = reference("theta_limit", &p, p.theta0);
            let stop = reference("theta_stop", &p, p.theta0);
            eprintln!(
                "branch {br}: {n} points, max |angle err| {:.2e} rad, rates {:.2e}, accelerations {:.2e}; stopped at t = {:.6} s, theta = {:.6} deg (limit {:.6} deg), last |e| = {:.2e} m",
                err[0],
                err[1],
                err[2],
                tr.time[n - 1],
                th_end.to_degrees(),
                limit.to_degrees(),
                tr.get("loop_residual")[n - 1]
            );
            assert!(err[0] < 1e-11 && err[1] < 5e-8 && err[2] < 5e-7, "{err:?}");
            // The stop is where |sin(theta4 - theta3)| = 0.05 on the loop (theta_stop, 204.86
            // deg), found from the exact input angle to the event location's precision.
            eprintln!("branch {br}: stop {:.6} deg, off by {:.2e} rad", stop.to_degrees(), th_end - stop);
            assert!(th_end < limit && (th_end - stop).abs() < 1e-8, "{th_end} vs {stop}");
            let msg = h.messages().join("\n");
            assert!(msg.contains("limit position at theta = 204.8"), "{msg}");
        }
    }

    /// MODELS.md: with C on the +x axis (theta_CO = 0) or the -x axis the handbook's double
    /// rocker cannot be assembled at 150 deg (|AC| = 0.572 m > 0.51, and 0.254 < 0.31).
    #[test]
    fn c_on_the_x_axis_does_not_assemble() {
        for tco in [0.0, PI] {
            let mut h = Harness::<FourBar>::new();
            h.set("theta_CO", tco).unwrap();
            let err = h.initialize(None).unwrap_err();
            assert!(
                err.contains("cannot be assembled at theta0 = 150.0000 deg") && err.contains("l_AB") && err.contains("theta_CO"),
                "{err}"
            );
        }
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
