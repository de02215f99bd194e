"""Sweeps on a Dask cluster: the points cut into chunks, each chunk one task that a worker runs
with the Rust engine, the results gathered as chunks finish into one table in point order.

Dask schedules, retries and reports; nothing here is a scheduler. What this module decides:

- the FMU's bytes are scattered once to every worker (``broadcast``), under a key of this
  sweep's own (``hash=False``: with the content's hash as key, sweeps of one FMU in a row
  scattered the very key the previous one was releasing, the likely cause of a CI sweep that
  failed with "Key lost during replication"), and each worker process unpacks and loads them
  once (``_loaded``), whatever the number of its tasks. Scattered data cannot be recomputed:
  should every worker holding it be lost, the chunks that needed it come back cancelled, and
  the bytes are scattered again and those chunks run again (a few times at most);
- chunk sizes: a first chunk per worker thread of a few points measures a point's cost on the
  cluster itself, and the following chunks are sized so a task takes about a second (never
  more than half of a thread's fair share of what is left, so the end of a sweep stays
  balanced);
- each task's result is compact (the chunk's metrics as float64 bytes, the statuses of its
  failed points only) and is written by point index into the result as soon as it arrives and
  then dropped, so the client holds the result and a bounded number of tasks, whatever the
  number of points;
- a chunk is deterministic and writes its own rows: one that Dask recomputes (its worker was
  lost) gives the same rows, and each row is filled exactly once;
- a chunk runs its points in a worker process of the runner's sandbox on its Dask worker (one
  per chunk), so a point that crashes or hangs is a failed row of the chunk, and the Dask worker
  lives on: Dask never sees the crash, so there is no KilledWorker after its retries
  (``in_process=True`` runs them on the Dask worker's own thread, for trusted FMUs).
"""

from __future__ import annotations

import hashlib
import math
import os
import sys
import tempfile
import threading
import time
import uuid
from collections import OrderedDict
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from . import _engine, _frame, _worker
from ._engine import RunnerError

if TYPE_CHECKING:
    import pandas as pd
    from distributed import Client, Future

#: A task should take about this long (s): long against Dask's per-task cost (about a
#: millisecond), short enough to balance the load and to lose little when a worker dies.
TASK_SECONDS = 1.0

#: At most this many tasks are queued or running per worker thread.
TASKS_PER_THREAD = 2

#: How many times a sweep scatters the FMU's bytes again after every copy was lost.
RESCATTERS = 3

#: How many times one scatter of the FMU is tried while the scheduler catches up with lost workers.
SCATTER_ATTEMPTS = 5

_models: OrderedDict[tuple[str, str | None], _engine.Model] = OrderedDict()
_models_lock = threading.Lock()


def _loaded(digest: str, data: bytes, name: str, interface: str | None = None) -> _engine.Model:
    """The FMU whose sha256 is ``digest`` through ``interface``, loaded once per worker process
    (the last 4 kept)."""
    key = (digest, interface)
    with _models_lock:
        model = _models.get(key)
        if model is None:
            model = _engine.Model.from_bytes(data, name, interface)
            _models[key] = model
            while len(_models) > 4:
                _models.popitem(last=False)
        _models.move_to_end(key)
        return model


_files: dict[str, str] = {}
_files_dir: tempfile.TemporaryDirectory[str] | None = None


def _written(digest: str, data: bytes, name: str) -> str:
    """The FMU whose sha256 is ``digest`` as a file of this worker process (written once), for
    the sandbox's workers to load."""
    global _files_dir
    with _models_lock:
        path = _files.get(digest)
        if path is None:
            if _files_dir is None:
                _files_dir = tempfile.TemporaryDirectory(prefix="fmurunner-")
            folder = os.path.join(_files_dir.name, digest[:16])
            os.makedirs(folder, exist_ok=True)
            path = os.path.join(folder, os.path.basename(name) or "model.fmu")
            with open(path, "wb") as f:
                f.write(data)
            _files[digest] = path
        return path


