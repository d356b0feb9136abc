"""The output low-pass designed: the digital Butterworth of the chip's BW codes (register
spec 5.3, ``bandwidths.py``) and of a profile's own ``[output]`` filter, its power response,
and what it does to white noise: the variance, the sample correlation and the Allan
variance of the filtered noise. ``lowpass.py`` runs the design on three axes.

Why in the noise layer: identification fits such a filter to a record and a profile
carries it, with no chip in sight; the chip builds its own filter from the same design.
The design is numpy only (a chip does not import scipy, issue 10); the impulse response,
used by identification alone, takes scipy.signal.lfilter.

For a digital Butterworth of order n made by the bilinear transform with the cut-off
prewarped (what scipy.signal.butter does), the power response is exactly

    |H(f)|^2 = 1 / (1 + (tan(pi f / fs) / tan(pi fc / fs))^(2 n))

so the -3 dB point sits at fc and the response falls to 0 at the Nyquist frequency.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

# Beyond the Nyquist frequency there is no low-pass to design; scipy.signal.butter refuses
# Wn >= 1. The chip table's widest band (523 Hz at 2000 Hz ODR, spec 5.3) is Wn = 0.52.
MAX_WN = 0.99
SETTLED = 1e-17  # impulse-response tail (of its first value) below which a filter has settled
MAX_SETTLE = 1 << 20  # samples: a corner 1e-4 of the rate settles within this


@dataclass(frozen=True)
class Butterworth:
    """A digital Butterworth low-pass of ``order`` with its -3 dB point at ``corner_hz`` when
    run at ``rate_hz`` (cut-off clamped to MAX_WN of Nyquist, as the chip's design)."""

    order: int
    corner_hz: float
    rate_hz: float

    @property
    def wn(self) -> float:
        """The cut-off over Nyquist the design uses."""
        return min(self.corner_hz / (self.rate_hz / 2.0), MAX_WN)

    def coefficients(self) -> tuple[np.ndarray, np.ndarray]:
        """(b, a) of the filter (scipy.signal.lfilter's convention)."""
        return _coefficients(int(self.order), float(self.wn))

    def power(self, f_hz: np.ndarray) -> np.ndarray:
        """|H(f)|^2 at frequencies ``f_hz`` (0 .. rate / 2)."""
        f = np.asarray(f_hz, dtype=float)
        ratio = np.tan(np.pi * np.minimum(f / self.rate_hz, 0.5)) / math.tan(np.pi * self.wn / 2)
        return 1.0 / (1.0 + ratio ** (2 * self.order))

    def settle_samples(self) -> int:
        """Samples after which the filter forgets its start (tail below SETTLED)."""
        return _settle(int(self.order), float(self.wn))

    def white_stats(self) -> WhiteThroughFilter:
        """What the filter makes of unit white noise (variance, correlation, Allan)."""
        return _white_stats(int(self.order), float(self.wn))

    def text(self) -> str:
        return f"order {self.order} Butterworth at {self.corner_hz:.4g} Hz"


def butterworth(order: int, wn: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of a digital Butterworth low-pass, ``wn`` the cut-off over Nyquist (0 < wn < 1).

    The steps of scipy.signal.butter(order, wn): analog prototype poles on the unit circle,
    cut-off prewarped to 2 fs tan(pi wn / fs) with fs = 2, bilinear transform, which puts all
    zeros at z = -1, and the gain that makes the analog prototype's gain 1 carry over."""
    if not 0.0 < wn < 1.0:
        raise ValueError(f"Butterworth cut-off must be between 0 and 1 times Nyquist, not {wn}")
    m = np.arange(-order + 1, order, 2)
    poles = -np.exp(1j * np.pi * m / (2 * order))
    fs = 2.0
    warped = 2.0 * fs * np.tan(np.pi * wn / fs)
    poles = warped * poles
    gain = warped**order  # lp2lp of the prototype (gain 1, no zeros)
    fs2 = 2.0 * fs
    z_poles = (fs2 + poles) / (fs2 - poles)
    gain = gain * np.real(1.0 / np.prod(fs2 - poles))
    b = gain * np.poly(-np.ones(order))
    a = np.poly(z_poles)
    # conjugate pole pairs give a real polynomial; drop the rounding-level imaginary parts
    return np.real(b).astype(float), np.real(a).astype(float)


@cache
def _coefficients(order: int, wn: float) -> tuple[np.ndarray, np.ndarray]:
    return butterworth(order, wn)


@cache
def _settle(order: int, wn: float) -> int:
    _, a = _coefficients(order, wn)
    radius = float(np.max(np.abs(np.roots(a)))) if a.size > 1 else 0.0
    if radius <= 0.0:
        return 1
    return int(min(MAX_SETTLE, math.ceil(math.log(SETTLED) / math.log(radius)) + order))


@dataclass(frozen=True)
class WhiteThroughFilter:
    """Unit-variance white noise through a filter: the output's autocovariance R(d) for
    d = 0 .. D (0 beyond), per unit input variance."""

    autocovariance: np.ndarray

    @property
    def variance_ratio(self) -> float:
        """Output variance over input variance (sum of h^2)."""
        return float(self.autocovariance[0])

    def correlation(self, lag: int = 1) -> float:
        r = self.autocovariance
        return float(r[lag] / r[0]) if lag < r.size else 0.0

    def avar_unit(self, m: np.ndarray) -> np.ndarray:
        """Allan variance at averaging factors ``m`` (samples) of the filtered noise per unit
        input variance, exactly (the expectation of the overlapping estimator):
        sigma^2(m) = [2 Var(S_m) - 2 Cov(S_m, S'_m)] / (2 m^2), S_m a sum of m samples, with
        Var(S_m) = m R0 + 2 sum_{d<m} (m - d) R(d) and Cov = sum_{d<2m} min(d, 2m - d) R(d).
        Beyond the correlation length D the sums close: sigma^2 = P0 / m - 3 M1 / m^2 with
        P0 = sum over all lags of R (the DC gain, 1) and M1 = sum_d d R(d): the white line
        less the filter's deficit (fit.py's -c / tau^2 column is this term)."""
        m = np.asarray(m, dtype=np.int64)
        r = self.autocovariance
        d = np.arange(r.size, dtype=float)
        c0 = np.concatenate(([0.0], np.cumsum(r[1:])))  # c0[k] = sum_{1..k} R
        c1 = np.concatenate(([0.0], np.cumsum(d[1:] * r[1:])))  # c1[k] = sum_{1..k} d R
        last = r.size - 1

        def at(c: np.ndarray, k: np.ndarray) -> np.ndarray:
            return c[np.minimum(k, last)]

        p0 = r[0] + 2.0 * c0[-1]
        out = np.empty(m.shape, dtype=float)
        far = m > last
        mf = m[far].astype(float)
        out[far] = p0 / mf - 3.0 * c1[-1] / mf**2
        near = ~far
        mn = m[near]
        mfn = mn.astype(float)
        var = mfn * r[0] + 2.0 * (mfn * at(c0, mn - 1) - at(c1, mn - 1))
        cov = at(c1, mn) + 2.0 * mfn * (at(c0, 2 * mn - 1) - at(c0, mn)) - (
            at(c1, 2 * mn - 1) - at(c1, mn))
        out[near] = (2.0 * var - 2.0 * cov) / (2.0 * mfn**2)
        return out


@cache
def _white_stats(order: int, wn: float) -> WhiteThroughFilter:
    from scipy.signal import lfilter

    b, a = _coefficients(order, wn)
    length = _settle(order, wn) + 8
    h = lfilter(b, a, np.r_[1.0, np.zeros(length - 1)])
    full = np.correlate(h, h, mode="full")[length - 1:]
    return WhiteThroughFilter(full)


def white_avar_unit(taus_s: np.ndarray, rate_hz: float, flt: Butterworth | None) -> np.ndarray:
    """Allan variance of white noise of density N = 1 (two-sided, IEEE 952) at ``taus_s``:
    1 / tau without a filter, the exact discrete value through ``flt``."""
    taus = np.asarray(taus_s, dtype=float)
    if flt is None:
        return 1.0 / taus
    m = np.maximum(np.rint(taus * rate_hz), 1).astype(np.int64)
    # white of density 1 has per-sample variance rate_hz; tau = m / rate_hz
    return flt.white_stats().avar_unit(m) * rate_hz
