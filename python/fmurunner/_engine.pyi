"""Type hints of the Rust extension (src/lib.rs); the public API is in fmurunner/__init__.py."""

from typing import Any

GridArgs = tuple[float | None, float | None, float | None]

MAX_POINTS: int

class RunnerError(Exception):
    """An error of the runner: its message is the one the command line prints."""

def locate(fmu: str, command: str) -> tuple[str, list[str], GridArgs]: ...
def describe(path: str) -> dict[str, Any]: ...
def plan_sweep(
    path: str, grid_sources: list[GridArgs], sets: list[str], ranges: list[tuple[str, list[float]]], metrics: list[str]
) -> tuple[str, int, list[str]]: ...
def reference_values(path: str, values: list[tuple[str, float]]) -> dict[str, float | list[list[float]]]: ...

class Model:
    """A loaded FMU that runs simulations and sweep points in this process."""

    identifier: str
    def __init__(self, path: str) -> None: ...
    @staticmethod
    def from_bytes(data: bytes, name: str) -> Model: ...
    def simulate(
        self,
        grid_sources: list[GridArgs],
        sets: list[str],
        input: tuple[list[str], list[float], list[list[float]]] | None = None,
    ) -> tuple[list[str], list[str], bytes, int, dict[str, list[str]], str | None]: ...
    def plan_sweep(
        self, grid_sources: list[GridArgs], sets: list[str], ranges: list[tuple[str, list[float]]], metrics: list[str]
    ) -> tuple[str, int, list[str]]: ...
    def run_points(self, spec_json: str, start: int, stop: int, threads: int) -> tuple[bytes, list[tuple[int, str]], float]: ...
