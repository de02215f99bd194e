"""Helpers of the Python package's tests: the workspace, the runner binary and FMUs that
`runner build` wrote, the CLI's sweep CSV read exactly, and the handbook's Ex. 4 sweep."""

import csv
import math
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
RUNNER = TARGET / "release" / "runner"
REFERENCE = ROOT.parent / "shared" / "reference-fmus"


def fmu_path(model: str) -> pathlib.Path:
    path = TARGET / "fmu" / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo run --release -p runner -- build` first")
    return path


def runner_sweep_csv(tmp_path: pathlib.Path, *args: str) -> list[dict]:
    """Runs `runner sweep ARGS --out FILE` and returns its rows, every number parsed exactly
    (float() reads the shortest round-trip text the runner writes back to the same double)."""
    out = tmp_path / "cli.csv"
    subprocess.run([str(RUNNER), "sweep", *args, "--out", str(out)], check=True, cwd=ROOT, capture_output=True)
    with open(out, newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        for key, text in row.items():
            if key != "status":
                row[key] = float(text) if text != "" else math.nan
    return rows


def assert_same_as_cli(frame, rows: list[dict]) -> None:
    """Every row, column by column, the same bits as the CLI's CSV (NaN where it is empty)."""
    assert len(frame) == len(rows)
    assert list(frame.columns) == list(rows[0].keys())
    for i, row in enumerate(rows):
        for key, expected in row.items():
            got = frame[key].iloc[i]
            if key == "status":
                assert got == expected, (i, got, expected)
            elif math.isnan(expected):
                assert math.isnan(got), (i, key, got)
            else:
                assert got == expected and math.copysign(1, got) == math.copysign(1, expected), (i, key, got, expected)


# Handbook Ex. 4, as models/quarter_car/experiment.toml's [sweep] gives it to the CLI.
EX4_SPEEDS = [1.0 + i * 0.5 for i in range(99)]
EX4_METRICS = {"transmissibility": "max(z_s)/max(z_r)", "steady_state": "amplitude(z_s, 5, 2*pi*speed/road_wavelength)/amplitude(z_r, 5, 2*pi*speed/road_wavelength)"}


# A stiff sweep: Reference VanDerPol (FMI 3.0) up to mu = 1000 through Model Exchange and the
# runner's BDF, as `sweep` takes it (STIFF_SWEEP) and as `runner sweep` does (STIFF_SWEEP_CLI).
STIFF_FMU = REFERENCE / "fmi3" / "VanDerPol.fmu"
STIFF_SWEEP = dict(params={"mu": [1.0, 10.0, 100.0, 1000.0]}, metrics={"x0_end": "final(x0)", "x1_peak": "max(x1)"},
                   stop_time=1000.0, output_interval=1.0, tolerance=1e-8, interface="model-exchange", solver="bdf",
                   abs_tolerance=1e-10)
STIFF_SWEEP_CLI = ["--param", "mu=1,10,100,1000", "--metric", "x0_end=final(x0)", "--metric", "x1_peak=max(x1)",
                   "--stop-time", "1000", "--output-interval", "1", "--tolerance", "1e-8", "--interface", "model-exchange",
                   "--solver", "bdf", "--abs-tolerance", "1e-10"]


def faulty_fmu(directory: pathlib.Path, name: str = "faulty.fmu") -> pathlib.Path:
    """Builds tests/c_fmu/faulty.c (an FMU that crashes, hangs or fails on request: its `fault`
    parameter) with the system C compiler into `directory/name`, as the runner's tests do."""
    import zipfile

    source = ROOT / "tests" / "c_fmu" / "faulty.c"
    so = directory / f"{name}.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", "-fvisibility=hidden", "-o", str(so), str(source), "-lm"], check=True)
    path = directory / name
    with zipfile.ZipFile(path, "w") as z:
        z.write(ROOT / "tests" / "c_fmu" / "faulty.xml", "modelDescription.xml")
        z.write(so, "binaries/linux64/faulty.so")
    return path
