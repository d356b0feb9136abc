"""The sensor's output stage as a record shows it: the low-pass of its output, the step it
quantizes to, and periodic lines (issue 23). identify fits the noise with them and writes
them into the profile (``[output]``, the sine terms), so generate reproduces the record.

- Filter, from the one-sided Welch PSD: S(f) = 2 N^2 |H(f)|^2 + the quantization floor,
  H a digital Butterworth (butterworth.py) of order 1 to 4 and corner fc, fitted to the
  log of the PSD in 60 logarithmic bins from rate/100 to Nyquist (there only white noise
  and the filter matter: a Gauss-Markov term of T = 5 s adds 0.1 % at rate/100). The order
  with the smallest residual wins; the record is called filtered when that residual beats
  the flat model by a wide margin (F above FILTERED_F) and the corner is below 0.95 of
  Nyquist. The corner's interval comes from the residual's curvature.
- Filter, from an Allan deviation curve alone (no samples): the points of its shallow start
  (diagnostics.white_region_start) fitted with the exact Allan variance of filtered white
  noise (butterworth.white_avar_unit), order 2 (the chip's, bandwidths.LOWPASS_ORDER) unless another fits better.
- Quantization: the grid the values sit on (``output_grid``): white noise of variance
  LSB^2 / 12 after the filter, which generate reproduces by rounding to the same grid.
- Lines: Welch bins far above the running median of their neighbours (beyond the
  chi-square quantile of a 1e-3 false alarm over all bins): IEEE 952 sinusoidal terms
  A sin(2 pi f t + phase), A from the line's power (A^2 / 2), f its power-weighted centre.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bmg160_emu.noise.allan import AllanCurve
from bmg160_emu.noise.bandwidths import LOWPASS_ORDER
from bmg160_emu.noise.butterworth import Butterworth, white_avar_unit
from bmg160_emu.noise.estimate import Estimate
from bmg160_emu.noise.spectrum import Spectrum, rounding_floor_psd

FILTER_ORDERS = (1, 2, 3, 4)
PSD_BINS = 60  # logarithmic bins of the PSD fit
FILTERED_F = 25.0  # (SSE flat - SSE filter) / (SSE filter / dof) above this: a filter
FLAT_CORNER = 0.95  # of Nyquist: a corner above this is no filter to speak of
CORNER_WIDENING = 2.0  # of the corner's linearized interval: Hann-windowed Welch bins next to
# each other share data, so the bins' residuals count about half as many independent ones
# (20 records of 20 min at 100 Hz, corners 20 and 40 Hz: all 40 intervals held the truth,
# half-widths 3 and 4.6 times the rms error of the corner)
MAX_LINES = 5
LINE_FALSE_ALARM = 1e-3  # chance of one false line over all bins of a record
LINE_WINDOW = 32  # bins either side of the running median behind a line
_GRID_SAMPLES = 200_000  # values looked at to find a record's LSB grid (the grid is the same
# over the whole record; 2e5 values hold every level of a 16-bit output within +-5 sigma)
_GRID_TOLERANCE = 0.05  # of a step: a RESD file holds rates to 1e-5 rad/s, 0.9 % of an LSB
# at 16.384 LSB/(deg/s), so its levels are off the LSB grid by less than 0.5 % of a step
_TARGET_BINS = 100  # histogram bins of a quantized record (whole LSBs per bin)


@dataclass(frozen=True)
class OutputGrid:
    """The values a quantized output can take: ``origin + k * step`` (step: one LSB, deg/s)."""

    step: float
    origin: float

    def level(self, value: float) -> int:
        return round((value - self.origin) / self.step)

    def snap(self, values: np.ndarray) -> np.ndarray:
        """``values`` rounded to the nearest level, as the chip's ADC rounds its output."""
        k = np.rint((np.asarray(values, dtype=float) - self.origin) / self.step)
        return self.origin + k * self.step

    def levels_per_bin(self, low: float, high: float) -> int:
        return max(1, math.ceil((self.level(high) - self.level(low) + 1) / _TARGET_BINS))


