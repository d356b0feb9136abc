"""Peak memory of reading a rate file, as a ratio to the float64 rate array it yields.

Writes a 3-axis record (time column + x, y, z in deg/s) of ``--hours`` at ``--rate`` Hz in
each format, then reads it with :func:`bmg160_emu.io.rates.load_rate_record` (what
``identify`` uses) under tracemalloc (numpy reports its buffers to it) and prints the peak
beside the size of the (n, 3) float64 array; issue 11 asks at most 1.5x.

    python tools/bench_rate_read.py [--hours 24] [--rate 200] [--formats npy,npz,csv]
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

from bmg160_emu.io.array_files import write_npz
from bmg160_emu.io.rates import load_rate_record


def _write(path: Path, n: int, rate_hz: float) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(1, n + 1) / rate_hz
    rate = rng.standard_normal((n, 3)) * 0.1
    if path.suffix == ".npy":
        np.save(path, rate)
    elif path.suffix == ".npz":
        write_npz(path, {"t_s": t, "rate_dps": rate})
    else:
        with open(path, "w", encoding="utf-8") as handle:
            handle.write("t_s,x_dps,y_dps,z_dps\n")
            step = 1_000_000
            for start in range(0, n, step):  # in blocks: the writer must not need the memory
                block = np.column_stack([t[start:start + step], rate[start:start + step]])
                np.savetxt(handle, block, fmt=["%.12g"] + ["%.10g"] * 3, delimiter=",")
    del t, rate


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0)
    parser.add_argument("--rate", type=float, default=200.0, help="sample rate, Hz")
    parser.add_argument("--formats", default="npy,npz,csv")
    args = parser.parse_args()
    n = round(args.hours * 3600 * args.rate)
    array_bytes = n * 3 * 8
    print(f"{n} samples x 3 axes: the float64 array is {array_bytes / 1e6:.1f} MB")
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in args.formats.split(","):
            path = Path(tmp) / f"record.{suffix}"
            _write(path, n, args.rate)
            gc.collect()
            tracemalloc.start()
            start = time.perf_counter()
            record = load_rate_record(path, rate_hz=None if suffix != "npy" else args.rate)
            seconds = time.perf_counter() - start
            _, peak = tracemalloc.get_traced_memory()
            tracemalloc.stop()
            assert record.rate_dps.shape == (n, 3)
            print(f"{suffix:>4}: peak {peak / 1e6:8.1f} MB = {peak / array_bytes:.2f}x the array "
                  f"({path.stat().st_size / 1e6:.0f} MB file, read in {seconds:.1f} s)")
            del record
            path.unlink()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
