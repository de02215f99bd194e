#![doc = include_str!("../derivation.md")]
#![deny(unsafe_code)]

use fmu_export::units::RPM;
use fmu_export::ModelInfo;
use linkages::{SliderCrankParameters, SliderCrankPreset};

/// Ex. 5A #2: the offset crank-slider's dimensions and identity on the shared slider-crank.
#[derive(Debug, Clone)]
pub struct Offset;

/// This FMU's model: the shared equations (crate `linkages`) with this preset.
pub type OffsetCrankSlider = linkages::SliderCrank<Offset>;

impl SliderCrankPreset for Offset {
    const HAS_OFFSET: bool = true;

    fn parameters() -> SliderCrankParameters {
        SliderCrankParameters { l_oa: 0.080, l_ab: 0.100, y_oc: 0.080, theta0: 60f64.to_radians(), omega: 15.0 * RPM, branch: 1 }
    }

    fn info() -> ModelInfo {
        ModelInfo {
            identifier: "offset_crank_slider",
            description: "ME326 Ex. 5 mechanism #2: offset crank-slider driven at constant speed, vector-loop kinematics; stops at its limit position",
            // The handbook's crank cannot turn fully: it reaches the limit position at
            // theta = 194.48 deg, t = 1.494 s; the run stops (fmi2Discard, terminated) the
            // margin |cos(theta3)| = 0.05 before it, at 194.385 deg, t = 1.4932 s.
            // 2 s covers that; derivation.md explains the choice.
            stop_time: 2.0,
            tolerance: 1e-6,
            output_interval: 1e-2,
            documentation: include_str!("../derivation.md"),
        }
    }
}

