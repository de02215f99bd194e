"""Helpers of the handbook checks: the release runner that tests/run builds, the FMUs `runner
build` wrote, a minimal GIF and PNG reader written here from the GIF89a and PNG
specifications, so frame counts and delays are checked independently of the encoder the
runner uses, and PNG figures opened as images (by Pillow, a decoder independent of the
runner's) and checked as a person would look at them."""

import json
import os
import pathlib
import struct
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

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


# The first curve's colour in every figure (Tableau 10's blue, the plots crate's PALETTE[0]).
FIRST_CURVE = (31, 119, 180)


def png_pixels(path):
    """The PNG at `path` opened as an image: its pixels as a (height, width, 3) RGB array."""
    with Image.open(path) as image:
        assert image.format == "PNG", f"{path} is a {image.format} file, not a PNG"
        return np.asarray(image.convert("RGB"))


def blend_levels(pixels, color):
    """The distinct levels (steps of 1/32, strictly between none and full) at which `color` is
    blended into the white background somewhere in the image. A pixel a line covers by a
    fraction a is a color + (1 - a) white in every channel (within 4 of 255 per channel, for the
    rasterizer's 8-bit arithmetic); a line drawn without anti-aliasing is either there or not,
    and stair-steps, while an anti-aliased one shades its edges through many levels."""
    ink = 255.0 - pixels.reshape(-1, 3).astype(float)
    line = 255.0 - np.asarray(color, dtype=float)
    a = ink @ line / (line @ line)
    off_the_blend = np.linalg.norm(ink - a[:, None] * line, axis=1)
    partial = (off_the_blend <= 4.0) & (a > 0.05) & (a < 0.95)
    return len(np.unique(np.round(a[partial] * 32)))


def check_png_figure(path, size=None, smooth=True):
    """A PNG figure as an image: of `size` (width, height) if given, not blank, with black text,
    and (`smooth`) its first curve drawn anti-aliased: its colour at 10 or more of the 31
    partial coverage levels (a line without anti-aliasing shows none)."""
    pixels = png_pixels(path)
    height, width, _ = pixels.shape
    if size is not None:
        assert (width, height) == size, (path, (width, height), size)
    assert width >= 480 and height >= 300, (path, width, height)
    inked = (pixels != 255).any(axis=2).mean()
    assert inked > 0.01, f"{path}: {inked:.2%} of the pixels drawn, blank"
    assert (pixels < 60).all(axis=2).any(), f"{path}: no black text or axes"
    if smooth:
        levels = blend_levels(pixels, FIRST_CURVE)
        assert levels >= 10, f"{path}: the first curve's colour at {levels} coverage levels, not anti-aliased"
    return pixels
