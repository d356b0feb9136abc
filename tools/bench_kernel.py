"""Benchmark: the kernel tests as a user runs them, wall and CPU seconds.

- one kernel test including its session's boot: ``pytest`` on one test of
  tests/test_kernel_fixture.py (the driver bound, ``in_anglvel_scale`` read), the whole
  process;
- with --suite, the kernel suite: ``pytest -m kernel tests --all``.

CPU seconds are the pytest process's and all it waited for (the guests, their orphan
guards), from ``getrusage(RUSAGE_CHILDREN)``; the host's load average is printed beside.
Time modes: ``--time virtual`` (the default on uml: time travel) or ``real``.

    python tools/bench_kernel.py [--engine uml] [--time virtual] [--suite] [--repeat 3] [--bare]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SINGLE_TEST = "tests/test_kernel_fixture.py::test_each_test_starts_at_the_probe_state"


def pytest_run(engine: str, time_mode: str, *words: str) -> tuple[float, float, str]:
    """(wall s, CPU s, pytest's summary line) of one pytest process."""
    env = {**os.environ, "PYTHONPATH": str(REPO), "BMG160_KERNEL_ENGINE": engine,
           "BMG160_KERNEL_TIME": time_mode}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             *words], cwd=REPO, env=env, capture_output=True, text=True,
                            check=False)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    summary = (result.stdout.strip().splitlines() or ["?"])[-1]
    return wall, cpu, summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engine", default="uml")
    parser.add_argument("--time", choices=("virtual", "real"), default="virtual")
    parser.add_argument("--suite", action="store_true", help="also time pytest -m kernel")
    parser.add_argument("--repeat", type=int, default=3, help="runs of the single test")
    parser.add_argument("--bare", action="store_true",
                        help="the single test without the pytest plugins of other packages "
                             "(hypothesis's imports cost about 1 s here)")
    args = parser.parse_args(argv)
    plugins = ["-p", "no:hypothesispytest"] if args.bare else []
    singles = [pytest_run(args.engine, args.time, *plugins, "--all", SINGLE_TEST)
               for _ in range(args.repeat)]
    print(f"{args.engine}, {args.time} time; load average {os.getloadavg()[0]:.1f} / "
          f"{os.getloadavg()[1]:.1f} (1 / 5 min) at the end")
    label = "one kernel test with its boot" + (" (no hypothesis plugin)" if args.bare else "")
    print(f"  {label}: {statistics.median(w for w, _, _ in singles):.2f} s "
          f"wall, {statistics.median(c for _, c, _ in singles):.2f} s CPU (median of "
          f"{args.repeat}; {singles[-1][2]})")
    if args.suite:
        wall, cpu, summary = pytest_run(args.engine, args.time, "-m", "kernel", "tests",
                                        "--all")
        print(f"  pytest -m kernel: {wall:.1f} s wall, {cpu:.1f} s CPU ({summary}; load "
              f"average {os.getloadavg()[0]:.1f} at its end)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
