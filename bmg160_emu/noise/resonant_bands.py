"""Narrowband resonant bands of a gyroscope's noise (a MEMS structure's mechanical mode, a
drive-loop spur spread by its own jitter): random processes with a centre, a width and a
power, not sinusoids (a band's power spreads over many PSD bins at any resolution; a line's
stays in one).

A band is a sum of discrete second-order resonators (AR(2) driven by white noise)

    x(k) = a1 x(k-1) + a2 x(k-2) + g w(k),   a1 = 2 r cos(2 pi f0 / rate),  a2 = -r^2,
    r = exp(-pi width / rate)

whose PSD peaks at f0 with a -3 dB full width of about ``width`` (exact as width / rate -> 0)
and whose variance is ``power``: g follows from the AR(2) variance
g^2 (1 - a2) / ((1 + a2)((1 - a2)^2 - a1^2)) (Box, Jenkins and Reinsel, Time Series
Analysis, 4th ed., sec. 3.2.4). The parameters are in Hz and (deg/s)^2, so a band is drawn
at any output data rate whose Nyquist frequency lies above f0. A band whose shape one
resonator does not follow (the shared ADIS16405 record's z band is skewed) is fitted as a
sum of up to MAX_RESONATORS, chosen by BIC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

MAX_RESONATORS = 3


@dataclass(frozen=True)
class Resonance:
    """One resonator: centre f0 (Hz), -3 dB width (Hz), stationary std B (deg/s)."""

    f0_hz: float
    width_hz: float
    B: float

    @property
    def power(self) -> float:
        return self.B * self.B

    def coefficients(self, rate_hz: float) -> tuple[float, float, float]:
        """(g, a1, a2) of the AR(2) recursion at ``rate_hz``."""
        r = math.exp(-math.pi * self.width_hz / rate_hz)
        w0 = 2.0 * math.pi * self.f0_hz / rate_hz
        a1, a2 = 2.0 * r * math.cos(w0), -r * r
        unit = (1.0 - a2) / ((1.0 + a2) * ((1.0 - a2) ** 2 - a1 * a1))
        return math.sqrt(self.power / unit), a1, a2

    def psd(self, f_hz: np.ndarray, rate_hz: float) -> np.ndarray:
        """One-sided PSD, (deg/s)^2/Hz, at ``f_hz``."""
        g, a1, a2 = self.coefficients(rate_hz)
        z = np.exp(-2j * np.pi * np.asarray(f_hz, dtype=float) / rate_hz)
        return 2.0 * g * g / rate_hz / np.abs(1.0 - a1 * z - a2 * z * z) ** 2

    def autocovariance(self, rate_hz: float, lags: int) -> np.ndarray:
        """R(0 .. lags - 1), (deg/s)^2: the AR(2) Yule-Walker recursion from R(0), R(1)."""
        _, a1, a2 = self.coefficients(rate_hz)
        out = np.empty(lags)
        out[0] = self.power
        if lags > 1:
            out[1] = self.power * a1 / (1.0 - a2)
        for k in range(2, lags):
            out[k] = a1 * out[k - 1] + a2 * out[k - 2]
        return out

    def settle_samples(self, rate_hz: float) -> int:
        """Samples after which the recursion forgets its start (r^k below 1e-12)."""
        r = math.exp(-math.pi * self.width_hz / rate_hz)
        return math.ceil(math.log(1e-12) / math.log(r)) + 2 if r > 0 else 2


@dataclass(frozen=True)
class Band:
    """A band as its record shows it: centre (power-weighted, Hz), -3 dB full width (Hz) and
    power ((deg/s)^2, before the output filter), each with its 95 % half-width, and the
    resonators that draw it."""

    centre_hz: float
    centre_half: float
    width_hz: float
    width_half: float
    power: float
    power_half: float
    resonances: tuple[Resonance, ...]

    @property
    def B(self) -> float:
        return math.sqrt(self.power)

    def text(self) -> str:
        return (f"band at {self.centre_hz:.4g} Hz [+-{self.centre_half:.2g}], width "
                f"{self.width_hz:.3g} Hz [+-{self.width_half:.2g}], B = {self.B:.4g} deg/s "
                f"(power {self.power:.3g} (deg/s)^2 [+-{self.power_half:.2g}])")


def measure_band(f_hz: np.ndarray, excess: np.ndarray, sd: np.ndarray, rate_hz: float) -> Band:
    """The band in ``excess`` (one-sided PSD before the output filter, with the bins' sd):
    its moments, and resonators fitted to it (up to MAX_RESONATORS by BIC; one resonator of
    the measured centre, width and power where the fit strays from them by over 30 %)."""
    df = float(f_hz[1] - f_hz[0])
    pos = np.clip(excess, 0.0, None)
    power = float(excess.sum() * df)
    power_half = 1.96 * float(np.sqrt(np.sum(sd**2))) * df
    centre = float(np.dot(f_hz, pos) / max(pos.sum(), 1e-300))
    # -3 dB width: where the excess, smoothed over 5 bins, stays above half its peak (its
    # middle is the centre reported; the power-weighted mean leans to the wider flank)
    smooth = np.convolve(pos, np.ones(5) / 5.0, mode="same")
    above = np.flatnonzero(smooth >= 0.5 * smooth.max())
    width = max(float(f_hz[above[-1]] - f_hz[above[0]]) + df, df)
    centre_half = 1.96 * float(np.sqrt(np.sum((sd * (f_hz - centre)) ** 2))) * df / max(power, 1e-300)
    centre = float(f_hz[above[0]] + f_hz[above[-1]]) / 2.0  # the middle of the -3 dB width
    width_half = max(2.0 * df, width * power_half / max(power, 1e-300))
    one = (Resonance(centre, width, math.sqrt(max(power, 1e-30))),)
    try:
        res, _ = fit_resonances(f_hz, excess, sd, rate_hz)
        fitted = sum(r.power for r in res)
        if abs(fitted / max(power, 1e-300) - 1.0) > 0.3 or any(
                not f_hz[0] <= r.f0_hz <= f_hz[-1] for r in res):
            res = one
    except (ValueError, np.linalg.LinAlgError):
        res = one
    return Band(centre, centre_half, width, width_half, max(power, 0.0), power_half, res)


def band_summary(resonances: tuple[Resonance, ...]) -> tuple[float, float, float]:
    """(centre Hz, rms width Hz, power (deg/s)^2) of a band made of several resonators: the
    power-weighted centre and spread of their centres and widths."""
    p = np.array([r.power for r in resonances])
    f = np.array([r.f0_hz for r in resonances])
    w = np.array([r.width_hz for r in resonances])
    total = float(p.sum())
    centre = float(np.dot(p, f) / total)
    spread = float(np.sqrt(np.dot(p, (f - centre) ** 2 + (w / 2.0) ** 2) / total))
    return centre, 2.0 * spread, total


def fit_resonances(f_hz: np.ndarray, excess: np.ndarray, sd: np.ndarray, rate_hz: float,
                   start: tuple[Resonance, ...] = ()) -> tuple[tuple[Resonance, ...], np.ndarray]:
    """Resonators whose summed PSD follows ``excess`` (one-sided PSD before the output
    filter, (deg/s)^2/Hz) at ``f_hz`` with the bins' standard deviations ``sd``. Returns the
    resonators and each one's 95 % half-widths (f0, width, B) from the Jacobian."""
    from scipy.optimize import least_squares

    df = float(f_hz[1] - f_hz[0])
    positive = np.clip(excess, 0.0, None)
    total = max(float(positive.sum() * df), 1e-30)
    counts = [len(start)] if start else range(1, MAX_RESONATORS + 1)
    best = None
    for k in counts:
        p0: list[float]
        if start:
            p0 = [v for r in start for v in (r.f0_hz, math.log(r.width_hz), math.log(r.power))]
        else:
            cum = np.cumsum(positive) / positive.sum()
            centres = [float(np.interp((i + 0.5) / k, cum, f_hz)) for i in range(k)]
            width = max((f_hz[-1] - f_hz[0]) / (2 * k), 2 * df)
            p0 = [v for c in centres for v in (c, math.log(width), math.log(total / k))]
        lo = [v for _ in range(k) for v in (f_hz[0], math.log(df / 2), math.log(total * 1e-4))]
        hi = [v for _ in range(k) for v in (f_hz[-1], math.log(rate_hz / 4), math.log(total * 10))]
        x0 = np.clip(p0, np.array(lo) + 1e-9, np.array(hi) - 1e-9)

        def model(p: np.ndarray, k: int = k) -> np.ndarray:
            return sum((_unpack(p, i).psd(f_hz, rate_hz) for i in range(k)),
                       np.zeros_like(f_hz))

        res = least_squares(lambda p: (model(p) - excess) / sd, x0, bounds=(lo, hi))
        bic = float(np.sum(res.fun**2)) + 3 * k * math.log(f_hz.size)
        if best is None or bic < best[0]:
            best = (bic, res, k)
    assert best is not None
    _, res, k = best
    chi2_red = max(float(np.sum(res.fun**2)) / max(f_hz.size - 3 * k, 1), 1.0)
    try:
        cov = np.linalg.pinv(res.jac.T @ res.jac) * chi2_red
        sd_p = np.minimum(np.sqrt(np.clip(np.diag(cov), 0.0, None)), 5.0)
    except np.linalg.LinAlgError:
        sd_p = np.full(3 * k, 5.0)
    found = tuple(_unpack(res.x, i) for i in range(k))
    half = np.array([[1.96 * sd_p[3 * i], r.width_hz * math.expm1(1.96 * sd_p[3 * i + 1]),
                      r.B * math.expm1(0.98 * sd_p[3 * i + 2])] for i, r in enumerate(found)])
    return found, half


def _unpack(p: np.ndarray, i: int) -> Resonance:
    return Resonance(float(p[3 * i]), float(math.exp(p[3 * i + 1])),
                     float(math.sqrt(math.exp(p[3 * i + 2]))))
