"""Instruction counts for the benchmarks: on this shared 2-core VM the CPU time of one program
moves by tens of percent from run to run, while the instructions it executes do not."""

import re
import shutil
import subprocess
import sys


def instructions(cmd):
    """Instructions `cmd` executes (all threads), counted by valgrind's cachegrind; None without
    valgrind."""
    if shutil.which("valgrind") is None:
        return None
    proc = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null", *map(str, cmd)],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    found = re.search(r"I\s+refs:\s+([\d,]+)", proc.stderr)
    if proc.returncode != 0 or not found:
        sys.exit(f"valgrind {' '.join(map(str, cmd))} failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
    return int(found.group(1).replace(",", ""))
