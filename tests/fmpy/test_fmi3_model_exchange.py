"""The runner integrating FMI 3.0 Model Exchange FMUs with the toolkit's own solvers
(`runner simulate --interface model-exchange`), against an independent importer: fmpy's FMI 3.0
Model Exchange runs of the Reference FMUs (../shared/reference-fmus/fmi3).

Two kinds of comparison, each chosen so that its tolerance is not a guess:
- forward Euler with the step equal to the output interval, in both (fmpy's Euler takes one
  step x + h f per output interval; the runner's `--solver euler --fixed-step h` on the same
  grid does the same arithmetic): every output at every point equal bit for bit;
- the adaptive integrators (the runner's DOPRI5 and fmpy's CVODE) at tight tolerances, where
  the difference is bounded by the two global errors, and closed forms where the model has one.
And the FMI 3.0 and FMI 2.0 Reference FMUs, built from the same model code, integrated by the
runner through either binding: the same calls in the same order, so the same bits."""

import csv
import os
import pathlib
import subprocess

import numpy as np
import pytest
from fmpy import simulate_fmu

from conftest import ROOT, TARGET

RUNNER = TARGET / "release" / "runner"
REFERENCE = pathlib.Path(os.environ.get("REFERENCE_FMUS", ROOT.parent / "shared" / "reference-fmus"))
ME = ["--interface", "model-exchange"]


def reference(name, version="fmi3"):
    path = REFERENCE / version / f"{name}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: the Reference FMUs are expected in ../shared/reference-fmus (or set REFERENCE_FMUS)")
    return path


def runner(*args):
    if not RUNNER.is_file():
        pytest.fail(f"{RUNNER} is missing: tests/run builds it with `cargo run --release -p runner -- build`")
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True, timeout=600)


def simulate(fmu, tmp_path, *args, name="run"):
    """`runner simulate` of `fmu` with `args`: the header, the rows as text, and stderr."""
    out = tmp_path / f"{name}.csv"
    p = runner("simulate", fmu, "--out", out, *args)
    assert p.returncode == 0, p.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:], p.stderr


def columns(header, rows):
    return {h: np.array([float(r[j]) for r in rows]) for j, h in enumerate(header)}


def fmpy_me(fmu, **kwargs):
    # record_events=False: rows on the output grid only, as the runner writes them; at a grid
    # point with an event both record the values after it.
    return simulate_fmu(str(fmu), fmi_type="ModelExchange", record_events=False, **kwargs)


def fmpy_column(result, name):
    """fmpy's values of the runner's column `name` (`y[2]`: element 2 of the array y)."""
    base, _, index = name.partition("[")
    values = result[base]
    if index:
        values = values[:, int(index.rstrip("]")) - 1]
    return values.astype(float)


@pytest.mark.parametrize("model, dt", [("Dahlquist", 0.1), ("VanDerPol", 0.01), ("StateSpace", 0.01)])
def test_forward_euler_equals_fmpys_bit_for_bit(tmp_path, model, dt):
    """One Euler step per output interval in both importers, from the same states through the
    same FMU: the same floating-point operations, so every value must be equal to the bit
    (StateSpace: arrays of states, inputs and outputs)."""
    fmu = reference(model)
    header, rows, _ = simulate(fmu, tmp_path, *ME, "--solver", "euler", "--fixed-step", dt, "--output-interval", dt)
    f = fmpy_me(fmu, solver="Euler", step_size=dt, output_interval=dt)
    ours = columns(header, rows)
    assert len(f) == len(rows)
    np.testing.assert_array_equal(ours["time"], f["time"])
    compared = 0
    for name in header[1:]:
        if name.partition("[")[0] in f.dtype.names:
            np.testing.assert_array_equal(ours[name], fmpy_column(f, name), err_msg=name)
            compared += 1
    assert compared >= 1


TIGHT = [*ME, "--tolerance", "1e-10", "--abs-tolerance", "1e-12"]


