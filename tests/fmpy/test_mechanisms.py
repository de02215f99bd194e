"""fmpy Co-Simulation runs of the Ex. 5 mechanisms against closed-form geometry computed here
with numpy (circle-line and circle-circle intersections), independently of the Rust code, and
their derivatives by central finite differences of that closed form."""

import numpy as np
import pytest

from conftest import fmu_path, simulate

# Every test here runs on the FMI 2.0 and on the FMI 3.0 FMU, against the same references.
pytestmark = pytest.mark.usefixtures("fmi_version")

RPM = np.pi / 30


def wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi


def slider_closed_form(theta, l_oa, l_ab, y_oc, branch):
    """B where the circle of radius l_AB about A meets the line y = y_OC: (r1, theta3)."""
    ax, ay = l_oa * np.cos(theta), l_oa * np.sin(theta)
    dy = y_oc - ay
    dx = branch * np.sqrt(l_ab**2 - dy**2)
    return ax + dx, np.arctan2(dy, dx)


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


def test_crank_slider_matches_circle_line_intersection():
    l_oa, l_ab, omega, theta0 = 0.080, 0.120, 10 * RPM, np.radians(60)
    for branch in (1, -1):
        r = run("crank_slider", branch=branch)
        t = r["time"]
        # Two revolutions at 10 rpm: 12 s.
        assert t[-1] == pytest.approx(12.0)
        theta = theta0 + omega * t
        np.testing.assert_allclose(r["theta"], theta, rtol=0, atol=1e-12)
        r1, th3 = slider_closed_form(theta, l_oa, l_ab, 0.0, branch)
        # Projected onto the loop at every output: agreement to rounding (bound 1e-12 m / rad).
        np.testing.assert_allclose(r["r1"], r1, rtol=0, atol=1e-12)
        assert np.max(np.abs(wrap(r["theta3"] - th3))) < 1e-12
        np.testing.assert_allclose(r["B_x"], r1, rtol=0, atol=1e-12)
        np.testing.assert_allclose(r["B_y"], 0.0, atol=0)
        np.testing.assert_allclose(r["A_x"], l_oa * np.cos(theta), atol=1e-12)
        np.testing.assert_allclose(r["A_y"], l_oa * np.sin(theta), atol=1e-12)
        np.testing.assert_allclose(r["v_A_x"], -l_oa * omega * np.sin(theta), atol=1e-12)
        np.testing.assert_allclose(r["v_A_y"], l_oa * omega * np.cos(theta), atol=1e-12)
        for name, k in (("r1", 0), ("theta3", 1)):
            f = lambda th: slider_closed_form(th, l_oa, l_ab, 0.0, branch)[k]
            d1, d2 = central(f, theta, omega)
            # Bounds from central()'s error estimate (values of order 0.1 to 1).
            np.testing.assert_allclose(r[name + "_dot"], d1, rtol=0, atol=1e-8)
            np.testing.assert_allclose(r[name + "_ddot"], d2, rtol=0, atol=1e-7)
        np.testing.assert_allclose(r["v_B_x"], r["r1_dot"], atol=0)
        assert np.all(branch * (r["B_x"] - r["A_x"]) > 0)
        assert np.max(r["loop_residual"]) < 1e-9


def fourbar_closed_form(theta, l_oa, l_ab, l_bc, l_co, theta_co, branch):
    """B as an intersection of the circles about A (radius l_AB) and C (radius l_BC), the one
    to the left of A->C for branch +1: (theta3, theta4)."""
    a = np.stack([l_oa * np.cos(theta), l_oa * np.sin(theta)])
    c = np.array([l_co * np.cos(theta_co), l_co * np.sin(theta_co)])[:, None]
    ac = c - a
    d = np.hypot(*ac)
    u = ac / d
    p = (l_ab**2 - l_bc**2 + d**2) / (2 * d)
    h = np.sqrt(l_ab**2 - p**2)
    b = a + p * u + branch * h * np.stack([-u[1], u[0]])
    return np.arctan2(*(b - a)[::-1]), np.arctan2(*(b - c)[::-1])


