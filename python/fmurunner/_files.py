"""A local sweep to a file, as ``runner sweep --out FILE.csv [--resume]`` keeps it: the rows
written in point order to ``<out>.partial`` as the points finish (flushed and synced as they
come, so a killed process loses nothing it had handed over), a record of what the sweep is
beside it (``<out>.sweep``: the FMU's sha256, the interface it runs through and the sweep as the
engine runs it, the integrator's settings included), and the file
renamed to ``<out>`` when complete. ``resume=True`` continues from the partial file when its
record is this sweep's and each of its rows is the row this sweep writes for its point.

The record is held under an exclusive ``flock`` for the sweep's life, as ``runner sweep`` holds
it, so a second sweep to the same ``out`` (of either) is refused instead of interleaving rows;
the lock ends with the process, so a killed sweep never blocks its resume. The lock, the
spelling of a row and the check of the rows read back are the engine's, the code ``runner
sweep`` runs: the two tools cannot drift apart.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from ._engine import RunnerError, SweepLock, csv_line, read_finished

#: The record's first line: what wrote it.
RECORD_HEADER = "# fmurunner sweep: what produced the CSV beside this file; sweep(..., resume=True) checks it"


def _sha256(path: str) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 16), b""):
            digest.update(block)
    return digest.hexdigest()


def _record(path: str, interface: str, spec: str, n: int) -> dict[str, Any]:
    return {"fmu": path, "fmu_sha256": _sha256(path), "interface": interface, "points": n, "sweep": json.loads(spec)}


def _difference(earlier: dict[str, Any], current: dict[str, Any]) -> str | None:
    """What differs between two records (the FMU's path is informational), or None."""
    lines = []
    for key in ("fmu_sha256", "interface", "points", "sweep"):
        if earlier.get(key) != current.get(key):
            what = "the FMU's content" if key == "fmu_sha256" else key
            lines.append(f"  {what}: {earlier.get(key)!r} then, {current.get(key)!r} now")
    return "\n".join(lines) or None


def _text(x: float) -> str:
    return "" if np.isnan(x) else repr(float(x))


def sweep_to_file(
    out: str,
    resume: bool,
    path: str,
    interface: str,
    interface_defaulted: bool,
    spec: str,
    n: int,
    ranges: list[tuple[str, list[float]]],
    metric_names: list[str],
    run: Callable[[int, Any], tuple[bytes, list[tuple[int, str]], float]],
) -> pd.DataFrame:
    """Runs the sweep (``run(first, on_rows)`` runs the points from ``first`` on, handing the
    finished ones to ``on_rows``) into ``out`` as described above; returns the whole table."""
    from . import _frame, _points

    partial, record_path = out + ".partial", out + ".sweep"
    current = _record(path, interface, spec, n)
    header = [name for name, _ in ranges] + metric_names + ["status"]
    m = len(metric_names)

    def earlier() -> None:
        text = ""
        try:
            with open(record_path, encoding="utf-8") as f:
                text = f.read()
            record = json.loads("".join(line for line in text.splitlines(keepends=True) if not line.startswith("#")))
            if not text:
                raise ValueError("it is empty")
            if not isinstance(record, dict):
                raise ValueError("it is not a JSON object")
        except (OSError, ValueError) as e:
            if text.startswith("# runner sweep"):
                raise RunnerError(f"{record_path} is the record of a sweep of the command line, runner sweep: continue it "
                                  f"there, with --out {out} --resume") from None
            raise RunnerError(f"cannot read {record_path}, the record of the sweep that wrote {partial}: {e}") from None
        # A record from before the interface was recorded ran through the default one: the same
        # sweep when this one takes the default too (its rows are not lost to an upgrade).
        if interface_defaulted and "interface" not in record:
            record["interface"] = current["interface"]
        diff = _difference(record, current)
        if diff is not None:
            raise RunnerError(
                f"{partial} is not from this sweep, so it cannot be resumed:\n{diff}\n"
                f"run the earlier sweep again with resume=True, or delete {partial} to start this one"
            )

    def read_rows(file: str) -> tuple[np.ndarray, list[tuple[int, str]], int]:
        """The finished rows of ``file``: their metrics, the (row, status) of those not ``ok``, and
        the bytes they take with the header. The engine reads them back as ``runner sweep
        --resume`` does: each must be exactly the row this sweep writes for its point; one that is
        not is refused, unless it is the last, which a kill may have cut short: that one is
        dropped (a header cut short starts the file again)."""
        # The parameter values of the points the file may hold, as the writer below spells them.
        with open(file, "rb") as f:
            lines = sum(block.count(b"\n") for block in iter(lambda: f.read(1 << 16), b""))
        points = _points(ranges, 0, min(n, lines))
        spelled = [[repr(float(points[name][i])) for name, _ in ranges] for i in range(len(points[ranges[0][0]]))]
        valid, rows, metrics, statuses = read_finished(file, header, m, spelled)
        return np.array(metrics, dtype=float).reshape(rows, m), statuses, valid

    # Before anything is read: another sweep at this `out` would change it under us.
    lock = SweepLock(out)  # held until the sweep ends (released below)
    try:
        first, kept = 0, None
        # False when `out` is found complete already (no partial file to put in its place).
        renaming = True
        if resume and os.path.exists(partial):
            earlier()
            kept = read_rows(partial)
            first, valid = len(kept[0]), kept[2]
            with open(partial, "r+b") as binary:
                binary.truncate(valid)
            if valid == 0:
                with open(partial, "wb") as f:
                    f.write(csv_line(header))
        elif resume and os.path.exists(out) and lock.had_record:
            earlier()
            kept = read_rows(out)
            if len(kept[0]) != n:
                raise RunnerError(f"{out} has {len(kept[0])} of this sweep's {n} rows and no partial file to continue; run without resume to start again")
            first, renaming = n, False
        else:
            if not resume and os.path.exists(partial):
                raise RunnerError(f"{partial} holds the finished points of an earlier sweep: continue it with resume=True, or delete it to start again")
            lock.write_record(RECORD_HEADER + "\n" + json.dumps(current, indent=1) + "\n")
            with open(partial, "wb") as f:
                f.write(csv_line(header))

        values = np.full((n, m), np.nan)
        status = np.full(n, "ok", dtype=object)
        if kept is not None and first:
            # The engine read the shortest round-trip text back to the same double.
            values[:first] = kept[0]
            for i, text in kept[1]:
                status[i] = text
        if first < n:
            with open(partial, "ab") as f:

                def on_rows(start: int, data: bytes, failures: list[tuple[int, str]]) -> None:
                    rows = np.frombuffer(data, dtype="<f8").reshape(-1, m)
                    stop = start + len(rows)
                    values[start:stop] = rows
                    for i, message in failures:
                        status[i] = message
                    points = _points(ranges, start, stop)
                    for k in range(len(rows)):
                        i = start + k
                        f.write(csv_line(
                            [repr(float(points[name][k])) for name, _ in ranges] + [_text(x) for x in rows[k]] + [status[i]]
                        ))
                    f.flush()
                    os.fsync(f.fileno())

                run(first, on_rows)
        # Also a partial file that holds every row (killed before it was renamed) is put in place.
        if renaming:
            os.replace(partial, out)
        return _frame(ranges, metric_names, values, status)
    finally:
        lock.release()