def test_bouncing_ball_bounces_at_the_closed_form_times_and_as_fmpy(tmp_path):
    """Free fall from 1 m with restitution 0.7 until the impact speed falls below 0.1 m/s:
    impacts at t1 = sqrt(2/g), then flights of 2 e^k v1 / g."""
    fmu = reference("BouncingBall")
    header, rows, _ = simulate(fmu, tmp_path, *TIGHT, "--output-interval", "0.01")
    r = columns(header, rows)
    g, e, v_min = 9.81, 0.7, 0.1
    t1 = np.sqrt(2 / g)
    impacts, speed = [t1], g * t1
    while e * speed >= v_min:
        speed *= e
        impacts.append(impacts[-1] + 2 * speed / g)
    # The runner's impacts: back along the parabola from the last falling sample (exact for
    # free fall).
    t, h, v = r["time"], r["h"], r["v"]
    found = [t[k] + (v[k] + np.sqrt(v[k] ** 2 + 2 * g * h[k])) / g for k in np.nonzero((v[:-1] < 0) & (v[1:] >= 0))[0]]
    assert len(found) == len(impacts)
    # Located to 1e-10 s at rtol 1e-10; the errors of ten bounces accumulate (FMI 2.0's run of
    # the same model: 1.5e-10 s): bound 1e-8 s.
    np.testing.assert_allclose(found, impacts, rtol=0, atol=1e-8)
    f = fmpy_me(fmu, relative_tolerance=1e-10, output_interval=0.01)
    assert len(f) == len(t)
    # Both runs err by ~1e-9 m; near an impact the two located times' difference (~1e-9 s)
    # times |v| <= 4.4 m/s adds to it: bound 1e-7.
    np.testing.assert_allclose(f["h"], h, rtol=0, atol=1e-7)
    np.testing.assert_allclose(f["v"], v, rtol=0, atol=1e-7)


def test_van_der_pol_matches_fmpy(tmp_path):
    fmu = reference("VanDerPol")
    header, rows, _ = simulate(fmu, tmp_path, *TIGHT)
    r = columns(header, rows)
    f = fmpy_me(fmu, relative_tolerance=1e-11, output_interval=0.01)
    np.testing.assert_allclose(f["time"], r["time"], rtol=0, atol=1e-12)
    # 20 s on the limit cycle (amplitude 2): both solvers' global errors stay below 1e-6 (the
    # FMI 2.0 run of the same model: 3e-8).
    for name in ("x0", "x1"):
        np.testing.assert_allclose(r[name], f[name], rtol=0, atol=1e-6)


def test_dahlquist_decays_as_exp(tmp_path):
    """x' = -k x from 1 with k = 1: DOPRI5 at rtol 1e-10 within 1e-10 of exp(-t), and fmpy's
    CVODE at rtol 1e-10 within 1e-9 of the runner (both errors well below)."""
    fmu = reference("Dahlquist")
    header, rows, _ = simulate(fmu, tmp_path, *TIGHT)
    r = columns(header, rows)
    assert np.max(np.abs(r["x"] - np.exp(-r["time"]))) < 1e-10
    f = fmpy_me(fmu, relative_tolerance=1e-10, output_interval=0.1)
    np.testing.assert_allclose(r["x"], f["x"], rtol=0, atol=1e-9)


def test_stair_counts_its_time_events_as_fmpy(tmp_path):
    """A time event every second raises the counter; at 10 the model ends the run
    (terminateSimulation) at t = 9: the runner keeps that last state as a row, fmpy stops
    before recording it. Integers: exact."""
    fmu = reference("Stair")
    header, rows, err = simulate(fmu, tmp_path, *ME, "--output-interval", "0.01")
    r = columns(header, rows)
    f = fmpy_me(fmu, output_interval=0.01)
    assert r["time"][-1] == pytest.approx(9.0) and "stopped before the stop time" in err
    np.testing.assert_array_equal(r["counter"], np.floor(r["time"] + 1e-9) + 1)
    assert len(f) == len(r["time"]) - 1 == 900
    np.testing.assert_array_equal(f["counter"], r["counter"][:-1])


