"""Benchmark: identification of one axis against allantools.oadev alone on the same data.

Target (issue 37): octave-spaced overlapping ADEV + confidence intervals + the output stage
(PSD shape, bands, lines) + warm-up and step checks + PSD + multi-term fit of one 24 h axis
at 200 Hz (17.28 M samples) in no more than 0.4x the time of
`allantools.oadev(..., taus='octave')` alone on the same data, measured in the same run
(issue 11's target was 1.0x, issue 2's 1.5x). The ratio falls with the record's length (the
fit costs the same on any record; allantools' whole-record temporaries grow faster than
the record), so the 24 h figure is the one the target names.

    python tools/bench_identification.py            # 24 h
    python tools/bench_identification.py --hours 6  # quicker
"""

from __future__ import annotations

import argparse
import time

import allantools

from bmg160_emu.noise import NoiseGenerator
from bmg160_emu.noise.identify import identify_axis


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hours", type=float, default=24.0, help="record length (default 24)")
    parser.add_argument("--repeat", type=int, default=3, help="best of N runs (default 3)")
    args = parser.parse_args()
    rate = 200.0
    n = int(args.hours * 3600 * rate)
    x = NoiseGenerator("paper", rate_hz=rate, seed=1).generate(n)[:, 0].copy()

    def reference() -> float:
        start = time.perf_counter()
        allantools.oadev(x, rate=rate, data_type="freq", taus="octave")
        return time.perf_counter() - start

    def ours() -> float:
        start = time.perf_counter()
        identify_axis(x, rate)
        return time.perf_counter() - start

    # interleaved, best of N: the machine is shared, so load drifts between runs
    refs, fulls = [], []
    for _ in range(args.repeat):
        refs.append(reference())
        fulls.append(ours())
    ref, full = min(refs), min(fulls)
    print(f"record: one axis, {args.hours:g} h at {rate:g} Hz = {n / 1e6:.2f} M samples")
    print(f"reference  allantools.oadev(taus='octave')   : {ref:7.2f} s")
    print(f"identify   ADEV + CI + checks + PSD + fit    : {full:7.2f} s  ratio {full / ref:.2f}")
    print("target (24 h): ratio <= 0.4")


if __name__ == "__main__":
    main()
