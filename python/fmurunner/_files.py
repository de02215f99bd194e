"""A local sweep to a file, as ``runner sweep --out FILE.csv [--resume]`` keeps it: the rows
written in point order to ``<out>.partial`` as the points finish (flushed and synced as they
come, so a killed process loses nothing it had handed over), a record of what the sweep is
beside it (``<out>.sweep``: the FMU's sha256, the interface it runs through and the sweep as the
engine runs it, the integrator's settings included), and the file
renamed to ``<out>`` when complete. ``resume=True`` continues from the partial file when its
record is this sweep's.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd

from ._engine import RunnerError

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
        try:
            with open(record_path, encoding="utf-8") as f:
                lines = [line for line in f if not line.startswith("#")]
            record = json.loads("".join(lines))
        except (OSError, ValueError) as e:
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

    def read_rows(file: str) -> tuple[pd.DataFrame, int]:
        """The complete rows of ``file`` as text (a last line cut short by a kill is dropped) and
        the byte length they take."""
        with open(file, "rb") as f:
            data = f.read()
        end = data.rfind(b"\n") + 1
        table = pd.read_csv(io.BytesIO(data[:end]), keep_default_na=False, dtype=str) if end else pd.DataFrame()
        if end and list(table.columns) != header:
            raise RunnerError(f"{file} has the columns {list(table.columns)}, not this sweep's {header}")
        return table, end

    first, kept = 0, None
    if resume and os.path.exists(partial):
        earlier()
        kept, valid = read_rows(partial)
        first = len(kept)
        with open(partial, "r+b") as binary:
            binary.truncate(valid)
        if valid == 0:
            with open(partial, "w", encoding="utf-8", newline="") as f:
                csv.writer(f, lineterminator="\n").writerow(header)
    elif resume and os.path.exists(out) and os.path.exists(record_path):
        earlier()
        kept, _ = read_rows(out)
        if len(kept) != n:
            raise RunnerError(f"{out} has {len(kept)} of this sweep's {n} rows and no partial file to continue; run without resume to start again")
        first = n
    else:
        if not resume and os.path.exists(partial):
            raise RunnerError(f"{partial} holds the finished points of an earlier sweep: continue it with resume=True, or delete it to start again")
        with open(record_path, "w", encoding="utf-8") as f:
            f.write(RECORD_HEADER + "\n" + json.dumps(current, indent=1) + "\n")
        with open(partial, "w", encoding="utf-8", newline="") as f:
            csv.writer(f, lineterminator="\n").writerow(header)

    values = np.full((n, m), np.nan)
    status = np.full(n, "ok", dtype=object)
    if kept is not None and first:
        for k, name in enumerate(metric_names):
            # Python's float() reads the shortest round-trip text back to the same double, which
            # pandas' own float parsers do not promise.
            values[:first, k] = [float(text) if text else np.nan for text in kept[name][:first]]
        status[:first] = kept["status"].to_numpy()[:first]
    if first < n:
        with open(partial, "a", encoding="utf-8", newline="") as f:
            writer = csv.writer(f, lineterminator="\n")

            def on_rows(start: int, data: bytes, failures: list[tuple[int, str]]) -> None:
                rows = np.frombuffer(data, dtype="<f8").reshape(-1, m)
                stop = start + len(rows)
                values[start:stop] = rows
                for i, message in failures:
                    status[i] = message
                points = _points(ranges, start, stop)
                for k in range(len(rows)):
                    i = start + k
                    writer.writerow(
                        [repr(float(points[name][k])) for name, _ in ranges] + [_text(x) for x in rows[k]] + [status[i]]
                    )
                f.flush()
                os.fsync(f.fileno())

            run(first, on_rows)
        os.replace(partial, out)
    return _frame(ranges, metric_names, values, status)
