"""`runner simulate --input-file` and `runner sweep --input-file` against fmpy's
`simulate_fmu(input=...)` on the same FMUs: the Reference FMUs' Feedthrough (third-party) and our
mass_spring_damper (input F).

Both read the table with the same convention (Reals linear between rows, Integers and Booleans
held, a repeated time a discontinuity), set the inputs before every step and shorten a step to
end on a discontinuity (both FMUs can take steps of any size). mass_spring_damper interpolates its
inputs (`canInterpolateInputs`): the runner gives it each continuous input's slope over the step,
as fmpy does with `set_input_derivatives=True`. The same binary then gets the same calls with the
same arguments, so every output at every communication point must be equal bit for bit: any
difference is a bug in the runner's table, not rounding."""

import csv
import pathlib
import subprocess

import numpy as np
from fmpy import simulate_fmu
from fmpy.util import read_csv

from conftest import ROOT, TARGET, fmu_path

FEEDTHROUGH = ROOT.parent / "shared" / "reference-fmus" / "fmi2" / "Feedthrough.fmu"
RUNNER = TARGET / "release" / "runner"


def runner(*args):
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True)


def derivative_buffers_sized(monkeypatch):
    """fmpy 0.3.32's Input allocates each group's derivative buffer with 9 values whatever the
    number of inputs, so `set_input_derivatives=True` fails with any other number ("Can only
    assign sequence of same size"); this gives each buffer one value per input, as fmpy means to
    (the values and calls are fmpy's own)."""
    from ctypes import c_double

    import fmpy.simulation

    original = fmpy.simulation.Input.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)
        self.continuous = [c._replace(derivatives=(c_double * len(c.vrs))()) for c in self.continuous]

    monkeypatch.setattr(fmpy.simulation.Input, "__init__", init)


def read_rows(path):
    """The CSV's numeric columns (its String columns, which FMI 2.0 CSVs include as FMI 3.0's
    do, are left out: every comparison here is numeric)."""
    with open(path) as f:
        rows = list(csv.reader(f))

    def numeric(x):
        try:
            float(x)
            return True
        except ValueError:
            return False

    keep = [j for j in range(len(rows[0])) if all(numeric(r[j]) for r in rows[1:])]
    return [rows[0][j] for j in keep], np.array([[float(r[j]) for j in keep] for r in rows[1:]])


def assert_same_as_fmpy(header, rows, result):
    """Every runner column equals fmpy's at the same time (fmpy also samples the step ends it
    inserts at discontinuities; the runner samples the grid only, so match on time)."""
    picked = []
    for t in rows[:, 0]:
        at = np.nonzero(result["time"] == t)[0]
        assert len(at), f"fmpy has no row at t = {t}"
        picked.append(at[-1])
    for j, name in enumerate(header[1:], 1):
        np.testing.assert_array_equal(rows[:, j], result[name][picked].astype(float), err_msg=name)


def test_feedthrough_follows_the_input_file_as_fmpy(tmp_path):
    """Discontinuities at 0.25 (between grid points: the step is shortened onto it) and 0.5 (on
    one), a ramp in between, a held Integer and Boolean that change at the discontinuities."""
    table = tmp_path / "in.csv"
    table.write_text("time,Float64_continuous_input,Int32_input,Boolean_input\n"
                     "0,0,0,0\n0.25,0.5,0,0\n0.25,2,3,1\n0.5,1,3,1\n0.5,-1,-2,0\n0.8,4,7,1\n")
    out = tmp_path / "out.csv"
    outputs = ["Float64_continuous_output", "Int32_output", "Boolean_output"]
    done = runner("simulate", FEEDTHROUGH, "--stop-time", 1, "--output-interval", 0.1, "--input-file", table, "--out", out)
    assert done.returncode == 0, done.stderr
    header, rows = read_rows(out)
    result = simulate_fmu(str(FEEDTHROUGH), stop_time=1, output_interval=0.1, input=read_csv(str(table)), output=outputs)
    header_kept = ["time"] + [h for h in header[1:] if h in outputs]
    keep = [0] + [j for j, h in enumerate(header) if h in outputs]
    assert len(keep) == 4, header
    assert_same_as_fmpy(header_kept, rows[:, keep], result)
    # The inputs did change the outputs (the test cannot pass on constant inputs).
    assert set(rows[:, header.index("Int32_output")]) == {0.0, 3.0, -2.0, 7.0}


