"""The synthetic "real" sensor of issue 23 and the worked example of docs/identification.md.

The sensor is a profile with an output stage, like the issue's held-out real unit (100 Hz,
2.8 h static records, white N 0.04-0.046 deg/s/sqrt(Hz), a bias that bends over two decades
of tau, lag-1 correlation 0.2-0.3 from its filter): per axis white noise, three Gauss-Markov
poles and a random walk, a sinusoidal line on x and z, all through a 2nd-order low-pass at
40 Hz and rounded to 1/16.4 deg/s (the output of a +-2000 deg/s range). A recording is what
``generate`` writes from it (sensor_noise.profile_noise, the chip's code); identify runs with its
defaults, and each identified profile is emulated (generate's default, its output stage
included) ``--emulated`` times. Scored per axis, as the issue scores its real records:

- the identified profile carries the filter (order and corner) and the LSB;
- std and lag-1 correlation: the emulated records' median against the recording's;
- ADEV: at every octave tau from two sample periods to L/10, the emulated median inside
  the recording's 95 % band (Greenhall edf of the fitted model's noise types), and the
  recording inside the emulated 2.5-97.5 % range.

    python tools/identification_example.py                    # 6 recordings x 3 axes, 20 each
    python tools/identification_example.py --recordings 2 --emulated 10
    python tools/identification_example.py --no-output-stage  # identify as before issue 23
    python tools/identification_example.py --figures docs/figures   # the page's figures too
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from bmg160_emu.noise.allan import overlapping_adev
from bmg160_emu.noise.identify import identify
from bmg160_emu.noise.profile import AxisNoise, OutputStage, Profile
from bmg160_emu.noise.sensor_noise import profile_noise

RATE = 100.0
LENGTH = int(2.8 * 3600 * RATE)
CORNER_HZ, ORDER, LSB_DPS = 40.0, 2, 1.0 / 16.4
SENSOR = Profile(
    "synthetic-real-sensor",
    AxisNoise(N=0.040, B=0.0, T=0.0, K=2.0e-4, bias=0.094,
              gm=((1.2e-2, 5.0), (8e-3, 60.0), (5e-3, 900.0)), sine=((0.01, 1.7),)),
    AxisNoise(N=0.043, B=0.0, T=0.0, K=1.5e-4, bias=-0.21,
              gm=((1.0e-2, 8.0), (6e-3, 120.0), (4e-3, 1500.0))),
    AxisNoise(N=0.046, B=0.0, T=0.0, K=2.5e-4, bias=0.05,
              gm=((1.4e-2, 3.0), (9e-3, 40.0), (6e-3, 600.0)), sine=((0.006, 2.9),)),
    description="issue 23's synthetic real sensor: 3 poles, K, lines, 40 Hz filter, LSB",
    output=OutputStage(order=ORDER, corner_hz=CORNER_HZ, lsb_dps=LSB_DPS, rate_hz=RATE),
)


def lag1(x: np.ndarray) -> float:
    x = x - x.mean()
    return float(np.dot(x[:-1], x[1:]) / np.dot(x, x))


def score_recording(seed: int, emulated: int, output_stage: bool = True,
                    length: int = LENGTH) -> dict:
    """One recording of the sensor identified, emulated and scored (module docstring)."""
    record = profile_noise(SENSOR, seed=seed).generate(length)
    result = identify(record, RATE, source=f"synthetic recording {seed}",
                      output_stage=output_stage)
    profile = result.to_profile("identified")
    runs = [profile_noise(profile, RATE, seed=10_000 * (seed + 1) + e).generate(length)
            for e in range(emulated)]
    axes = []
    for i, axis in enumerate(result.axes):
        c = axis.allan
        sel = (c.taus >= 2.0 / RATE * (1 - 1e-9)) & (c.taus <= length / RATE / 10)
        low = c.adev * np.sqrt(c.edf / chi2.ppf(0.975, c.edf))
        high = c.adev * np.sqrt(c.edf / chi2.ppf(0.025, c.edf))
        emu = np.array([overlapping_adev(r[:, i], RATE).adev[: c.taus.size] for r in runs])
        median = np.median(emu, axis=0)
        q_low, q_high = np.percentile(emu, [2.5, 97.5], axis=0)
        axes.append({
            "axis": axis.axis,
            "N": axis.N.value, "N_truth": SENSOR.axes[i].N,
            "filter": axis.output_filter,
            "lsb": axis.lsb_dps,
            "lines": [(A.value, f) for A, f in axis.sines],
            "std": float(record[:, i].std()),
            "std_emulated": float(np.median([r[:, i].std() for r in runs])),
            "lag1": lag1(record[:, i]),
            "lag1_emulated": float(np.median([lag1(r[:, i]) for r in runs])),
            "taus": c.taus[sel],
            "inside": ((median >= low) & (median <= high))[sel],
            "covered": ((c.adev >= q_low) & (c.adev <= q_high))[sel],
            "ratio": (median / c.adev)[sel],
        })
    return {"seed": seed, "profile": profile, "result": result, "axes": axes,
            "record": record, "runs": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=6)
    parser.add_argument("--emulated", type=int, default=20)
    parser.add_argument("--first-seed", type=int, default=11)
    parser.add_argument("--no-output-stage", action="store_true")
    parser.add_argument("--figures", type=Path, default=None, metavar="DIR")
    args = parser.parse_args()
    inside = covered = points = 0
    std_worst = lag_worst = 0.0
    start = time.time()
    print("rec axis  N/truth  filter found             LSB      std emu/rec  lag-1 rec  emu"
          "   inside  covered")
    for r in range(args.recordings):
        scored = score_recording(args.first_seed + r, args.emulated, not args.no_output_stage)
        for a in scored["axes"]:
            flt = a["filter"]
            found = f"order {flt.order} at {flt.corner_hz:6.2f} Hz" if flt else "none"
            std_ratio = a["std_emulated"] / a["std"]
            std_worst = max(std_worst, abs(std_ratio - 1))
            lag_worst = max(lag_worst, abs(a["lag1_emulated"] - a["lag1"]))
            inside += int(a["inside"].sum())
            covered += int(a["covered"].sum())
            points += a["inside"].size
            print(f"{scored['seed']:3d} {a['axis']:>4}  {a['N'] / a['N_truth']:.4f}  "
                  f"{found:24s} {a['lsb'] or 0:.5f}  {std_ratio:.4f}      {a['lag1']:+.3f}  "
                  f"{a['lag1_emulated']:+.3f}  {a['inside'].mean():6.1%}  {a['covered'].mean():6.1%}")
            missed = a["taus"][~a["inside"]]
            if missed.size:
                print(f"      median outside the band at tau {', '.join(f'{t:g}' for t in missed)} s"
                      f" (median / recording {', '.join(f'{q:.3f}' for q in a['ratio'][~a['inside']])})")
        if r == 0:
            print("\n".join(scored["result"].summary().split("\n\naxis y")[0].splitlines()[2:]))
            print(_stage_text(scored["profile"]))
            if args.figures is not None:
                figures(scored, args.figures)
    print(f"\nADEV, octave taus 2 samples .. L/10 over {points} axis-taus: emulated median "
          f"inside the recording's 95 % band {inside / points:.1%}, recording inside the "
          f"emulated range {covered / points:.1%}; std within {std_worst:.2%}, lag-1 within "
          f"{lag_worst:.3f} ({time.time() - start:.0f} s)")


def _stage_text(profile: Profile) -> str:
    stage = profile.output
    if stage is None:
        return "profile: no output stage"
    return (f"profile [output]: order {stage.order}, corner {stage.corner_hz:.4g} Hz, "
            f"LSB {stage.lsb_dps}, rate {stage.rate_hz:g} Hz; lines: "
            + ", ".join(f"{axis}: " + ", ".join(f"{A:.3g} deg/s at {f:.4g} Hz" for A, f in
                                                 noise.sine) for axis, noise in
                        zip("xyz", profile.axes) if noise.sine))


def figures(scored: dict, out: Path) -> None:
    """The page's figures from the first recording's x axis."""
    from matplotlib.figure import Figure

    from bmg160_emu.noise import plots

    out.mkdir(parents=True, exist_ok=True)
    result = scored["result"]
    plots.save(plots.adev_figure(result.axes[:1]), out / "identify_example_adev.png")
    c = result.axes[0].allan
    emulated = np.array([overlapping_adev(r[:, 0], RATE).adev[: c.taus.size]
                         for r in scored["runs"]])
    fig = Figure(figsize=(8.0, 5.0), layout="constrained")
    ax = fig.subplots()
    ax.fill_between(c.taus, *np.percentile(emulated, [2.5, 97.5], axis=0), color="tab:orange",
                    alpha=0.3, lw=0, label=f"emulator, {len(emulated)} records: 2.5-97.5 %")
    ax.loglog(c.taus, np.median(emulated, axis=0), "-", color="tab:orange",
              label="emulator: median")
    ax.loglog(c.taus, c.adev, "o", ms=4, color="tab:blue", label="recording (synthetic sensor)")
    ax.fill_between(c.taus, c.ci_low, c.ci_high, color="tab:blue", alpha=0.2, lw=0,
                    label="recording: 68 % interval")
    ax.axvline(2.0 / RATE, color="0.5", ls=":", lw=0.8)
    ax.axvline(LENGTH / RATE / 10, color="0.5", ls=":", lw=0.8, label="2 samples and L/10")
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small")
    ax.set_title("identify -> profile -> generate: emulator against the recording")
    plots.save(fig, out / "identify_example_emulated.png")


if __name__ == "__main__":
    sys.exit(main())