def output_grid(values: np.ndarray) -> OutputGrid | None:
    """The grid a quantized record's values sit on (one LSB apart), or None for a record of
    real numbers. Found from the data, so it holds for any source: ``record`` and a chip
    (counts / sensitivity), the firmware's stream (whole mdps), a RESD file (1e-5 rad/s)."""
    x = np.asarray(values, dtype=float).ravel()[:_GRID_SAMPLES]
    x = x[np.isfinite(x)]
    levels = np.unique(x)
    if levels.size < 2 or x.size < 2 * levels.size:  # real numbers: nearly every value new
        return None
    step0 = float(np.median(np.diff(levels)))
    index = np.rint((levels - levels[0]) / step0)
    step = float(np.dot(levels - levels[0], index) / np.dot(index, index))  # least squares
    if not step > 0:
        return None
    if np.abs(levels - levels[0] - index * step).max() > _GRID_TOLERANCE * step:
        return None
    return OutputGrid(step, float(levels[0]))


def quantization_avar(lsb_dps: float | None, rate_hz: float, taus_s: np.ndarray) -> np.ndarray:
    """Allan variance of rounding to ``lsb_dps``: white of variance LSB^2 / 12 per sample."""
    taus = np.asarray(taus_s, dtype=float)
    if not lsb_dps:
        return np.zeros_like(taus)
    return lsb_dps**2 / 12.0 / (taus * rate_hz)


@dataclass(frozen=True)
class FilterFit:
    """The output filter found on one axis: order, corner with its 95 % interval, and how."""

    order: int
    corner_hz: float
    corner_low_hz: float
    corner_high_hz: float
    rate_hz: float
    how: str  # one sentence: what it was fitted on and how well

    @property
    def design(self) -> Butterworth:
        return Butterworth(self.order, self.corner_hz, self.rate_hz)

    def text(self) -> str:
        return (f"order {self.order} Butterworth at {self.corner_hz:.4g} Hz "
                f"[{self.corner_low_hz:.3g}, {self.corner_high_hz:.3g}]")


def _log_bins(spectrum: Spectrum, rate_hz: float) -> tuple[np.ndarray, ...] | None:
    f, psd = spectrum.frequency_hz, spectrum.psd
    nyquist = rate_hz / 2.0
    keep = (f >= rate_hz / 100.0) & (f <= nyquist * 0.995) & (psd > 0)
    if keep.sum() < 3 * PSD_BINS:
        return None
    f, psd = f[keep], psd[keep]
    edges = np.geomspace(f[0], f[-1] * (1 + 1e-12), PSD_BINS + 1)
    which = np.searchsorted(edges, f, side="right") - 1
    counts = np.bincount(which, minlength=PSD_BINS)
    used = counts > 0
    mean = np.bincount(which, weights=psd, minlength=PSD_BINS)[used] / counts[used]
    return f, which, counts, used, np.log(mean)


