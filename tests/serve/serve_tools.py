"""Helpers of the `runner serve` checks: the release runner (which tests/run builds), a server
of every lab model on a free port for the session, HTTP calls with urllib, and `runner
simulate` / `runner sweep` runs of the same settings to compare with."""

import csv
import io
import json
import os
import pathlib
import signal
import subprocess
import time
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
import zipfile

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]
TARGET = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
# The release runner tests/run builds (RUNNER_BINARY: another build of it).
RUNNER = pathlib.Path(os.environ.get("RUNNER_BINARY", TARGET / "release" / "runner"))
FMU_DIR = TARGET / "fmu"
# The fixture's limit on sweep points, which the API tests cross.
MAX_POINTS = 300


def lab_models():
    """The workspace's models: one crate under models/ that builds an FMU (a cdylib) each."""
    return sorted(p.parent.name for p in (ROOT / "models").glob("*/Cargo.toml") if '"cdylib"' in p.read_text())


def runner(*args, check=True):
    """Runs the release runner; the completed process (text)."""
    if not RUNNER.is_file():
        pytest.fail(f"{RUNNER} is missing: run `cargo build --release -p runner` first")
    done = subprocess.run([str(RUNNER), *map(str, args)], cwd=ROOT, capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=600)
    if check and done.returncode != 0:
        pytest.fail(f"runner {' '.join(map(str, args))} failed ({done.returncode}):\n{done.stderr}")
    return done


class Server:
    """A `runner serve` process on a free port (--port 0), its URL read from its first line."""

    def __init__(self, *args):
        if not RUNNER.is_file():
            pytest.fail(f"{RUNNER} is missing: run `cargo build --release -p runner` first")
        self.process = subprocess.Popen([str(RUNNER), "serve", "--port", "0", *map(str, args)], cwd=ROOT, stdout=subprocess.PIPE,
                                        stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, text=True)
        line = self.process.stdout.readline()
        if "http://" not in line:
            self.process.kill()
            pytest.fail(f"runner serve printed no URL: {line!r}\n{self.process.stderr.read()}")
        self.url = line[line.index("http://"):].split()[0].rstrip("/")
        self.stderr = ""

    def stop(self):
        """Ctrl-C, as a user stops it; the server must end by itself."""
        self.process.send_signal(signal.SIGINT)
        try:
            _, self.stderr = self.process.communicate(timeout=20)
        except subprocess.TimeoutExpired:
            self.process.kill()
            pytest.fail("runner serve did not stop within 20 s of Ctrl-C")
        return self.process.returncode

    def call(self, path, body=None, method=None, headers=None, raw=None):
        """(status, headers, body bytes) of a request; a JSON `body` is sent as application/json."""
        data = raw if raw is not None else (json.dumps(body).encode() if body is not None else None)
        all_headers = {"Content-Type": "application/json"} if data is not None else {}
        all_headers.update(headers or {})
        request = urllib.request.Request(self.url + path, data=data, method=method, headers=all_headers)
        try:
            with urllib.request.urlopen(request, timeout=120) as response:
                return response.status, dict(response.headers), response.read()
        except urllib.error.HTTPError as e:
            return e.code, dict(e.headers), e.read()

    def json(self, path, body=None, method=None, headers=None, status=200):
        """The JSON answer of a request, checked to have `status`."""
        code, _, data = self.call(path, body, method, headers)
        assert code == status, f"{method or ('POST' if body is not None else 'GET')} {path}: {code} {data[:500]!r}"
        return json.loads(data)


@pytest.fixture(scope="session")
def server():
    """Every lab model served for the session."""
    s = Server("--max-points", MAX_POINTS)
    yield s
    assert s.stop() == 0, f"runner serve ended with {s.process.returncode}:\n{s.stderr}"


def read_csv(text):
    """(header, rows as lists of texts) of a CSV."""
    rows = list(csv.reader(io.StringIO(text)))
    return rows[0], rows[1:]


def simulate_csv(tmp_path, model, sets):
    """The CSV text `runner simulate MODEL --set ... --out` writes."""
    out = tmp_path / f"{model}.csv"
    args = ["simulate", model, "--out", out]
    for s in sets:
        args += ["--set", s]
    runner(*args)
    return out.read_text()


def description(model):
    """The model's modelDescription.xml (FMI 2.0) as an ElementTree root, read here with the
    standard library: independent of the runner's reader."""
    with zipfile.ZipFile(FMU_DIR / f"{model}.fmu") as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def wait_for(predicate, seconds, what):
    """Polls `predicate` until it is true; fails naming `what` after `seconds`."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(0.05)
    pytest.fail(f"{what}: not within {seconds} s")
