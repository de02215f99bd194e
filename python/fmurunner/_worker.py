"""A worker process of fmurunner's sandbox: the extension module itself serves the runner's
worker protocol (its descriptors 3, 4 and 5, set up by the supervisor), so an installed wheel
needs no other program.

The supervisor (a local sweep, an isolated ``Simulation``) starts it as
``python -I -S .../fmurunner/_worker.py ENGINE KIND``: run as a file, not as ``-m
fmurunner._worker``, so the worker imports neither the package nor numpy and pandas, only the
extension module ``ENGINE`` (its path), and starts in milliseconds. ``KIND`` is ``sweep`` (runs
and sweep points) or ``step`` (a stepped simulation). Not for use by hand.
"""

from __future__ import annotations

import importlib.util
import sys


def main(argv: list[str]) -> int:
    """Loads the extension module at ``argv[1]`` and serves as a worker of kind ``argv[2]``."""
    if len(argv) != 3:
        print("usage: python -I -S _worker.py ENGINE KIND (only a supervisor starts workers)", file=sys.stderr)
        return 2
    spec = importlib.util.spec_from_file_location("fmurunner._engine", argv[1])
    if spec is None or spec.loader is None:
        print(f"cannot load the extension module {argv[1]}", file=sys.stderr)
        return 2
    engine = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(engine)
    engine.serve_worker(argv[2])
    return 0


def command(kind: str) -> tuple[str, list[str]]:
    """The program and arguments that start a worker of ``kind`` with this interpreter."""
    from . import _engine

    return sys.executable, ["-I", "-S", __file__, _engine.__file__ or "", kind]


if __name__ == "__main__":
    sys.exit(main(sys.argv))
