"""fmpy Co-Simulation runs of second_order and mass_spring_damper against their analytical
solutions (derived in each model's derivation.md), as written once in each model's
experiment.toml (closed_form.py evaluates them)."""

import math

import numpy as np
import pytest

from closed_form import Formula, reference
from conftest import fmu_path, simulate


@pytest.mark.usefixtures("fmi_version")
def test_second_order_matches_the_closed_form():
    r = simulate(str(fmu_path("second_order")), fmi_type="CoSimulation", relative_tolerance=1e-10,
                     output_interval=0.01, start_values={"abs_tol": 1e-12})
    t = r["time"]
    q, q_dot, u = (reference("second_order", name)(t=t) for name in ("q", "q_dot", "u"))
    # rtol 1e-10 on a solution of size ~2: 1e-8 leaves room for error accumulation over 1000 steps.
    assert np.max(np.abs(r["q"] - q)) < 1e-8
    assert np.max(np.abs(r["q_dot"] - q_dot)) < 1e-8
    assert np.max(np.abs(r["u"] - u)) < 1e-14
    # The reference itself: q(0) = 2, q'(0) = 1 and u = exp(-3t), whatever the FMU does.
    assert (q[0], q_dot[0]) == (2.0, 1.0) and abs(u[50] - math.exp(-1.5)) < 1e-16


@pytest.mark.usefixtures("fmi_version")
def test_mass_spring_damper_step_force_from_fmpy_input():
    lbf, inch = 4.4482216152605, 0.0254
    k, m, b = 10 * lbf / inch, 2 * lbf / inch, lbf / inch
    f0 = 100.0
    # fmpy drives the input F as a signal table: a constant 100 N step from t = 0.
    signals = np.array([(0.0, f0), (10.0, f0)], dtype=[("time", np.float64), ("F", np.float64)])
    r = simulate(str(fmu_path("mass_spring_damper")), fmi_type="CoSimulation", relative_tolerance=1e-10,
                     output_interval=0.01, input=signals, start_values={"abs_tol": 1e-13})
    t = r["time"]
    # From rest under a constant f0: the free vibration about the shifted equilibrium f0/k.
    x = f0 / k + reference("mass_spring_damper", "x")(t=t, m=m, b=b, k=k, x0=-f0 / k, v0=0.0)
    # Response scale F0/k ~ 0.057 m; rtol 1e-10 gives errors near 1e-11.
    assert np.max(np.abs(r["x"] - x)) < 1e-9
    np.testing.assert_allclose(r["F_total"], k * r["x"] + b * r["v"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("text, values, expected", [
    ("1 + 2 * 3", {}, 7.0),
    ("(1 + 2) * 3", {}, 9.0),
    ("-2^2", {}, -4.0),
    ("2^-1", {}, 0.5),
    ("2^3^2", {}, 512.0),
    ("8 / 4 / 2", {}, 1.0),
    ("1 - 2 - 3", {}, -4.0),
    ("- -x", {"x": 3.0}, 3.0),
    ("1.5e-1*x + .5", {"x": 2.0}, 0.8),
    ("sqrt(abs(x)) + exp(log(4)) - atan(1)*4", {"x": -9.0}, 7.0 - math.pi),
])
def test_the_formula_evaluator_follows_the_runner_grammar(text, values, expected):
    """Precedence and associativity as runner-engine's parser documents them (metrics.rs):
    power binds tighter than unary minus and is right-associative, the rest left-associative."""
    assert Formula(text)(**values) == pytest.approx(expected, rel=1e-15)


def test_the_formula_evaluator_refuses_what_the_runner_refuses():
    for bad in ("1 +", "(1", "cosh(1)", "1 2", "x $ 2"):
        with pytest.raises(ValueError):
            Formula(bad)
    with pytest.raises(KeyError):
        Formula("k * x")(k=1.0)