def check_fourbar(r, dims, theta0, omega, branch):
    t = r["time"]
    theta = theta0 + omega * t
    np.testing.assert_allclose(r["theta"], theta, rtol=0, atol=1e-12)
    th3, th4 = fourbar_closed_form(theta, *dims, branch)
    # Projected onto the loop at every output: angles agree to rounding (bound 1e-12 rad).
    assert np.max(np.abs(wrap(r["theta3"] - th3))) < 1e-12
    assert np.max(np.abs(wrap(r["theta4"] - th4))) < 1e-12
    l_oa, l_ab, l_bc, l_co, theta_co = dims
    np.testing.assert_allclose(r["B_x"], l_co * np.cos(theta_co) + l_bc * np.cos(th4), rtol=0, atol=1e-12)
    np.testing.assert_allclose(r["B_y"], l_co * np.sin(theta_co) + l_bc * np.sin(th4), rtol=0, atol=1e-12)
    np.testing.assert_allclose(r["A_x"], l_oa * np.cos(theta), rtol=0, atol=1e-12)
    np.testing.assert_allclose(r["v_A_x"], -l_oa * omega * np.sin(theta), rtol=0, atol=1e-12)
    for k, name in enumerate(("theta3", "theta4")):
        f = lambda th: fourbar_closed_form(th, *dims, branch)[k]
        d1, d2 = central(f, theta, omega)
        np.testing.assert_allclose(r[name + "_dot"], d1, rtol=0, atol=1e-8)
        np.testing.assert_allclose(r[name + "_ddot"], d2, rtol=0, atol=1e-7)
    assert np.max(r["loop_residual"]) < 1e-9


def test_crank_rocker_matches_circle_circle_intersection_and_is_periodic():
    dims = (0.100, 0.180, 0.500, 0.560, 0.0)
    theta0, omega = np.radians(135), 5 * RPM
    for branch in (1, -1):
        r = run("crank_rocker", branch=branch)
        # Two revolutions at 5 rpm: 24 s.
        assert r["time"][-1] == pytest.approx(24.0)
        check_fourbar(r, dims, theta0, omega, branch)
        # One revolution (12 s, sample 1200) brings every output back (bound 1e-12).
        for name in ("theta3_dot", "theta4_dot", "B_x", "B_y", "v_B_x", "v_B_y"):
            assert abs(r[name][1200] - r[name][0]) < 1e-12, name


def test_offset_crank_slider_matches_closed_form_and_stops_at_its_limit():
    l_oa, l_ab, y_oc, omega, theta0 = 0.080, 0.100, 0.080, 15 * RPM, np.radians(60)
    limit = np.pi + np.arcsin(0.25)  # l_OA sin(theta) = y_OC - l_AB: the rod is vertical
    r = run("offset_crank_slider")
    t = r["time"]
    theta = theta0 + omega * t
    # fmpy records the located stop as the last row: just short of the limit (bound 1e-5 rad,
    # the 1e-3 threshold on cos(theta3) puts it ~6.5e-7 rad short), before the 2 s stop time.
    assert t[-1] < 2.0
    assert 0 <= limit - theta[-1] < 1e-5
    for name in r.dtype.names:
        assert np.all(np.isfinite(r[name])), name
    r1, th3 = slider_closed_form(theta, l_oa, l_ab, y_oc, 1)
    # Projected rows (all but the located stop): rounding, amplified near the limit by
    # 1/cos(theta3) ~ 1/0.1 on the 10 ms grid; bound 1e-11.
    np.testing.assert_allclose(r["r1"][:-1], r1[:-1], rtol=0, atol=1e-11)
    assert np.max(np.abs(wrap(r["theta3"][:-1] - th3[:-1]))) < 1e-11
    # central()'s truncation error grows like a high power of 1/cos(theta3) near the limit:
    # compare where cos(theta3) > 0.5.
    ok = np.cos(th3) > 0.5
    for name, k in (("r1", 0), ("theta3", 1)):
        f = lambda th: slider_closed_form(th, l_oa, l_ab, y_oc, 1)[k]
        d1, d2 = central(f, theta[ok], omega)
        np.testing.assert_allclose(r[name + "_dot"][ok], d1, rtol=0, atol=1e-8)
        np.testing.assert_allclose(r[name + "_ddot"][ok], d2, rtol=0, atol=1e-7)
    np.testing.assert_allclose(r["B_y"], y_oc, atol=0)
    assert np.all(r["B_x"] > r["A_x"])
    assert np.max(r["loop_residual"]) < 1e-9


