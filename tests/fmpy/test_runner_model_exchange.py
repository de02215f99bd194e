"""The runner integrating Model Exchange FMUs with the toolkit's own solvers
(`runner simulate --interface model-exchange`), checked against an independent importer: fmpy's
Model Exchange run (CVODE) of the Reference FMUs at tight tolerance, and closed forms where the
model has one (the bouncing ball's bounce times, the Dahlquist decay); and on this project's
FMUs, the runner's Model Exchange run against its Co-Simulation run."""

import csv
import os
import pathlib
import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import MODELS, ROOT, TARGET, fmu_path

RUNNER = TARGET / "release" / "runner"
REFERENCE = pathlib.Path(os.environ.get("REFERENCE_FMUS", ROOT.parent / "shared" / "reference-fmus" / "fmi2"))


def reference(name):
    path = REFERENCE / f"{name}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: the Reference FMUs are expected in ../shared/reference-fmus (or set REFERENCE_FMUS)")
    return path


def runner(*args):
    if not RUNNER.is_file():
        pytest.fail(f"{RUNNER} is missing: tests/run builds it with `cargo run --release -p runner -- build`")
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True, timeout=600)


def simulate(fmu, tmp_path, *args, name="run"):
    """`runner simulate` of `fmu` with `args`; the CSV's columns as arrays, and stderr."""
    out = tmp_path / f"{name}.csv"
    p = runner("simulate", fmu, "--out", out, *args)
    assert p.returncode == 0, p.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    def column(j):
        # String outputs stay text (FMI 2.0 CSVs include them, as FMI 3.0's do).
        try:
            return np.array([float(r[j]) for r in rows[1:]])
        except ValueError:
            return np.array([r[j] for r in rows[1:]])

    columns = {h: column(j) for j, h in enumerate(rows[0])}
    return columns, p.stderr


def fmpy_me(fmu, **kwargs):
    # record_events=False: rows on the output grid only, as the runner writes them; at a grid
    # point with an event both record the values after it.
    return simulate_fmu(str(fmu), fmi_type="ModelExchange", record_events=False, **kwargs)


TIGHT = ["--interface", "model-exchange", "--tolerance", "1e-10", "--abs-tolerance", "1e-12"]


def test_bouncing_ball_bounces_at_the_closed_form_times_and_as_fmpy(tmp_path):
    fmu = reference("BouncingBall")
    r, _ = simulate(fmu, tmp_path, *TIGHT, "--output-interval", "0.01")
    g, e, v_min = 9.81, 0.7, 0.1
    # Free fall from 1 m; each bounce returns e times the impact speed, and the ball rests once
    # that is below v_min: impacts at t1 = sqrt(2/g), then flights of 2 e^k v1 / g.
    t1 = np.sqrt(2 / g)
    v1 = g * t1
    impacts = [t1]
    speed = v1
    while e * speed >= v_min:
        speed *= e
        impacts.append(impacts[-1] + 2 * speed / g)
    # The runner's impacts: between the last sample falling (v < 0) and the first rising, back
    # along the parabola from the sample before (exact for free fall).
    t, h, v = r["time"], r["h"], r["v"]
    found = []
    for k in np.nonzero((v[:-1] < 0) & (v[1:] >= 0))[0]:
        found.append(t[k] + (v[k] + np.sqrt(v[k] ** 2 + 2 * g * h[k])) / g)
    assert len(found) == len(impacts) == 11
    # The located events' error at rtol 1e-10 is ~1e-11 s and accumulates over 10 bounces with
    # the speeds' errors; measured 1.5e-10 s: bound 1e-8 s.
    np.testing.assert_allclose(found, impacts, rtol=0, atol=1e-8)
    assert np.all(h[t > impacts[-1] + 0.01] < 1e-300), "at rest after the last bounce"
    f = fmpy_me(fmu, relative_tolerance=1e-10, output_interval=0.01)
    assert len(f) == len(t)
    np.testing.assert_allclose(f["time"], t, rtol=0, atol=1e-12)
    # Both runs err by ~1e-9 m; near an impact the difference of the two located times (~1e-9 s)
    # times |v| <= 4.4 m/s adds to it (measured 4e-9 m): bound 1e-7.
    np.testing.assert_allclose(f["h"], h, rtol=0, atol=1e-7)
    np.testing.assert_allclose(f["v"], v, rtol=0, atol=1e-7)