fmu_export::export_fmu!(OffsetCrankSlider);

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
    /// vector loop (models/linkages/references/slider_crank.toml, shared with the crank-slider),
    /// and the limit position; tests/fmpy evaluates them too.
    fn reference(name: &str, p: &OffsetCrankSlider, th: f64) -> f64 {
        let mut values = Table::<OffsetCrankSlider>::new().parameter_values(p);
        values.push(("theta", th));
        References::of_model(env!("CARGO_MANIFEST_DIR")).and_then(|r| r.value(name, &values)).expect("a reference of the parameters")
    }

    /// The closed form's (r1, theta3) and their first and second time derivatives at the crank
    /// angle `th`, on the branch of `p`.
    fn closed_form(p: &OffsetCrankSlider, th: f64) -> [f64; 6] {
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

    fn harness(params: &[(&str, f64)]) -> Harness<OffsetCrankSlider> {
        Harness::started(params, None).unwrap()
    }

    fn wrap(a: f64) -> f64 {
        (a + PI).rem_euclid(2.0 * PI) - PI
    }

    /// Runs with `params` to `stop` on a `dt` grid and compares every communication point
    /// (projected) with the analytic closed form and its derivatives; rates and accelerations
    /// relative to max(1, |value|). Returns the trajectory and the largest errors (bounds in
    /// the callers: rounding times the conditioning 1/cos(theta3) of A).
    fn compare(params: &[(&str, f64)], p: &OffsetCrankSlider, stop: f64, dt: f64) -> (fmu_export::harness::Trajectory, [f64; 3]) {
        let mut h = harness(params);
        let tr = h.run(stop, dt, &NAMES).unwrap();
        let br = p.branch as f64;
        let mut err = [0.0f64; 3];
        // The last point of a run stopped at a limit position is the located event (not
        // projected); it is checked separately.
        let n = if h.instance.terminated().unwrap() { tr.time.len() - 1 } else { tr.time.len() };
        for k in 0..n {
            let g = |n: &str| tr.get(n)[k];
            let th = p.theta0 + p.omega * tr.time[k];
            let cf = closed_form(p, th);
            err[0] = err[0].max((g("r1") - cf[0]).abs()).max(wrap(g("theta3") - cf[1]).abs());
            let rel = |v: f64, r: f64| (v - r).abs() / r.abs().max(1.0);
            err[1] = err[1].max(rel(g("r1_dot"), cf[2])).max(rel(g("theta3_dot"), cf[3]));
            err[2] = err[2].max(rel(g("r1_ddot"), cf[4])).max(rel(g("theta3_ddot"), cf[5]));
            assert!((g("B_y") - p.y_oc).abs() == 0.0 && g("v_B_y") == 0.0 && g("B_x") == g("r1") && g("v_B_x") == g("r1_dot"));
            assert!(g("loop_residual") < 1e-9);
            assert!(br * (g("B_x") - g("A_x")) > 0.0);
        }
        (tr, err)
    }

    /// The handbook's offset crank-slider up to its limit position, both branches, 1 ms grid.
    #[test]
    fn motion_matches_the_closed_form_up_to_the_limit() {
        for br in [1.0, -1.0] {
            let p = OffsetCrankSlider { branch: br as i32, ..Default::default() };
            let (tr, err) = compare(&[("branch", br)], &p, 2.0, 1e-3);
            eprintln!(
                "branch {br}: {} points, max errors pos {:.2e}, rel vel {:.2e}, rel acc {:.2e}",
                tr.time.len(),
                err[0],
                err[1],
                err[2]
            );
            // Near the limit A (and the closed form's sqrt) is ill-conditioned: on this 1 ms
            // grid the last projected point has cos(theta3) ~ 0.05, which amplifies rounding by
            // ~1/cos for positions and ~1/cos^2, 1/cos^3 for rates and accelerations; measured
            // 1.3e-12, 6e-11, 1.8e-10, bounds 1e-11, 1e-9 and 1e-9.
            assert!(err[0] < 1e-11 && err[1] < 1e-9 && err[2] < 1e-9, "{err:?}");
        }
    }

    /// With y_OC = 10 mm (l_AB = 100 > l_OA + y_OC = 90 mm) the crank turns fully: two
    /// revolutions (8 s at 15 rpm) with no stop, against the closed form.
    #[test]
    fn small_offset_turns_fully() {
        let p = OffsetCrankSlider { y_oc: 0.01, ..Default::default() };
        let mut h = harness(&[("y_OC", 0.01)]);
        h.run(8.0, 0.1, &["theta"]).unwrap();
        assert!(!h.instance.terminated().unwrap());
        let (tr, err) = compare(&[("y_OC", 0.01)], &p, 8.0, 0.01);
        eprintln!("y_OC = 10 mm: {} points, max errors pos {:.2e}, rel vel {:.2e}, rel acc {:.2e}", tr.time.len(), err[0], err[1], err[2]);
        assert_eq!(tr.time.len(), 801);
        assert!(err[0] < 1e-12 && err[1] < 1e-9 && err[2] < 1e-9, "{err:?}");
    }

    /// The handbook's dimensions: the rod reaches the vertical when A_y = y_OC - l_AB, i.e.
    /// sin(theta) = -0.25, theta = 194.4775 deg (references.toml's theta_limit), t = 1.4942 s. The FMU stops
    /// the margin |cos(theta3)| = 0.05 before it (theta_stop, 194.3850 deg, t = 1.4932 s) with
    /// Discard and terminated, the message names the limit and the angle, all outputs are
    /// finite, the last point (the located event) is at theta_stop to the event location's
    /// precision (the indicator is a function of the exact crank angle; bound 1e-8 rad), its
    /// loop gap is still below 1e-9 m, and B never jumps to the other branch.
    #[test]
    fn stops_cleanly_at_the_limit_position() {
        for br in [1.0, -1.0] {
            let mut h = harness(&[("branch", br)]);
            let tr = h.run(2.0, 1e-2, &NAMES).unwrap();
            assert_eq!(h.instance.do_step_status().unwrap(), Status::Discard);
            assert!(h.instance.terminated().unwrap());
            let p = OffsetCrankSlider::default();
            let limit = reference("theta_limit", &p, p.theta0);
            let stop = reference("theta_stop", &p, p.theta0);
            let th_end = *tr.get("theta").last().unwrap();
            let t_end = *tr.time.last().unwrap();
            let res_end = *tr.get("loop_residual").last().unwrap();
            eprintln!(
                "branch {br}: stopped at t = {t_end:.6} s, theta = {:.6} deg (limit {:.6} deg, {:.2e} rad from theta_stop), final |e| = {res_end:.2e} m, n_steps = {}",
                th_end.to_degrees(),
                limit.to_degrees(),
                th_end - stop,
                h.get("n_steps").unwrap()
            );
            assert!(th_end < limit && (th_end - stop).abs() < 1e-8);
            assert!(res_end < 1e-9);
            for (j, n) in NAMES.iter().enumerate() {
                assert!(tr.values[j].iter().all(|v| v.is_finite()), "{n} not finite");
            }
            assert!(tr.get("B_x").iter().zip(tr.get("A_x")).all(|(b, a)| br * (b - a) > 0.0), "branch jump");
            let msg = h.messages().join("\n");
            assert!(msg.contains("limit position at theta = 194.38"), "{msg}");
            // A further step is refused: the experiment is over.
            assert!(h.step(0.01).is_err());
        }
    }

    /// The fixed-step solvers (0 Euler, 1 RK4, step 1 ms) also stop at the margin before the
    /// limit with finite outputs on the same branch. The indicator follows the exact crank
    /// angle (which both integrate exactly), so both locate theta_stop (bound 1e-8 rad), where
    /// the stop's projection closes the loop to rounding (bound 1e-12 m) when the solver's
    /// drift left it within reach on this branch.
    #[test]
    fn fixed_step_solvers_stop_cleanly_too() {
        for solver in [1.0, 0.0] {
            let mut h = harness(&[("solver", solver)]);
            let tr = h.run(2.0, 1e-2, &NAMES).unwrap();
            assert!(h.instance.terminated().unwrap());
            let p = OffsetCrankSlider::default();
            let stop = reference("theta_stop", &p, p.theta0);
            let th_end = *tr.get("theta").last().unwrap();
            let gap = *tr.get("loop_residual").last().unwrap();
            eprintln!(
                "solver {solver}: stopped at theta = {:.4} deg ({:+.2e} rad from theta_stop), last |e| = {gap:.2e} m",
                th_end.to_degrees(),
                th_end - stop
            );
            assert!((th_end - stop).abs() < 1e-8 && gap < 1e-12);
            for (j, n) in NAMES.iter().enumerate() {
                assert!(tr.values[j].iter().all(|v| v.is_finite()), "{n} not finite");
            }
            assert!(tr.get("B_x").iter().zip(tr.get("A_x")).all(|(b, a)| b > a), "branch jump");
        }
    }

    #[test]
    fn impossible_assembly_is_refused_naming_the_parameters() {
        let mut h = Harness::<OffsetCrankSlider>::new();
        h.set("theta0", 1.5 * PI).unwrap();
        let err = h.initialize(None).unwrap_err();
        assert!(err.contains("theta0 = 270.0000 deg") && err.contains("l_AB") && err.contains("y_OC") && err.contains("l_OA"), "{err}");
    }

    #[test]
    fn variable_table_is_well_formed() {
        let problems = fmu_export::table::Table::<OffsetCrankSlider>::new().problems();
        assert!(problems.is_empty(), "{problems:?}");
    }

    /// MODELS.md's entry for this model is the one its variable table gives.
    #[test]
    fn catalogue_entry_is_current() {
        fmu_export::catalogue::check::<OffsetCrankSlider>(env!("CARGO_MANIFEST_DIR"));
    }

    /// The FMU's exact derivatives (dual numbers through the model's own equations) against
    /// central differences of its f64 equations, along the default run and at initialization
    /// (`check_derivatives` states the bound and why).
    #[test]
    fn exact_derivatives_match_central_differences() {
        let report = fmu_export::harness::check_derivatives::<OffsetCrankSlider>().unwrap();
        eprintln!("{report:?}");
        assert!(report.points > 10, "{report:?}");
    }
}
