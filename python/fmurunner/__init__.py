"""The runner's engine from Python: inspect, simulate, sweep and step FMUs.

``info``, ``simulate`` and ``sweep`` call the Rust engine of the ``runner`` command line
directly (no subprocess, no CSV in between; the GIL is released while it runs), so their numbers
are the command line's, bit for bit. ``fmu`` is a path to any ``.fmu`` or, inside this
repository, one of its model names (``quarter_car``), whose experiment defaults apply as on the
command line. A local ``sweep`` runs its points in worker processes of the runner's sandbox (a
crashing or hanging FMU is a failed row); ``sweep(..., client=client)`` runs them on a Dask
cluster. :class:`Simulation` steps one FMU instance from your own loop. :func:`plot` draws a
result with matplotlib.

Errors (a bad parameter name, a bad metric expression, an unreadable FMU) raise
:class:`RunnerError` with the runner's message; a point that fails is a row whose ``status``
holds its error.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from . import _engine, _worker
from ._engine import RunnerError, StepResult

if TYPE_CHECKING:
    from distributed import Client

__all__ = ["info", "simulate", "sweep", "plot", "Simulation", "StepResult", "RunnerError"]

StartValues = Mapping[str, "float | int | bool | str | Sequence[float]"]


def info(fmu: str | os.PathLike[str]) -> dict[str, Any]:
    """What the FMU declares, as ``runner info`` shows it.

    Returns a dict with ``model_name``, ``description``, ``fmi_version``, ``guid``,
    ``generation_tool``, ``co_simulation`` and ``model_exchange`` (their capabilities, or
    ``None`` when not offered), ``number_of_continuous_states``,
    ``number_of_event_indicators``, ``default_experiment`` and ``variables`` (one dict per
    variable: ``name``, ``value_reference``, ``causality``, ``variability``, ``type``,
    ``unit``, ``display_unit``, ``start``, ``description``, ``dimensions``). The FMU's binary is
    not loaded.
    """
    path, _, _ = _engine.locate(os.fspath(fmu), "info")
    return _engine.describe(path)


def _value_text(name: str, value: Any) -> str:
    """A start value as the runner's ``--set NAME=VALUE`` spells it."""
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        # repr is the shortest text that reads back as the same double.
        return repr(float(value))
    if isinstance(value, str):
        return value
    if isinstance(value, (Sequence, np.ndarray)):
        return " ".join(_value_text(name, v) for v in value)
    raise RunnerError(f"start_values['{name}']: {value!r} is not a number, a bool, a string or a sequence of numbers")


def _sets(start_values: StartValues | None) -> list[str]:
    if start_values is None:
        return []
    if not isinstance(start_values, Mapping):
        raise RunnerError("start_values must be a dict of variable name to value")
    return [f"{name}={_value_text(name, value)}" for name, value in start_values.items()]


def _number(what: str, value: float | None) -> float | None:
    if value is None:
        return None
    try:
        return float(value)
    except (TypeError, ValueError):
        raise RunnerError(f"{what} {value!r} is not a number") from None


def _resolve(
    fmu: str | os.PathLike[str],
    command: str,
    stop_time: float | None,
    output_interval: float | None,
    tolerance: float | None,
    start_values: StartValues | None,
) -> tuple[str, list[tuple[float | None, float | None, float | None]], list[str]]:
    """The FMU's file, the grid sources (the call's, then the model's experiment) and the sets."""
    path, defaults_sets, defaults_grid = _engine.locate(os.fspath(fmu), command)
    grid = (_number("stop_time", stop_time), _number("output_interval", output_interval), _number("tolerance", tolerance))
    return path, [grid, defaults_grid], defaults_sets + _sets(start_values)


