"""Checks on a real recording before and beside the fit: the sensor's own filter, warm-up,
steps in the bias.

- Filter. A sensor's low-pass (the chip's BW setting, an anti-alias filter) removes white
  noise above its bandwidth, so at the shortest taus the Allan deviation lies below the
  white-noise line N / sqrt(tau) and falls more slowly than tau^-1/2 (slope shallower than
  -1/2). Fitting those points with the generator's model makes a Gauss-Markov term of the
  shortest T out of the roll-off and returns N low (issue 11: 20-25 % on 12 of 18 real
  axes). The white region starts at the first octave segment whose slope is within 0.05 of
  -1/2; with a filter found, the fit starts one octave above it, where the remaining
  deficit (about 0.15 / (tau BW) of the variance for a 2nd-order low-pass) is half as
  large again. A Gauss-Markov term shorter than that tau cannot be told from the filter
  and is absorbed in N.
- Warm-up. A sensor that has not reached thermal equilibrium drifts more at the start. The
  Allan deviation of the first quarter is compared with that of the rest on 1 s averages
  (block means: cheap on day-long records, and enough for a 10 % check).
- Bias step. A jump of the bias between two 1/64 blocks of the record, far outside the
  scatter of the other block-to-block differences (robust z-score above 6).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bmg160_emu.durations import duration_text
from bmg160_emu.noise.allan import AllanCurve, octave_oadev

WHITE_SLOPE_TOLERANCE = 0.05  # |slope + 1/2| of an octave segment in the white region
WARMUP_RATIO = 1.25  # first quarter ADEV / rest ADEV that is reported (with its significance)
STEP_Z = 6.0  # robust z-score of a block-to-block jump that is called a step
STEP_BLOCKS = 64


@dataclass(frozen=True)
class FilterEnd:
    """Where the white -1/2 region of the curve starts (the sensor's filter ends)."""

    filtered: bool
    tau_min_s: float  # the fit's default shortest tau
    reason: str


def white_region_start(curve: AllanCurve) -> FilterEnd:
    """The shortest tau to fit: the first point if the curve starts on the -1/2 line,
    otherwise one octave above the first segment that reaches it."""
    taus, adev = curve.taus, curve.adev
    if taus.size < 3:
        return FilterEnd(False, float(taus[0]), "too few points to look for a filter")
    slopes = np.diff(np.log(adev)) / np.diff(np.log(taus))
    if slopes[0] <= -0.5 + WHITE_SLOPE_TOLERANCE:
        return FilterEnd(False, float(taus[0]), "the curve starts on the white -1/2 slope")
    on_white = np.flatnonzero(np.abs(slopes + 0.5) <= WHITE_SLOPE_TOLERANCE)
    # only a shallow start that ends in a -1/2 stretch before the curve's minimum is a filter
    i_min = int(np.argmin(adev))
    on_white = on_white[on_white < max(i_min, 1)]
    if on_white.size == 0:
        return FilterEnd(False, float(taus[0]),
                         "no white -1/2 stretch found: every point is fitted")
    i = int(on_white[0])
    start = min(i + 1, taus.size - 1)
    return FilterEnd(
        True,
        float(taus[start]),
        f"the curve is below the white-noise line up to tau = {taus[i]:.3g} s (slope "
        f"{slopes[0]:+.2f} instead of -0.50 at the start: the sensor's low-pass); fitted "
        f"from one octave above, tau = {taus[start]:.3g} s",
    )


def _block_means(x: np.ndarray, m: int) -> np.ndarray:
    """Means of consecutive blocks of m samples (reduceat: no copy of a strided column)."""
    k = x.shape[0] // m
    return np.add.reduceat(x[: k * m], np.arange(0, k * m, m)) / m


def warmup_check(x: np.ndarray, rate_hz: float) -> str | None:
    """A warning when the first quarter's ADEV exceeds the rest's beyond their scatter."""
    n = x.shape[0]
    m = max(1, round(rate_hz))  # 1 s averages
    means = _block_means(x, m)
    q = means.shape[0] // 4
    if q < 40:  # fewer than 40 s in the first quarter: nothing to compare at taus >= 4 s
        return None
    first_t, first, first_n = octave_oadev(means[:q], rate_hz / m)
    _rest_t, rest, _rest_n = octave_oadev(means[q:], rate_hz / m)
    k = min(first.size, rest.size)
    keep = first_n[:k] >= 10 * 2  # at least ~10 independent differences in the quarter
    if not keep.any():
        return None
    ratio = first[:k] / rest[:k]
    # 1-sigma relative error of an overlapping ADEV point of white-ish noise ~ 1 / sqrt(N/m)
    sigma = np.sqrt(1.0 / np.maximum((q / (first_t[:k] * rate_hz / m)) - 1, 1))
    bad = keep & (ratio > WARMUP_RATIO) & (ratio - 1 > 3 * sigma)
    if not bad.any():
        return None
    span = first_t[:k][bad]
    worst = float(ratio[bad].max())
    quarter = duration_text(n / 4 / rate_hz, gap="")  # as --skip takes it
    return (
        f"non-stationary start: the first quarter ({quarter}) has up to "
        f"{worst:.2f}x the Allan deviation of the rest at tau {span.min():.3g} .. "
        f"{span.max():.3g} s (warm-up?); try --skip {quarter}, or record "
        "after the sensor has settled"
    )


def step_check(x: np.ndarray, rate_hz: float) -> str | None:
    """A warning when the bias jumps between two blocks far beyond the other jumps."""
    n = x.shape[0]
    m = n // STEP_BLOCKS
    if m < 2:
        return None
    means = _block_means(x, m)
    d = np.diff(means)
    med = float(np.median(d))
    mad = float(np.median(np.abs(d - med))) * 1.4826
    if not mad > 0:
        return None
    z = np.abs(d - med) / mad
    j = int(np.argmax(z))
    if z[j] < STEP_Z:
        return None
    at = duration_text((j + 1) * m / rate_hz, gap="")  # as --skip takes it
    return (
        f"the bias jumps by {d[j]:+.3g} deg/s around t = {at} ({z[j]:.0f} times the "
        "typical block-to-block change): a step is not noise; split the record there or "
        "--skip past it"
    )
