"""fmurunner.sweep on a Dask LocalCluster of 2 worker processes x 1 thread: the same table as
the CLI and as the local run, a worker SIGKILLed mid-sweep costing nothing, a failed point as a
row, and client memory flat in the number of points."""

import io
import sys
import os
import signal
import threading
import time
import tracemalloc

import distributed
import numpy as np
import pandas as pd
import pytest

import fmurunner
from fmurunner import _dask
from fmurunner_helpers import (EX4_METRICS, EX4_SPEEDS, STIFF_FMU, STIFF_SWEEP, STIFF_SWEEP_CLI, assert_same_as_cli,
                               runner_sweep_csv)


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    """A LocalCluster of 2 worker processes x 1 thread, as CI's 2 cores allow (no conftest.py
    here: tests/fmpy imports its own as `conftest`). Its workers unpack FMUs in a directory of
    the test run's (TMPDIR, which they inherit): the workers the tests SIGKILL cannot remove
    their copies, which would otherwise stay in /tmp or /dev/shm."""
    scratch = tmp_path_factory.mktemp("dask-workers")
    before = os.environ.get("TMPDIR")
    os.environ["TMPDIR"] = str(scratch)
    try:
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            with distributed.Client(cluster) as c:
                c.wait_for_workers(2)
                yield c
    finally:
        if before is None:
            del os.environ["TMPDIR"]
        else:
            os.environ["TMPDIR"] = before


def test_the_ex4_sweep_on_the_cluster_is_the_clis_bit_for_bit(client, tmp_path):
    frame = fmurunner.sweep("quarter_car", {"speed": EX4_SPEEDS}, EX4_METRICS, client=client)
    assert_same_as_cli(frame, runner_sweep_csv(tmp_path, "quarter_car"))


def test_chunks_of_any_size_give_the_local_table(client):
    params = {"speed": [2.0, 4.0, 8.0, 16.0], "k_s": [15000.0, 18000.0, 21000.0]}
    kwargs = dict(stop_time=1.0, output_interval=0.01, start_values={"b_s": 1100.0})
    local = fmurunner.sweep("quarter_car", params, ["peak=max(z_s)"], threads=2, **kwargs)
    for chunk_size in [1, 5, 12, 100]:
        remote = fmurunner.sweep("quarter_car", params, ["peak=max(z_s)"], client=client, chunk_size=chunk_size, **kwargs)
        pd.testing.assert_frame_equal(remote, local)


def test_a_stiff_sweep_with_bdf_on_the_cluster_is_the_clis_bit_for_bit(client, tmp_path):
    """The interface and the solver reach the Dask workers, in their sandbox workers and on their
    own threads (in_process): the same bits as `runner sweep --interface model-exchange --solver
    bdf` (see test_package's local test of the same sweep, which checks the comparison can fail)."""
    cli = runner_sweep_csv(tmp_path, str(STIFF_FMU), *STIFF_SWEEP_CLI)
    for in_process in (False, True):
        frame = fmurunner.sweep(STIFF_FMU, client=client, chunk_size=2, in_process=in_process, **STIFF_SWEEP)
        assert_same_as_cli(frame, cli)


def test_a_failed_point_is_a_row_not_a_failed_task(client):
    frame = fmurunner.sweep("quarter_car", {"m_s": [200.0, -1.0, 250.0, 300.0]}, {"peak": "max(z_s)"}, stop_time=1.0,
                            client=client, chunk_size=2)
    assert list(frame["status"][[0, 2, 3]]) == ["ok", "ok", "ok"]
    assert "m_s" in frame["status"][1] and frame["status"][1] != "ok"
    assert np.isnan(frame["peak"][1]) and (frame["peak"][[0, 2, 3]] > 0).all()


def test_progress_shows_on_a_terminal_and_ends_at_every_point(client, monkeypatch):
    """The client's progress bar: drawn when stderr is a terminal, counting points as chunks
    arrive, and ending at exactly the number of points (a chunk counted twice or missed would
    end elsewhere)."""

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    fmurunner.sweep("quarter_car", {"speed": [5.0, 10.0, 15.0, 20.0, 25.0]}, {"peak": "max(z_s)"}, stop_time=0.5,
                    client=client, chunk_size=2)
    drawn = terminal.getvalue()
    assert drawn.endswith("\n") and "5/5 points" in drawn.rsplit("\r", 1)[-1], drawn


def test_errors_are_raised_before_anything_runs_on_the_cluster(client):
    with pytest.raises(fmurunner.RunnerError, match="did you mean 'speed'"):
        fmurunner.sweep("quarter_car", {"sped": [1.0]}, {"p": "max(z_s)"}, client=client)
    with pytest.raises(fmurunner.RunnerError, match="chunk_size"):
        fmurunner.sweep("quarter_car", {"speed": [1.0]}, {"p": "max(z_s)"}, client=client, chunk_size=0)


def test_an_error_on_a_worker_reaches_the_client_as_the_runners_error(client):
    """RunnerError pickles (it is fmurunner.RunnerError), so a chunk whose FMU cannot be loaded
    on a worker raises it on the client with the runner's message."""
    path, grid, sets = fmurunner._resolve("quarter_car", "sweep", None, None, None, None)
    spec, _, _, _ = fmurunner._engine.plan_sweep(path, grid, sets, [("speed", [1.0])], ["p=max(z_s)"])
    future = client.submit(_dask._run_chunk, b"not a zip archive", "0" * 64, "broken.fmu", spec, 0, 1)
    with pytest.raises(fmurunner.RunnerError, match="broken.fmu"):
        future.result()