def _input_columns(input: Any) -> tuple[list[str], list[float], list[list[float]]]:
    """An input table as fmpy takes it (a structured array whose first field is ``time``, or a
    DataFrame with a ``time`` column) as the engine's (names, time, columns)."""
    if isinstance(input, pd.DataFrame):
        names = [str(c) for c in input.columns]
        if "time" not in names:
            raise RunnerError(f"the input DataFrame has no 'time' column (its columns are {', '.join(names)})")
        columns = {str(c): input[c].to_numpy() for c in input.columns}
    elif isinstance(input, np.ndarray) and input.dtype.names:
        names = list(input.dtype.names)
        if names[0] != "time":
            raise RunnerError(f"the input array's first field must be 'time', not '{names[0]}' (fmpy's convention)")
        columns = {n: input[n] for n in names}
    else:
        raise RunnerError("input must be a pandas DataFrame with a 'time' column or a numpy structured array whose first field is 'time'")
    time = columns.pop("time")
    try:
        values = [np.asarray(column, dtype=np.float64).tolist() for column in columns.values()]
        time_values = np.asarray(time, dtype=np.float64).tolist()
    except (TypeError, ValueError) as e:
        raise RunnerError(f"input: every column must hold numbers or bools: {e}") from None
    return list(columns.keys()), time_values, values


def simulate(
    fmu: str | os.PathLike[str],
    stop_time: float | None = None,
    output_interval: float | None = None,
    tolerance: float | None = None,
    start_values: StartValues | None = None,
    input: pd.DataFrame | np.ndarray | None = None,
    *,
    interface: str | None = None,
    solver: str | None = None,
    fixed_step: float | None = None,
    abs_tolerance: float | None = None,
) -> pd.DataFrame:
    """Simulates the FMU once, as ``runner simulate`` does, and returns its outputs.

    ``stop_time``, ``output_interval`` and ``tolerance`` default to the model's experiment (for a
    model name), else to the FMU's default experiment. ``start_values`` maps variable names to
    values set before initialization (a Real may carry a declared unit: ``{"theta0": "15deg"}``).
    ``input`` drives inputs over time as fmpy takes it: a structured array whose first field is
    ``time`` or a DataFrame with a ``time`` column; continuous Reals are interpolated linearly,
    other values held, and a repeated time is a discontinuity.

    ``interface`` is ``"co-simulation"`` or ``"model-exchange"`` (default: Co-Simulation when
    the FMU offers it). A Model Exchange FMU is integrated by the runner's ``solver`` (as
    ``runner simulate --solver``: ``"dopri5"`` by default; ``"bdf"`` or ``"esdirk"`` for a
    stiff FMU), with ``fixed_step`` (s) for the fixed-step methods and
    ``abs_tolerance`` beside ``tolerance`` for the adaptive ones.

    Returns a DataFrame whose first column is ``time``, then one column per output (array
    elements as ``name[i]``); Reals are float64, Integers int64, Booleans bool, Strings (FMI 2.0
    and 3.0) and Binaries (hexadecimal) str, as ``runner simulate`` writes them. ``df.attrs["ended_early"]`` holds why a run stopped before
    its stop time (else ``None``); ``df.attrs["units"]`` each column's unit (values are in SI),
    ``df.attrs["display_units"]`` the unit :func:`plot` shows a column in, as ``(name, factor,
    offset)`` with ``display = factor * value + offset``, and ``df.attrs["model_name"]`` the model.
    """
    path, grid_sources, sets = _resolve(fmu, "simulate", stop_time, output_interval, tolerance, start_values)
    table = _input_columns(input) if input is not None else None
    model = _engine.Model(path, interface)
    names, kinds, data, rows, texts, ended_early = model.simulate(
        grid_sources, sets, table, solver, _number("fixed_step", fixed_step), _number("abs_tolerance", abs_tolerance)
    )
    matrix = np.frombuffer(data, dtype="<f8").reshape(rows, len(names))
    columns: dict[str, Any] = {}
    for c, (name, kind) in enumerate(zip(names, kinds)):
        if name in texts:
            values = texts[name]
            columns[name] = pd.Series(values, dtype=object) if kind == "text" else pd.Series([int(v) for v in values], dtype=object)
        elif kind == "int":
            columns[name] = matrix[:, c].astype(np.int64)
        elif kind == "bool":
            columns[name] = matrix[:, c] != 0.0
        else:
            columns[name] = matrix[:, c].copy()
    frame = pd.DataFrame(columns)
    frame.attrs["ended_early"] = ended_early
    _attach_units(frame, model.model_name, model.units(names))
    return frame


def _attach_units(frame: pd.DataFrame, model_name: str, units: dict[str, Any]) -> None:
    """Records each column's unit (SI) and display unit in ``frame.attrs``."""
    frame.attrs["model_name"] = model_name
    frame.attrs["units"] = {name: unit for name, (unit, _) in units.items() if unit is not None}
    frame.attrs["display_units"] = {name: tuple(display) for name, (_, display) in units.items() if display is not None}
    if "time" in frame.columns:
        frame.attrs["units"]["time"] = "s"


