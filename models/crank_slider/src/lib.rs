#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::RPM;
use fmu_export::ModelInfo;
use linkages::{SliderCrankParameters, SliderCrankPreset};

/// Ex. 5A #1: the centred crank-slider (slider on the x-axis) on the shared slider-crank.
#[derive(Debug, Clone)]
pub struct Centred;

/// This FMU's model: the shared equations (crate `linkages`) with this preset.
pub type CrankSlider = linkages::SliderCrank<Centred>;

impl SliderCrankPreset for Centred {
    const HAS_OFFSET: bool = false;

    fn parameters() -> SliderCrankParameters {
        SliderCrankParameters { l_oa: 0.080, l_ab: 0.120, y_oc: 0.0, theta0: 60f64.to_radians(), omega: 10.0 * RPM, branch: 1 }
    }

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "crank_slider",
            description: "ME326 Ex. 5 mechanism #1: crank-slider driven at constant speed, vector-loop kinematics",
            // Two revolutions at 10 rpm.
            stop_time: 12.0,
            tolerance: 1e-6,
            output_interval: 1e-2,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(CrankSlider);

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

    /// Entry `name` of references.toml at the crank angle `th` for the parameters of `p`: the
    /// slider-crank's closed form (circle meets line, and the chain rule), independent of the
    /// vector loop (models/linkages/references/slider_crank.toml, shared with the offset crank-slider),
    /// and the short rod's limit position; tests/fmpy evaluates them too.
    fn reference(name: &str, p: &CrankSlider, th: f64) -> f64 {
        let mut values = Table::<CrankSlider>::new().parameter_values(p);
        values.push(("theta", th));
        References::of_model(env!("CARGO_MANIFEST_DIR")).and_then(|r| r.value(name, &values)).expect("a reference of the parameters")
    }

    /// The closed form's (r1, theta3) and their first and second time derivatives at the crank
    /// angle `th`, on the branch of `p`.
    fn closed_form(p: &CrankSlider, th: f64) -> [f64; 6] {
        ["r1", "theta3", "r1_dot", "theta3_dot", "r1_ddot", "theta3_ddot"].map(|name| reference(name, p, th))
    }