def test_double_rocker_matches_closed_form_and_stops_at_its_limit():
    dims = (0.400, 0.100, 0.410, 0.190, np.radians(90))
    theta0, omega = np.radians(150), 8 * RPM
    # |AC| = l_AB + l_BC: AB and BC collinear, theta = 90 + 114.901 deg.
    limit = dims[4] + np.arccos((0.4**2 + 0.19**2 - 0.51**2) / (2 * 0.4 * 0.19))
    for branch in (1, -1):
        r = run("double_rocker", branch=branch)
        t = r["time"]
        theta = theta0 + omega * t
        # The located stop is the last row: just short of the limit (bound 1e-5 rad), before 2 s.
        assert t[-1] < 2.0 and 0 <= limit - theta[-1] < 1e-5
        for name in r.dtype.names:
            assert np.all(np.isfinite(r[name])), name
        th3, th4 = fourbar_closed_form(theta[:-1], *dims, branch)
        # Projected rows: rounding amplified by 1/|sin(theta4 - theta3)| near the limit: 1e-11.
        assert np.max(np.abs(wrap(r["theta3"][:-1] - th3))) < 1e-11
        assert np.max(np.abs(wrap(r["theta4"][:-1] - th4))) < 1e-11
        # Derivatives where central() is valid: |sin(theta4 - theta3)| > 0.6 (its truncation
        # grows like powers of 1/sin: at 0.5 it reaches 1.3e-8 rad/s, at 0.6 1.8e-9).
        ok = np.abs(np.sin(th4 - th3)) > 0.6
        for k, name in enumerate(("theta3", "theta4")):
            d1, d2 = central(lambda th: fourbar_closed_form(th, *dims, branch)[k], theta[:-1][ok], omega)
            np.testing.assert_allclose(r[name + "_dot"][:-1][ok], d1, rtol=0, atol=1e-8)
            np.testing.assert_allclose(r[name + "_ddot"][:-1][ok], d2, rtol=0, atol=1e-7)
        assert np.max(r["loop_residual"]) < 1e-9
        # B never changes side of A->C (no jump to the other branch).
        cx, cy = 0.0, 0.19
        cross = (cx - r["A_x"]) * (r["B_y"] - r["A_y"]) - (cy - r["A_y"]) * (r["B_x"] - r["A_x"])
        assert np.all(branch * cross > 0)


def test_inverted_crank_slider_kinematics_and_power_balance():
    r1, r2, L3, m3 = 0.240, 0.080, 0.350, 0.5
    I3, omega = m3 * L3**2 / 12, -60 * RPM
    r = simulate(str(fmu_path("inverted_crank_slider")), fmi_type="CoSimulation", output_interval=1e-3)
    t = r["time"]
    assert t[-1] == pytest.approx(2.0)  # two revolutions at 60 rpm
    th2 = omega * t
    closed = lambda th: (np.hypot(r1 + r2 * np.cos(th), r2 * np.sin(th)), np.arctan2(r2 * np.sin(th), r1 + r2 * np.cos(th)))
    r3, th3 = closed(th2)
    # Projected at every output: rounding (bound 1e-12).
    np.testing.assert_allclose(r["r3"], r3, rtol=0, atol=1e-12)
    assert np.max(np.abs(wrap(r["theta3"] - th3))) < 1e-12
    for k, name in enumerate(("r3", "theta3")):
        d1, d2 = central(lambda th: closed(th)[k], th2, omega)
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
