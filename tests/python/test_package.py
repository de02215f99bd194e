"""fmurunner on this machine: info, simulate (against fmpy on the same FMU, with and without
inputs), sweep (against the CLI's CSV, bit for bit), and errors with the runner's messages."""

import json
import math

import numpy as np
import pandas as pd
import pytest
from fmpy import simulate_fmu

import fmurunner
from fmurunner_helpers import (EX4_METRICS, EX4_SPEEDS, REFERENCE, STIFF_FMU, STIFF_SWEEP, STIFF_SWEEP_CLI, assert_same_as_cli,
                               fmu_path, runner_sweep_csv)


def test_info_lists_the_variables_and_capabilities():
    d = fmurunner.info("quarter_car")
    assert d["model_name"] == "quarter_car"
    assert d["co_simulation"]["model_identifier"] == "quarter_car"
    assert d["model_exchange"] is not None
    speed = next(v for v in d["variables"] if v["name"] == "speed")
    assert (speed["causality"], speed["type"], speed["unit"], speed["start"]) == ("parameter", "Real", "m/s", "30")
    assert d["default_experiment"]["stop_time"] == 10.0
    ball = fmurunner.info(REFERENCE / "fmi3" / "BouncingBall.fmu")
    assert ball["fmi_version"] == "3.0" and ball["model_name"] == "BouncingBall"


def test_the_ex4_sweep_is_the_clis_bit_for_bit(tmp_path):
    """The model name picks up the experiment's [sweep] grid (1 ms, rtol 1e-9) as the CLI does;
    the CLI runs its points in worker processes, the package on threads: same engine, same bits."""
    frame = fmurunner.sweep("quarter_car", {"speed": EX4_SPEEDS}, EX4_METRICS, threads=2)
    assert_same_as_cli(frame, runner_sweep_csv(tmp_path, "quarter_car"))
    assert (frame["status"] == "ok").all()
    peak = frame.loc[frame["transmissibility"].idxmax()]
    assert peak["speed"] == 4.0 and abs(peak["transmissibility"] - 2.1758) < 1e-4


def test_points_are_the_cartesian_product_in_the_clis_order(tmp_path):
    params = {"speed": [2.0, 4.0, 8.0], "k_s": [15000.0, 18000.0]}
    metrics = ["peak=max(z_s)"]
    frame = fmurunner.sweep(fmu_path("quarter_car"), params, metrics, stop_time=2.0, output_interval=0.01, threads=2,
                            start_values={"b_s": 1100.0})
    assert frame[["speed", "k_s"]].values.tolist() == [[2, 15000], [2, 18000], [4, 15000], [4, 18000], [8, 15000], [8, 18000]]
    rows = runner_sweep_csv(tmp_path, str(fmu_path("quarter_car")), "--param", "speed=2,4,8", "--param", "k_s=15000,18000",
                            "--metric", "peak=max(z_s)", "--stop-time", "2", "--output-interval", "0.01", "--set", "b_s=1100")
    assert_same_as_cli(frame, rows)


def test_a_failed_point_is_a_row_with_its_error():
    frame = fmurunner.sweep("quarter_car", {"m_s": [200.0, -1.0, 250.0]}, {"peak": "max(z_s)"}, stop_time=1.0, threads=2)
    assert list(frame["status"][[0, 2]]) == ["ok", "ok"]
    assert "m_s" in frame["status"][1] and frame["status"][1] != "ok", frame["status"][1]
    assert math.isnan(frame["peak"][1]) and frame["peak"][0] > 0


def test_errors_raise_the_runners_messages():
    with pytest.raises(fmurunner.RunnerError, match="did you mean 'speed'"):
        fmurunner.sweep("quarter_car", {"sped": [1.0]}, {"p": "max(z_s)"})
    with pytest.raises(fmurunner.RunnerError, match="z_q"):
        fmurunner.sweep("quarter_car", {"speed": [1.0]}, {"p": "max(z_q)"})
    with pytest.raises(fmurunner.RunnerError, match="metric"):
        fmurunner.sweep("quarter_car", {"speed": [1.0]}, ["p=maxx(z_s"])
    with pytest.raises(fmurunner.RunnerError, match="neither an existing .fmu file nor a model"):
        fmurunner.simulate("quater_car")
    with pytest.raises(fmurunner.RunnerError, match="does not exist"):
        fmurunner.info("missing/thing.fmu")
    with pytest.raises(fmurunner.RunnerError, match="only parameters and inputs can be set"):
        fmurunner.simulate("quarter_car", start_values={"z_s": 1.0})