    const NAMES: [&str; 16] = [
        "theta",
        "r1",
        "theta3",
        "r1_dot",
        "theta3_dot",
        "r1_ddot",
        "theta3_ddot",
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

    fn harness(params: &[(&str, f64)], tol: Option<f64>) -> Harness<CrankSlider> {
        Harness::started(params, tol).unwrap()
    }

    fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Largest errors of (positions, velocities, accelerations) of a run against the closed form.
    fn errors(branch: f64, tol: Option<f64>) -> [f64; 3] {
        let p = CrankSlider { branch: branch as i32, ..CrankSlider::default() };
        let mut h = harness(&[("branch", branch), ("abs_tol", 1e-12)], tol);
        let tr = h.run(12.0, 0.01, &NAMES).unwrap();
        assert_eq!(tr.time.len(), 1201);
        let mut err = [0.0f64; 3];
        for k in 0..tr.time.len() {
            let g = |n: &str| tr.get(n)[k];
            let th = p.theta0 + p.omega * tr.time[k];
            assert!((g("theta") - th).abs() < 1e-12);
            let cf = closed_form(&p, th);
            err[0] = err[0].max((g("r1") - cf[0]).abs()).max(p.l_ab * wrap(g("theta3") - cf[1]).abs());
            err[1] = err[1].max((g("r1_dot") - cf[2]).abs()).max(p.l_ab * (g("theta3_dot") - cf[3]).abs());
            err[2] = err[2].max((g("r1_ddot") - cf[4]).abs()).max(p.l_ab * (g("theta3_ddot") - cf[5]).abs());
            // Point coordinates and velocities: A from the crank alone, B on the x-axis at r1.
            for point in ["A_x", "A_y", "v_A_x", "v_A_y"] {
                assert!((g(point) - reference(point, &p, th)).abs() < 1e-12, "{point} at t = {}", tr.time[k]);
            }
            assert!((g("B_x") - cf[0]).abs() < 1e-9 && g("B_y") == 0.0 && g("v_B_y") == 0.0);
            assert!((g("v_B_x") - cf[2]).abs() < 1e-9);
            assert!(branch * (g("B_x") - g("A_x")) > 0.0, "branch {branch} at t = {}", tr.time[k]);
        }
        err
    }

    /// Both branches over two revolutions (1201 points) against the analytic closed form and
    /// its analytic derivatives. Errors are scaled to m, m/s, m/s2 (angles times l_AB).
    /// Positions and velocities are projected at every point, so they agree to rounding
    /// (bound 1e-12 m, 1e-12 m/s: measured ~3e-14); accelerations follow from A x'' = b at the
    /// projected state, so also to rounding (bound 1e-11 m/s2 on values ~0.1 m/s2, measured 7e-14).
    #[test]
    fn motion_matches_the_closed_form_on_both_branches() {
        for branch in [1.0, -1.0] {
            let e = errors(branch, None);
            eprintln!("branch {branch}: max errors pos {:.2e} vel {:.2e} acc {:.2e}", e[0], e[1], e[2]);
            assert!(e[0] < 1e-12 && e[1] < 1e-12 && e[2] < 1e-11, "{e:?}");
        }
    }

    /// The projection only corrects drift: the integration of A x'' = b alone must already
    /// follow the closed form. The model's `derivatives` integrated here by classical RK4
    /// (12000 steps of 5e-4 s, global error ~ h^4 = 6e-14 times derivative scales of order 1)
    /// over one revolution, with no projection: r1 and r1' within 1e-10 (measured ~4e-14).
    #[test]
    fn integration_alone_follows_the_closed_form() {
        let p = CrankSlider::default();
        let mut x = [0.0; 5];
        p.assemble(&mut x).unwrap();
        // Classical RK4 written here, 12000 steps over one revolution (h = 5e-4 s, error ~h^4).
        let n = 12000;
        let dt = 6.0 / n as f64;
        let f = |x: &[f64; 5]| {
            let mut d = [0.0; 5];
            p.derivatives(0.0, x, &mut d);
            d
        };
        for _ in 0..n {
            let add = |x: &[f64; 5], k: &[f64; 5], s: f64| std::array::from_fn::<f64, 5, _>(|i| x[i] + s * k[i]);
            let k1 = f(&x);
            let k2 = f(&add(&x, &k1, dt / 2.0));
            let k3 = f(&add(&x, &k2, dt / 2.0));
            let k4 = f(&add(&x, &k3, dt));
            x = std::array::from_fn(|i| x[i] + dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        }
        let cf = closed_form(&p, x[0]);
        let (er, ev) = ((x[1] - cf[0]).abs(), (x[3] - cf[2]).abs());
        eprintln!("unprojected RK4 after one revolution: |r1 err| {er:.2e} m, |r1' err| {ev:.2e} m/s");
        assert!(er < 1e-10 && ev < 1e-10);
    }

    /// At the default tolerance (1e-6) the projection keeps |e| below 1e-9 m (it is ~1e-17).
    #[test]
    fn loop_stays_closed_at_the_default_tolerance() {
        let mut h = harness(&[], None);
        let tr = h.run(12.0, 0.05, &["loop_residual"]).unwrap();
        let worst = tr.get("loop_residual").iter().cloned().fold(0.0, f64::max);
        eprintln!("max loop_residual at rtol 1e-6: {worst:.2e} m");
        assert!(worst < 1e-9);
        assert_eq!(tr.time.len(), 241);
    }

    /// The crank turns fully (l_AB > l_OA): the default run reaches the stop time with Ok.
    /// With l_AB = 60 mm < l_OA it cannot: from theta0 = 0 the rod becomes vertical when
    /// sin(theta) = l_AB / l_OA = 0.75 (references.toml's theta_limit), theta = 48.590 deg;
    /// the FMU must stop the margin |cos(theta3)| = 0.05 before it (references.toml's
    /// theta_stop, 48.51 deg) with Discard, a message naming the limit and the angle, finite
    /// outputs, and no jump of branch.
    #[test]
    fn short_rod_stops_at_the_limit_position() {
        let mut h = harness(&[("l_AB", 0.06), ("theta0", 0.0)], None);
        let tr = h.run(12.0, 0.01, &NAMES).unwrap();
        let t_end = *tr.time.last().unwrap();
        let p = CrankSlider { l_ab: 0.06, theta0: 0.0, ..CrankSlider::default() };
        let limit = reference("theta_limit", &p, p.theta0);
        let stop = reference("theta_stop", &p, p.theta0);
        let th_end = *tr.get("theta").last().unwrap();
        eprintln!(
            "stopped at t = {t_end}, theta = {:.6} deg (limit {:.6} deg, stop {:.6} deg, off by {:.2e} rad)",
            th_end.to_degrees(),
            limit.to_degrees(),
            stop.to_degrees(),
            th_end - stop
        );
        assert_eq!(h.instance.do_step_status().unwrap(), Status::Discard);
        assert!(h.instance.terminated().unwrap());
        // The indicator is a function of the exact crank angle: the located stop is at
        // theta_stop to the event location's precision (bound 1e-8 rad).
        assert!(th_end < limit && (th_end - stop).abs() < 1e-8, "{th_end} vs {stop}");
        for (j, n) in NAMES.iter().enumerate() {
            assert!(tr.values[j].iter().all(|v| v.is_finite()), "{n} not finite");
        }
        assert!(tr.get("B_x").iter().zip(tr.get("A_x")).all(|(b, a)| b > a), "branch jump");
        let msg = h.messages().join("\n");
        assert!(msg.contains("limit position at theta = 48.50"), "{msg}");
    }

    #[test]
    fn impossible_assembly_is_refused_naming_the_parameters() {
        let mut h = Harness::<CrankSlider>::new();
        h.set("l_AB", 0.05).unwrap();
        h.set("theta0", PI / 2.0).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(err.contains("theta0 = 90.0000 deg") && err.contains("l_AB") && err.contains("l_OA"), "{err}");
        let mut h = Harness::<CrankSlider>::new();
        h.set("branch", 0.0).unwrap();
        assert!(h.initialize(None).unwrap_err().contains("parameter branch"));
        let mut h = Harness::<CrankSlider>::new();
        h.set("l_OA", -1.0).unwrap();
        assert!(h.initialize(None).unwrap_err().contains("parameter l_OA"));
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<CrankSlider>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<CrankSlider>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<CrankSlider>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
