"""The runner's CSV convention against fmpy's CSV of the same Reference FMU: Feedthrough, FMI
2.0 and 3.0, its outputs copied from inputs set to values of every kind. fmpy's `write_csv`
writes integers and enumerations as integers and Booleans as True/False; the runner writes the
integers as the same text and Booleans as 1/0 (as its FMI 3.0 CSVs always did), in both
versions. fmpy (0.3.32) records no Strings (its Recorder reads Reals, Integers and Booleans
only), so the runner's String column, written in both versions, is checked against the input it
copies. Values are copied, not computed, so every comparison is exact."""

import csv
import subprocess

import pytest
from fmpy import simulate_fmu
from fmpy.util import write_csv

from conftest import ROOT, TARGET

REFERENCE = ROOT.parent / "shared" / "reference-fmus"
RUNNER = TARGET / "release" / "runner"

INPUTS = {"Int32_input": -7, "Boolean_input": True, "String_input": "hello, world", "Enumeration_input": 2,
          "Float64_continuous_input": 1.5}
OUTPUTS = ["Float64_continuous_output", "Int32_output", "Enumeration_output", "Boolean_output"]


def read(path):
    with open(path) as f:
        rows = list(csv.reader(f))
    return {name: [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_integers_strings_and_booleans_as_fmpy_writes_them(tmp_path, version):
    fmu = REFERENCE / version / "Feedthrough.fmu"
    sets = [a for name, value in INPUTS.items() for a in ("--set", f"{name}={str(value).lower() if value is True else value}")]
    out = tmp_path / "runner.csv"
    done = subprocess.run([str(RUNNER), "simulate", str(fmu), "--stop-time", "0.02", "--output-interval", "0.01",
                           "--out", str(out), *sets], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    ours = read(out)
    result = simulate_fmu(str(fmu), stop_time=0.02, output_interval=0.01, start_values=INPUTS, output=OUTPUTS)
    write_csv(str(tmp_path / "fmpy.csv"), result)
    theirs = read(tmp_path / "fmpy.csv")
    assert ours["time"] == theirs["time"]
    for name in ["Float64_continuous_output", "Int32_output", "Enumeration_output"]:
        assert ours[name] == theirs[name], f"{version} {name}: runner {ours[name]}, fmpy {theirs[name]}"
    assert ours["Boolean_output"] == ["1" if b == "True" else "0" for b in theirs["Boolean_output"]]
    assert ours["Int32_output"][0] == "-7"
    assert ours["String_output"] == ["hello, world"] * 3
