"""The Python package's cost, against baselines measured in the same script:

0. Stepping: one `Simulation.step` of 1 ms plus one `get` of two variables on quarter_car
   (Co-Simulation), against fmpy's `FMU2Slave.doStep` plus `getReal` loop on the same FMU; and
   the same loop with isolated=True (a round trip to the worker per call). Target: at least 10x
   faster per step than fmpy (information: it measures the machine's Python as much as ours).
   Then `reset()` (the same instance, fmi2Reset, initialized again) against a new `Simulation`
   (the FMU unpacked, loaded and instantiated): target reset faster.
   `--stepping` runs only this case (a few seconds).
1. fmurunner.sweep on 2 local threads (in_process=True) against `runner sweep --threads 2`
   (in-process threads, the same work; and the default worker processes), on the Ex. 4 sweep
   widened to 4 values of b_s (396 points). Target: at most 1.05x `runner sweep --in-process`;
   and fmurunner.sweep in its default 2 worker processes within 1.1x of in_process=True.
   `--local` runs only cases 0 and 1 (no Dask; under a minute).
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
METRICS = {"transmissibility": "max(z_s)/max(z_r)", "steady_state": "amplitude(z_s, 5, 2*pi*speed/road_wavelength)/amplitude(z_r, 5, 2*pi*speed/road_wavelength)"}
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


def stepping(repeats, steps=20_000):
    """Seconds per step (+ get of two variables) of fmurunner in process, isolated, and fmpy."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave

    names = ["z_s", "z_u"]

    def ours(isolated):
        with fmurunner.Simulation(FMU, isolated=isolated) as sim:
            for _ in range(100):  # warm: the selection of names, caches
                sim.step(1e-3)
                sim.get(names)
            start = time.perf_counter()
            for _ in range(steps):
                sim.step(1e-3)
                sim.get(names)
            return (time.perf_counter() - start) / steps

    def fmpys():
        md = read_model_description(str(FMU))
        with tempfile.TemporaryDirectory() as unzipped:
            extract(str(FMU), unzipdir=unzipped)
            vrs = [v.valueReference for v in md.modelVariables if v.name in names]
            fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                            instanceName="fmpy")
            fmu.instantiate()
            fmu.setupExperiment(tolerance=float(md.defaultExperiment.tolerance), startTime=0.0)
            fmu.enterInitializationMode()
            fmu.exitInitializationMode()
            t = 0.0
            for _ in range(100):
                fmu.doStep(t, 1e-3)
                t += 1e-3
                fmu.getReal(vrs)
            start = time.perf_counter()
            for _ in range(steps):
                fmu.doStep(t, 1e-3)
                t += 1e-3
                fmu.getReal(vrs)
            seconds = (time.perf_counter() - start) / steps
            fmu.terminate()
            fmu.freeInstance()
            return seconds

    best = {}
    for _ in range(repeats):
        for name, f in [("fmurunner", lambda: ours(False)), ("fmurunner isolated", lambda: ours(True)), ("fmpy", fmpys)]:
            best[name] = min(best.get(name, float("inf")), f())
    print(f"step(1 ms) + get of 2 variables, quarter_car Co-Simulation, fastest of {repeats} x {steps} steps:")
    for name, seconds in best.items():
        print(f"  {name:<20} {seconds * 1e6:8.2f} us per step")
    ratio = best["fmpy"] / best["fmurunner"]
    print(f"fmpy FMU2Slave / fmurunner.Simulation: {ratio:.1f}x faster per step (target >= 10x, information)")
    print(f"isolated / in process: {best['fmurunner isolated'] / best['fmurunner']:.1f}x per step")

    def resets(n=200):
        with fmurunner.Simulation(FMU) as sim:
            start = time.perf_counter()
            for _ in range(n):
                sim.step(1e-3)
                sim.reset()
            return (time.perf_counter() - start) / n

    def new_simulations(n=20):
        start = time.perf_counter()
        for _ in range(n):
            with fmurunner.Simulation(FMU) as sim:
                sim.step(1e-3)
        return (time.perf_counter() - start) / n

    again = {}
    for _ in range(repeats):
        for name, f in [("reset()", resets), ("new Simulation", new_simulations)]:
            again[name] = min(again.get(name, float("inf")), f())
    for name, seconds in again.items():
        print(f"  {name:<20} {seconds * 1e6:8.1f} us (with one step)")
    print(f"new Simulation / reset(): {again['new Simulation'] / again['reset()']:.1f}x (target > 1x)\n")
    return again["reset()"] < again["new Simulation"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument("--stepping", action="store_true", help="run only the stepping case")
    parser.add_argument("--local", action="store_true", help="run only the stepping case and the local sweeps (no Dask)")
    args = parser.parse_args()
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    resets_faster = stepping(args.repeats)
    if args.stepping:
        return 0 if resets_faster else 1
    wide = {"speed": SPEEDS, "b_s": [800.0, 1100.0, 1300.0, 1600.0]}
    thousand = {"speed": SPEEDS + [50.5 + 0.5 * i for i in range(1)], "k_s": [15000.0 + 1000.0 * i for i in range(10)]}
    best = {}

    def keep(name, seconds):
        best[name] = min(best.get(name, float("inf")), seconds)

    def local_round():
        keep("runner sweep --in-process", timed(lambda: cli("--in-process")))
        keep("runner sweep (worker processes)", timed(lambda: cli()))
        keep("fmurunner.sweep, 2 threads", timed(lambda: fmurunner.sweep(FMU, wide, METRICS, threads=2, in_process=True, **GRID)))
        keep("fmurunner.sweep, 2 worker processes", timed(lambda: fmurunner.sweep(FMU, wide, METRICS, threads=2, **GRID)))

    if args.local:
        for _ in range(args.repeats):
            local_round()
        return 1 if report_local(args, best) or not resets_faster else 0

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            client.wait_for_workers(2)
            # Warm the workers (their import of fmurunner, their first load of the FMU).
            fmurunner.sweep(FMU, {"speed": [4.0, 5.0]}, METRICS, client=client, stop_time=0.1)
            cheap = {"speed": [1.0 + 0.01 * i for i in range(400)]}
            for _ in range(args.repeats):
                local_round()
                keep("1,000 points, 2 local threads",
                     timed(lambda: fmurunner.sweep(FMU, thousand, METRICS, threads=2, in_process=True, **GRID)))
                keep("1,000 points, Dask 2 x 1", timed(lambda: fmurunner.sweep(FMU, thousand, METRICS, client=client, **GRID)))
                keep("400 cheap points, 2 local threads",
                     timed(lambda: fmurunner.sweep(FMU, cheap, {"p": "max(z_s)"}, threads=2, in_process=True, stop_time=0.05,
                                                   output_interval=0.01)))
                cpu = time.process_time()
                keep("400 cheap points, Dask, 400 tasks",
                     timed(lambda: fmurunner.sweep(FMU, cheap, {"p": "max(z_s)"}, client=client, chunk_size=1, stop_time=0.05,
                                                   output_interval=0.01)))
                # The scheduler runs in this process (LocalCluster), beside the client.
                keep("client + scheduler CPU, 400 tasks", time.process_time() - cpu)
    local_missed = report_local(args, best)
    dask_ratio = best["1,000 points, Dask 2 x 1"] / best["1,000 points, 2 local threads"]
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
    return 1 if local_missed or dask_ratio > 1.3 or not resets_faster else 0


def report_local(args, best):
    """Prints the rounds' fastest times and the local sweeps' ratios; 1 if a target is missed."""
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"fastest of {args.repeats} interleaved rounds, release build\n")
    for name, seconds in best.items():
        print(f"  {name:<36} {seconds:8.3f} s")
    local_ratio = best["fmurunner.sweep, 2 threads"] / best["runner sweep --in-process"]
    isolated_ratio = best["fmurunner.sweep, 2 worker processes"] / best["fmurunner.sweep, 2 threads"]
    print(f"\nfmurunner.sweep / runner sweep --in-process (396 points, 2 threads): {local_ratio:.3f}x (target <= 1.05x)")
    print(f"fmurunner.sweep / runner sweep, worker processes:                 "
          f"{best['fmurunner.sweep, 2 threads'] / best['runner sweep (worker processes)']:.3f}x")
    print(f"fmurunner.sweep, 2 worker processes / in_process=True:             {isolated_ratio:.3f}x (target <= 1.1x)")
    return 1 if local_ratio > 1.05 or isolated_ratio > 1.1 else 0


if __name__ == "__main__":
    sys.exit(main())
