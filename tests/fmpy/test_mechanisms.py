"""fmpy Co-Simulation runs of the Ex. 5 mechanisms against their closed forms (models/<id>/references.toml,
with the four-bar's and the slider-crank's in models/linkages/references/: the law of cosines, the
circle-line intersection and its chain rule, written once and evaluated by the Rust tests too),
independent of the models' vector loops, and the derivatives of the closed forms where it has none by
central finite differences."""

import functools

import numpy as np
import pytest
from fmpy import read_model_description

from closed_form import references
from conftest import fmu_path, simulate

# Every test here runs on the FMI 2.0 and on the FMI 3.0 FMU, against the same references.
pytestmark = pytest.mark.usefixtures("fmi_version")


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


@functools.cache
def defaults(model):
    """The model's numeric parameters and inputs at their start values (its FMI 2.0
    modelDescription)."""
    md = read_model_description(str(fmu_path(model, "2.0")))
    return {v.name: float(v.start) for v in md.modelVariables
            if v.causality in ("parameter", "input") and v.type in ("Real", "Integer") and v.start is not None}


def closed(model, name, **inputs):
    """Entry `name` of the model's references.toml: `inputs` (the input angle, and parameters that
    differ from the defaults) over the model's default parameters."""
    return references(model)[name](**{**defaults(model), **inputs})


def central(f, theta, omega, h=1e-3):
    """First and second time derivatives of f(theta(t)) by fourth-order central differences
    in theta (five points, step h rad). Truncation ~h^4 f(5) / 30 ~ 1e-12 |f(5)|, rounding
    ~eps |f| / h ~ 1e-12 (first) and ~4 eps |f| / h^2 ~ 2e-9 (second derivative) for
    |f| ~ 3 rad. Bounds used: 1e-8 (first) and 1e-7 (second derivatives, SI units), valid
    where f(5), f(6) stay below ~1e3 (away from limit positions)."""
    f0 = f(theta)
    # Differences from the centre, wrapped into (-pi, pi] so atan2's cut does not matter (a
    # no-op for lengths, whose differences are ~1e-4 m).
    d = {k: wrap(f(theta + k * h) - f0) for k in (-2, -1, 1, 2)}
    d1 = (-d[2] + 8 * d[1] - 8 * d[-1] + d[-2]) / (12 * h) * omega
    d2 = (-d[2] + 16 * d[1] + 16 * d[-1] - d[-2]) / (12 * h**2) * omega**2
    return d1, d2


def run(model, **start):
    return simulate(str(fmu_path(model)), fmi_type="CoSimulation", output_interval=0.01, start_values=start)


SLIDER = ("r1", "theta3", "r1_dot", "theta3_dot", "r1_ddot", "theta3_ddot")


def test_crank_slider_matches_circle_line_intersection():
    omega, theta0 = defaults("crank_slider")["omega"], defaults("crank_slider")["theta0"]
    for branch in (1, -1):
        r = run("crank_slider", branch=branch)
        t = r["time"]
        # Two revolutions at 10 rpm: 12 s.
        assert t[-1] == pytest.approx(12.0)
        theta = theta0 + omega * t
        np.testing.assert_allclose(r["theta"], theta, rtol=0, atol=1e-12)
        # Positions and rates projected onto the loop at every output, accelerations from
        # A x'' = b there: all agree with the closed form and its analytic derivatives to
        # rounding (bounds 1e-12 m, rad, m/s, rad/s and 1e-11 m/s2, rad/s2 on values of order 0.1
        # to 1; the Rust test measured 7e-14).
        for name in SLIDER + ("A_x", "A_y", "v_A_x", "v_A_y"):
            expected = closed("crank_slider", name, theta=theta, branch=branch)
            bound = 1e-11 if name.endswith("_ddot") else 1e-12
            assert np.max(np.abs(wrap(r[name] - expected))) < bound, name
        np.testing.assert_allclose(r["B_x"], r["r1"], rtol=0, atol=0)
        np.testing.assert_allclose(r["B_y"], 0.0, atol=0)
        np.testing.assert_allclose(r["v_B_x"], r["r1_dot"], atol=0)
        assert np.all(branch * (r["B_x"] - r["A_x"]) > 0)
        assert np.max(r["loop_residual"]) < 1e-9