def _run_chunk(
    data: bytes,
    digest: str,
    name: str,
    spec: str,
    start: int,
    stop: int,
    in_process: bool = False,
    timeout: float | None = None,
    worker_memory: int | None = None,
    interface: str | None = None,
) -> tuple[int, int, bytes, list[tuple[int, str]], float]:
    """A task: the points ``start..stop``, in a sandbox worker process (or on this worker thread
    with ``in_process``) through ``interface``, the GIL released while they run."""
    if in_process:
        model = _loaded(digest, data, name, interface)
        values, failures, seconds = model.run_points(spec, start, stop, 1)
    else:
        path = _written(digest, data, name)
        values, failures, seconds = _engine.run_points_isolated(
            path, spec, start, stop, 1, _worker.command("sweep"), point_timeout=timeout, worker_memory=worker_memory,
            interface=interface,
        )
    return start, stop, values, failures, seconds


class _Sizer:
    """Chunk sizes: fixed when the caller gives one, else from the measured cost of a point."""

    def __init__(self, points: int, threads: int, fixed: int | None):
        self.threads = max(1, threads)
        self.fixed = fixed
        self.probe = max(1, min(8, points // (4 * self.threads)))
        self.seconds = 0.0
        self.measured = 0

    def record(self, points: int, seconds: float) -> None:
        self.seconds += seconds
        self.measured += points

    def next(self, remaining: int) -> int:
        if self.fixed is not None:
            return min(self.fixed, remaining)
        if self.measured == 0:
            return min(self.probe, remaining)
        per_point = max(self.seconds / self.measured, 1e-7)
        size = max(1, round(TASK_SECONDS / per_point))
        fair = max(1, math.ceil(remaining / (2 * self.threads)))
        return min(size, fair, remaining)


class _Progress:
    """The client's progress bar: points done of all, their rate and the time left, on stderr
    when it is a terminal (the CLI's convention), redrawn at most five times a second. Dask's
    own ``progress()`` needs every future at once, which the bounded window of tasks never
    holds; its dashboard shows the tasks under the ``fmurunner-sweep`` prefix."""

    def __init__(self, points: int, stream: TextIO | None = None, force: bool = False) -> None:
        self.points, self.done = points, 0
        self.stream = sys.stderr if stream is None else stream
        self.shown = force or (hasattr(self.stream, "isatty") and self.stream.isatty())
        self.start = self.drawn = time.monotonic()

    def advance(self, points: int) -> None:
        self.done += points
        now = time.monotonic()
        if self.shown and (now - self.drawn >= 0.2 or self.done == self.points):
            self.drawn = now
            elapsed = max(now - self.start, 1e-9)
            rate = self.done / elapsed
            left = (self.points - self.done) / rate if rate > 0 else float("inf")
            width = 30
            full = width * self.done // max(self.points, 1)
            bar = "#" * full + "-" * (width - full)
            end = "\n" if self.done == self.points else ""
            self.stream.write(
                f"\rsweep on Dask [{bar}] {self.done}/{self.points} points, {rate:.0f}/s, {left:.0f} s left{end}"
            )
            self.stream.flush()


def sweep_on_cluster(
    client: Client,
    path: str,
    grid_sources: Any,
    sets: list[str],
    ranges: list[tuple[str, list[float]]],
    metric_texts: list[str],
    chunk_size: int | None,
    in_process: bool = False,
    timeout: float | None = None,
    worker_memory: int | None = None,
    interface: str | None = None,
    integrator: tuple[str | None, float | None, float | None] = (None, None, None),
) -> pd.DataFrame:
    """``sweep(..., client=client)``: see :func:`fmurunner.sweep`; ``integrator`` is its
    ``(solver, fixed_step, abs_tolerance)``."""
    from distributed import as_completed

    if chunk_size is not None and (not isinstance(chunk_size, int) or chunk_size < 1):
        raise RunnerError(f"chunk_size must be a whole number of points, at least 1, not {chunk_size!r}")
    # Checked here first, from the description alone: a typo costs nothing on the cluster.
    spec, n, metric_names, interface = _engine.plan_sweep(path, grid_sources, sets, ranges, metric_texts, interface, *integrator)
    with open(path, "rb") as f:
        data = f.read()
    digest = hashlib.sha256(data).hexdigest()
    name = os.path.basename(path)

    nthreads = client.nthreads()
    if not nthreads:
        client.wait_for_workers(1)
        nthreads = client.nthreads()
    threads = sum(nthreads.values())
    sizer = _Sizer(n, threads, chunk_size)
    window = TASKS_PER_THREAD * threads

    m = len(metric_names)
    values = np.full((n, m), np.nan)
    status = np.full(n, "ok", dtype=object)
    filled = np.zeros(n, dtype=bool)
    sweep_id = uuid.uuid4().hex[:12]
    def scatter() -> Future[Any]:
        """The FMU's bytes on every worker. Right after workers were lost, the scheduler may not
        know yet that they are gone, and sending to them fails: wait for it, and try again."""
        for attempt in range(SCATTER_ATTEMPTS):
            try:
                scattered: Future[Any] = client.scatter(data, broadcast=True, hash=False)
                return scattered
            except OSError as e:  # distributed's CommClosedError: a worker that just died
                if attempt == SCATTER_ATTEMPTS - 1:
                    raise RunnerError(f"the FMU could not be sent to the cluster's workers: {e!r}") from e
                time.sleep(0.5 * (attempt + 1))
                client.wait_for_workers(1, timeout=60)
        raise AssertionError("unreachable")

    fmu = scatter()
    rescattered = 0
    # The points of each chunk task by its key (a cancelled task has no result to say them), and
    # how many times each chunk was sent.
    bounds: dict[str, tuple[int, int]] = {}
    sent: dict[int, int] = {}
    next_point = 0
    progress = _Progress(n)

    def run(start: int, stop: int) -> Future[Any]:
        sent[start] = sent.get(start, 0) + 1
        # The key's prefix names the task group in Dask's dashboard and progress bars; a chunk
        # sent again gets a key of its own.
        key = f"fmurunner-sweep-{sweep_id}-{start}" + (f"-again{sent[start]}" if sent[start] > 1 else "")
        bounds[key] = (start, stop)
        return client.submit(
            _run_chunk, fmu, digest, name, spec, start, stop, in_process, timeout, worker_memory, interface, key=key, retries=0
        )

    def submit() -> Future[Any]:
        nonlocal next_point
        size = sizer.next(n - next_point)
        start, next_point = next_point, next_point + size
        return run(start, next_point)

    # Only `pending` refers to a task: once a chunk's result is taken, Dask releases it on the
    # worker, so a worker lost later has nothing of it left to recompute.
    pending = as_completed([submit() for _ in range(min(threads, n))], with_results=True)
    try:
        for future, result in pending:
            # A cancelled chunk comes as its exception: its input, the FMU's scattered bytes, was
            # lost with every worker that held it. Scatter them again, once per loss (every
            # chunk waiting on them comes back so), and run the chunk again.
            start, stop = bounds.pop(future.key)
            del future
            if isinstance(result, BaseException):
                lost = fmu.status != "finished"
                if (lost and rescattered == RESCATTERS) or sent[start] > RESCATTERS:
                    raise RunnerError(f"points {start}..{stop} of the sweep were lost on the cluster "
                                      f"{sent[start]} times{' with the FMU' if lost else ''}: {result!r}") from result
                if lost:
                    rescattered += 1
                    fmu = scatter()
                pending.add(run(start, stop))
                continue
            start, stop, chunk, failures, seconds = result
            if filled[start:stop].any():
                raise RunnerError(f"points {start}..{stop} arrived twice")
            values[start:stop] = np.frombuffer(chunk, dtype="<f8").reshape(stop - start, m)
            for i, message in failures:
                status[i] = message
            filled[start:stop] = True
            sizer.record(stop - start, seconds)
            progress.advance(stop - start)
            # Keep the cluster busy with a bounded number of tasks.
            while next_point < n and pending.count() < window:
                pending.add(submit())
    except BaseException:
        client.cancel(list(pending.futures))
        raise
    finally:
        del fmu
    missing = np.flatnonzero(~filled)
    if missing.size:
        raise RunnerError(f"{missing.size} points never arrived (the first is point {missing[0]})")
    return _frame(ranges, metric_names, values, status)
