"""Benchmark: peak memory of identification of a 3-axis record against the record itself.

Target (issue 11): identify on a 3-axis 24 h record at 200 Hz (51.8 M samples, 415 MB of
float64) peaks at no more than 1.5x the array, the array included (the pipeline after
reading the file: the loader's own memory is not counted). Measured with tracemalloc,
which sees numpy's allocations; the record is made before tracing starts.

    python tools/bench_identify_memory.py            # 24 h
    python tools/bench_identify_memory.py --hours 6  # quicker
"""

from __future__ import annotations

import argparse
import time
import tracemalloc

from bmg160_emu.noise import NoiseGenerator
from bmg160_emu.noise.identify import identify


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0, help="record length (default 24)")
    args = parser.parse_args()
    rate = 200.0
    n = int(args.hours * 3600 * rate)
    data = NoiseGenerator("paper", rate_hz=rate, seed=1).generate(n)
    tracemalloc.start()
    start = time.perf_counter()
    identify(data, rate)
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    ratio = (data.nbytes + peak) / data.nbytes
    print(f"record: 3 axes x {args.hours:g} h at {rate:g} Hz = {data.nbytes / 1e6:.0f} MB")
    print(f"identify: peak {peak / 1e6:.0f} MB above the record ({elapsed:.1f} s)")
    print(f"peak with the record: {ratio:.2f}x the array   target: <= 1.5x")


if __name__ == "__main__":
    main()
