"""Stepping an FMU from Python's own loop: :class:`Simulation` (see its docstring)."""

from __future__ import annotations

import os
from collections.abc import Mapping
from types import TracebackType
from typing import Any

from . import _engine, _worker
from ._engine import RunnerError


class Simulation(_engine.Stepper):
    """One FMU instance stepped from your own loop: a controller, a reinforcement-learning
    environment, hardware in the loop.

    ``fmu`` is a path to any ``.fmu`` (FMI 2.0 or 3.0, Co-Simulation or Model Exchange) or, inside
    this repository, one of its model names (its experiment's ``[simulate]`` settings apply, as on
    the command line). The instance is created and initialized at once, at ``start_time`` (default:
    the FMU's default experiment's start, else 0), with ``start_values`` (variable name to value;
    a Real may carry a declared unit: ``{"theta0": "15deg"}``). ``interface`` chooses
    ``"co-simulation"`` or ``"model-exchange"`` (default: Co-Simulation when offered);
    ``tolerance`` is the relative tolerance; ``solver`` the runner's integrator for Model
    Exchange (``"dopri5"``, ``"rk4"``, ... as ``runner simulate --solver``). ``stop_time``, when
    given, is the FMU's stop time, past which no step goes (default: none).

    ``realtime=1.0`` paces the steps so that simulated time follows the wall clock (2.0: twice as
    fast); a step that ends later than the wall clock allows is an overrun, counted in
    :attr:`overruns` (the worst in :attr:`lateness`), and the steps after it run without sleeping
    until they have caught up.

    Where the FMU runs:

    - by default **in this process** (fast: a step and a read cost about a microsecond plus the
      FMU's own work). The FMU's code runs inside the interpreter: an FMU that crashes takes the
      interpreter with it, one that hangs hangs it. For FMUs you trust.
    - with ``isolated=True`` **in a worker process** of the runner's sandbox (safe: every call is
      a round trip of some tens of microseconds). A crash, a hang past ``timeout`` seconds per
      call, or memory past ``worker_memory`` MiB costs the worker only: the call raises
      :class:`RunnerError` saying what happened and where (``crashed: SIGSEGV in fmi2DoStep at
      t = 0.31``), and :meth:`reset` starts a fresh worker. For FMUs you do not trust.

    Every misuse raises :class:`RunnerError` with a clear message and never crashes the
    interpreter: a call after :meth:`close`, a name that is not a variable (with the nearest
    names), a value of the wrong type, a variable that cannot be set while stepping, a step
    past the stop time, a call the FMU refuses (with its message; the instance is then failed,
    as the FMI standard has it, and only :meth:`reset` is allowed). The FMU ending the
    simulation raises :class:`RunnerError` with its reason; its last values can still be read.

    A ``Simulation`` takes one call at a time: a second thread calling while one call runs gets
    a :class:`RunnerError`.

    The stepping calls (:meth:`step`, :meth:`advance_to`, :meth:`get`, :meth:`set`,
    :attr:`time`) are the runner's own, with no Python function in between. In this process a
    step releases the GIL for other threads unless the steps take less than 50 us (releasing it
    would cost as much as such a step; one step in 8 is timed).

    Example::

        with fmurunner.Simulation("quarter_car") as sim:
            while sim.time < 1.0:
                sim.set("z_r_dot_ext", 0.1)
                sim.step(1e-3)
                z_s, z_u = sim.get(["z_s", "z_u"])
    """

    # No instance dict: a method call then finds the engine's method at once.
    __slots__ = ("_path", "_defaults_sets", "_isolated")
    _path: str
    _defaults_sets: list[str]
    _isolated: bool

    def __new__(
        cls,
        fmu: str | os.PathLike[str],
        start_values: Mapping[str, Any] | None = None,
        interface: str | None = None,
        tolerance: float | None = None,
        solver: str | None = None,
        *,
        start_time: float | None = None,
        stop_time: float | None = None,
        realtime: float | None = None,
        isolated: bool = False,
        timeout: float | None = None,
        worker_memory: int | None = None,
    ) -> Simulation:
        from . import _number, _sets

        path, defaults_sets, defaults_grid = _engine.locate(os.fspath(fmu), "simulate")
        if tolerance is None:
            tolerance = defaults_grid[2]
        worker = _worker.command("step") if isolated else None
        if worker_memory is not None and (not isinstance(worker_memory, int) or worker_memory < 1):
            raise RunnerError(f"worker_memory must be a whole number of MiB, not {worker_memory!r}")
        self = super().__new__(
            cls,
            path,
            defaults_sets + _sets(start_values),
            interface=interface,
            start_time=_number("start_time", start_time),
            stop_time=_number("stop_time", stop_time),
            tolerance=_number("tolerance", tolerance),
            solver=solver,
            realtime=_number("realtime", realtime),
            worker=worker,
            timeout=_number("timeout", timeout),
            worker_memory=worker_memory,
        )
        self._path = path
        self._defaults_sets = defaults_sets
        self._isolated = isolated
        return self

    @property
    def isolated(self) -> bool:
        """True when the FMU runs in a worker process."""
        return self._isolated

    @property
    def fmu(self) -> str:
        """The ``.fmu`` file simulated."""
        return self._path

    def reset(self, start_values: Mapping[str, Any] | None = None) -> None:
        """Back to the start time, initialized again, reusing the FMU instance (``fmi2Reset``,
        ``fmi3Reset``: faster than a new ``Simulation``; an FMU without them, or one that refuses,
        gets a new instance instead, as after a failed call). ``start_values``, when given, replace
        the ones the simulation was created with. After a worker was lost (``isolated=True``), a
        fresh worker starts."""
        from . import _sets

        sets = None if start_values is None else self._defaults_sets + _sets(start_values)
        self._reset(sets)

    @property
    def overruns(self) -> int:
        """With ``realtime``: the steps that ended later than the wall clock allowed (0 without)."""
        pacing = self._pacing
        return 0 if pacing is None else pacing[0]

    @property
    def lateness(self) -> float:
        """With ``realtime``: the worst lateness of an overrun, in seconds of wall-clock time."""
        pacing = self._pacing
        return 0.0 if pacing is None else pacing[1]

    def __enter__(self) -> Simulation:
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, traceback: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        where = "closed" if self.closed else f"t = {self.time!r}"
        return f"Simulation({os.path.basename(self._path)!r}, {where}{', isolated' if self.isolated else ''})"
