"""Figure (issue 33): a Zephyr build plus a 2,000-sample run, configure and build included.

One command, from nothing: configure and build zephyr/samples/gyro_stats for
native_sim/native/64 with the module (a fresh build folder), start ``bmg160-emu serve``,
run the app with --no-rt until Zephyr's unmodified bmg160 driver has read 2,000 samples at
100 Hz. Prints each step's wall and CPU time (the children's user + system), the host's
load before and after, and the Zephyr version. The target is <= 60 s on a quiet 2-core
host; a loaded host stretches the wall time, not the CPU time.

    ZEPHYR_BASE=/path/to/zephyr python tools/bench_zephyr.py [--keep DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import signal
import sys
import tempfile
import time
from pathlib import Path

from bmg160_emu.serve import zephyr_app as za

SAMPLES = 2000
TARGET_S = 60.0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", type=Path, default=None,
                        help="build in DIR (kept) instead of a temporary folder")
    args = parser.parse_args()
    base = za.zephyr_base()
    if base is None:
        print("bench_zephyr: set ZEPHYR_BASE to a Zephyr tree (docs/zephyr.md)", file=sys.stderr)
        return 2
    lacking = za.missing()
    if lacking:
        print(f"bench_zephyr: missing {', '.join(lacking)}", file=sys.stderr)
        return 2
    load_before = os.getloadavg()
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        build_dir = root / "gyro_stats"
        started = time.monotonic()
        build = za.build_app(za.MODULE_ROOT / "zephyr" / "samples" / "gyro_stats", build_dir,
                             base, options={"CONFIG_GYRO_STATS_SAMPLES": str(SAMPLES)})
        proc, socket = za.serve_process(root / "srv", "--seed", "7", "--true-rate", "20", "-10",
                                        "5")
        try:
            output, run = za.run_app(build.executable, socket, stop_at_s=SAMPLES / 100 + 2)
        finally:
            proc.send_signal(signal.SIGTERM)
            proc.communicate(timeout=60)
        total = time.monotonic() - started
    load_after = os.getloadavg()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    all_cpu = (after.ru_utime - children.ru_utime) + (after.ru_stime - children.ru_stime)
    samples = za.gyro_samples(output)
    steps = build.configure.cpu_s + build.build.cpu_s + run.cpu_s
    print(f"Zephyr {za.zephyr_version(base)} ({base}), {za.BOARD}")
    print(f"  configure {build.configure.wall_s:6.1f} s wall {build.configure.cpu_s:6.1f} s CPU")
    print(f"  build     {build.build.wall_s:6.1f} s wall {build.build.cpu_s:6.1f} s CPU")
    print(f"  run       {run.wall_s:6.1f} s wall {run.cpu_s:6.1f} s CPU  "
          f"({len(samples)} samples read by the bmg160 driver)")
    print(f"  server    {'':6} {'':6} {all_cpu - steps:6.1f} s CPU  (bmg160-emu serve, start "
          "included)")
    print(f"  total     {total:6.1f} s wall {all_cpu:6.1f} s CPU, target <= {TARGET_S:.0f} s "
          "wall on a quiet 2-core host")
    print(f"  load before {load_before[0]:.1f} / {load_before[1]:.1f} / {load_before[2]:.1f}, "
          f"after {load_after[0]:.1f} / {load_after[1]:.1f} / {load_after[2]:.1f} (1/5/15 min)")
    return 0 if len(samples) == SAMPLES else 1


if __name__ == "__main__":
    raise SystemExit(main())
