"""The worked example of docs/identification.md: a synthetic unit like the issue's real one.

White noise N = 0.04 deg/s/sqrt(Hz), three Gauss-Markov poles (B, T) = (0.012, 5 s),
(0.008, 60 s), (0.005, 900 s), rate random walk K = 2e-4 deg/s/sqrt(s), through the chip's
2nd-order low-pass at 40 Hz, 2.8 h at 100 Hz (the length of the issue's public runs).
Identifies it with the defaults, writes the profile, emulates 20 records of the same length
and draws the figures of the page (docs/figures/identify_example_*.png).

    python tools/identification_example.py [OUTDIR]
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bmg160_emu.device.lowpass import LowPass
from bmg160_emu.noise import NoiseGenerator, plots
from bmg160_emu.noise.allan import overlapping_adev
from bmg160_emu.noise.identification import identify
from bmg160_emu.noise.profile import AxisNoise, Profile

RATE = 100.0
LENGTH = int(2.8 * 3600 * RATE)
TRUTH = AxisNoise(N=0.04, B=0.0, T=0.0, K=2e-4, bias=0.1,
                  gm=((1.2e-2, 5.0), (8e-3, 60.0), (5e-3, 900.0)))


def main() -> None:
    out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path("docs/figures")
    out.mkdir(parents=True, exist_ok=True)
    raw = NoiseGenerator(Profile("truth", TRUTH, TRUTH, TRUTH), rate_hz=RATE, seed=11)
    x = raw.generate(LENGTH)
    lp = LowPass(RATE, 40.0)
    lp.restart(x[0])
    record = lp.run(x)[0][:, 0]
    result = identify(record, RATE, source="synthetic unit")
    print(result.summary())
    plots.save(plots.adev_figure(result.axes), out / "identify_example_adev.png")
    axis = result.axes[0]
    c = axis.allan
    emulated = np.array([
        overlapping_adev(NoiseGenerator(result.to_profile(), rate_hz=RATE, seed=100 + s)
                         .generate(LENGTH)[:, 0], RATE).adev[: c.taus.size]
        for s in range(20)
    ])
    fig = Figure(figsize=(8.0, 5.0), layout="constrained")
    ax = fig.subplots()
    ax.fill_between(c.taus, *np.percentile(emulated, [2.5, 97.5], axis=0), color="tab:orange",
                    alpha=0.3, lw=0, label="emulator, 20 records: 2.5-97.5 %")
    ax.loglog(c.taus, np.median(emulated, axis=0), "-", color="tab:orange",
              label="emulator: median")
    ax.loglog(c.taus, c.adev, "o", ms=4, color="tab:blue", label="recording (synthetic unit)")
    ax.fill_between(c.taus, c.ci_low, c.ci_high, color="tab:blue", alpha=0.2, lw=0,
                    label="recording: 68 % interval")
    ax.axvline(0.2, color="0.5", ls=":", lw=0.8)
    ax.axvline(LENGTH / RATE / 10, color="0.5", ls=":", lw=0.8, label="0.2 s and L/10")
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small")
    ax.set_title("identify -> profile -> generate: emulator against the recording")
    plots.save(fig, out / "identify_example_emulated.png")


if __name__ == "__main__":
    main()
