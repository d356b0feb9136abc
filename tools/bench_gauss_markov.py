"""Benchmark: one Gauss-Markov term and the random walk per sample, against the previous
implementation (scipy lfilter, np.cumsum) and numpy drawing one normal, in the same run.

The generator's cost per term is what this isolates (the end-to-end ratios of
bench_noise_generation.py move by +-0.15 on a shared machine).

    python tools/bench_gauss_markov.py
"""

from __future__ import annotations

import math
import timeit

import numpy as np
from scipy.signal import lfilter

from bmg160_emu.noise.gauss_markov import _superblock, pole_coefficients, walk_coefficients

N = 32768  # one super-block


def main() -> None:
    dt = 1 / 200.0
    gm = pole_coefficients(4.047421e-3, dt, 33.9)  # the paper's term at 200 Hz
    walk = walk_coefficients(4.023987e-4 * math.sqrt(dt))
    w = np.random.default_rng(0).standard_normal(N)
    rng = np.random.default_rng(1)

    def old_walk():
        r = np.multiply(w, walk.g)
        r[0] += 0.1
        np.cumsum(r, out=r)

    cases = {
        "numpy standard_normal (one normal)": lambda: rng.standard_normal(N),
        "Gauss-Markov, lfilter (before)": lambda: lfilter([gm.g], [1.0, -gm.a], w, zi=[0.1]),
        "Gauss-Markov, block recursion (now)": lambda: _superblock(gm, w, 0.1),
        "random walk, cumsum (before)": old_walk,
        "random walk, block recursion (now)": lambda: _superblock(walk, w, 0.1),
    }
    best = {name: math.inf for name in cases}
    for _ in range(15):  # interleaved, best of 15: the machine is shared
        for name, f in cases.items():
            best[name] = min(best[name], min(timeit.repeat(f, number=20, repeat=3)) / 20 / N)
    for name, t in best.items():
        print(f"{name:40s} {t * 1e9:6.2f} ns/sample")


if __name__ == "__main__":
    main()
