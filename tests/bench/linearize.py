"""What `runner linearize` costs as a whole process (start, unpack, start a worker process that
loads the FMU, initialize, one Jacobian by directional derivatives, eigenvalues, report) on our
FMUs, against the baseline of `runner info` of the same FMU (start, unpack, read the description),
measured in the same script: the difference is what linearizing adds to opening an FMU. The same
with --in-process (no worker) shows what the worker costs.

The machine is shared and noisy, so the commands run in interleaved rounds and each keeps its
fastest; the load average is printed before and after. Target: under 20 ms per FMU. Exit code 1
if an FMU misses it.
"""

import argparse
import os
import sys
from pathlib import Path

from validate import wall

ROOT = Path(__file__).resolve().parents[2]
RUNNER = ROOT / "target/release/runner"
TARGET_SECONDS = 0.020
MODELS = ["second_order", "mass_spring_damper", "quarter_car", "pendulum"]


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=20, help="interleaved rounds (default 20)")
    parser.add_argument("fmus", nargs="*", type=Path, help="FMUs (default: the FMI 2.0 and 3.0 FMUs of " + ", ".join(MODELS) + ")")
    args = parser.parse_args()
    fmus = args.fmus or [ROOT / d / f"{m}.fmu" for m in MODELS for d in ("target/fmu", "target/fmu3")]
    missing = [f for f in fmus if not f.is_file()]
    if missing:
        sys.exit(f"missing FMUs: {', '.join(map(str, missing))}: run tests/bench/linearize")
    print(f"load average before: {' '.join(f'{x:.1f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    best = {fmu: [float("inf")] * 3 for fmu in fmus}
    for _ in range(args.repeats):
        for fmu in fmus:
            best[fmu][0] = min(best[fmu][0], wall([RUNNER, "info", fmu]))
            best[fmu][1] = min(best[fmu][1], wall([RUNNER, "linearize", fmu]))
            best[fmu][2] = min(best[fmu][2], wall([RUNNER, "linearize", fmu, "--in-process"]))
    print(f"load average after:  {' '.join(f'{x:.1f}' for x in os.getloadavg())}")
    print(f"fastest of {args.repeats} interleaved rounds, release build\n")
    print(f"| FMU | runner info (ms) | runner linearize (ms) | linearize / info | --in-process (ms) | under {TARGET_SECONDS * 1e3:.0f} ms |")
    print("|---|---|---|---|---|---|")
    missed = False
    for fmu, (info, linearize, in_process) in best.items():
        met = linearize < TARGET_SECONDS
        missed |= not met
        name = f"{fmu.parent.name}/{fmu.stem}"
        print(f"| {name} | {info * 1e3:.1f} | {linearize * 1e3:.1f} | {linearize / info:.2f} | {in_process * 1e3:.1f} | {'met' if met else 'MISSED'} |")
    sys.exit(1 if missed else 0)


if __name__ == "__main__":
    main()