def check_fourbar(model, r, branch):
    p = defaults(model)
    theta = p["theta0"] + p["omega"] * r["time"]
    np.testing.assert_allclose(r["theta"], theta, rtol=0, atol=1e-12)
    # Projected onto the loop at every output: angles and points agree to rounding (bound 1e-12
    # rad, m, m/s).
    for name in ("theta3", "theta4", "A_x", "A_y", "B_x", "B_y", "v_A_x", "v_A_y"):
        expected = closed(model, name, theta=theta, branch=branch)
        assert np.max(np.abs(wrap(r[name] - expected))) < 1e-12, name
    for name in ("theta3", "theta4"):
        d1, d2 = central(lambda th: closed(model, name, theta=th, branch=branch), theta, p["omega"])
        np.testing.assert_allclose(r[name + "_dot"], d1, rtol=0, atol=1e-8)
        np.testing.assert_allclose(r[name + "_ddot"], d2, rtol=0, atol=1e-7)
    assert np.max(r["loop_residual"]) < 1e-9


def test_crank_rocker_matches_the_law_of_cosines_and_is_periodic():
    for branch in (1, -1):
        r = run("crank_rocker", branch=branch)
        # Two revolutions at 5 rpm: 24 s.
        assert r["time"][-1] == pytest.approx(24.0)
        check_fourbar("crank_rocker", r, branch)
        # One revolution (12 s, sample 1200) brings every output back (bound 1e-12).
        for name in ("theta3_dot", "theta4_dot", "B_x", "B_y", "v_B_x", "v_B_y"):
            assert abs(r[name][1200] - r[name][0]) < 1e-12, name


def test_offset_crank_slider_matches_closed_form_and_stops_at_its_limit():
    p = defaults("offset_crank_slider")
    # l_OA sin(theta) = y_OC - l_AB: the rod is vertical.
    limit = closed("offset_crank_slider", "theta_limit")
    r = run("offset_crank_slider")
    t = r["time"]
    theta = p["theta0"] + p["omega"] * t
    # fmpy records the located stop as the last row: the margin |cos(theta3)| = 0.05 short of
    # the limit (references.toml's theta_stop; the indicator follows the exact crank angle, so
    # bound 1e-8 rad), before the 2 s stop time.
    assert t[-1] < 2.0
    assert theta[-1] < limit and abs(closed("offset_crank_slider", "theta_stop") - theta[-1]) < 1e-8
    for name in r.dtype.names:
        assert np.all(np.isfinite(r[name])), name
    # Projected rows (all but the located stop): rounding, amplified near the limit by
    # 1/cos(theta3) ~ 1/0.1 on the 10 ms grid for positions, and by its square and cube for
    # rates and accelerations, relative to max(1, |value|) (the Rust test measured 1.3e-12,
    # 6e-11, 1.8e-10 on a 1 ms grid, closer to the limit); bounds 1e-11, 1e-9 and 1e-9.
    for name, bound in zip(SLIDER, (1e-11, 1e-11, 1e-9, 1e-9, 1e-9, 1e-9)):
        expected = closed("offset_crank_slider", name, theta=theta[:-1])
        error = np.abs(wrap(r[name][:-1] - expected)) / np.maximum(1, np.abs(expected))
        assert np.max(error) < bound, name
    np.testing.assert_allclose(r["B_y"], p["y_OC"], atol=0)
    assert np.all(r["B_x"] > r["A_x"])
    assert np.max(r["loop_residual"]) < 1e-9


