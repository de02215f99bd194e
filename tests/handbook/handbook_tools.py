"""Helpers of the handbook checks: the release runner that tests/run builds, the FMUs `runner
build` wrote, and a minimal GIF and PNG reader written here from the GIF89a and PNG
specifications, so frame counts and delays are checked independently of the encoder the
runner uses."""

import json
import os
import pathlib
import struct
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
# The models' closed forms (references.toml, experiment.toml) are evaluated by tests/fmpy's
# closed_form.py, the one evaluator the Python checks share.
sys.path.insert(0, str(ROOT / "tests" / "fmpy"))
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
RUNNER = TARGET / "release" / "runner"
FMU_DIR = TARGET / "fmu"


def runner(*args, cwd=None, check=True):
    """Runs the release runner; returns the completed process (stdout and stderr as text)."""
    if not RUNNER.is_file():
        pytest.fail(f"{RUNNER} is missing: run `cargo build --release -p runner` first")
    done = subprocess.run([str(RUNNER), *map(str, args)], cwd=cwd or ROOT, capture_output=True, text=True,
                          stdin=subprocess.DEVNULL, timeout=600)
    if check and done.returncode != 0:
        pytest.fail(f"runner {' '.join(map(str, args))} failed ({done.returncode}):\n{done.stderr}")
    return done


@pytest.fixture(scope="session")
def handbook(tmp_path_factory):
    """One `runner handbook --out DIR` for the session: (DIR, summary.json as a dict, stdout)."""
    out = tmp_path_factory.mktemp("handbook")
    done = runner("handbook", "--out", out)
    return out, json.loads((out / "summary.json").read_text()), done.stdout


def fmu(model):
    path = FMU_DIR / f"{model}.fmu"
    if not path.is_file():
        pytest.fail(f"{path} is missing: run `cargo run --release -p runner -- build` first")
    return path


def read_gif(path):
    """(width, height, [frame delays in centiseconds], loops forever) of a GIF file."""
    data = open(path, "rb").read()
    if data[:6] not in (b"GIF87a", b"GIF89a"):
        raise ValueError(f"{path} is not a GIF")
    width, height, flags = struct.unpack_from("<HHB", data, 6)
    pos = 13
    if flags & 0x80:  # global colour table
        pos += 3 * (2 << (flags & 7))
    delays, pending_delay, loops = [], 0, False

    def skip_blocks(pos):
        while data[pos] != 0:
            pos += data[pos] + 1
        return pos + 1

    while True:
        kind = data[pos]
        if kind == 0x3B:  # trailer
            return width, height, delays, loops
        if kind == 0x21:  # extension
            label = data[pos + 1]
            if label == 0xF9:  # graphic control: the next image's delay
                pending_delay = struct.unpack_from("<H", data, pos + 4)[0]
            if label == 0xFF and data[pos + 3:pos + 14] == b"NETSCAPE2.0":
                loops = struct.unpack_from("<H", data, pos + 16)[0] == 0
            pos = skip_blocks(pos + 2)
        elif kind == 0x2C:  # image descriptor
            left, top, w, h, iflags = struct.unpack_from("<HHHHB", data, pos + 1)
            if left + w > width or top + h > height:
                raise ValueError(f"{path}: a frame outside the canvas")
            pos += 10
            if iflags & 0x80:
                pos += 3 * (2 << (iflags & 7))
            pos = skip_blocks(pos + 1)  # LZW minimum code size, then the data blocks
            delays.append(pending_delay)
            pending_delay = 0
        else:
            raise ValueError(f"{path}: unexpected block 0x{kind:02x} at byte {pos}")


def png_size(path):
    """Width and height of a PNG, from its IHDR chunk."""
    data = open(path, "rb").read(24)
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path} is not a PNG")
    return struct.unpack(">II", data[16:24])