def test_an_unreadable_fmu_is_an_error(tmp_path):
    bad = tmp_path / "bad.fmu"
    bad.write_bytes(b"not a zip archive")
    with pytest.raises(fmurunner.RunnerError, match="bad.fmu"):
        fmurunner.simulate(bad)
    with pytest.raises(fmurunner.RunnerError, match="bad.fmu"):
        fmurunner.sweep(bad, {"k": [1.0]}, {"p": "max(x)"})


def _fmpy_frame(result) -> pd.DataFrame:
    return pd.DataFrame({name: result[name] for name in result.dtype.names})


@pytest.mark.parametrize("fmu, outputs", [(REFERENCE / "fmi2" / "BouncingBall.fmu", ["h", "v"]),
                                          (REFERENCE / "fmi2" / "VanDerPol.fmu", ["x0", "x1"])])
def test_simulate_equals_fmpy_on_the_same_fmu(fmu, outputs):
    """The same Co-Simulation FMU stepped on the same grid by both importers: the FMU does all
    the arithmetic, so the values agree to rounding of the communication times (1e-12)."""
    ours = fmurunner.simulate(fmu, stop_time=3.0, output_interval=0.01)
    theirs = _fmpy_frame(simulate_fmu(str(fmu), stop_time=3.0, output_interval=0.01, fmi_type="CoSimulation"))
    assert list(ours.columns[:1]) == ["time"] and set(outputs) <= set(ours.columns)
    assert len(ours) == len(theirs)
    np.testing.assert_allclose(ours["time"], theirs["time"], rtol=0, atol=1e-12)
    for name in outputs:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=1e-12, atol=1e-12)


def test_simulate_of_a_model_name_uses_its_experiment():
    frame = fmurunner.simulate("quarter_car", stop_time=0.5, start_values={"speed": 4.0})
    assert frame.columns[0] == "time" and "z_s" in frame.columns
    assert frame["time"].iloc[1] == 1e-3 and frame["time"].iloc[-1] == 0.5
    assert frame["n_steps"].dtype == np.int64


def _feedthrough_input():
    """fmpy's convention: a structured array, time first; 0.5 repeated is a step."""
    return np.array([(0.0, 0.0, 0), (0.5, 1.0, 0), (0.5, 2.0, 3), (1.0, 3.0, 3)],
                    dtype=[("time", np.float64), ("Float64_continuous_input", np.float64), ("Int32_input", np.int32)])


def test_simulate_with_inputs_equals_fmpy():
    """Feedthrough passes its inputs to its outputs: the interpolated Real and the held Integer
    must match fmpy's at every point, both given the same structured array."""
    fmu = REFERENCE / "fmi2" / "Feedthrough.fmu"
    signals = _feedthrough_input()
    theirs = _fmpy_frame(simulate_fmu(str(fmu), stop_time=1.0, output_interval=0.1, input=signals, fmi_type="CoSimulation"))
    ours = fmurunner.simulate(fmu, stop_time=1.0, output_interval=0.1, input=signals)
    as_frame = fmurunner.simulate(fmu, stop_time=1.0, output_interval=0.1, input=pd.DataFrame(signals))
    pd.testing.assert_frame_equal(ours, as_frame)
    assert len(ours) == len(theirs)
    for name in ["Float64_continuous_output", "Int32_output"]:
        np.testing.assert_allclose(ours[name], theirs[name], rtol=0, atol=1e-12, err_msg=name)
    # And not merely the same as fmpy: an FMI 2.0 Feedthrough's output at t = 0.3 is the input
    # set for the step into it, u(0.2) = 0.4 (linear from 0 at 0 to 1 at 0.5), and the Integer
    # steps to 3 at the repeated time 0.5.
    assert ours["Float64_continuous_output"].iloc[3] == pytest.approx(0.4, abs=1e-12)
    assert list(ours["Int32_output"]) == [0] * 6 + [3] * 5


