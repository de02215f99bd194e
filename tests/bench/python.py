"""The Python package's cost, against baselines measured in the same script:

1. fmurunner.sweep on 2 local threads against `runner sweep --threads 2` (in-process threads,
   the same work; and the default worker processes), on the Ex. 4 sweep widened to 4 values of
   b_s (396 points). Target: at most 1.05x `runner sweep --in-process`.
2. fmurunner.sweep on a Dask LocalCluster of 2 worker processes x 1 thread against 2 local
   threads, on 1,000 Ex. 4 points (the FMU's scatter included). Target: at most 1.3x.
3. Dask's cost per task: 400 tasks of one point of 5 steps each (chunk_size=1), from which the
   throughput a cluster of N worker threads reaches and where it stops scaling.

The machine is shared: the cases run in interleaved rounds, each keeps its fastest, and the load
average is printed before and after. Exit code 1 if a target is missed.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import distributed

import fmurunner

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "target/release/runner"
FMU = ROOT / "target/fmu/quarter_car.fmu"
SPEEDS = [1.0 + 0.5 * i for i in range(99)]
METRICS = {"transmissibility": "max(z_s)/max(z_r)", "steady_state": "max(z_s, 5)/max(z_r, 5)"}
GRID = {"tolerance": 1e-9, "output_interval": 1e-3}


def timed(f):
    start = time.perf_counter()
    f()
    return time.perf_counter() - start


def cli(*args):
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [RUNNER, "sweep", FMU, "--param", "speed=1:50:0.5", "--param", "b_s=800,1100,1300,1600", "--metric",
               f"transmissibility={METRICS['transmissibility']}", "--metric", f"steady_state={METRICS['steady_state']}",
               "--tolerance", "1e-9", "--output-interval", "1e-3", "--threads", "2", "--out", Path(tmp) / "s.csv", *args]
        subprocess.run(cmd, check=True, capture_output=True)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds (default 3)")
    args = parser.parse_args()
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    wide = {"speed": SPEEDS, "b_s": [800.0, 1100.0, 1300.0, 1600.0]}
    thousand = {"speed": SPEEDS + [50.5 + 0.5 * i for i in range(1)], "k_s": [15000.0 + 1000.0 * i for i in range(10)]}
    best = {}

    def keep(name, seconds):
        best[name] = min(best.get(name, float("inf")), seconds)

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            client.wait_for_workers(2)
            # Warm the workers (their import of fmurunner, their first load of the FMU).
            fmurunner.sweep(FMU, {"speed": [4.0, 5.0]}, METRICS, client=client, stop_time=0.1)
            cheap = {"speed": [1.0 + 0.01 * i for i in range(400)]}
            for _ in range(args.repeats):
                keep("runner sweep --in-process", timed(lambda: cli("--in-process")))
                keep("runner sweep (worker processes)", timed(lambda: cli()))
                keep("fmurunner.sweep, 2 threads", timed(lambda: fmurunner.sweep(FMU, wide, METRICS, threads=2, **GRID)))
                keep("1,000 points, 2 local threads", timed(lambda: fmurunner.sweep(FMU, thousand, METRICS, threads=2, **GRID)))
                keep("1,000 points, Dask 2 x 1", timed(lambda: fmurunner.sweep(FMU, thousand, METRICS, client=client, **GRID)))
                keep("400 cheap points, 2 local threads",
                     timed(lambda: fmurunner.sweep(FMU, cheap, {"p": "max(z_s)"}, threads=2, stop_time=0.05, output_interval=0.01)))
                cpu = time.process_time()
                keep("400 cheap points, Dask, 400 tasks",
                     timed(lambda: fmurunner.sweep(FMU, cheap, {"p": "max(z_s)"}, client=client, chunk_size=1, stop_time=0.05,
                                                   output_interval=0.01)))
                # The scheduler runs in this process (LocalCluster), beside the client.
                keep("client + scheduler CPU, 400 tasks", time.process_time() - cpu)
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"fastest of {args.repeats} interleaved rounds, release build\n")
    for name, seconds in best.items():
        print(f"  {name:<36} {seconds:8.3f} s")
    local_ratio = best["fmurunner.sweep, 2 threads"] / best["runner sweep --in-process"]
    dask_ratio = best["1,000 points, Dask 2 x 1"] / best["1,000 points, 2 local threads"]
    print(f"\nfmurunner.sweep / runner sweep --in-process (396 points, 2 threads): {local_ratio:.3f}x (target <= 1.05x)")
    print(f"fmurunner.sweep / runner sweep, worker processes:                 "
          f"{best['fmurunner.sweep, 2 threads'] / best['runner sweep (worker processes)']:.3f}x")
    print(f"Dask 2 workers x 1 thread / 2 local threads (1,000 points):         {dask_ratio:.3f}x (target <= 1.3x)")
    # Per task: the wall time of 400 one-point tasks on 2 threads, less the same points' work.
    per_task = (best["400 cheap points, Dask, 400 tasks"] - best["400 cheap points, 2 local threads"]) * 2 / 400
    point = best["1,000 points, 2 local threads"] * 2 / 1000
    print(f"\nDask's cost per task: {per_task * 1e3:.2f} ms of a worker thread's time (scheduler, transfer, "
          f"deserialization), against {point * 1e3:.2f} ms per Ex. 4 point")
    task = 1.0
    print(f"with 1 s tasks ({task / point:.0f} Ex. 4 points each) that is {per_task / task:.2%} per task: N worker threads "
          f"reach N x {1 / (point + per_task * point / task):.0f} points/s")
    # The serial part is the scheduler and the client, which handle every task: their CPU time
    # per task bounds the whole cluster at 1 / serial tasks/s, whatever the number of workers.
    serial = best["client + scheduler CPU, 400 tasks"] / 400
    limit = task / serial
    print(f"client + scheduler CPU per task: {serial * 1e3:.2f} ms, so at most {1 / serial:.0f} tasks/s: it stops scaling "
          f"at about {limit:.0f} worker threads with 1 s tasks ({limit / point:.0f} points/s); longer tasks "
          f"(chunk_size) move that limit up in proportion")
    missed = local_ratio > 1.05 or dask_ratio > 1.3
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