def _sweep_memory(client, points: int) -> tuple[pd.DataFrame, int]:
    """A cheap sweep of `points` points (5 steps each) and the client's peak Python memory
    (tracemalloc: numpy's buffers included) above what it held before, less the result's size."""
    params = {"speed": np.linspace(1.0, 50.0, points // 10), "k_s": np.linspace(15000.0, 21000.0, 10)}
    metrics = {f"m{k}": f"max(z_s)*{k}" for k in range(16)}
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracemalloc.reset_peak()
        frame = fmurunner.sweep("quarter_car", params, metrics, stop_time=0.05, output_interval=0.01, client=client,
                                chunk_size=points // 10)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    held = int(frame.memory_usage(index=True, deep=True).sum())
    assert len(frame) == points and (frame["status"] == "ok").all()
    return frame, peak - before - held


def test_client_memory_stays_flat_with_the_number_of_points(client):
    """10,000 points against 1,000, both in 10 chunks: the memory beyond the result itself
    (1.5 MB of metrics at 10,000 points) grows by less than a quarter of the result. Holding
    every chunk's table until the end, or building the result from per-chunk DataFrames,
    would add at least the result's size once more. The chunks are as many in both sweeps
    because the scheduler runs in this process: its bookkeeping of each task (about 40 kB at
    the peak, Dask's, bounded) would otherwise count as the client's memory; a constant 12 MB
    peak of the FMU's hashed scatter used to hide it."""
    _, small = _sweep_memory(client, 1_000)
    frame, large = _sweep_memory(client, 10_000)
    result = int(frame.memory_usage(index=True, deep=True).sum())
    print(f"client memory beyond the result: {small / 1e6:.2f} MB at 1,000 points, {large / 1e6:.2f} MB at 10,000 "
          f"(result {result / 1e6:.2f} MB)")
    assert large - small < 0.25 * result, (small, large, result)


@pytest.mark.parametrize("victims", ["one", "all"])
def test_a_worker_killed_mid_sweep_costs_nothing(client, victims):
    """SIGKILL one worker while it runs a chunk, after other chunks have finished: Dask
    recomputes its chunks on the other worker (and on its restarted replacement), and the
    result has every point once, identical to the local run. With `all`, every worker is
    killed at once, so no copy of the FMU's scattered bytes is left on the cluster: the chunks
    come back cancelled, and the sweep scatters the bytes again and runs them again (it used to
    fail with "cannot unpack non-iterable FutureCancelledError object")."""
    params = {"speed": EX4_SPEEDS, "k_s": [15000.0, 18000.0, 21000.0, 24000.0]}
    kwargs = dict(stop_time=4.0, tolerance=1e-9, output_interval=1e-3)
    local = fmurunner.sweep("quarter_car", params, EX4_METRICS, threads=2, **kwargs)
    pids = client.run(os.getpid)
    victim = sorted(pids)[0]
    done = {}

    def run():
        try:
            done["frame"] = fmurunner.sweep("quarter_car", params, EX4_METRICS, client=client, chunk_size=6, **kwargs)
        except BaseException as e:  # reported by the assertion below
            done["error"] = e

    def chunks_finished() -> int:
        """Sweep tasks that reached memory on a worker so far (a cumulative count)."""
        return client.run_on_scheduler(lambda dask_scheduler: sum(
            tp.state_counts["memory"] for name, tp in dask_scheduler.task_prefixes.items() if name == "fmurunner-sweep"))

    before = chunks_finished()
    sweeping = threading.Thread(target=run)
    sweeping.start()
    deadline = time.monotonic() + 120
    killed = False
    while sweeping.is_alive() and time.monotonic() < deadline:
        if chunks_finished() - before >= 4 and client.processing().get(victim):
            for worker in sorted(pids) if victims == "all" else [victim]:
                os.kill(pids[worker], signal.SIGKILL)
            killed = True
            break
        time.sleep(0.05)
    assert killed, "the sweep ended before a worker could be killed mid-sweep"
    assert sweeping.is_alive(), "the kill came after the sweep ended"
    sweeping.join(timeout=300)
    assert "error" not in done, done.get("error")
    pd.testing.assert_frame_equal(done["frame"], local)
    # The nanny starts a replacement: the cluster is back to 2 workers for the other tests.
    client.wait_for_workers(2, timeout=60)
    restarted = set(client.run(os.getpid).values())
    assert restarted.isdisjoint(pids.values()) if victims == "all" else restarted != set(pids.values())


def test_a_crashing_point_is_a_failed_row_not_a_killed_worker(client, tmp_path):
    """faulty.c's fault 1 segfaults in fmi2DoStep at t = 0.31: on the cluster the chunk runs its
    points in a sandbox worker process of its Dask worker, so the crash is that point's row, its
    chunk's other points are computed, and no Dask worker dies (no KilledWorker after retries).
    With in_process=True the same crash would take the Dask worker down."""
    from fmurunner_helpers import faulty_fmu

    fmu = faulty_fmu(tmp_path)
    workers = set(client.scheduler_info()["workers"])
    frame = fmurunner.sweep(fmu, {"fault": [0, 1, 0, 0, 1, 0]}, {"x_end": "final(x)"}, stop_time=1.0, client=client,
                            chunk_size=3)
    status = list(frame["status"])
    assert [s == "ok" for s in status] == [True, False, True, True, False, True], status
    assert all("crashed: SIGSEGV in fmi2DoStep at t = 0.31" in status[i] for i in (1, 4)), status
    assert np.allclose(frame["x_end"][[0, 2, 3, 5]], np.exp(-1.0), rtol=1e-12, atol=0)
    assert set(client.scheduler_info()["workers"]) == workers, "the same Dask workers, none restarted"