def test_van_der_pol_matches_fmpy(tmp_path):
    fmu = reference("VanDerPol")
    r, _ = simulate(fmu, tmp_path, *TIGHT)
    f = fmpy_me(fmu, relative_tolerance=1e-11, output_interval=0.01)
    np.testing.assert_allclose(f["time"], r["time"], rtol=0, atol=1e-12)
    # 20 s on the limit cycle (amplitude 2): both solvers' global errors (measured difference
    # 3e-8) stay below 1e-6.
    for name in ("x0", "x1"):
        np.testing.assert_allclose(r[name], f[name], rtol=0, atol=1e-6)


def test_dahlquist_decays_exactly_as_exp_and_as_fmpy(tmp_path):
    fmu = reference("Dahlquist")
    for solver, bound in (("dopri5", 1e-10), ("rk4", 1e-9), ("euler", 2e-3)):
        r, _ = simulate(fmu, tmp_path, "--interface", "model-exchange", "--solver", solver, "--fixed-step", "1e-3",
                        "--tolerance", "1e-10", "--abs-tolerance", "1e-12", name=solver)
        # x' = -x from 1: DOPRI5 at rtol 1e-10, RK4 at h = 1e-3 (error h^4/120 per unit time),
        # Euler at h = 1e-3 (x h t e^-t / 2 <= 1.8e-4): measured below each bound.
        assert np.max(np.abs(r["x"] - np.exp(-r["time"]))) < bound, solver
    f = fmpy_me(fmu, relative_tolerance=1e-10, output_interval=0.1)
    r, _ = simulate(fmu, tmp_path, *TIGHT)
    np.testing.assert_allclose(r["x"], f["x"], rtol=0, atol=1e-9)


