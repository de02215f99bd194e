"""fmpy Co-Simulation runs of the walking arm trebuchet (models/trebuchet/derivation.md): the
launch runs to the landing and stops there cleanly, and the landing point agrees with the
ballistic closed form of references.toml (closed_form.py evaluates it) from the release state
read from the FMU's outputs."""

import numpy as np
import pytest
from fmpy import read_model_description

from closed_form import references
from conftest import fmu_path, simulate

# Every test here runs on the FMI 2.0 and on the FMI 3.0 FMU, against the same references.
pytestmark = pytest.mark.usefixtures("fmi_version")

G = 9.81
OUT = ["regime", "E_x", "E_y", "x_p", "y_p", "vx_p", "vy_p", "projectile_speed", "t_release",
       "range", "range_ideal", "efficiency", "misfire", "energy", "theta2", "theta3"]


def launch(**start):
    return simulate(str(fmu_path("trebuchet")), fmi_type="CoSimulation", relative_tolerance=1e-10,
                        output_interval=1e-3, start_values={"abs_tol": 1e-12, **start}, output=OUT)


def test_default_launch_lands_forward_and_stops_at_landing():
    md = read_model_description(str(fmu_path("trebuchet")))
    assert float(md.defaultExperiment.stopTime) == 10.0
    r = launch()
    t = r["time"]
    # fmi2Discard + fmi2Terminated: fmpy records the landing time as the last sample.
    assert 2.0 < t[-1] < 10.0
    regimes = r["regime"]
    assert set(np.unique(regimes)) == {1, 3, 4}
    assert np.all(np.diff(regimes) >= 0)
    assert r["regime"][-1] == 4 and not r["misfire"][-1]
    # At the landing event the projectile is on the ground (located to 1e-10 s, |vy| ~ 15 m/s).
    assert abs(r["E_y"][-1]) < 1e-8
    assert r["range"][-1] > 0 and abs(r["range"][-1] - r["E_x"][-1]) < 1e-8
    assert 0 < r["efficiency"][-1] < 1 and r["range"][-1] < r["range_ideal"][-1]


def test_range_matches_the_ballistic_closed_form_from_the_release_state():
    r = launch()
    t_r = r["t_release"][-1]
    k = np.nonzero(r["regime"] == 4)[0][0]
    tau = r["time"][k] - t_r
    assert 0 <= tau <= 1e-3 + 1e-12
    # Back along the parabola to the release instant, then the flight to the ground.
    ballistics = references("trebuchet")
    sample = dict(x=r["x_p"][k], y=r["y_p"][k], vx=r["vx_p"][k], vy=r["vy_p"][k], tau=tau, g=G)
    vx = r["vx_p"][k]
    # The release happened where theta3 - theta2 = release_angle = 140 deg (frozen after it).
    assert abs(r["theta3"][k] - r["theta2"][k] - np.radians(140.0)) < 1e-8
    assert abs(r["projectile_speed"][k] - np.hypot(vx, r["vy_p"][k])) < 1e-12
    t_f, expected = ballistics["t_flight"](**sample), ballistics["range"](**sample)
    # Event located to 1e-10 s times |vx| ~ 12 m/s, flight polynomial integrated exactly.
    assert abs(r["range"][-1] - expected) < 1e-8, (r["range"][-1], expected)
    assert abs(r["time"][-1] - (t_r + t_f)) < 1e-8
    # Flight conserves the projectile's energy, and the total output stays constant.
    flight = r["regime"] == 4
    e = r["energy"][flight]
    assert np.ptp(e) < 1e-9 * abs(e[0])


def test_a_heavy_projectile_misfires_and_stops():
    r = launch(w_3=5 * 4.4482216152605)
    assert r["misfire"][-1] and r["regime"][-1] == 3
    assert r["t_release"][-1] == -1 and r["time"][-1] < 10.0