def test_every_type_passes_through_model_exchange(tmp_path):
    """Feedthrough copies each input to its output, under Model Exchange as under
    Co-Simulation: every scalar type, in full (64-bit integers beyond an f64's 53 bits, Float32
    in its own shortest form, String as text, Binary as hexadecimal); fmpy reads the same."""
    fmu = reference("Feedthrough")
    sets = {"Float32_continuous_input": "0.1", "Float64_continuous_input": "2.5", "Int8_input": "-128",
            "UInt16_input": "65535", "Int64_input": "-9223372036854775807", "UInt64_input": "18446744073709551615",
            "Boolean_input": "true", "String_input": "héllo", "Binary_input": "00ff10", "Enumeration_input": "2"}
    args = [a for name, value in sets.items() for a in ("--set", f"{name}={value}")]
    header, rows, _ = simulate(fmu, tmp_path, *ME, "--stop-time", 0.2, "--output-interval", 0.1, *args)
    last = dict(zip(header, rows[-1]))
    assert last["Float32_continuous_output"] == "0.1" and last["Float64_continuous_output"] == "2.5"
    assert last["Int8_output"] == "-128" and last["UInt16_output"] == "65535"
    assert last["Int64_output"] == "-9223372036854775807" and last["UInt64_output"] == "18446744073709551615"
    assert last["Boolean_output"] == "1" and last["Enumeration_output"] == "2"
    assert last["String_output"] == "héllo" and last["Binary_output"] == "00ff10"
    f = fmpy_me(fmu, stop_time=0.2, output_interval=0.1,
                start_values={"Int64_input": -9223372036854775807, "UInt16_input": 65535, "Float64_continuous_input": 2.5})
    assert int(f["Int64_output"][-1]) == -9223372036854775807 and int(f["UInt16_output"][-1]) == 65535
    assert f["Float64_continuous_output"][-1] == 2.5


def test_resource_reads_its_file_as_fmpy(tmp_path):
    fmu = reference("Resource")
    header, rows, _ = simulate(fmu, tmp_path, *ME)
    r = columns(header, rows)
    # resources/y.txt starts with 'a' (97).
    assert np.all(r["y"] == 97) and np.all(fmpy_me(fmu)["y"] == 97)


@pytest.mark.parametrize("model", ["BouncingBall", "Dahlquist", "VanDerPol", "Stair"])
def test_fmi3_and_fmi2_runs_of_the_same_model_are_identical(tmp_path, model):
    """The Reference FMUs of both versions compile the same model.c: integrated by the same
    solver through the two bindings (the same calls, in the same order), every value must be
    equal to the bit. A difference would be a binding's bug. (Stair's counter is an Int32 in
    FMI 3.0 and a Real in FMI 2.0, written "1" and "1.0": the values are compared, not the text.)"""
    three = simulate(reference(model), tmp_path, *ME, name="three")
    two = simulate(reference(model, "fmi2"), tmp_path, *ME, name="two")
    assert three[0] == two[0] and len(three[1]) == len(two[1])
    for name, values in columns(*three[:2]).items():
        np.testing.assert_array_equal(values, columns(*two[:2])[name], err_msg=name)


def test_sweep_compare_and_info_take_fmi3_model_exchange(tmp_path):
    """Dahlquist x' = -k x from 1: final(x) at t = 10 is exp(-10 k) (DOPRI5 at rtol 1e-10:
    within 1e-12 absolute); compare reaches its target with the runner's solvers; info names
    the interface."""
    fmu = reference("Dahlquist")
    done = runner("sweep", fmu, *ME, "--tolerance", "1e-10", "--abs-tolerance", "1e-14", "--param", "k=0.5,1",
                  "--metric", "xf=final(x)")
    assert done.returncode == 0, done.stderr
    for row in csv.DictReader(done.stdout.splitlines()):
        assert abs(float(row["xf"]) - np.exp(-10 * float(row["k"]))) < 1e-12, row
    done = runner("compare", fmu, *ME, "--solvers", "euler,rk4,dopri5", "--target-error", "1e-4", "--out", tmp_path / "c.csv")
    assert done.returncode == 0, done.stderr
    assert "not reached" not in done.stdout, done.stdout
    done = runner("info", fmu)
    assert done.returncode == 0 and "Model Exchange: modelIdentifier Dahlquist (1 continuous states, 0 event indicators" in done.stdout, done.stdout