def _metric_texts(metrics: Mapping[str, str] | Sequence[str]) -> list[str]:
    if isinstance(metrics, str):
        return [metrics]
    if isinstance(metrics, Mapping):
        return [f"{name}={expression}" for name, expression in metrics.items()]
    return [str(m) for m in metrics]


def _ranges(params: Mapping[str, Sequence[float]]) -> list[tuple[str, list[float]]]:
    if not isinstance(params, Mapping):
        raise RunnerError("params must be a dict of parameter name to a sequence of values")
    ranges = []
    for name, values in params.items():
        given: Any = [values] if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__") else values
        try:
            numbers = [float(v) for v in np.asarray(given).ravel()]
        except (TypeError, ValueError):
            raise RunnerError(f"params['{name}']: every value must be a number") from None
        bad = [v for v in numbers if not math.isfinite(v)]
        if bad:
            raise RunnerError(f"params['{name}']: {bad[0]} is not a finite number")
        ranges.append((str(name), numbers))
    return ranges


def _points(ranges: list[tuple[str, list[float]]], start: int = 0, stop: int | None = None) -> dict[str, np.ndarray]:
    """The parameter columns of points ``start..stop``: the cartesian product, the last
    parameter varying fastest (the engine's point order)."""
    sizes = [len(v) for _, v in ranges]
    total = math.prod(sizes)
    index = np.arange(start, total if stop is None else stop, dtype=np.int64)
    columns = {}
    stride = total
    for (name, values), size in zip(ranges, sizes):
        stride //= size
        columns[name] = np.asarray(values, dtype=np.float64)[(index // stride) % size]
    return columns


def _frame(
    ranges: list[tuple[str, list[float]]], metric_names: list[str], metrics: np.ndarray, status: np.ndarray
) -> pd.DataFrame:
    columns: dict[str, Any] = _points(ranges)
    for k, name in enumerate(metric_names):
        columns[name] = metrics[:, k]
    columns["status"] = status
    return pd.DataFrame(columns)


def sweep(
    fmu: str | os.PathLike[str],
    params: Mapping[str, Sequence[float]],
    metrics: Mapping[str, str] | Sequence[str],
    stop_time: float | None = None,
    output_interval: float | None = None,
    tolerance: float | None = None,
    start_values: StartValues | None = None,
    threads: int | None = None,
    client: Client | None = None,
    chunk_size: int | None = None,
    *,
    in_process: bool = False,
    point_timeout: float | None = None,
    worker_memory: int | None = None,
    out: str | os.PathLike[str] | None = None,
    resume: bool = False,
    interface: str | None = None,
    solver: str | None = None,
    fixed_step: float | None = None,
    abs_tolerance: float | None = None,
) -> pd.DataFrame:
    """Runs the FMU at every point of a parameter space, as ``runner sweep`` does.

    ``params`` maps each swept parameter to its values; the points are their cartesian product
    with the last parameter varying fastest (the command line's order). ``metrics`` maps each
    metric's name to its expression over a run (``{"amplitude": "max(x)"}``, the runner's
    ``--metric`` language), or is a list of ``"NAME=EXPR"`` texts. ``stop_time``,
    ``output_interval``, ``tolerance`` and ``start_values`` are as in :func:`simulate` (for a
    model name, its experiment's ``[sweep]`` section gives the defaults). ``interface``,
    ``solver``, ``fixed_step`` and ``abs_tolerance`` are as in :func:`simulate`, as ``runner
    sweep --interface --solver --fixed-step --abs-tolerance`` takes them: a stiff FMU is swept
    through Model Exchange with ``interface="model-exchange", solver="bdf"``.

    Locally the points run in ``threads`` worker processes (default: one per core) of the
    runner's sandbox, as on the command line: a point whose FMU crashes, runs longer than
    ``point_timeout`` seconds, or grows its worker past ``worker_memory`` MiB (default: three
    quarters of the machine's memory, shared) is a row whose ``status`` says so (``crashed:
    SIGSEGV in fmi2DoStep at t = 0.31``), and the sweep goes on. ``in_process=True`` runs them on
    threads of this process instead, for FMUs you trust: a crash then takes the interpreter down.

    With ``out`` (a CSV path) the rows are written as points finish to ``<out>.partial``, beside a
    record of the sweep (``<out>.sweep``), and the file is renamed to ``out`` when complete; a
    sweep that was interrupted (Ctrl-C, a killed process) continues with ``resume=True``, running
    only the points not in the file (the record must match: same FMU, same sweep).

    With ``client`` (a ``dask.distributed.Client``) the points run on its cluster in chunks of
    ``chunk_size`` points (default: sized from the measured cost of a point so that a task takes
    about a second), each chunk in worker processes of the sandbox on its Dask worker (a
    crashing point is a failed row, not a lost Dask worker; ``in_process=True``: on the Dask
    worker's thread); the FMU's bytes go to each worker once, a lost worker's chunks are
    recomputed elsewhere, and the tasks show in Dask's dashboard.

    Returns one row per point, in point order: the parameters, the metrics (NaN where a point
    did not run) and ``status`` (``ok``, or the point's error). ``df.attrs["units"]`` holds the
    parameters' units.
    """
    ranges = _ranges(params)
    metric_texts = _metric_texts(metrics)
    path, grid_sources, sets = _resolve(fmu, "sweep", stop_time, output_interval, tolerance, start_values)
    if in_process and (point_timeout is not None or worker_memory is not None):
        raise RunnerError("point_timeout and worker_memory limit worker processes: drop in_process=True")
    if worker_memory is not None and (not isinstance(worker_memory, int) or worker_memory < 1):
        raise RunnerError(f"worker_memory must be a whole number of MiB, not {worker_memory!r}")
    timeout = _number("point_timeout", point_timeout)
    integrator = (solver, _number("fixed_step", fixed_step), _number("abs_tolerance", abs_tolerance))
    if client is not None:
        if threads is not None:
            raise RunnerError("threads is for a local sweep; on a cluster each Dask worker thread runs one chunk at a time")
        if out is not None or resume:
            raise RunnerError("out and resume are for a local sweep: a sweep on a cluster returns its DataFrame")
        from ._dask import sweep_on_cluster

        frame = sweep_on_cluster(
            client, path, grid_sources, sets, ranges, metric_texts, chunk_size, in_process, timeout, worker_memory,
            interface, integrator,
        )
    else:
        if chunk_size is not None:
            raise RunnerError("chunk_size is for a sweep on a Dask cluster: give client too")
        if threads is None:
            threads = os.cpu_count() or 1
        if not isinstance(threads, int) or threads < 1:
            raise RunnerError(f"threads must be a whole number of at least 1, not {threads!r}")
        # `interface` becomes the one planned (None chosen): every process that loads the FMU uses it.
        interface_defaulted = interface is None
        spec, n, metric_names, interface = _engine.plan_sweep(path, grid_sources, sets, ranges, metric_texts, interface, *integrator)
        if in_process:
            model = _engine.Model(path, interface)

            def run(start: int, on_rows: Any) -> tuple[bytes, list[tuple[int, str]], float]:
                return model.run_points(spec, start, n, threads, on_rows)

        else:
            worker = _worker.command("sweep")

            def run(start: int, on_rows: Any) -> tuple[bytes, list[tuple[int, str]], float]:
                return _engine.run_points_isolated(
                    path, spec, start, n, threads, worker, point_timeout=timeout, worker_memory=worker_memory, on_rows=on_rows,
                    interface=interface,
                )

        if out is None:
            if resume:
                raise RunnerError("resume needs out=FILE.csv: a sweep that only returns its DataFrame keeps no partial file")
            data, failures, _ = run(0, None)
            values = np.frombuffer(data, dtype="<f8").reshape(n, len(metric_names))
            status = np.full(n, "ok", dtype=object)
            for i, message in failures:
                status[i] = message
            frame = _frame(ranges, metric_names, values, status)
        else:
            from ._files import sweep_to_file

            frame = sweep_to_file(os.fspath(out), resume, path, interface, interface_defaulted, spec, n, ranges, metric_names, run)
    units = _engine.column_units(path, [name for name, _ in ranges])
    _attach_units(frame, info(path)["model_name"], units)
    return frame


from ._plot import plot  # noqa: E402
from ._simulation import Simulation  # noqa: E402
