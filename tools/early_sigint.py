"""How a ^C in a command's first moments is answered (docs/outputs.md, issue 35).

    python tools/early_sigint.py [--trials 40] [--within 0.12] [--command bmg160-emu]

Starts ``bmg160-emu dump`` TRIALS times and sends SIGINT at a seeded random moment within
the first WITHIN seconds; counts the answers: CPython killed before any handler (exit -2,
silent), CPython's own start-up traceback (``site``: nothing of ours has run), the
package's one line (``interrupted by SIGINT while starting``), or a traceback from the
package's code (a defect). Prints the latest CPython traceback and the earliest own line,
the boundary between them, and the load average beside them.
"""

from __future__ import annotations

import argparse
import collections
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

PACKAGE = str(Path(__file__).resolve().parents[1] / "bmg160_emu")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=40)
    parser.add_argument("--within", type=float, default=0.12, help="seconds")
    parser.add_argument("--command", default=shutil.which("bmg160-emu") or "bmg160-emu",
                        help="the console script to start (default: the one on PATH)")
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    kinds: collections.Counter[str] = collections.Counter()
    cpython: list[float] = []
    ours: list[float] = []
    for _ in range(args.trials):
        delay = rng.uniform(0.0, args.within)
        process = subprocess.Popen([args.command, "dump", "--seed", "1"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                                   text=True, cwd="/")
        time.sleep(delay)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate()
        if "Traceback" in err:
            frames = [line for line in err.splitlines() if line.strip().startswith("File ")]
            if any(PACKAGE in line for line in frames):
                kinds["traceback from the package (a defect)"] += 1
            else:
                kinds["CPython's start-up traceback"] += 1
                cpython.append(delay)
        elif "interrupted by" in err:
            kinds["the package's one line"] += 1
            ours.append(delay)
        elif process.returncode == -signal.SIGINT:
            kinds["killed before any handler (silent)"] += 1
        else:
            kinds[f"exit {process.returncode}"] += 1
    for kind, count in sorted(kinds.items()):
        print(f"{count:4d}  {kind}")
    if cpython:
        print(f"latest CPython traceback at {1000 * max(cpython):.1f} ms")
    if ours:
        print(f"earliest line of the package at {1000 * min(ours):.1f} ms")
    print(f"load average {os.getloadavg()[0]:.2f}")
    return 1 if kinds["traceback from the package (a defect)"] else 0


if __name__ == "__main__":
    sys.exit(main())
