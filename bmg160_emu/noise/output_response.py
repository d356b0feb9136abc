"""A sensor's output stage as its record shows it, of any shape: the broadband response
(averaging and decimation FIRs, cascaded stages, Butterworths of any order), resonant bands
(resonant_bands.py) and true lines.

Why non-parametric. A static record's fast noise is white noise through the output stage, so
its one-sided PSD above rate/100 (where the slow terms add below 0.1 %) is 2 N^2 |H(f)|^2 plus
the rounding floor. |H(f)|^2 of any stable filter is a cosine series,
c0 + 2 sum_k c_k cos(2 pi k f / rate), whose coefficients are the filtered noise's
autocovariance (Wiener-Khinchin): an FIR of K + 1 taps has exactly K of them, an IIR
filter's decay geometrically. The series is linear in c, so it is fitted by weighted least
squares and its order K chosen by BIC (Schwarz 1978) from 0 (flat) to 64: the ADIS16405's
x and y (a two-sample average, lag-1 0.17) take K = 1, a 4th-order Butterworth at 20 Hz at
100 Hz K = 16. The shape is realised as the minimum-phase FIR with that |H|^2, the spectral
factor of an MA(K) process, computed by folding the real cepstrum (Oppenheim and Schafer,
Discrete-Time Signal Processing, 3rd ed., sec. 13.9): its output has the record's
autocovariance at every lag, so std, lag-1..K correlation and PSD are reproduced by
construction, whatever the filter was. No family of filters is assumed; none is needed.

Steps (find_output_stage, then fit_fast_shape once the slow terms are known):

1. Narrowband excesses: Welch bins above the running median of a window of rate/10 (on a
   monotone roll-off the median is the centre value; a peak stands out) beyond the
   chi-square quantile of a 1e-3 false alarm over all bins. An excess held in a few fine
   bins is a line (IEEE 952 sinusoid, A^2 / 2 its power); a wider one a band, fitted with
   resonators over a span of 7 times its width, on S / |H|^2 - 2 N^2.
2. The broadband response: the cosine series on the bins outside the bands' spans, of an
   order low enough not to follow a band (its resolution rate / 2K at least twice the band).
3. The whole fast shape for reproduction at the record's rate (fit_fast_shape): the PSD from
   rate/300 up, less the slow terms' PSD from the Allan fit and the lines' bins, bands
   included, K up to 64. Anchored that low its DC value is the white level the slow terms
   sit on (fitted from rate/100 with K = 96 the DC value of the ADIS16405's z axis was 30 %
   off and the emulated Allan deviation missed 8 of 12 taus).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from bmg160_emu.noise.resonant_bands import Band, Resonance, measure_band
from bmg160_emu.noise.spectrum import rounding_floor_psd

ORDERS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48)  # K tried (autocovariance lags)
SMOOTH_ORDER = 8  # the first pass's largest K: too smooth to follow a band
BAND_ORDER = 16  # largest K beside bands (a larger one would take a band's wings)
FIT_BINS = 512  # equal-width bins of the fit (each the mean of a few Welch bins)
STRONG_EVIDENCE = 10.0  # BIC difference that counts as strong evidence (Kass and Raftery
# 1995, "Bayes factors", JASA 90: 2 ln B > 10 is very strong)
FALSE_ALARM = 1e-3  # chance of one bin wrongly called an excess over all bins
LINE_SHARE = 0.8  # share of an excess in its 6 largest fine bins that makes it a line
MERGE_FRACTION = 0.04  # of the rate: excesses closer than this are one band
FFT_GRID = 4096
MIN_BAND_SHARE = 0.01  # of the white variance: a smaller band changes no figure by 0.5 %
WING = 0.02  # of the white level: where a band's wings end
STOPBAND = 1e-3  # of the white level: below it the shape is fitted in absolute terms  # points of the cepstrum that factors the shape


@dataclass(frozen=True)
class OutputResponse:
    """|H(f)|^2 = c0 + 2 sum_k c_k cos(2 pi k f / rate_hz), with |H(0)| = 1 (``cosine``:
    c0 .. cK); ``rate_hz`` the rate it was found at."""

    rate_hz: float
    cosine: tuple[float, ...]

    @property
    def order(self) -> int:
        return len(self.cosine) - 1

    def power(self, f_hz: np.ndarray) -> np.ndarray:
        u = np.asarray(f_hz, dtype=float) / self.rate_hz
        return _cosine_matrix(u, self.order) @ np.asarray(self.cosine)

    @cached_property
    def taps(self) -> np.ndarray:
        """Minimum-phase FIR with this |H|^2, DC gain 1."""
        return minimum_phase_fir(np.asarray(self.cosine))

    def autocovariance(self) -> np.ndarray:
        """Autocovariance of unit-variance white noise through ``taps``, lags 0 .. K."""
        h = self.taps
        return np.correlate(h, h, "full")[h.size - 1:]

    def white_avar_unit(self, taus_s: np.ndarray) -> np.ndarray:
        """Allan variance at ``taus_s`` of white noise of density N = 1 through ``taps`` at
        ``rate_hz`` (exact, from the filtered noise's autocovariance)."""
        from bmg160_emu.noise.butterworth import WhiteThroughFilter

        m = np.maximum(np.rint(np.asarray(taus_s, dtype=float) * self.rate_hz), 1)
        stats = WhiteThroughFilter(np.r_[self.autocovariance(), 0.0])
        return stats.avar_unit(m.astype(np.int64)) * self.rate_hz

    @property
    def lag1(self) -> float:
        r = self.autocovariance()
        return float(r[1] / r[0]) if r.size > 1 else 0.0

    def text(self) -> str:
        if self.order == 0:
            return "flat (no output filter)"
        return (f"measured shape, {self.order + 1}-tap minimum-phase FIR (lag-1 "
                f"{self.lag1:+.3f}, -3 dB at {self.corner_hz():.3g} Hz)")

    def corner_hz(self) -> float:
        f = np.linspace(0.0, self.rate_hz / 2.0, 2049)
        below = np.flatnonzero(self.power(f) < 0.5)
        return float(f[below[0]]) if below.size else self.rate_hz / 2.0


@dataclass
class SpectralFindings:
    """What the PSD above rate/100 shows: the output response, the white level 2 N^2
    (one-sided, at DC) it implies, the bands (resonators with 95 % half-widths of f0, width,
    B) and the lines (A deg/s, f Hz, A's 95 % half-width)."""

    response: OutputResponse
    white_level: float
    bands: list[Band] = field(default_factory=list)
    lines: list[tuple[float, float, float]] = field(default_factory=list)

    @property
    def N_psd(self) -> float:
        return math.sqrt(self.white_level / 2.0)


def _cosine_matrix(u: np.ndarray, order: int) -> np.ndarray:
    k = np.arange(order + 1)
    a = np.cos(2.0 * np.pi * np.outer(u, k))
    a[:, 1:] *= 2.0
    return a


def minimum_phase_fir(cosine: np.ndarray, grid: int = FFT_GRID) -> np.ndarray:
    """The minimum-phase spectral factor h (K + 1 taps, sum 1) of |H|^2 = c0 + 2 sum c_k
    cos(k w), by folding the real cepstrum of log |H| (causal, minimum phase)."""
    order = cosine.size - 1
    if order == 0:
        return np.array([1.0])
    s = _cosine_matrix(np.arange(grid) / grid, order) @ cosine
    s = np.maximum(s, 1e-9 * float(s.max()))
    cep = np.fft.ifft(0.5 * np.log(s)).real
    fold = np.zeros(grid)
    fold[0] = cep[0]
    fold[1: grid // 2] = 2.0 * cep[1: grid // 2]
    fold[grid // 2] = cep[grid // 2]
    h = np.fft.ifft(np.exp(np.fft.fft(fold))).real[: order + 1]
    return h / h.sum()


def _fit_bins(f: np.ndarray, S: np.ndarray, segments: float) -> tuple[
        int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The PSD averaged into up to FIT_BINS equal bins: (count of bins, bin edges, the bin
    of each frequency, frequencies per bin, mean frequency, mean PSD, chi-square dof)."""
    nb = max(min(FIT_BINS, f.size // 2), 8)
    edges = np.linspace(f[0], f[-1] * (1 + 1e-12), nb + 1)
    idx = np.searchsorted(edges, f, side="right") - 1
    cnt = np.maximum(np.bincount(idx, minlength=nb), 1)
    fb = np.bincount(idx, f, nb) / cnt
    sb = np.bincount(idx, S, nb) / cnt
    # chi-square dof of a bin: 1.9 per half-overlapping Hann segment (Welch 1967), halved
    # because neighbouring Welch bins share data
    dof = 0.95 * max(segments, 1.0) * cnt
    return nb, edges, idx, cnt, fb, sb, dof


def find_output_stage(frequency_hz: np.ndarray, psd: np.ndarray, segments: float,
                      rate_hz: float, lsb_dps: float | None = None) -> SpectralFindings:
    """The output response, bands and lines from a one-sided Welch PSD of ``segments``
    half-overlapping segments."""
    from scipy.stats import chi2

    floor = rounding_floor_psd(lsb_dps, rate_hz)
    sel = frequency_hz >= rate_hz / 100.0
    f, S = frequency_hz[sel], psd[sel]
    nb, edges, idx, cnt, fb, sb, dof = _fit_bins(f, S, segments)
    u = fb / rate_hz
    limit = (chi2.isf(FALSE_ALARM / nb, dof) / dof - 1.0) * np.sqrt(dof)

    # narrowband excesses: bins far above the running median of a window wider than any
    # band (rate/10): on a monotone roll-off the median is the centre value, a peak stands out
    from scipy.ndimage import median_filter

    window = max(round(0.1 * rate_hz / float(f[1] - f[0])) | 1, 65)
    med = median_filter(S, size=window, mode="nearest")
    medb = np.bincount(idx, med, nb) / cnt
    z = (sb - medb) / (medb / np.sqrt(dof))
    keep = ~_widen((z > limit) & (fb < 0.98 * rate_hz / 2.0))
    regions = _runs(~keep)
    df = float(f[1] - f[0])
    lines, band_runs, line_bins = [], [], np.zeros(nb, dtype=bool)
    for i, j in regions:
        s = (f >= edges[i]) & (f < edges[j])
        excess = np.clip(S[s] - med[s], 0.0, None)
        if not excess.sum() > 0:
            continue
        top = np.sort(excess)[::-1][:6].sum() / excess.sum()
        if top > LINE_SHARE:
            power = float(excess.sum() * df)
            amplitude = math.sqrt(2.0 * power)
            noise = float(med[s].sum() * df)
            sd_power = math.sqrt((2.0 * power * noise + noise**2) * 2.0 / (1.9 * segments))
            lines.append((amplitude, float(np.dot(f[s], excess) / excess.sum()),
                          1.96 * sd_power / amplitude))
            line_bins[i:j] = True
        elif s.sum() > 3:
            band_runs.append((i, j))
    merged: list[tuple[int, int]] = []
    for i, j in band_runs:
        if merged and edges[i] - edges[merged[-1][1]] < MERGE_FRACTION * rate_hz:
            merged[-1] = (merged[-1][0], j)
        else:
            merged.append((i, j))
    keep = ~line_bins
    dof_fine = 0.95 * max(segments, 1.0)
    starts = merged
    spans = []
    for i, j in merged:
        width = edges[j] - edges[i]
        spans.append((edges[i] - 3.0 * width, edges[j] + 3.0 * width))
    fine_keep = np.ones(f.size, dtype=bool)
    for i, j in regions:
        if line_bins[i]:
            fine_keep &= ~((f >= edges[i]) & (f < edges[j]))
    c, level, fit_bands = _joint_fit(u, fb, sb, dof, keep, floor, rate_hz, starts, spans,
                                     f, S, fine_keep, dof_fine)
    # a band is kept with the resonators whose B is told from 0 (95 % interval; a chance
    # excess of a few bins fits as a resonator whose B interval reaches 0) and when it holds
    # MIN_BAND_SHARE of the white variance
    significant = [b for b in fit_bands if b.power - b.power_half > 0
                   and b.power >= MIN_BAND_SHARE * level * rate_hz / 2.0]
    fit_bands = significant
    response = OutputResponse(float(rate_hz), tuple(float(v) for v in c / level))
    return SpectralFindings(response, level, fit_bands, lines)


def _shape_fit(u, sb, dof, keep, floor, ratio, model, largest, orders=ORDERS):
    """The cosine series of order (from ``orders``, at most ``largest``) chosen by BIC,
    fitted by weighted least squares to the bins ``keep``."""
    scored: list[tuple[float, np.ndarray, np.ndarray, float]] = []
    for order in orders:
        if order > largest or order + 1 > keep.sum() // 4:
            break
        a = _cosine_matrix(u, order)
        w = np.sqrt(dof) / np.maximum(model, STOPBAND * float(np.max(model)))
        for _ in range(2):
            ar = a * ratio[:, None]
            c = _weighted_solve(ar[keep] * w[keep, None], (sb[keep] - floor) * w[keep])
            total = np.maximum(ar @ c, 1e-9 * float(np.abs(ar @ c).max())) + floor
            w = np.sqrt(dof) / np.maximum(total, STOPBAND * float(np.max(total)))
        cost = float(np.sum(((sb[keep] - total[keep]) * w[keep]) ** 2))
        bic = cost + (order + 1) * math.log(max(int(keep.sum()), 2))
        scored.append((bic, c, total, cost))
    assert scored
    # the smallest order within STRONG_EVIDENCE of the best: neighbouring Welch bins share
    # data, so the cost counts about twice the evidence it holds; on white records a lag-1
    # of 0.007 (2 sigma at 120,000 samples) was taken by a bare BIC
    lowest = min(item[0] for item in scored)
    best = next(item for item in scored if item[0] <= lowest + STRONG_EVIDENCE)
    return best[1], best[2], best[3], best[0]


def _weighted_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares by the normal equations on unit columns: the cosine columns are near
    orthogonal (condition below 1e3 with the weights), and LAPACK's SVD solver took 40 ms a
    call on the shared 2-core machine against 4 ms for this."""
    scale = np.linalg.norm(a, axis=0)
    scale[scale == 0] = 1.0
    an = a / scale
    try:
        return np.linalg.solve(an.T @ an, an.T @ b) / scale
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(an, b, rcond=None)[0] / scale


def _joint_fit(u, fb, sb, dof, keep, floor, rate_hz, starts, spans, fine_f, fine_s,
               fine_keep, fine_dof):
    """The broadband shape (cosine series, order by BIC) and the bands' resonators, fitted in
    turn: the shape on the bins outside the bands' spans, of an order too low to follow a
    band (its resolution rate / 2K at least twice the widest span), the resonators on
    S / |H|^2 - 2 N^2 inside each span."""
    model = sb.copy()
    if not starts:
        c, model, _, _ = _shape_fit(u, sb, dof, keep, floor, np.ones(u.size), model, ORDERS[-1])
        return c, float(np.sum(c * np.r_[1.0, 2.0 * np.ones(c.size - 1)])), []
    core = np.zeros(fb.size, dtype=bool)
    widest = 0.0
    for lo, hi in spans:
        width = (hi - lo) / 7.0  # spans are the core and 3 core widths either side
        core |= (fb >= lo + 3.0 * width) & (fb <= hi - 3.0 * width)
        widest = max(widest, width)
    largest = max(int(rate_hz / (4.0 * max(widest, 1e-9))), 1)
    clear = keep & ~core
    ratio = np.ones(u.size)
    bands: list[Band] = []
    for _ in range(3):  # a band's wings outside its core lift the broadband: divided out
        c, model, _c, _b = _shape_fit(u, sb, dof, clear, floor, ratio, model, largest)
        level = float(np.sum(c * np.r_[1.0, 2.0 * np.ones(c.size - 1)]))
        h2 = np.maximum(_cosine_matrix(fine_f / rate_hz, c.size - 1) @ c / level, 1e-6)
        total = (fine_s - floor) / h2
        bands = []
        for lo, hi in spans:
            reg = (fine_f >= lo) & (fine_f <= hi) & fine_keep
            bands.append(measure_band(fine_f[reg], total[reg] - level,
                                      total[reg] / np.sqrt(fine_dof), rate_hz))
        ratio = 1.0 + sum((Resonance(b.centre_hz, b.width_hz, b.B).psd(fb, rate_hz)
                           for b in bands if b.power > 0), np.zeros(fb.size)) / level
    return c, level, bands


def _bands_psd(bands, f: np.ndarray, rate_hz: float) -> np.ndarray:
    out = np.zeros(np.shape(f))
    for band in bands:
        for r in band.resonances:
            out = out + r.psd(f, rate_hz)
    return out


def _widen(mask: np.ndarray, by: int = 2) -> np.ndarray:
    out = mask.copy()
    for s in range(1, by + 1):
        out[s:] |= mask[:-s]
        out[:-s] |= mask[s:]
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    runs, i = [], 0
    while i < mask.size:
        if mask[i]:
            j = i
            while j < mask.size and mask[j]:
                j += 1
            runs.append((i, j))
            i = j
        else:
            i += 1
    return runs


FULL_ORDERS = (0, 1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64)
FULL_LOW_FRACTION = 1.0 / 300.0  # of the rate: where the whole fast shape is fitted from


def fit_fast_shape(frequency_hz: np.ndarray, psd: np.ndarray, segments: float, rate_hz: float,
                   lsb_dps: float | None = None, slow_psd: np.ndarray | None = None,
                   lines: tuple[tuple[float, float, float], ...] | list[tuple[float, float, float]] = (),
                   ) -> tuple[OutputResponse, float]:
    """The record's whole fast spectrum (output filter and bands as measured) as one
    response normalised at DC, and its white level 2 N^2: the PSD from rate/300 up, less the
    slow terms' PSD (``slow_psd``, from the Allan fit) and the lines' bins, fitted as a cosine
    series of order up to 64 by BIC. Anchored that low, its DC value is the white level the
    slow terms sit on; a band narrower than rate / 128 is followed by it exactly."""
    floor = rounding_floor_psd(lsb_dps, rate_hz)
    sel = frequency_hz >= rate_hz * FULL_LOW_FRACTION
    f, S = frequency_hz[sel], psd[sel].copy()
    if slow_psd is not None:
        S = S - slow_psd[sel]
    nb, edges, _, _, fb, sb, dof = _fit_bins(f, S, segments)
    keep = np.ones(nb, dtype=bool)
    df = float(f[1] - f[0]) if f.size > 1 else 1.0
    for _, fl, _ in lines:
        keep &= np.abs(fb - fl) > 4.0 * df + (edges[1] - edges[0])
    c, _, _, _ = _shape_fit(fb / rate_hz, sb, dof, keep, floor, np.ones(nb), sb.copy(),
                            FULL_ORDERS[-1], FULL_ORDERS)
    level = float(np.sum(c * np.r_[1.0, 2.0 * np.ones(c.size - 1)]))
    return OutputResponse(float(rate_hz), tuple(float(v) for v in c / level)), level


def bands_autocovariance(bands: list[Band], response: OutputResponse, rate_hz: float,
                         lags: int = 8192) -> np.ndarray:
    """Autocovariance (lags 0 .. lags - 1, (deg/s)^2) of the bands' resonators through the
    response: the bands' own autocovariance convolved with the response's (both even)."""
    own = np.zeros(lags)
    for band in bands:
        for r in band.resonances:
            own += r.autocovariance(rate_hz, lags)
    h = response.autocovariance()
    both = np.convolve(np.r_[own[:0:-1], own], np.r_[h[:0:-1], h])
    middle = both.size // 2
    return both[middle: middle + lags]
