"""fmpy Co-Simulation runs of second_order and mass_spring_damper against their analytical
solutions (derived in each model's derivation.md)."""

import numpy as np
from fmpy import simulate_fmu

from conftest import fmu_path


def test_second_order_matches_the_closed_form():
    r = simulate_fmu(str(fmu_path("second_order")), fmi_type="CoSimulation", relative_tolerance=1e-10,
                     output_interval=0.01, start_values={"abs_tol": 1e-12})
    t = r["time"]
    q = 7.5 * np.exp(-2 * t) - 5.5 * np.exp(-3 * t) - 0.5 * t * np.exp(-3 * t)
    q_dot = -15 * np.exp(-2 * t) + 16 * np.exp(-3 * t) + 1.5 * t * np.exp(-3 * t)
    # rtol 1e-10 on a solution of size ~2: 1e-8 leaves room for error accumulation over 1000 steps.
    assert np.max(np.abs(r["q"] - q)) < 1e-8
    assert np.max(np.abs(r["q_dot"] - q_dot)) < 1e-8
    assert np.max(np.abs(r["u"] - np.exp(-3 * t))) < 1e-14


def test_mass_spring_damper_step_force_from_fmpy_input():
    lbf, inch = 4.4482216152605, 0.0254
    k, m, b = 10 * lbf / inch, 2 * lbf / inch, lbf / inch
    f0 = 100.0
    # fmpy drives the input F as a signal table: a constant 100 N step from t = 0.
    signals = np.array([(0.0, f0), (10.0, f0)], dtype=[("time", np.float64), ("F", np.float64)])
    r = simulate_fmu(str(fmu_path("mass_spring_damper")), fmi_type="CoSimulation", relative_tolerance=1e-10,
                     output_interval=0.01, input=signals, start_values={"abs_tol": 1e-13})
    t = r["time"]
    wn = np.sqrt(k / m)
    zeta = b / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta**2)
    a = -f0 / k
    bb = zeta * wn * a / wd
    x = f0 / k + np.exp(-zeta * wn * t) * (a * np.cos(wd * t) + bb * np.sin(wd * t))
    # Response scale F0/k ~ 0.057 m; rtol 1e-10 gives errors near 1e-11.
    assert np.max(np.abs(r["x"] - x)) < 1e-9
    np.testing.assert_allclose(r["F_total"], k * r["x"] + b * r["v"], rtol=0, atol=1e-9)
