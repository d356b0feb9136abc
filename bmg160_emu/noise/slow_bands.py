"""Resonant bands of the slow part of a record's spectrum: narrowband excess power below the
output stage's range (rate/50 and down), where the model has only white noise, Lorentzian
Gauss-Markov terms and a random walk, none of which makes a bump.

Why. The shared ADIS16405 record's z axis has 10.6 % more power at 0.28-0.38 Hz than its
identified model (4.4 sigma of 30 Welch bins of 2^15 samples) and 4.8 % less at 0.5-0.67 Hz:
a bump at 0.3 Hz that the Gauss-Markov terms (monotone in frequency) and the measured
response (fitted from rate/300 = 0.33 Hz up, at a resolution of rate/128 = 0.78 Hz) cannot
follow. The Allan deviation's transfer function peaks at 0.37 / tau, so the bump lifts the
point at tau = 1.28 s: the recording lay 1.5 % above every emulated record there, outside its
95 % band (issue 37's per-axis figures). A bump is a band, as at 20 Hz, only slower: the same
resonators (resonant_bands.py) draw it, in every route (a profile's ``slow_band``).

How (find_slow_bands). The record's long-segment Welch PSD (spectrum.one_sided_psd) over the
model's PSD (the first Allan fit's terms through the broadband response, with the bands above
and the rounding floor) on log-spaced bins, 16 per octave, from 8 Welch bins up (the Hann
window's leakage of the 1/f^2 random walk stays below 1 % there) to rate/50. A resonator of
centre f0 and width f0/4 .. f0 is scanned over every bin; its power and the sizes of the
other terms (white through the response, each Gauss-Markov term at its fitted T, the random
walk) are refitted with it by non-negative least squares on the bins' chi-square scatter, so
a term that had taken part of a bump gives it back; the chi-square it removes is its
evidence. The best is kept when it removes more than DETECTION (25), refined by least
squares in (f0, ln width, ln power) with the other sizes solved alongside, and kept when its
power's 95 % interval leaves out 0. Then a second one, the first in the model.

The threshold, measured on simulated records without a slow band (white noise, Gauss-Markov
terms of 0.5 and 100 s, a random walk, a band at 20 Hz; 100 Hz): on 20 x axes of 50 min the
best candidate removed 3.1 to 19.3 (median 11.5); of 18 axes of 83 min one took a band, at
0.25 Hz (B = 0.008 deg/s, 0.1 % of the variance): its white normals alone hold 22 % more power
at 0.21-0.28 Hz than their density, in the first half of the record, a fluctuation the record
really has (so the emulation follows it). About 1 axis in 40 without a band gets one; the
ADIS16405's z bump removes 35.7.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bmg160_emu.noise.resonant_bands import Band, Resonance

PER_OCTAVE = 16  # log bins per octave (4.4 % wide: narrower than the narrowest width tried)
HIGH_FRACTION = 1.0 / 50.0  # of the rate: the top of the search (the output stage's bands
# are read from rate/100 up, so a band there is in the model already)
LOWEST_BIN = 8  # Welch bins: the search starts this many bins above 0 Hz
RELATIVE_WIDTHS = (0.25, 0.5, 1.0)  # of the centre frequency: a band, Q of 1 to 4 (a
# narrower one is found by the 0.25 shape and narrowed by the refinement)
DETECTION = 25.0  # chi-square a band must remove (5 sigma of one candidate; measured: below)
MAX_SLOW_BANDS = 2


def find_slow_bands(frequency_hz: np.ndarray, psd: np.ndarray, segments: float, rate_hz: float,
                    fixed_psd: Callable[[np.ndarray], np.ndarray],
                    columns: Callable[[np.ndarray], list[np.ndarray]],
                    exclude: tuple[tuple[float, float], ...] = ()) -> list[Band]:
    """The slow bands of a one-sided Welch PSD of ``segments`` half-overlapping segments. The
    model: ``fixed_psd(f)`` (known: the rounding floor, the bands above) plus a non-negative
    combination of ``columns(f)`` (the white term through the response, each Gauss-Markov
    term, the random walk: their sizes refitted with each candidate band, so that a term that
    took part of a bump gives it back); ``exclude``: spans (Hz) left out (lines)."""
    from scipy.optimize import nnls

    f = np.asarray(frequency_hz, dtype=float)
    if f.size < 4 * LOWEST_BIN:
        return []
    lo, hi = LOWEST_BIN * float(f[0]), HIGH_FRACTION * rate_hz
    if not hi > 4.0 * lo:
        return []
    sel = (f >= lo) & (f <= hi)
    for a, b in exclude:
        sel &= (f < a) | (f > b)
    fs, ss = f[sel], np.asarray(psd, dtype=float)[sel]
    nb = max(math.ceil(math.log2(hi / lo) * PER_OCTAVE), 4)
    edges = np.geomspace(lo, hi * (1 + 1e-12), nb + 1)
    idx = np.searchsorted(edges, fs, side="right") - 1
    cnt = np.bincount(idx, minlength=nb)
    used = cnt > 0
    cnt = np.maximum(cnt, 1)

    def binned(values: np.ndarray) -> np.ndarray:
        return (np.bincount(idx, values, nb) / cnt)[used]

    fb, sb = binned(fs), binned(ss)
    fixed = binned(fixed_psd(fs))
    cols = [binned(c) for c in columns(fs)]
    # chi-square dof of a bin's mean: 1.9 per half-overlapping Hann segment (Welch 1967),
    # halved because neighbouring Welch bins share data
    dof = 0.95 * max(segments, 1.0) * cnt[used]
    found: list[Band] = []
    for _ in range(MAX_SLOW_BANDS):
        known = fixed + sum((r.psd(fb, rate_hz) for b in found for r in b.resonances),
                            np.zeros(fb.size))
        base, weight = _solve(cols, sb - known, sb, dof, nnls)
        best: tuple[float, float, float] | None = None
        for f0 in fb:
            for share in RELATIVE_WIDTHS:
                shape = Resonance(float(f0), share * float(f0), 1.0).psd(fb, rate_hz)
                cost, _ = _solve(cols + [shape], sb - known, sb, dof, nnls, weight)
                gain = base - cost
                if best is None or gain > best[0]:
                    best = (gain, float(f0), share * float(f0))
        if best is None or best[0] < DETECTION:
            break
        _, f0, width = best
        refined = _refine(f0, width, fb, sb, known, cols, weight, rate_hz)
        if refined is None:
            break  # refined out of the searched range, or its power's interval reaches 0
        found.append(refined)
    return found


def _solve(cols: list[np.ndarray], target: np.ndarray, data: np.ndarray, dof: np.ndarray,
           nnls: Callable[..., tuple[np.ndarray, float]], weight: np.ndarray | None = None
           ) -> tuple[float, np.ndarray]:
    """Weighted non-negative least squares of ``target`` by ``cols``: (chi-square, weights).
    Weights sqrt(dof) / model, the model from a first solve on the data's own scatter
    (weights from the noisy estimate itself bias the fit low)."""
    a = np.column_stack(cols)
    if weight is None:
        w = np.sqrt(dof) / np.maximum(data, 1e-300)
        scale = np.maximum(np.linalg.norm(a * w[:, None], axis=0), 1e-300)
        theta, _ = nnls(a * w[:, None] / scale, target * w)
        model = np.maximum(a @ (theta / scale) + (data - target), 1e-300)
        weight = np.sqrt(dof) / model
    aw = a * weight[:, None]
    scale = np.maximum(np.linalg.norm(aw, axis=0), 1e-300)
    _, rnorm = nnls(aw / scale, target * weight)
    return float(rnorm**2), weight


def _refine(f0: float, width: float, fb: np.ndarray, sb: np.ndarray, known: np.ndarray,
            cols: list[np.ndarray], weight: np.ndarray, rate_hz: float) -> Band | None:
    """The resonator that fits the bins best from this start, the other terms' sizes solved
    with it (variable projection): least squares in (f0, ln width, ln power) with 95 %
    half-widths from the Jacobian (scaled by the reduced chi-square when above 1); None when
    its power's interval reaches 0 or its centre leaves the searched range."""
    from scipy.optimize import least_squares, nnls

    a = np.column_stack(cols) * weight[:, None]
    scale = np.maximum(np.linalg.norm(a, axis=0), 1e-300)
    an = a / scale

    def residual(p: np.ndarray) -> np.ndarray:
        r = Resonance(float(p[0]), math.exp(p[1]), math.sqrt(math.exp(p[2])))
        target = (sb - known - r.psd(fb, rate_hz)) * weight
        theta, _ = nnls(an, target)
        return an @ theta - target

    shape = Resonance(f0, width, 1.0).psd(fb, rate_hz)
    power = max(float(np.sum(shape * (sb - known) * weight**2)
                      / np.sum((shape * weight) ** 2)), 1e-30)
    lo = [float(fb[0]), math.log(float(fb[0]) / 20.0), math.log(power) - 7.0]
    hi = [float(fb[-1]), math.log(2.0 * float(fb[-1])), math.log(power) + 7.0]
    x0 = np.clip([f0, math.log(width), math.log(power)], np.array(lo) + 1e-9,
                 np.array(hi) - 1e-9)
    try:
        fit = least_squares(residual, x0, bounds=(lo, hi))
        chi2 = max(float(np.sum(fit.fun**2)) / max(fb.size - 3 - len(cols), 1), 1.0)
        sd_p = np.sqrt(np.clip(np.diag(np.linalg.pinv(fit.jac.T @ fit.jac)), 0.0, None) * chi2)
    except (ValueError, np.linalg.LinAlgError):
        return None
    f_c, w, p_c = float(fit.x[0]), math.exp(fit.x[1]), math.exp(fit.x[2])
    if not (fb[0] < f_c < fb[-1]) or not 1.96 * sd_p[2] < 1.0:
        return None  # ln power's interval reaching ln 0 is any half-width: kept when < 1
    r = Resonance(f_c, w, math.sqrt(p_c))
    power_half = 1.96 * float(sd_p[2]) * p_c  # linear: below p_c, as kept
    return Band(f_c, 1.96 * float(sd_p[0]), w, w * math.expm1(1.96 * float(sd_p[1])), p_c,
                power_half, (r,))
