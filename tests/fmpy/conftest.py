"""Shared fixtures: the workspace, the FMUs `runner build` wrote (FMI 2.0 in target/fmu, FMI 3.0
in target/fmu3), and helpers to run them. A test that uses the `fmi_version` fixture runs once
per FMI version: `fmu_path` and `simulate` then take that version's FMU."""

import os
import pathlib

import pytest
from fmpy import simulate_fmu

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
FMU_DIR = TARGET / "fmu"
FMU3_DIR = TARGET / "fmu3"
# The FMI version `fmu_path` serves; the `fmi_version` fixture switches it.
FMI_VERSION = "2.0"



def _builds_an_fmu(crate: pathlib.Path) -> bool:
    """A model crate builds a cdylib; models/linkages is a library the models share."""
    manifest = crate / "Cargo.toml"
    return manifest.is_file() and '"cdylib"' in manifest.read_text()


# Every model crate under models/ must have produced an FMU.
MODELS = sorted(p.name for p in (ROOT / "models").iterdir() if _builds_an_fmu(p))


def fmu_path(model: str, version: str | None = None) -> pathlib.Path:
    """The model's FMU of `version` (default: the one the `fmi_version` fixture chose)."""
    path = (FMU3_DIR if (version or FMI_VERSION) == "3.0" else FMU_DIR) / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo run --release -p runner -- build` first")
    return path


@pytest.fixture(params=MODELS)
def any_fmu(request):
    """Each model's FMU path in turn."""
    return fmu_path(request.param)


@pytest.fixture(params=["2.0", "3.0"])
def fmi_version(request):
    """Runs the test on the FMI 2.0 FMUs, then on the FMI 3.0 ones."""
    global FMI_VERSION
    FMI_VERSION = request.param
    yield request.param
    FMI_VERSION = "2.0"


def simulate(path, **kwargs):
    """fmpy's simulate_fmu. An FMI 3.0 Co-Simulation run allows early return, so that fmpy records
    an early end (a landing, a limit position) at the time it happened, as FMI 2.0's Discard with
    lastSuccessfulTime makes it do; each event inside a step then ends the step there, after the
    FMU handled it."""
    if FMI_VERSION == "3.0" and kwargs.get("fmi_type") == "CoSimulation":
        kwargs.setdefault("early_return_allowed", True)
    return simulate_fmu(path, **kwargs)
