"""The formula language of closed_form.py against runner-engine's (metrics::Formula,
references::References): the same functions, constant and errors, and the same numbers for every
models/<id>/references.toml entry. The engine's values come from the installed fmurunner package's
extension, the engine itself (fmurunner._engine.reference_values)."""

import math
import re

import numpy as np
import pytest

from closed_form import Formula, load, References
from conftest import MODELS, ROOT
from test_mechanisms import defaults


def test_functions_of_two_arguments_and_pi():
    assert Formula("atan2(y, x)")(y=-1.0, x=-2.0) == math.atan2(-1.0, -2.0)
    assert Formula("atan2(1, -1)")() == 0.75 * math.pi, "the second quadrant, not atan(-1)"
    assert Formula("hypot(a - 1, 2*b)")(a=4.0, b=2.0) == 5.0
    assert Formula("asin(x) + acos(x) + atan(x)")(x=0.3) == math.asin(0.3) + math.acos(0.3) + math.atan(0.3)
    assert Formula("2*pi - atan2(0, -1)")() == math.pi
    f = Formula("r*cos(pi/2 + theta)")
    assert f.names == ["r", "theta"], "pi is a constant, not a name the caller gives"
    np.testing.assert_array_equal(Formula("atan2(y, x)")(y=np.array([1.0, -1.0]), x=-1.0), [0.75 * math.pi, -0.75 * math.pi])


@pytest.mark.parametrize("text, message", [
    ("atan2(y)", "'atan2' in 'atan2(y)' takes 2 arguments, given 1"),
    ("1 + sqrt(x, y)", "'sqrt' in '1 + sqrt(x, y)' takes 1 argument, given 2"),
    ("hypot(x, y, z)", "takes 2 arguments, given 3"),
    ("atan2(y, x", "expected ')'"),
    ("arctan2(y, x)", "'arctan2' is not a function"),
    ("pi(2)", "'pi' is not a function"),
])
def test_wrong_argument_counts_and_unknown_functions_are_refused(text, message):
    with pytest.raises(ValueError, match=re.escape(message)):
        Formula(text)


def test_an_entry_named_pi_and_bad_includes_are_refused(tmp_path):
    with pytest.raises(ValueError, match="'pi' is a constant"):
        References({"pi": "3.14"})
    (tmp_path / "shared.toml").write_text('y = "l*sin(theta)"\n')
    (tmp_path / "model.toml").write_text('include = ["shared.toml"]\nr = "hypot(l, y)"\n')
    assert load(tmp_path / "model.toml")["r"](l=3.0, theta=math.pi / 2) == math.hypot(3.0, 3.0)
    (tmp_path / "twice.toml").write_text('include = ["shared.toml"]\ny = "0"\n')
    with pytest.raises(ValueError, match="reference y is given twice"):
        load(tmp_path / "twice.toml")
    (tmp_path / "cycle.toml").write_text('include = ["cycle.toml"]\n')
    with pytest.raises(ValueError, match="include each other in a cycle"):
        load(tmp_path / "cycle.toml")


# The inputs of the references that are not parameters, at values inside their domains: the
# bumper's time (in contact and separated alike), the trebuchet's flight sample, and each
# linkage's input angle 0.3 rad on from its start (before the limit positions).
SAMPLES = {"t": 0.05, "x": 20.0, "y": 2.0, "vx": 12.0, "vy": -3.0, "tau": 0.1}
ANGLES = {"theta": "theta0", "theta2": "theta2_0"}
# The crank-slider's theta_limit exists only for a rod shorter than the crank: its Rust test's.
# The pendulum's Jacobian and energy gradient hold at any state: a swinging one (omega, the
# angular velocity state, is not a parameter).
OVERRIDES = {"crank_slider": {"l_AB": 0.06, "theta0": 0.0}, "pendulum": {"omega": 1.5}}
FILES = sorted(p.parent.name for p in (ROOT / "models").glob("*/references.toml"))


def test_every_model_with_closed_forms_is_compared():
    assert set(FILES) <= set(MODELS) and len(FILES) >= 9, FILES


@pytest.mark.parametrize("model", FILES)
def test_the_engine_and_closed_form_py_give_the_same_numbers(model):
    """Every entry at the FMU's default parameters (and inputs). Both evaluators build the same expression tree
    and do the same IEEE operations in the same order, so they differ only where a function's
    implementation does (Rust's f64 methods call the C library; numpy may use its own vectorised
    loops, within 1 ulp of the exact value): a few ulps, carried through at most ~20 operations of
    condition numbers of order 1 at these values. Bound 1e-14 relative to max(1, |value|)
    (about 50 ulps). Measured: bit-identical everywhere but the pendulum's period, 1.3e-16 (ellipk,
    scipy's against the engine's arithmetic-geometric mean)."""
    try:
        from fmurunner import _engine
    except ImportError as e:
        pytest.fail(f"the fmurunner package is not installed ({e}): tests/run installs its wheel")
    path = ROOT / "models" / model / "references.toml"
    values = {**defaults(model), **SAMPLES, **OVERRIDES.get(model, {})}
    values.update({angle: values[start] + 0.3 for angle, start in ANGLES.items() if start in values})
    engine = _engine.reference_values(str(path), sorted(values.items()))
    python = load(path)
    assert sorted(engine) == sorted([*python.formulas, *python.matrices])
    worst = 0.0
    for name, expected in engine.items():
        ours = python.matrix(name, **values) if name in python.matrices else python[name](**values)
        expected, ours = np.asarray(expected, dtype=float), np.asarray(ours, dtype=float)
        assert np.all(np.isfinite(expected)), f"{name} is not finite at the sample: choose another"
        difference = np.max(np.abs(ours - expected) / np.maximum(1, np.abs(expected)))
        worst = max(worst, difference)
        assert difference < 1e-14, (name, ours, expected)
    print(f"{model}: {len(engine)} entries, largest difference {worst:.1e}")
