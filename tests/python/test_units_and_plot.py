"""Results carry their units (DataFrame.attrs) and fmurunner.plot draws them in display units,
one panel per output, as `runner simulate --plot` does. The units are the FMU's
modelDescription's, read here independently with fmpy."""

import math

import matplotlib
import numpy as np
import pytest
from fmpy import read_model_description

import fmurunner
from fmurunner_helpers import REFERENCE, fmu_path

matplotlib.use("Agg")


def test_simulate_records_each_columns_unit_and_display_unit():
    df = fmurunner.simulate("pendulum", stop_time=1.0)
    md = read_model_description(str(fmu_path("pendulum")))
    declared = {v.name: v.unit or (v.declaredType.unit if v.declaredType else None) for v in md.modelVariables}
    for column in df.columns:
        if column == "time":
            assert df.attrs["units"]["time"] == "s"
        elif declared.get(column):
            assert df.attrs["units"][column] == declared[column], column
    assert df.attrs["model_name"] == "pendulum"
    name, factor, offset = df.attrs["display_units"]["theta"]
    assert (name, offset) == ("deg", 0.0) and math.isclose(factor, 180 / math.pi, rel_tol=1e-15)
    ball = fmurunner.simulate(REFERENCE / "fmi3" / "BouncingBall.fmu", stop_time=1.0)
    assert ball.attrs["units"]["h"] == "m" and ball.attrs["units"]["v"] == "m/s"


def test_plot_draws_one_panel_per_output_in_display_units(tmp_path):
    df = fmurunner.simulate("pendulum", stop_time=1.0)
    floats = [c for c in df.columns if c != "time" and df[c].dtype == np.float64]
    fig = fmurunner.plot(df, path=tmp_path / "pendulum.png")
    axes = fig.get_axes()
    assert len(axes) == len(floats)
    theta = axes[floats.index("theta")]
    assert theta.get_ylabel() == "theta (deg)"
    x, y = theta.get_lines()[0].get_data()
    assert np.array_equal(x, df["time"]) and np.allclose(y, np.degrees(df["theta"]), rtol=1e-15, atol=0)
    assert axes[-1].get_xlabel() == "time (s)"
    assert (tmp_path / "pendulum.png").stat().st_size > 1000
    one = fmurunner.plot(df, columns=["energy"])
    assert [a.get_ylabel() for a in one.get_axes()] == ["energy (J)"]


def test_plot_refuses_what_it_cannot_draw():
    df = fmurunner.simulate("pendulum", stop_time=0.1)
    with pytest.raises(fmurunner.RunnerError, match="no column 'thet'"):
        fmurunner.plot(df, columns=["thet"])
    with pytest.raises(fmurunner.RunnerError, match="takes the DataFrame"):
        fmurunner.plot([1, 2, 3])  # type: ignore[arg-type]
