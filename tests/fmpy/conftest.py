"""Shared fixtures: the workspace, the FMUs `runner build` wrote, and helpers to run them."""

import os
import pathlib

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
FMU_DIR = TARGET / "fmu"



def _builds_an_fmu(crate: pathlib.Path) -> bool:
    """A model crate builds a cdylib; models/linkages is a library the models share."""
    manifest = crate / "Cargo.toml"
    return manifest.is_file() and '"cdylib"' in manifest.read_text()


# Every model crate under models/ must have produced an FMU.
MODELS = sorted(p.name for p in (ROOT / "models").iterdir() if _builds_an_fmu(p))


def fmu_path(model: str) -> pathlib.Path:
    path = FMU_DIR / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo run --release -p runner -- build` first")
    return path


@pytest.fixture(params=MODELS)
def any_fmu(request):
    """Each model's FMU path in turn."""
    return fmu_path(request.param)
