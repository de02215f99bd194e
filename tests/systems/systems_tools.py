"""Shared helpers for the system checks: the packed systems (`runner build` writes
target/ssp/<name>.ssp), the runner, and libcosim's run of the same archive."""

import csv
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
RUNNER = TARGET / "release" / "runner"
SYSTEMS = sorted(p.name for p in (ROOT / "systems").iterdir() if (p / "SystemStructure.ssd").is_file())


def ssp_version(name):
    """The SSP version systems/<name>'s SSD declares (SSP 2.0 keeps SSP 1.0's namespaces)."""
    import re

    text = (ROOT / "systems" / name / "SystemStructure.ssd").read_text()
    return re.search(r'<ssd:SystemStructureDescription[^>]*\sversion="([^"]+)"', text).group(1)


# libcosim refuses SSP 2.0's connector types (Float64, Int32) and FMI 3.0 FMUs: the SSP 2.0
# systems are checked against their SSP 1.0 twins instead (test_ssp2.py).
SSP1_SYSTEMS = [name for name in SYSTEMS if ssp_version(name) == "1.0"]


def ssp_path(name):
    path = TARGET / "ssp" / f"{name}.ssp"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo run --release -p runner -- build` first")
    return path


def runner(*args):
    return subprocess.run([str(RUNNER), *map(str, args)], capture_output=True, text=True)


def runner_csv(tmp_path, target, *args):
    """The runner's CSV of `simulate target args` as (header, rows)."""
    out = tmp_path / "runner.csv"
    done = runner("simulate", target, "--out", out, *args)
    assert done.returncode == 0, done.stderr
    with open(out) as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def libcosim_run(ssp, steps):
    """libcosim's fixed-step run of `ssp` (its step from the SSD's OSP annotation): every Real
    output of every component after initialization and after each of `steps` steps, as
    {"component.variable": array}."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimEnums import CosimVariableCausality, CosimVariableType

    log_output_level(CosimLogLevel.ERROR)
    execution = CosimExecution.from_ssp_file(str(ssp))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    outputs = {}
    for info in execution.slave_infos():
        refs = [(v.name.decode(), v.reference) for v in execution.slave_variables(info.index)
                if v.type == CosimVariableType.REAL.value and v.causality == CosimVariableCausality.OUTPUT.value]
        outputs[info.index] = (info.name.decode(), refs)
    series = {f"{name}.{v}": [] for name, refs in outputs.values() for v, _ in refs}

    def record():
        for index, (name, refs) in outputs.items():
            values = observer.last_real_values(index, [r for _, r in refs])
            for (v, _), x in zip(refs, values):
                series[f"{name}.{v}"].append(x)

    execution.step(1)  # initializes, then takes the first step
    # libcosim initializes on the first step; the values at t = 0 come from a fresh execution,
    # so compare from the first step on: row k of the series is the state at (k + 1) h.
    record()
    for _ in range(steps - 1):
        execution.step(1)
        record()
    return {k: np.array(v) for k, v in series.items()}