def test_bad_inputs_are_refused_with_the_runners_message():
    fmu = REFERENCE / "fmi2" / "Feedthrough.fmu"
    with pytest.raises(fmurunner.RunnerError, match="first field must be 'time'"):
        fmurunner.simulate(fmu, input=np.array([(1.0, 0.0)], dtype=[("x", float), ("time", float)]))
    with pytest.raises(fmurunner.RunnerError, match="not an input"):
        fmurunner.simulate(fmu, input=pd.DataFrame({"time": [0.0], "Float64_continuous_output": [1.0]}))
    with pytest.raises(fmurunner.RunnerError, match="time must not decrease"):
        fmurunner.simulate(fmu, input=pd.DataFrame({"time": [1.0, 0.0], "Float64_continuous_input": [1.0, 2.0]}))


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_simulate_records_the_outputs_runner_simulate_writes_strings_included(tmp_path, version):
    """Feedthrough (FMI 2.0 and 3.0) copies its inputs, set as start values, to its outputs: the
    DataFrame has the columns of `runner simulate`'s CSV, in its order, String outputs included
    (the CLI's convention for both versions), and the same values: Strings as the same text,
    Booleans as 1/0, integers as the same integers, numbers as the same doubles (copied values,
    so compared exactly)."""
    import csv
    import subprocess

    from fmurunner_helpers import RUNNER

    fmu = REFERENCE / version / "Feedthrough.fmu"
    inputs = {"Int32_input": -7, "Boolean_input": True, "String_input": "hello, world", "Enumeration_input": 2,
              "Float64_continuous_input": 1.5}
    out = tmp_path / "cli.csv"
    sets = [a for name, value in inputs.items() for a in ("--set", f"{name}={str(value).lower() if value is True else value}")]
    subprocess.run([str(RUNNER), "simulate", str(fmu), "--stop-time", "0.02", "--output-interval", "0.01", "--out", str(out),
                    *sets], check=True, capture_output=True)
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    cli = {name: [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}
    ours = fmurunner.simulate(fmu, stop_time=0.02, output_interval=0.01, start_values=inputs)
    assert list(ours.columns) == rows[0]
    assert list(ours["String_output"]) == cli["String_output"] == ["hello, world"] * 3
    for name in ours.columns:
        column = ours[name]
        if column.dtype == bool:
            assert ["1" if b else "0" for b in column] == cli[name], name
        elif column.dtype == object:
            assert [str(v) for v in column] == cli[name], name
        elif np.issubdtype(column.dtype, np.integer):
            assert [int(v) for v in column] == [int(t) for t in cli[name]], name
        else:
            assert column.tolist() == [float(t) for t in cli[name]], name
    assert list(ours["Int32_output"]) == [-7] * 3 and list(ours["Boolean_output"]) == [True] * 3


def test_a_stiff_model_exchange_fmu_runs_with_an_implicit_solver_as_the_cli_and_cvode_run_it(tmp_path):
    """Reference VanDerPol (FMI 3.0) with mu = 1000 through Model Exchange and the runner's BDF:
    the same engine as `runner simulate --interface model-exchange --solver bdf`, so the same
    bits; and against fmpy's CVODE, an independent integrator, at rtol 1e-7 (the tightest at
    which it gets through the jump near t = 807 s within its 500 steps per sample). x0 is
    compared where the solution is slow (|x1| < 0.01): in a jump a shift in time of the order of
    the tolerance is an O(1) difference. CVODE's own error there (its atol 1e-7) sets the bound,
    5e-4 of x0's amplitude, as in tests/fmpy's comparison of the command line."""
    import csv
    import subprocess

    from fmurunner_helpers import RUNNER

    fmu = REFERENCE / "fmi3" / "VanDerPol.fmu"
    ours = fmurunner.simulate(fmu, interface="model-exchange", solver="bdf", abs_tolerance=1e-10, stop_time=1000.0, output_interval=1.0,
                              tolerance=1e-8, start_values={"mu": 1000.0})
    out = tmp_path / "cli.csv"
    subprocess.run([str(RUNNER), "simulate", str(fmu), "--interface", "model-exchange", "--solver", "bdf", "--abs-tolerance", "1e-10",
                    "--stop-time", "1000", "--output-interval", "1", "--tolerance", "1e-8", "--set", "mu=1000", "--out", str(out)],
                   check=True, capture_output=True)
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    assert list(ours.columns) == rows[0]
    for i, name in enumerate(rows[0]):
        assert ours[name].tolist() == [float(r[i]) for r in rows[1:]], name
    theirs = _fmpy_frame(simulate_fmu(str(fmu), fmi_type="ModelExchange", solver="CVode", relative_tolerance=1e-7, stop_time=1000.0,
                                      output_interval=1.0, start_values={"mu": 1000.0}, record_events=False))
    assert len(ours) == len(theirs)
    slow = np.abs(theirs["x1"].to_numpy()) < 0.01
    assert slow.sum() > 900
    assert np.max(np.abs(ours["x0"].to_numpy()[slow] - theirs["x0"].to_numpy()[slow])) < 5e-4


def test_solver_options_are_checked():
    fmu = REFERENCE / "fmi2" / "VanDerPol.fmu"
    with pytest.raises(fmurunner.RunnerError, match="only Model Exchange uses.*interface='model-exchange'"):
        fmurunner.simulate(fmu, solver="bdf")
    # Any of the options, not only solver=, is refused under Co-Simulation, by the names
    # Python spells them (the stepped Simulation's refusal is the same engine check).
    with pytest.raises(fmurunner.RunnerError, match=r"\(solver=, fixed_step=, abs_tolerance=\) set the .* only Model Exchange uses"):
        fmurunner.simulate(fmu, fixed_step=1e-3)
    with pytest.raises(fmurunner.RunnerError, match="only Model Exchange uses.*interface='model-exchange'"):
        fmurunner.Simulation(fmu, solver="bdf")
    with pytest.raises(fmurunner.RunnerError, match="unknown solver 'cvode'"):
        fmurunner.simulate(fmu, interface="model-exchange", solver="cvode")
    with pytest.raises(fmurunner.RunnerError, match="fixed_step=-1 must be a positive number"):
        fmurunner.simulate(fmu, interface="model-exchange", solver="rk4", fixed_step=-1.0)
    with pytest.raises(fmurunner.RunnerError, match="'me' is not an interface"):
        fmurunner.simulate(fmu, interface="me")


def test_a_stiff_sweep_with_bdf_is_the_clis_bit_for_bit_in_workers_and_in_process(tmp_path):
    """`sweep(interface="model-exchange", solver="bdf", ...)` is `runner sweep --interface
    model-exchange --solver bdf ...`: the same engine, so the same bits, whether the points run
    in worker processes or on threads of this process. Were the solver or the interface lost on
    the way to the points, the FMU would be integrated by DOPRI5 or by itself, whose numbers
    differ from BDF's in their last digits at least (checked below, so the comparison can fail)."""
    cli = runner_sweep_csv(tmp_path, str(STIFF_FMU), *STIFF_SWEEP_CLI)
    workers = fmurunner.sweep(STIFF_FMU, threads=2, **STIFF_SWEEP)
    assert_same_as_cli(workers, cli)
    threads = fmurunner.sweep(STIFF_FMU, threads=2, in_process=True, **STIFF_SWEEP)
    assert_same_as_cli(threads, cli)
    assert (workers["status"] == "ok").all()
    others = {**STIFF_SWEEP, "params": {"mu": [1.0, 10.0]}, "solver": None, "abs_tolerance": None}
    dopri5 = fmurunner.sweep(STIFF_FMU, threads=2, **others)
    cosimulation = fmurunner.sweep(STIFF_FMU, threads=2, **{**others, "interface": None})
    for other in (dopri5, cosimulation):
        assert other["x0_end"].tolist() != workers["x0_end"][:2].tolist()


def test_sweep_solver_options_are_checked():
    fmu = REFERENCE / "fmi2" / "VanDerPol.fmu"
    params, metrics = {"mu": [1.0, 2.0]}, {"x0_end": "final(x0)"}
    with pytest.raises(fmurunner.RunnerError, match="only Model Exchange uses.*interface='model-exchange'"):
        fmurunner.sweep(fmu, params, metrics, solver="bdf")
    with pytest.raises(fmurunner.RunnerError, match="only Model Exchange uses"):
        fmurunner.sweep(fmu, params, metrics, interface="co-simulation", abs_tolerance=1e-9, in_process=True)
    with pytest.raises(fmurunner.RunnerError, match="unknown solver 'cvode'"):
        fmurunner.sweep(fmu, params, metrics, interface="model-exchange", solver="cvode")
    with pytest.raises(fmurunner.RunnerError, match="fixed_step=0 must be a positive number"):
        fmurunner.sweep(fmu, params, metrics, interface="model-exchange", solver="rk4", fixed_step=0.0)
    with pytest.raises(fmurunner.RunnerError, match="abs_tolerance=-1 must be a number, zero or greater"):
        fmurunner.sweep(fmu, params, metrics, interface="model-exchange", abs_tolerance=-1.0)
    with pytest.raises(fmurunner.RunnerError, match="fixed_step 'small' is not a number"):
        fmurunner.sweep(fmu, params, metrics, interface="model-exchange", fixed_step="small")
    with pytest.raises(fmurunner.RunnerError, match="'me' is not an interface"):
        fmurunner.sweep(fmu, params, metrics, interface="me")


def test_a_sweep_to_a_file_is_not_resumed_with_other_solver_settings_or_interface(tmp_path):
    """The record beside the CSV holds the interface and the integrator's settings (in the
    sweep), so a resume that changes either is another sweep and is refused, while the same
    settings resume (here: find the file complete and return its rows), also with a metric
    typed another way."""
    out = tmp_path / "stiff.csv"
    fmu, params, metrics = REFERENCE / "fmi2" / "VanDerPol.fmu", {"mu": [1.0, 2.0]}, {"x0_end": "final(x0)"}
    bdf = dict(interface="model-exchange", solver="bdf", stop_time=5.0)
    first = fmurunner.sweep(fmu, params, metrics, out=out, threads=1, **bdf)
    with pytest.raises(fmurunner.RunnerError, match="is not from this sweep(.|\n)*'method': 'Esdirk'"):
        fmurunner.sweep(fmu, params, metrics, out=out, resume=True, **{**bdf, "solver": "esdirk"})
    with pytest.raises(fmurunner.RunnerError, match="is not from this sweep(.|\n)*1e-12"):
        fmurunner.sweep(fmu, params, metrics, out=out, resume=True, **{**bdf, "abs_tolerance": 1e-12})
    again = fmurunner.sweep(fmu, params, metrics, out=out, resume=True, **bdf)
    pd.testing.assert_frame_equal(again, first, check_exact=True)
    # The metric is recorded by what it computes: typed another way, it is the same sweep;
    # another metric is not.
    retyped = fmurunner.sweep(fmu, params, {"x0_end": " final( x0 ) "}, out=out, resume=True, **bdf)
    pd.testing.assert_frame_equal(retyped, first, check_exact=True)
    with pytest.raises(fmurunner.RunnerError, match="is not from this sweep(.|\n)*x0_end=final\\(x1\\)"):
        fmurunner.sweep(fmu, params, {"x0_end": "final(x1)"}, out=out, resume=True, **bdf)
    # Without solver options the spec is the same through either interface: the record's
    # interface tells the sweeps apart.
    other = tmp_path / "interface.csv"
    fmurunner.sweep(fmu, params, metrics, out=other, threads=1, interface="model-exchange", stop_time=5.0)
    with pytest.raises(fmurunner.RunnerError, match="is not from this sweep(.|\n)*interface: 'model-exchange' then, 'co-simulation' now"):
        fmurunner.sweep(fmu, params, metrics, out=other, resume=True, stop_time=5.0)


def test_a_sweep_recorded_before_interfaces_were_recorded_resumes_through_the_default(tmp_path):
    """A `.sweep` record written by an fmurunner that did not record the interface ran through
    the default one: a resume that takes the default too is the same sweep (its rows are kept),
    one that names an interface is refused, as the record cannot tell."""
    out = tmp_path / "old.csv"
    fmu, params, metrics = REFERENCE / "fmi2" / "VanDerPol.fmu", {"mu": [1.0, 2.0]}, {"x0_end": "final(x0)"}
    first = fmurunner.sweep(fmu, params, metrics, out=out, threads=1, stop_time=5.0)
    record_path = tmp_path / "old.csv.sweep"
    record = json.loads("".join(line for line in record_path.read_text().splitlines(True) if not line.startswith("#")))
    del record["interface"]
    record_path.write_text(json.dumps(record))
    again = fmurunner.sweep(fmu, params, metrics, out=out, resume=True, stop_time=5.0)
    pd.testing.assert_frame_equal(again, first, check_exact=True)
    with pytest.raises(fmurunner.RunnerError, match="is not from this sweep(.|\n)*interface: None then, 'co-simulation' now"):
        fmurunner.sweep(fmu, params, metrics, out=out, resume=True, stop_time=5.0, interface="co-simulation")


def test_every_public_name_has_a_docstring():
    """The issue asks for docstrings on every public function and class: fmurunner's names, and
    every public method, property and attribute of Simulation (its stepping calls are the Rust
    engine's, documented there) and StepResult."""
    missing = [name for name in fmurunner.__all__ if not (getattr(fmurunner, name).__doc__ or "").strip()]
    for cls in (fmurunner.Simulation, fmurunner.StepResult):
        missing += [f"{cls.__name__}.{name}" for name in dir(cls)
                    if not name.startswith("_") and not (getattr(cls, name).__doc__ or "").strip()]
    assert not missing, missing