def test_stair_counts_its_time_events_as_fmpy(tmp_path):
    fmu = reference("Stair")
    r, err = simulate(fmu, tmp_path, "--interface", "model-exchange", "--output-interval", "0.01")
    f = fmpy_me(fmu, output_interval=0.01)
    # A time event every second; the counter's row at t = k already shows the event of t = k,
    # and the model ends the run (terminateSimulation) when it reaches 10, at t = 9: the runner
    # keeps that last state as a row, fmpy stops before recording it.
    assert r["time"][-1] == pytest.approx(9.0) and "stopped before the stop time" in err
    np.testing.assert_array_equal(r["counter"], np.floor(r["time"] + 1e-9) + 1)
    assert len(f) == len(r["time"]) - 1 == 900
    np.testing.assert_allclose(f["time"], r["time"][:-1], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(f["counter"], r["counter"][:-1])


def test_feedthrough_passes_its_inputs_as_fmpy(tmp_path):
    fmu = reference("Feedthrough")
    inputs = {"Float64_continuous_input": 2.5, "Float64_discrete_input": -1.5, "Int32_input": 7,
              "Boolean_input": 1, "Enumeration_input": 2}
    sets = [a for name, value in inputs.items() for a in ("--set", f"{name}={value}")]
    r, _ = simulate(fmu, tmp_path, "--interface", "model-exchange", "--output-interval", "0.01", *sets)
    f = fmpy_me(fmu, output_interval=0.01, start_values={k: bool(v) if k == "Boolean_input" else v for k, v in inputs.items()})
    assert len(f) == len(r["time"]) == 201
    for out, value in (("Float64_continuous_output", 2.5), ("Float64_discrete_output", -1.5), ("Int32_output", 7),
                       ("Boolean_output", 1), ("Enumeration_output", 2)):
        assert np.all(r[out] == value), out
        assert np.all(f[out].astype(float) == r[out]), out


def test_resource_reads_its_file_as_fmpy(tmp_path):
    fmu = reference("Resource")
    r, _ = simulate(fmu, tmp_path, "--interface", "model-exchange")
    f = fmpy_me(fmu)
    # resources/y.txt starts with 'a' (97).
    assert np.all(r["y"] == 97) and np.all(f["y"] == 97)


@pytest.mark.parametrize("model", MODELS)
def test_model_exchange_run_agrees_with_the_co_simulation_run(model, tmp_path):
    """Same method (DOPRI5), tolerances (rtol 1e-9, atol 1e-9) and grid: the runner's
    integrator on the FMU's derivatives against the FMU's own. Both do the same arithmetic
    (measured: every output equal to the bit, for every model without constraints); the
    linkages project their loop closure at every communication point under Co-Simulation but
    at step events (a drift beyond rtol) under Model Exchange, and near a limit position, where
    the rates grow like 1/cos, that difference is amplified (measured 1.9e-8 and 1.4e-8 of the
    outputs' peaks for the offset crank-slider and the double rocker when both stepped onto
    every communication point; since the adaptive methods step across them, 1.6e-7 for the
    double rocker's theta3_ddot in the row before its limit position, where it is 1,450 rad/s²
    and rising like 1/cos³): bound 1000 rtol, still far below what a wrong equation gives. The counters differ by design
    (n_steps counts completed integrator steps, n_rhs derivative evaluations, in each
    interface's sense)."""
    tolerance = ["--tolerance", "1e-9"]
    me, me_err = simulate(fmu_path(model), tmp_path, "--interface", "model-exchange", *tolerance, name="me")
    cs, cs_err = simulate(fmu_path(model), tmp_path, *tolerance, name="cs")
    assert list(me) == list(cs)
    assert len(me["time"]) == len(cs["time"])
    ended = "stopped before the stop time" in cs_err
    assert ("stopped before the stop time" in me_err) == ended
    # A run that ends at a located event (a limit position, a landing) has it as its last row,
    # where the two runs' event times differ by their error (measured 4e-11 s), which near a
    # limit position moves the rates by far more: the times are compared, the values before.
    if ended:
        assert abs(me["time"][-1] - cs["time"][-1]) < 1e-8
    rows = slice(0, len(cs["time"]) - 1) if ended else slice(None)
    for name in cs:
        if name in ("n_steps", "n_rhs"):
            continue
        scale = max(1.0, np.max(np.abs(cs[name][rows])))
        assert np.max(np.abs(me[name][rows] - cs[name][rows])) <= 1e-6 * scale, name


def test_step_events_project_the_linkages_drift(tmp_path):
    """Forward Euler drifts off the crank-slider's loop closure in each 10 ms output interval.
    The FMU's fmi2CompletedIntegratorStep, called by the runner at every point it reaches, asks
    for a step event when the gap exceeds rtol (1e-6) times the links' length (0.2 m), and its
    event update projects the states back (valuesOfContinuousStatesChanged), which the runner
    reads before it goes on. So no row's gap exceeds 2e-7 m, and most rows are projected to
    rounding (measured 1101 of 1201; Euler alone drifts by ~1e-5 m per interval). Under
    Co-Simulation the projection runs at every communication point: the runs differ by the gaps
    Model Exchange leaves below its threshold (measured 1.9e-7 m, 1.2e-6 rad, 3.0e-6 rad/s):
    bounds 1e-6 m and 1e-5 for the angles and rates."""
    me, _ = simulate(fmu_path("crank_slider"), tmp_path, "--interface", "model-exchange", "--solver", "euler", name="me")
    cs, _ = simulate(fmu_path("crank_slider"), tmp_path, "--set", "solver=0", name="cs")
    assert len(me["time"]) == len(cs["time"]) == 1201
    gap = me["loop_residual"]
    assert np.max(gap) <= 2e-7 * (1 + 1e-9)
    assert np.count_nonzero(gap < 1e-12) > 0.9 * len(gap)
    np.testing.assert_allclose(me["theta"], cs["theta"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(me["r1"], cs["r1"], rtol=0, atol=1e-6)
    for name in ("theta3", "r1_dot", "theta3_dot"):
        np.testing.assert_allclose(me[name], cs[name], rtol=0, atol=1e-5, err_msg=name)