def fit_filter_psd(spectrum: Spectrum, rate_hz: float, lsb_dps: float | None = None
                   ) -> FilterFit | None:
    """The output filter that shapes the PSD's white level, or None for a flat one."""
    from scipy.optimize import minimize

    binned = _log_bins(spectrum, rate_hz)
    if binned is None:
        return None
    f, which, counts, used, log_s = binned
    weights = counts[used].astype(float)  # each bin's log mean: variance ~ 1 / its bins
    floor = rounding_floor_psd(lsb_dps, rate_hz)
    nyquist = rate_hz / 2.0

    def binned_power(order: int, corner: float) -> np.ndarray:
        h2 = Butterworth(order, corner, rate_hz).power(f)
        return (np.bincount(which, weights=h2, minlength=PSD_BINS)[used] / counts[used])

    def sse(level: float, h2: np.ndarray) -> float:
        model = np.exp(level) * h2 + floor
        return float(np.sum(weights * (log_s - np.log(model)) ** 2))

    low_level = float(np.average(log_s[:5], weights=weights[:5]))
    flat = minimize(lambda p: sse(p[0], np.ones(used.sum())), [low_level], method="Nelder-Mead")
    best: tuple[float, int, float, float] | None = None
    for order in FILTER_ORDERS:
        for start in (0.1, 0.25, 0.5):
            res = minimize(lambda p, o=order: sse(p[0], binned_power(o, math.exp(p[1]))),
                           [low_level, math.log(start * nyquist)], method="Nelder-Mead",
                           options={"xatol": 1e-6, "fatol": 1e-9, "maxiter": 2000})
            corner = math.exp(res.x[1])
            if not rate_hz / 400.0 < corner < nyquist:
                continue
            if best is None or res.fun < best[0]:
                best = (float(res.fun), order, corner, float(res.x[0]))
    if best is None:
        return None
    cost, order, corner, level = best
    dof = max(int(used.sum()) - 2, 1)
    scale = max(cost / dof, 1e-300)
    f_stat = (float(flat.fun) - cost) / scale
    if f_stat < FILTERED_F or corner > FLAT_CORNER * nyquist:
        return None
    # the corner's interval from the Hessian of the scaled residual in (level, ln fc): the
    # level moves with the corner, so the corner's variance is the inverse's (1, 1) entry;
    # widened by CORNER_WIDENING for the neighbouring Welch bins' correlation
    h = 1e-3

    def at(dl: float, du: float) -> float:
        return sse(level + dl, binned_power(order, corner * math.exp(du)))

    hess = np.empty((2, 2))
    hess[0, 0] = (at(h, 0) - 2 * cost + at(-h, 0)) / h**2
    hess[1, 1] = (at(0, h) - 2 * cost + at(0, -h)) / h**2
    hess[0, 1] = hess[1, 0] = (at(h, h) - at(h, -h) - at(-h, h) + at(-h, -h)) / (4 * h**2)
    try:
        var_u = float(np.linalg.inv(hess / (2.0 * scale))[1, 1])
    except np.linalg.LinAlgError:
        var_u = math.inf
    half = min(1.96 * CORNER_WIDENING * math.sqrt(max(var_u, 0.0)), math.log(2.0))
    return FilterFit(order, corner, corner * math.exp(-half), min(corner * math.exp(half), nyquist),
                     rate_hz, f"fitted on the PSD above {rate_hz / 100:g} Hz (order {order} of "
                     f"{FILTER_ORDERS[0]}-{FILTER_ORDERS[-1]} by residual, F = {f_stat:.0f} "
                     "against no filter)")


def fit_filter_curve(curve: AllanCurve, rate_hz: float, upto_s: float,
                     lsb_dps: float | None = None, white: float | None = None
                     ) -> FilterFit | None:
    """The output filter from an Allan curve's shallow start: the points up to ``upto_s``
    (two octaves into the white region) fitted as filtered white noise, of level N^2 =
    ``white`` when given (else fitted with the corner)."""
    from scipy.optimize import minimize_scalar

    sel = curve.taus <= upto_s * (1 + 1e-9)
    tau, avar = curve.taus[sel], curve.avar[sel] - quantization_avar(lsb_dps, rate_hz,
                                                                     curve.taus[sel])
    if tau.size < 3:
        return None
    w = np.sqrt(curve.edf[sel] / 2.0) / curve.avar[sel]
    nyquist = rate_hz / 2.0

    def cost(order: int, log_corner: float) -> tuple[float, float]:
        col = white_avar_unit(tau, rate_hz, Butterworth(order, math.exp(log_corner), rate_hz))
        n2 = white if white is not None else float(np.sum(w**2 * col * avar) / np.sum(w**2 * col**2))
        return float(np.sum((w * (avar - n2 * col)) ** 2)), n2

    best: tuple[float, int, float] | None = None
    for order in FILTER_ORDERS:
        res = minimize_scalar(lambda u, o=order: cost(o, u)[0],
                              bounds=(math.log(rate_hz / 400.0), math.log(FLAT_CORNER * nyquist)),
                              method="bounded", options={"xatol": 1e-5})
        value = float(res.fun) - (0.5 if order == LOWPASS_ORDER else 0.0)  # ties: the chip's order
        if best is None or value < best[0]:
            best = (value, order, math.exp(float(res.x)))
    assert best is not None
    _, order, corner = best
    if corner > 0.99 * FLAT_CORNER * nyquist:  # on the search's edge: no filter to speak of
        return None
    return FilterFit(order, corner, corner / 2.0, min(corner * 2.0, nyquist), rate_hz,
                     f"fitted on the Allan curve's first {tau.size} points (the corner to "
                     "about a factor 2)")


