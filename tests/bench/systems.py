"""The co-simulation master's overhead per communication step on systems/quarter_car_road (the
road FMU driving the quarter car through z_r_dot_ext, 1 ms steps), for the runner's Jacobi master
and for libcosim's fixed-step master on the same .ssp, against the two FMUs' own step time,
all measured in this script.

Each way's cost per step is the CPU time of a run to 30 s less that of a run to 10 s, divided by
the steps between: process start, loading, instantiation and initialization cancel, and CPU time
(not wall time) does not count the waits for a core on a shared machine. The
FMUs' own step time is that of each FMU run alone by the runner (in-process, one thread): the
road as it is, the car with `--input-file` holding the road's rate at every step (so it does the
same work as in the system: a new input every step). The master's overhead is what the system
costs beyond the two FMUs alone; it includes passing the value (fmi2GetReal, fmi2SetReal),
reading both FMUs' outputs, the loop and the metric, and is set against the FMUs' own time.
Target: the runner's overhead is at most 10 % of it. Ways run in interleaved rounds; each
keeps its fastest. Exit code 1 if the target is missed.
"""

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "target/release/runner"
SSP = ROOT / "target/ssp/quarter_car_road.ssp"
CAR = ROOT / "target/fmu/quarter_car.fmu"
ROAD = ROOT / "target/fmu/road.fmu"
POINTS = 20
SPEED = 30.0
H = 1e-3
# The longer run (s); the shorter is a third of it.
LONG = 30.0


def cpu(cmd):
    """CPU seconds (user and system, all threads) of `cmd`, which must succeed: on a shared
    machine the wall time mostly measures the wait for a core."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}):\n{proc.stderr.decode()}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def libcosim(stop):
    """CPU seconds (this process, all threads) libcosim takes to step the system from 0 to
    `stop`, POINTS times (creation and initialization excluded: the first step initializes, and
    is taken before the clock starts). libcosim counts time in nanoseconds."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    log_output_level(CosimLogLevel.ERROR)
    total = 0.0
    for _ in range(POINTS):
        execution = CosimExecution.from_ssp_file(str(SSP))
        execution.step(1)
        start = time.process_time()
        assert execution.simulate_until(int(stop * 1e9))
        total += time.process_time() - start
        del execution
    return total


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=5, help="interleaved rounds (default 5)")
    args = parser.parse_args()
    for path in (SSP, CAR, ROAD):
        if not path.is_file():
            sys.exit(f"{path} is missing: run `runner build` first")
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    with tempfile.TemporaryDirectory() as tmp:
        rate = Path(tmp) / "rate.csv"
        w = 2 * math.pi * SPEED / 3.0
        with open(rate, "w") as f:
            f.write("time,z_r_dot_ext\n")
            for k in range(int(LONG / H) + 1):
                f.write(f"{k * H!r},{0.04 * w * math.cos(w * k * H)!r}\n")
        speeds = ",".join([str(SPEED)] * POINTS)
        common = ["--threads", "1", "--output-interval", str(H), "--out", str(Path(tmp) / "o.csv")]
        ways = {
            "system, runner (Jacobi)": lambda stop: cpu([RUNNER, "sweep", SSP, "--param", f"road.speed={speeds}",
                                                          "--metric", "m=max(car.z_s)", "--stop-time", str(stop), *common]),
            "quarter_car alone, runner": lambda stop: cpu([RUNNER, "sweep", CAR, "--param", f"speed={','.join(['0'] * POINTS)}",
                                                            "--input-file", rate, "--in-process", "--metric", "m=max(z_s)",
                                                            "--stop-time", str(stop), *common]),
            "quarter_car alone, input held constant, runner": lambda stop: cpu([RUNNER, "sweep", CAR, "--param", f"speed={','.join(['0'] * POINTS)}",
                                                                                "--in-process", "--metric", "m=max(z_s)",
                                                                                "--stop-time", str(stop), *common]),
            "road alone, runner": lambda stop: cpu([RUNNER, "sweep", ROAD, "--param", f"speed={speeds}", "--in-process",
                                                     "--metric", "m=max(z_r)", "--stop-time", str(stop), *common]),
            "system, libcosim": libcosim,
        }
        best = {name: [math.inf, math.inf] for name in ways}
        for _ in range(args.repeats):
            for name, run in ways.items():
                for k, stop in enumerate((LONG / 3, LONG)):
                    best[name][k] = min(best[name][k], run(stop))
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    steps = POINTS * (LONG - LONG / 3) / H
    per_step = {name: (t20 - t10) / steps * 1e9 for name, (t10, t20) in best.items()}
    own = per_step["quarter_car alone, runner"] + per_step["road alone, runner"]
    print(f"fastest of {args.repeats} interleaved rounds; CPU ns per communication step (runs to {LONG:g} s less runs to {LONG / 3:g} s, {POINTS} points each)\n")
    print("| way | ns per step | x the two FMUs alone |")
    print("|---|---|---|")
    for name, ns in per_step.items():
        print(f"| {name} | {ns:.0f} | {ns / own:.3f} |")
    runner_overhead = per_step["system, runner (Jacobi)"] - own
    libcosim_overhead = per_step["system, libcosim"] - own
    # Without the input table the car does no input work at all: the master's overhead then
    # also counts the fmi2SetReal of the connection, an upper bound.
    bare = per_step["quarter_car alone, input held constant, runner"] + per_step["road alone, runner"]
    print(f"\nthe two FMUs' own step: {own:.0f} ns (the car with its input table); {bare:.0f} ns with the car's input constant")
    print(f"runner master overhead over the constant-input FMUs: {per_step['system, runner (Jacobi)'] - bare:.0f} ns per step, {(per_step['system, runner (Jacobi)'] - bare) / bare:.1%}")
    print(f"runner master overhead: {runner_overhead:.0f} ns per step, {runner_overhead / own:.1%} of the FMUs' own step (target at most 10 %)")
    print(f"libcosim master overhead: {libcosim_overhead:.0f} ns per step, {libcosim_overhead / own:.1%} of the FMUs' own step")
    print(f"runner overhead / libcosim overhead: {runner_overhead / libcosim_overhead:.3f}")
    sys.exit(0 if runner_overhead <= 0.10 * own else 1)


if __name__ == "__main__":
    main()
