"""fmpy's command line and the runner's with the same flags, side by side: `fmpy simulate FMU
--start-time T0 --stop-time T1 --output-interval H --output-variables A B ... --output-file F`
against `runner simulate FMU --start-time T0 --stop-time T1 --output-interval H
--output-variables A B ... --out F` (the runner takes fmpy's `--output-variables` spelling as
well as fmusim's repeatable `--output-variable`), on a Reference FMU (BouncingBall, FMI 2.0 and
3.0) and on one of ours (quarter_car, FMI 2.0 and 3.0), with a parameter and a derivative (a
local) among the recorded variables. Both drive the FMU's own Co-Simulation over the same grid
with the same calls, so the CSVs agree: the same columns (the runner in the order given, as
fmusim; fmpy in the modelDescription's), the same times, and values equal to 1e-12 relative
(fmpy's CSV writer prints numbers with %.16g, the runner prints them in full)."""

import csv
import subprocess

import pytest

from conftest import FMU3_DIR, FMU_DIR, ROOT, TARGET

REFERENCE = ROOT.parent / "shared" / "reference-fmus"
RUNNER = TARGET / "release" / "runner"
FMPY = ROOT / ".venv" / "bin" / "fmpy"

CASES = [
    (REFERENCE / "fmi2" / "BouncingBall.fmu", ["h", "v", "g"], ["--start-time", "0.5", "--stop-time", "2", "--output-interval", "0.01"]),
    (REFERENCE / "fmi3" / "BouncingBall.fmu", ["h", "v", "e"], ["--start-time", "0.5", "--stop-time", "2", "--output-interval", "0.01"]),
    (FMU_DIR / "quarter_car.fmu", ["z_s", "der(z_u)", "k_s"], ["--start-time", "0.25", "--stop-time", "1", "--output-interval", "0.005"]),
    (FMU3_DIR / "quarter_car.fmu", ["z_s", "der(z_u)", "k_s"], ["--start-time", "0.25", "--stop-time", "1", "--output-interval", "0.005"]),
]


def fmpy_command():
    """fmpy's CLI from the pinned environment (tests/python-env), else the one on PATH."""
    return str(FMPY) if FMPY.exists() else "fmpy"


def read(path):
    with open(path) as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    return rows[0], [[float(x.strip('"')) for x in r] for r in rows[1:]]


@pytest.mark.parametrize("fmu, variables, grid", CASES, ids=lambda c: getattr(c, "parent", None) and f"{c.parent.name}/{c.stem}")
def test_the_same_flags_give_the_same_csv(tmp_path, fmu, variables, grid):
    if not fmu.is_file():
        pytest.fail(f"{fmu} is missing: run `cargo run --release -p runner -- build` first")
    ours, theirs = tmp_path / "runner.csv", tmp_path / "fmpy.csv"
    done = subprocess.run([str(RUNNER), "simulate", str(fmu), *grid, "--output-variables", *variables, "--out", str(ours)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([fmpy_command(), "simulate", str(fmu), *grid, "--output-variables", *variables, "--output-file", str(theirs)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stdout + done.stderr
    our_header, our_rows = read(ours)
    their_header, their_rows = read(theirs)
    # The runner keeps the order given (fmusim's); fmpy the modelDescription's: match by name.
    assert our_header == ["time", *variables]
    their_header = [h.strip('"') for h in their_header]
    assert sorted(their_header) == sorted(our_header)
    at = [their_header.index(name) for name in our_header]
    assert len(our_rows) == len(their_rows), f"{len(our_rows)} rows against fmpy's {len(their_rows)}"
    for a, b in zip(our_rows, their_rows):
        for name, x, j in zip(our_header, a, at):
            assert x == pytest.approx(b[j], rel=1e-12, abs=1e-300), f"{fmu.name} {name} at t = {a[0]}: runner {x}, fmpy {b[j]}"