@dataclass(frozen=True)
class Line:
    """A periodic component: amplitude A (deg/s) with its 95 % interval, frequency f (Hz)."""

    amplitude: Estimate
    frequency_hz: float
    ratio: float  # peak bin over its neighbours' median


def find_lines(spectrum: Spectrum, rate_hz: float, segments: float) -> list[Line]:
    """Narrow lines of the PSD (sinusoidal terms), strongest first, at most MAX_LINES."""
    from scipy.ndimage import median_filter
    from scipy.stats import chi2

    f, psd = spectrum.frequency_hz, spectrum.psd
    if f.size < 4 * LINE_WINDOW:
        return []
    background = median_filter(psd, size=2 * LINE_WINDOW + 1, mode="nearest")
    # a Welch bin of K half-overlapping Hann segments: chi-square with about 1.9 K degrees
    # of freedom (Welch 1967); its median is that distribution's median, not its mean
    dof = max(1.9 * segments, 2.0)
    median = chi2.median(dof) / dof
    threshold = chi2.isf(LINE_FALSE_ALARM / f.size, dof) / dof / median
    ratio = psd / np.maximum(background, 1e-300)
    df = float(f[1] - f[0])
    lines: list[Line] = []
    peaks = np.flatnonzero((ratio > threshold) & (f > 4 * df) & (f < 0.98 * rate_hz / 2))
    taken = np.zeros(f.size, dtype=bool)
    for i in peaks[np.argsort(-ratio[peaks])]:
        if taken[i] or len(lines) == MAX_LINES:
            continue
        lo, hi = max(i - 3, 0), min(i + 4, f.size)  # the Hann main lobe: 4 bins
        excess = np.clip(psd[lo:hi] - background[lo:hi] / median, 0.0, None)
        power = float(excess.sum() * df)  # A^2 / 2
        if not power > 0:
            continue
        taken[lo:hi] = True
        # the power's sd: per segment |S + N|^2 = |S|^2 + |N|^2 + 2 Re(S N*), whose cross
        # term has variance 2 P Pb and the noise's Pb^2 (Pb: the background's power in the
        # line's bins), over dof / 2 segments; A = sqrt(2 P), so dA = dP / A
        amplitude = math.sqrt(2.0 * power)
        noise_power = float(np.sum(background[lo:hi] / median)) * df
        sd_power = math.sqrt((2.0 * power * noise_power + noise_power**2) * 2.0 / dof)
        half = 1.96 * sd_power / amplitude
        lines.append(Line(Estimate(amplitude, max(amplitude - half, 0.0), amplitude + half,
                                   "deg/s"),
                          float(np.dot(f[lo:hi], excess) / excess.sum()), float(ratio[i])))
    return lines


def sine_avar_unit(taus_s: np.ndarray, frequency_hz: float,
                   rate_hz: float | None = None) -> np.ndarray:
    """Allan variance of A sin(2 pi f t) per unit A^2 (IEEE 952 annex C):
    (sin^2(pi f tau) / (pi f tau))^2; of its samples at ``rate_hz`` (averages of m = tau rate
    samples), sin^4(pi f tau) / (m sin(pi f / rate))^2, which it tends to far below the
    Nyquist frequency and which holds up to it (a line near Nyquist ripples the first taus)."""
    x = np.pi * frequency_hz * np.asarray(taus_s, dtype=float)
    if rate_hz is None:
        return (np.sin(x) ** 2 / x) ** 2
    m = np.maximum(np.rint(np.asarray(taus_s, dtype=float) * rate_hz), 1.0)
    return np.sin(x) ** 4 / (m * math.sin(math.pi * frequency_hz / rate_hz)) ** 2
