"""What `runner validate` costs: each of our FMUs validated (every static check and every
dynamic probe, each probe in its own process) against the baseline of one `runner simulate` of
the same FMU through its DefaultExperiment, measured in the same script.

The machine is shared and noisy, so both commands run in interleaved rounds and each keeps its
fastest; the load average is printed before and after. Target: validating one of our FMUs takes
under 10 s. Exit code 1 if an FMU misses it or is not clean.
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "target/release/runner"
TARGET_SECONDS = 10.0


def wall(cmd):
    """Wall seconds of `cmd`, which must succeed."""
    start = time.perf_counter()
    proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    seconds = time.perf_counter() - start
    if proc.returncode != 0:
        sys.exit(f"{' '.join(map(str, cmd))} failed ({proc.returncode}):\n{proc.stdout.decode()}{proc.stderr.decode()}")
    return seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved rounds (default 3)")
    parser.add_argument("fmus", nargs="*", type=Path, help="FMUs (default: target/fmu/*.fmu)")
    args = parser.parse_args()
    fmus = args.fmus or sorted((ROOT / "target/fmu").glob("*.fmu"))
    if not fmus:
        sys.exit("no FMUs: run `runner build` first")
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    best = {fmu: [float("inf"), float("inf")] for fmu in fmus}
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "run.csv"
        for _ in range(args.repeats):
            for fmu in fmus:
                best[fmu][0] = min(best[fmu][0], wall([RUNNER, "simulate", fmu, "--out", csv]))
                best[fmu][1] = min(best[fmu][1], wall([RUNNER, "validate", fmu]))
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"fastest of {args.repeats} interleaved rounds, release build\n")
    print(f"| FMU | runner simulate (s) | runner validate (s) | validate / simulate | under {TARGET_SECONDS:.0f} s |")
    print("|---|---|---|---|---|")
    missed = False
    for fmu, (simulate, validate) in best.items():
        met = validate < TARGET_SECONDS
        missed |= not met
        print(f"| {fmu.stem} | {simulate:.3f} | {validate:.3f} | {validate / simulate:.1f} | {'met' if met else 'MISSED'} |")
    total = sum(v for _, v in best.values())
    print(f"\nall {len(fmus)} FMUs: {total:.1f} s of validation")
    sys.exit(1 if missed else 0)


if __name__ == "__main__":
    main()