def test_mass_spring_damper_driven_by_a_force_table_as_fmpy(tmp_path, monkeypatch):
    """Our FMU (DOPRI5 inside): a force ramp, a step down at 0.37 s (between grid points) and a
    ramp back; the outputs depend on the whole history of the input. The FMU interpolates, so
    each step gets the slope of the table's segment too: the ramps start and end between grid
    points, as fmpy gives a grid point that falls on a row the slope of the segment before it
    (and none at the table's first row), the runner that of the segment the step goes into.
    Without the slopes the outputs differ from the second point on (by up to 100 %)."""
    derivative_buffers_sized(monkeypatch)
    table = tmp_path / "force.csv"
    table.write_text("time,F\n0,0\n0.105,0\n0.37,80\n0.37,-40\n1.205,30\n2,30\n")
    out = tmp_path / "out.csv"
    fmu = fmu_path("mass_spring_damper")
    done = runner("simulate", fmu, "--stop-time", 2, "--output-interval", 0.01, "--input-file", table, "--out", out)
    assert done.returncode == 0, done.stderr
    header, rows = read_rows(out)
    names = [h for h in header[1:] if h in ("x", "v", "a", "F_total")]
    assert len(names) == 4, header
    result = simulate_fmu(str(fmu), stop_time=2, output_interval=0.01, input=read_csv(str(table)), output=names,
                          set_input_derivatives=True)
    keep = [0] + [header.index(n) for n in names]
    assert_same_as_fmpy(["time"] + names, rows[:, keep], result)
    assert np.max(np.abs(rows[:, header.index("x")])) > 1e-4, "the force moved the mass"


def test_sweep_points_are_driven_by_the_input_file(tmp_path):
    """Each sweep point runs with the table: its final x equals a simulate run of that point."""
    table = tmp_path / "force.csv"
    table.write_text("time,F\n0,0\n0.5,50\n1,50\n")
    fmu = fmu_path("mass_spring_damper")
    sweep = tmp_path / "sweep.csv"
    done = runner("sweep", fmu, "--stop-time", 1, "--output-interval", 0.01, "--param", "m=100,400",
                  "--metric", "x_end=final(x)", "--input-file", table, "--out", sweep, "--threads", 2)
    assert done.returncode == 0, done.stderr
    with open(sweep) as f:
        points = list(csv.DictReader(f))
    for point in points:
        out = tmp_path / f"m{point['m']}.csv"
        done = runner("simulate", fmu, "--stop-time", 1, "--output-interval", 0.01, "--set", f"m={point['m']}",
                      "--input-file", table, "--out", out)
        assert done.returncode == 0, done.stderr
        header, rows = read_rows(out)
        assert float(point["x_end"]) == rows[-1, header.index("x")]
    assert points[0]["x_end"] != points[1]["x_end"]


def test_bad_input_files_are_refused_with_the_reason(tmp_path):
    fmu = fmu_path("mass_spring_damper")
    cases = {
        "time,G\n0,1\n": "column 'G'",
        "time,k\n0,1\n": "not an input",
        "time,F\n0,1\n1,2\n0.5,3\n": "time must not decrease",
        "time,F\n0,1\n1,one\n": "'one' is not a finite number",
        "F,time\n0,1\n": "first column must be 'time'",
    }
    for text, reason in cases.items():
        table = tmp_path / "bad.csv"
        table.write_text(text)
        for command in ("simulate", "sweep"):
            extra = ["--param", "m=1,2", "--metric", "e=final(x)"] if command == "sweep" else []
            done = runner(command, fmu, "--input-file", table, "--out", tmp_path / "o.csv", *extra)
            assert done.returncode != 0 and reason in done.stderr, (command, text, done.stderr)
    done = runner("simulate", fmu, "--input-file", tmp_path / "missing.csv")
    assert done.returncode != 0 and "cannot read the input file" in done.stderr, done.stderr
