"""Type hints of the Rust extension (src/lib.rs, src/stepping.rs); the public API is in
fmurunner/__init__.py and fmurunner/_simulation.py."""

from collections.abc import Callable, Sequence
from typing import Any, Self, overload

import numpy as np
from numpy.typing import NDArray


GridArgs = tuple[float | None, float | None, float | None]
Points = tuple[bytes, list[tuple[int, str]], float]
OnRows = Callable[[int, bytes, list[tuple[int, str]]], None]
UnitInfo = tuple[str | None, tuple[str, float, float] | None]

MAX_POINTS: int

class RunnerError(Exception):
    """An error of the runner: its message is the one the command line prints."""

def locate(fmu: str, command: str) -> tuple[str, list[str], GridArgs]: ...
def describe(path: str) -> dict[str, Any]: ...
Plan = tuple[str, int, list[str], str]

def plan_sweep(
    path: str,
    grid_sources: list[GridArgs],
    sets: list[str],
    ranges: list[tuple[str, list[float]]],
    metrics: list[str],
    interface: str | None = None,
    solver: str | None = None,
    fixed_step: float | None = None,
    abs_tolerance: float | None = None,
) -> Plan: ...
def reference_values(path: str, values: list[tuple[str, float]]) -> dict[str, float | list[list[float]]]: ...
def column_units(path: str, names: list[str]) -> dict[str, UnitInfo]: ...
def run_points_isolated(
    path: str,
    spec_json: str,
    start: int,
    stop: int,
    workers: int,
    worker: tuple[str, list[str]],
    point_timeout: float | None = None,
    worker_memory: int | None = None,
    on_rows: OnRows | None = None,
    interface: str | None = None,
) -> Points: ...
def serve_worker(kind: str) -> None: ...

# A sweep to a file, through the code `runner sweep --out` uses (see _files.py).
def csv_line(fields: list[str]) -> bytes: ...
def read_finished(path: str, header: list[str], metrics: int, points: list[list[str]]) -> tuple[int, int, list[float], list[tuple[int, str]]]: ...

class SweepLock:
    def __init__(self, out: str) -> None: ...
    @property
    def had_record(self) -> bool: ...
    def write_record(self, text: str) -> None: ...
    def release(self) -> None: ...

class Model:
    """A loaded FMU that runs simulations and sweep points in this process."""

    identifier: str
    model_name: str
    def __init__(self, path: str, interface: str | None = None) -> None: ...
    @staticmethod
    def from_bytes(data: bytes, name: str, interface: str | None = None) -> Model: ...
    def simulate(
        self,
        grid_sources: list[GridArgs],
        sets: list[str],
        input: tuple[list[str], list[float], list[list[float]]] | None = None,
        solver: str | None = None,
        fixed_step: float | None = None,
        abs_tolerance: float | None = None,
    ) -> tuple[list[str], list[str], bytes, int, dict[str, list[str]], str | None]: ...
    def plan_sweep(
        self,
        grid_sources: list[GridArgs],
        sets: list[str],
        ranges: list[tuple[str, list[float]]],
        metrics: list[str],
        solver: str | None = None,
        fixed_step: float | None = None,
        abs_tolerance: float | None = None,
    ) -> Plan: ...
    def run_points(self, spec_json: str, start: int, stop: int, threads: int, on_rows: OnRows | None = None) -> Points: ...
    def units(self, names: list[str]) -> dict[str, UnitInfo]: ...

class StepResult:
    """How a step ended: ``time`` reached; ``complete`` False when an FMI 3.0 FMU returned early
    at an event (handled, at ``time``); ``events`` handled during the step."""

    @property
    def time(self) -> float: ...
    @property
    def complete(self) -> bool: ...
    @property
    def events(self) -> int: ...

class Stepper:
    """One stepped FMU instance, in this process or in a worker process; ``Simulation`` is its
    subclass, and these are its stepping calls."""

    def __new__(
        cls,
        path: str,
        sets: list[str],
        interface: str | None = None,
        start_time: float | None = None,
        stop_time: float | None = None,
        tolerance: float | None = None,
        solver: str | None = None,
        realtime: float | None = None,
        worker: tuple[str, list[str]] | None = None,
        timeout: float | None = None,
        worker_memory: int | None = None,
        name: str | None = None,
    ) -> Self: ...
    @property
    def time(self) -> float:
        """The simulated time reached (s)."""
    @property
    def closed(self) -> bool:
        """True once :meth:`close` was called."""
    @property
    def _pacing(self) -> tuple[int, float] | None: ...
    def step(self, dt: float) -> StepResult:
        """Advances the simulation by one communication step of ``dt`` seconds."""
    def advance_to(self, t: float) -> StepResult:
        """Advances the simulation to time ``t``, through every event on the way."""
    @overload
    def get(self, names: str) -> Any: ...
    @overload
    def get(self, names: Sequence[str]) -> NDArray[np.float64] | list[Any]: ...
    def set(self, name: str, value: Any) -> None:
        """Sets an input or a tunable parameter."""
    def get_state(self) -> bytes:
        """The simulation's state as bytes."""
    def set_state(self, state: bytes) -> None:
        """Goes back to a state :meth:`get_state` returned."""
    def _reset(self, sets: list[str] | None = None) -> None: ...
    def close(self) -> None:
        """Frees the FMU instance (and lets its worker go)."""