def test_double_rocker_matches_closed_form_and_stops_at_its_limit():
    p = defaults("double_rocker")
    # |AC| = l_AB + l_BC: AB and BC collinear, theta = 90 + 114.901 deg.
    limit = closed("double_rocker", "theta_limit")
    for branch in (1, -1):
        r = run("double_rocker", branch=branch)
        t = r["time"]
        theta = p["theta0"] + p["omega"] * t
        # The located stop is the last row: the margin |sin(theta4 - theta3)| = 0.05 short of the
        # limit (theta_stop, bound 1e-8 rad), before 2 s.
        assert t[-1] < 2.0 and theta[-1] < limit and abs(closed("double_rocker", "theta_stop") - theta[-1]) < 1e-8
        for name in r.dtype.names:
            assert np.all(np.isfinite(r[name])), name
        th3, th4 = (closed("double_rocker", name, theta=theta[:-1], branch=branch) for name in ("theta3", "theta4"))
        # Projected rows: rounding amplified by 1/|sin(theta4 - theta3)| near the limit: 1e-11.
        assert np.max(np.abs(wrap(r["theta3"][:-1] - th3))) < 1e-11
        assert np.max(np.abs(wrap(r["theta4"][:-1] - th4))) < 1e-11
        # Derivatives where central() is valid: |sin(theta4 - theta3)| > 0.6 (its truncation
        # grows like powers of 1/sin: at 0.5 it reaches 1.3e-8 rad/s, at 0.6 1.8e-9).
        ok = np.abs(np.sin(th4 - th3)) > 0.6
        for name in ("theta3", "theta4"):
            f = lambda th: closed("double_rocker", name, theta=th, branch=branch)
            d1, d2 = central(f, theta[:-1][ok], p["omega"])
            np.testing.assert_allclose(r[name + "_dot"][:-1][ok], d1, rtol=0, atol=1e-8)
            np.testing.assert_allclose(r[name + "_ddot"][:-1][ok], d2, rtol=0, atol=1e-7)
        assert np.max(r["loop_residual"]) < 1e-9
        # B never changes side of A->C (no jump to the other branch).
        cx, cy = closed("double_rocker", "C_x"), closed("double_rocker", "C_y")
        cross = (cx - r["A_x"]) * (r["B_y"] - r["A_y"]) - (cy - r["A_y"]) * (r["B_x"] - r["A_x"])
        assert np.all(branch * cross > 0)


def test_inverted_crank_slider_kinematics_and_power_balance():
    p = defaults("inverted_crank_slider")
    L3, m3, I3, omega = p["L3"], p["m3"], p["I3"], p["omega"]
    r = simulate(str(fmu_path("inverted_crank_slider")), fmi_type="CoSimulation", output_interval=1e-3)
    t = r["time"]
    assert t[-1] == pytest.approx(2.0)  # two revolutions at 60 rpm
    th2 = p["theta2_0"] + omega * t
    for name in ("r3", "theta3"):
        exact = lambda th: closed("inverted_crank_slider", name, theta2=th)
        # Projected at every output: rounding (bound 1e-12).
        assert np.max(np.abs(wrap(r[name] - exact(th2)))) < 1e-12, name
        d1, d2 = central(exact, th2, omega)
        # central()'s error estimate at omega = 6.3 rad/s: rounding 4 eps |f| / h^2 * omega^2
        # ~ 1e-7 dominates the second derivative (measured 2.9e-8), ~1e-11 the first
        # (measured 7e-12). Bounds 1e-9 and 2e-7.
        np.testing.assert_allclose(r[name + "_dot"], d1, rtol=0, atol=1e-9)
        np.testing.assert_allclose(r[name + "_ddot"], d2, rtol=0, atol=2e-7)
    # Power balance T omega = d(KE)/dt, KE of link 3 (the crank's is constant; no gravity).
    g = r["r3"] - L3 / 2
    vu, vn = r["r3_dot"], g * r["theta3_dot"]
    ke = 0.5 * m3 * (vu**2 + vn**2) + 0.5 * I3 * r["theta3_dot"] ** 2
    dt = 1e-3
    dke = (-ke[4:] + 8 * ke[3:-1] - 8 * ke[1:-3] + ke[:-4]) / (12 * dt)
    power = r["T"][2:-2] * omega
    assert np.max(np.abs(power)) > 0.1
    # Fourth-order difference of KE on the 1 ms grid: truncation ~2e-11 W, plus the rates'
    # ~1e-10 errors; the Rust test measured 2.3e-9 W. Bound 1e-7 W on powers of 0.3 W.
    assert np.max(np.abs(power - dke)) < 1e-7
    assert np.max(r["loop_residual"]) < 1e-9


def test_inverted_crank_slider_at_rest_has_no_loads():
    r = simulate(str(fmu_path("inverted_crank_slider")), fmi_type="CoSimulation", output_interval=0.1,
                     start_values={"omega": 0.0, "theta2_0": 0.7})
    # No motion and no gravity: every force and the torque vanish exactly.
    for name in ("F_Ax", "F_Ay", "F_Bx", "F_By", "F_C", "T", "r3_dot", "theta3_dot"):
        assert np.all(r[name] == 0.0), name
