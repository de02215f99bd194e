"""The runner on the FMI 3.0 Reference FMUs (third-party FMUs), against fmpy's run of the same
FMU: every shared output at every communication point.

Both drive the same binary through the same call sequence (the same communication points,
Event Mode and early return where the FMU declares them, the same event iteration), so the
values must be equal bit for bit: any difference is an importer bug, not rounding."""

import csv
import pathlib
import subprocess

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from conftest import ROOT, TARGET

REFERENCE = ROOT.parent / "shared" / "reference-fmus" / "fmi3"
RUNNER = TARGET / "release" / "runner"


def runner(*args):
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True)


def runner_csv(tmp_path, fmu, *args):
    out = tmp_path / "out.csv"
    done = runner("simulate", fmu, "--out", out, *args)
    assert done.returncode == 0, done.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    return rows[0], rows[1:]


def fmpy_run(fmu, dt, start_values=None):
    """fmpy with Event Mode and early return exactly when the FMU offers them, as the runner."""
    cs = read_model_description(str(fmu)).coSimulation
    return simulate_fmu(str(fmu), fmi_type="CoSimulation", output_interval=dt, start_values=start_values or {},
                        use_event_mode=cs.hasEventMode, early_return_allowed=cs.mightReturnEarlyFromDoStep)


def compare(header, rows, result):
    """Every runner column against fmpy's value at the same time (fmpy also keeps rows at
    events; the last row at a time is the one after the event, as the runner's)."""
    times = np.array([float(r[0]) for r in rows])
    picked = []
    for t in times:
        at = np.nonzero(result["time"] == t)[0]
        assert len(at), f"fmpy has no row at t = {t}"
        picked.append(at[-1])
    compared = 0
    for j, name in enumerate(header[1:], 1):
        base, _, index = name.partition("[")
        if base not in result.dtype.names:
            continue
        values = result[base][picked]
        if index:
            values = values[:, int(index.rstrip("]")) - 1]
        ours = np.array([float(r[j]) for r in rows])
        np.testing.assert_array_equal(ours, values.astype(float), err_msg=name)
        compared += 1
    return compared


@pytest.mark.parametrize("model, dt", [("BouncingBall", 0.01), ("Dahlquist", 0.1), ("VanDerPol", 0.01), ("Stair", 0.2),
                                       ("Resource", 0.002), ("StateSpace", 0.02), ("Feedthrough", 0.1)])
def test_runner_equals_fmpy_on_the_reference_fmus(tmp_path, model, dt):
    fmu = REFERENCE / f"{model}.fmu"
    header, rows = runner_csv(tmp_path, fmu, "--output-interval", dt)
    assert compare(header, rows, fmpy_run(fmu, dt)) >= 1


def test_every_type_is_written_and_read_back(tmp_path):
    """Feedthrough copies each input to its output: the set values come back, in full for the
    64-bit integers (beyond an f64's 53 bits), as text for String, as hexadecimal for Binary."""
    fmu = REFERENCE / "Feedthrough.fmu"
    sets = {"Float32_continuous_input": "0.1", "Int8_input": "-128", "UInt16_input": "65535",
            "Int64_input": "-9223372036854775807", "UInt64_input": "18446744073709551615",
            "Boolean_input": "true", "String_input": "héllo, world", "Binary_input": "00ff10", "Enumeration_input": "2"}
    args = [a for name, value in sets.items() for a in ("--set", f"{name}={value}")]
    header, rows = runner_csv(tmp_path, fmu, "--stop-time", 0.2, "--output-interval", 0.1, *args)
    last = dict(zip(header, rows[-1]))
    assert last["Float32_continuous_output"] == "0.1", "Float32 in its own shortest form"
    assert last["Int8_output"] == "-128" and last["UInt16_output"] == "65535"
    assert last["Int64_output"] == "-9223372036854775807" and last["UInt64_output"] == "18446744073709551615"
    assert last["Boolean_output"] == "1" and last["Enumeration_output"] == "2"
    assert last["String_output"] == "héllo, world" and last["Binary_output"] == "00ff10"
    # And fmpy reads the same numbers from the same FMU with the same inputs.
    result = fmpy_run(fmu, 0.1, {"Int64_input": -9223372036854775807, "UInt16_input": 65535, "Int8_input": -128})
    assert int(result["Int64_output"][-1]) == -9223372036854775807 and int(result["UInt16_output"][-1]) == 65535


def test_arrays_are_columns_and_are_set_whole(tmp_path):
    """StateSpace's input u (3 elements) set whole; the output y, one column per element, is
    compared with fmpy given the same u."""
    fmu = REFERENCE / "StateSpace.fmu"
    header, rows = runner_csv(tmp_path, fmu, "--set", "u=2 4 6", "--output-interval", 0.5)
    assert header == ["time", "y[1]", "y[2]", "y[3]"]
    assert compare(header, rows, fmpy_run(fmu, 0.5, {"u": [2, 4, 6]})) == 3


def test_structural_parameter_refusal_is_reported_with_the_fmus_reason(tmp_path):
    """StateSpace v0.0.41 refuses setting its structural parameters (fmi3SetUInt64 checks
    nValues after consuming the value: a bug of the Reference FMU, fmpy fails alike); the
    runner sets them in Configuration Mode as the standard asks and reports the FMU's reason."""
    done = runner("simulate", REFERENCE / "StateSpace.fmu", "--set", "n=2", "--out", tmp_path / "x.csv")
    assert done.returncode == 1
    assert "fmi3SetUInt64 of n returned fmi3Error: Expected nValues" in done.stderr, done.stderr


def test_events_are_recorded_with_the_flag(tmp_path):
    """BouncingBall returns early at each bounce: with --record-events the runner adds a row at
    each event (before it is handled); those times are the ones fmpy's early-return run stops at."""
    fmu = REFERENCE / "BouncingBall.fmu"
    header, plain = runner_csv(tmp_path, fmu, "--output-interval", 0.01)
    _, with_events = runner_csv(tmp_path, fmu, "--output-interval", 0.01, "--record-events")
    grid = {r[0] for r in plain}
    extra = sorted(float(r[0]) for r in with_events if r[0] not in grid)
    assert len(extra) >= 3, "at least three bounces in 3 s"
    result = fmpy_run(fmu, 0.01)
    fmpy_times = set(result["time"].tolist())
    assert all(t in fmpy_times for t in extra), f"event times {extra} not among fmpy's rows"
    # Velocity just before the first bounce is downward, and after it upward.
    first = next(r for r in with_events if float(r[0]) == extra[0])
    assert float(first[header.index("v")]) < 0


def test_clocks_and_scheduled_execution_are_refused_by_name(tmp_path):
    done = runner("simulate", REFERENCE / "Clocks.fmu", "--out", tmp_path / "x.csv")
    assert done.returncode == 1 and "Scheduled Execution" in done.stderr, done.stderr


def test_a_sweep_runs_an_fmi3_fmu():
    """Dahlquist x' = -k x from x(0) = 1: final(x) at t = 10 falls with k; against fmpy's."""
    done = runner("sweep", REFERENCE / "Dahlquist.fmu", "--param", "k=1,2", "--metric", "xf=final(x)")
    assert done.returncode == 0, done.stderr
    rows = list(csv.DictReader(done.stdout.splitlines()))
    for row in rows:
        expected = simulate_fmu(str(REFERENCE / "Dahlquist.fmu"), output_interval=0.1, start_values={"k": float(row["k"])})["x"][-1]
        assert float(row["xf"]) == expected
