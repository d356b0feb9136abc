"""Haar wavelet variance of a rate record at dyadic scales, and its asymptotic covariance.

Conventions (Percival and Walden 2000, ch. 8; Guerrier et al., JASA 2013): the Haar MODWT
coefficient at scale m samples (tau = m dt, m = 1, 2, 4, ...) is half the difference of two
adjacent m-sample means,

    W(t) = (mean(x[t-m+1 .. t]) - mean(x[t-2m+1 .. t-m])) / 2,

so its variance nu^2(tau) is half the Allan variance at the same averaging time:

    AVAR(tau) = 2 nu^2(tau)        (tau = m dt, Haar filter of 2m taps)

The estimator is the mean of W^2 over the M = n - 2m + 1 coefficients free of the boundary
(the overlapping Allan variance's points, so allantools.oadev gives the same curve).

For a Gaussian process with two-sided spectral density S(f) (f in cycles per sample), the
estimates at scales i and j have the asymptotic covariance (Serroukh, Walden and Percival,
JASA 2000; Guerrier et al. 2013, eq. for Omega)

    cov(nu_i, nu_j) = (2 / max(M_i, M_j)) * integral_{-1/2}^{1/2} |H_i(f)|^2 |H_j(f)|^2 S(f)^2 df,
    |H_m(f)|^2 = sin^4(pi f m) / (m^2 sin^2(pi f)),

times a finite-record factor 1 - m / (3 M) for the larger scale (FINITE_KAPPA below),

which is what `wv_covariance` integrates (the two sin^4 factors are averaged exactly over each
cell of a log-spaced grid, so the fast oscillations of the large scales need no fine grid).
That limit is 1.8x off at the top dyadic scale of a record (M < 2m); `wv_covariance_finite`
is the exact finite-record covariance from the autocovariance (below), which the GMWM uses.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

MIN_COEFFS_FRACTION = 0.5  # default top scale: at least n / 2 coefficients (M >= n / 2)


@dataclass(frozen=True)
class WaveletVariance:
    """Haar wavelet variance of one record: nu^2 per dyadic scale (deg/s)^2."""

    m: np.ndarray  # scale in samples, 1, 2, 4, ...
    taus_s: np.ndarray  # scale in seconds, m dt
    wv: np.ndarray  # nu^2, (deg/s)^2
    n_coeffs: np.ndarray  # M = n - 2m + 1 boundary-free coefficients per scale
    n_samples: int
    rate_hz: float

    @property
    def avar(self) -> np.ndarray:
        """The overlapping Allan variance at the same taus: 2 nu^2."""
        return 2.0 * self.wv

    def edf(self) -> np.ndarray:
        """Percival and Walden's (2000, eq. 314c) lower-bound edf, max(M / m, 1)."""
        return np.maximum(self.n_coeffs / self.m, 1.0)

    def ci(self, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Chi-square interval of each nu^2 from the edf above (a per-scale, model-free bound)."""
        eta = self.edf()
        a = (1.0 - level) / 2.0
        return eta * self.wv / chi2.ppf(1.0 - a, eta), eta * self.wv / chi2.ppf(a, eta)

    def up_to(self, m_max: int) -> WaveletVariance:
        """The same estimate restricted to the scales m <= m_max."""
        keep = self.m <= m_max
        return WaveletVariance(
            self.m[keep],
            self.taus_s[keep],
            self.wv[keep],
            self.n_coeffs[keep],
            self.n_samples,
            self.rate_hz,
        )


def dyadic_scales(n_samples: int, min_coeffs_fraction: float = 0.0) -> np.ndarray:
    """Scales m = 1, 2, 4, ... with M = n - 2m + 1 >= max(1, fraction * n) coefficients."""
    least = max(1.0, min_coeffs_fraction * n_samples)
    m_max = (n_samples + 1 - least) / 2.0
    if m_max < 1:
        return np.zeros(0, dtype=np.int64)
    return 2 ** np.arange(math.floor(math.log2(m_max)) + 1, dtype=np.int64)


def haar_wv(
    rate_dps: np.ndarray, rate_hz: float, min_coeffs_fraction: float = 0.0
) -> WaveletVariance:
    """Haar wavelet variance of a 1-D record at every dyadic scale (default: all of them,
    m <= n / 2, the scales allantools.oadev(taus='octave') returns)."""
    x = np.asarray(rate_dps, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"haar_wv takes one axis (1-D array), got shape {x.shape}")
    n = x.size
    m = dyadic_scales(n, min_coeffs_fraction)
    if m.size == 0:
        raise ValueError(f"a record of {n} sample(s) has no dyadic scale (need at least 2)")
    # sums of x from a zero-padded cumulative sum; the mean is removed first so the running
    # sum stays small (the Haar filter ignores constants)
    c = np.empty(n + 1)
    c[0] = 0.0
    np.cumsum(x - x.mean(), out=c[1:])
    buf = np.empty(n)
    wv = np.empty(m.size)
    counts = n - 2 * m + 1
    for k, (mk, count) in enumerate(zip(m.tolist(), counts.tolist())):
        d = buf[:count]
        np.add(c[2 * mk :], c[:count], out=d)
        d -= c[mk : mk + count]
        d -= c[mk : mk + count]
        wv[k] = float(np.einsum("i,i->", d, d)) / (4.0 * mk * mk * count)  # no BLAS threads
    return WaveletVariance(m, m / float(rate_hz), wv, counts, n, float(rate_hz))


def haar_squared_gain(f: np.ndarray, m: int) -> np.ndarray:
    """|H_m(f)|^2 = sin^4(pi f m) / (m^2 sin^2(pi f)) of the Haar filter at scale m."""
    f = np.asarray(f, dtype=float)
    return np.sin(np.pi * f * m) ** 4 / (m * m * np.sin(np.pi * f) ** 2)


# sin^4(x) = 3/8 - cos(2x)/2 + cos(4x)/8: coefficient of cos(2 pi p m f), p = 0, 1, 2
_SIN4 = ((0, 3.0 / 8.0), (1, -0.5), (2, 1.0 / 8.0))


def _cell_mean_cos(nu: float | np.ndarray, f_mid: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Mean of cos(2 pi nu f) over each cell [f_mid - half, f_mid + half]."""
    return np.cos(2.0 * np.pi * nu * f_mid) * np.sinc(2.0 * nu * half)


def frequency_cells(m_max: int, cells_per_octave: int = 70) -> tuple[np.ndarray, np.ndarray]:
    """Log-spaced cells (midpoints, half-widths) covering (0, 1/2] cycles per sample.

    The first cell starts at 0 and ends three decades below the largest scale's band."""
    f_lo = 1e-3 / (4.0 * m_max)
    octaves = math.log2(0.5 / f_lo)
    edges = 0.5 * 2.0 ** -np.linspace(octaves, 0.0, math.ceil(octaves * cells_per_octave) + 1)
    edges = np.concatenate(([0.0], edges))
    return 0.5 * (edges[1:] + edges[:-1]), 0.5 * (edges[1:] - edges[:-1])


def wv_covariance(
    m: np.ndarray,
    n_coeffs: np.ndarray,
    spectrum: Callable[[np.ndarray], np.ndarray],
    cells_per_octave: int = 70,
) -> np.ndarray:
    """Asymptotic covariance matrix of the Haar WV estimates of a Gaussian process.

    spectrum(f): the process's two-sided spectral density at f cycles per sample, with
    integral over (-1/2, 1/2] equal to the variance (a random walk's pseudo-spectrum is fine:
    the Haar gain vanishes at f = 0 fast enough). Module docstring for the formula.
    """
    m = np.asarray(m, dtype=np.int64)
    f, half = frequency_cells(int(m.max()), cells_per_octave)
    width = 2.0 * half
    s = spectrum(f)
    envelope = 2.0 * width * s * s / np.sin(np.pi * f) ** 4  # factor 2: both signs of f
    J = m.size
    out = np.empty((J, J))
    mf = m.astype(float)
    # a factor whose oscillation the cell resolves is evaluated at the midpoint (exact where
    # sin^4 is tiny); an unresolved one is replaced by its exact mean over the cell
    resolved = half[None, :] * mf[:, None] < _RESOLVED
    direct = np.sin(np.pi * f[None, :] * mf[:, None]) ** 4
    mean_one = np.where(resolved, direct, _sin4_cell_mean(mf[:, None], f, half))
    for i in range(J):
        for j in range(i, J):
            osc = mean_one[i] * mean_one[j]
            both = ~resolved[i] & ~resolved[j]
            if both.any() and i != j:
                osc[both] = _sin4_product_cell_mean(mf[i], mf[j], f[both], half[both])
            elif both.any():
                osc[both] = _sin4_product_cell_mean(mf[i], mf[i], f[both], half[both])
            value = float(np.einsum("i,i->", envelope, osc)) / (mf[i] ** 2 * mf[j] ** 2)
            count = max(n_coeffs[i], n_coeffs[j])
            finite = max(1.0 - FINITE_KAPPA * mf[j] / count, 0.1)
            out[i, j] = out[j, i] = 2.0 * value * finite / count
    return out


# Finite-record correction of the asymptotic formula: the exact variance is
# (2 / M^2) sum_h (M - |h|) c(h)^2, i.e. the asymptotic one times 1 - kappa m / M with kappa =
# sum |h| c^2 / (m sum c^2): 1/2 for white noise (closed form), 0.23 for a random walk
# (3000-record Monte Carlo at m / M = 1/2); the middle value is used for every process.
FINITE_KAPPA = 1.0 / 3.0


_RESOLVED = 0.05  # cell half-width times scale below which sin^4(pi f m) is taken at the midpoint


def _sin4_cell_mean(m: np.ndarray, f: np.ndarray, half: np.ndarray) -> np.ndarray:
    out = np.zeros(np.broadcast(m, f).shape)
    for p, a in _SIN4:
        out += a * _cell_mean_cos(p * m, f, half)
    return out


def _sin4_product_cell_mean(mi: float, mj: float, f: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Exact cell mean of sin^4(pi f mi) sin^4(pi f mj) (a product of two cosine sums)."""
    osc = np.zeros_like(f)
    for p, ap in _SIN4:
        for q, aq in _SIN4:
            plus = p * mi + q * mj
            minus = abs(p * mi - q * mj)
            osc += 0.5 * ap * aq * (_cell_mean_cos(plus, f, half) + _cell_mean_cos(minus, f, half))
    return osc


# -- exact finite-record covariance ----------------------------------------------------------
#
# The estimate at scale m is the mean of W_m(t)^2 over the M = n - 2m + 1 boundary-free t, so
# for a Gaussian process, exactly (no large-sample limit),
#
#     cov(nu_i, nu_j) = 2 / (M_i M_j) sum_h count_ij(h) c_ij(h)^2,
#
# c_ij(h) = cov(W_i(t), W_j(t + h)) and count_ij(h) the number of pairs (t, t + h) of the two
# index ranges. The Haar filters are two boxes each, so c_ij(h) is a signed sum of 16 box-box
# sums of the autocovariance gamma, each four values of its second sum P (P(j + 1) - 2 P(j) +
# P(j - 1) = gamma(j): gmwm_processes.model_second_sum). P is a polynomial (white noise,
# random walk) or a polynomial plus an exponential (Gauss-Markov) between the lags where one
# of its arguments changes sign; around those lags the sum over h is taken term by term, and
# between them, where the summand is smooth, by Gauss-Legendre quadrature of the integral
# over the cells [h - 1/2, h + 1/2] (exact for the polynomials' degree; pieces growing
# geometrically away from the breaks for the exponentials).

_EXACT_HALF_WIDTH = 2  # lags summed term by term on each side of a break
_EXACT_GAP = 64  # gaps shorter than this are summed term by term too
_GAUSS_X, _GAUSS_W = np.polynomial.legendre.leggauss(16)  # exact to degree 31


def _box_terms(mi: int, mj: int) -> tuple[np.ndarray, np.ndarray]:
    """Offsets c_k and weights w_k with c_ij(h) = sum_k w_k P(h + c_k)."""
    offs, wts = [], []
    for a0, sa in ((0, 1.0), (mi, -1.0)):
        for b0, sb in ((0, 1.0), (mj, -1.0)):
            e = a0 - b0
            for c, s in ((e + mi, 1.0), (e + mi - mj, -1.0), (e, -1.0), (e - mj, 1.0)):
                offs.append(c)
                wts.append(sa * sb * s / (4.0 * mi * mj))
    return np.array(offs, dtype=float), np.array(wts)


def _graded(a: float, b: float, decay: float | None) -> np.ndarray:
    """Piece edges of [a, b]: one piece, or pieces doubling away from both ends."""
    if decay is None or b - a <= 2.0 * decay:
        return np.array([a, b])
    steps = decay * (2.0 ** np.arange(0, 64) - 1.0) / 2.0
    steps = steps[steps < (b - a) / 2.0]
    return np.unique(np.concatenate((a + steps, b - steps, [a, b])))


def wv_covariance_finite(
    m: np.ndarray,
    n_samples: int,
    second_sum: Callable[[np.ndarray], np.ndarray],
    decay: float | None = None,
) -> np.ndarray:
    """Exact covariance matrix of the Haar WV estimates of a record of n_samples samples of a
    Gaussian process, given the second sum P of its (generalized) autocovariance and the
    shortest correlation length in samples (None: P is piecewise polynomial). See above."""
    m = np.asarray(m, dtype=np.int64)
    n = int(n_samples)
    J = m.size
    out = np.empty((J, J))
    hi = n - 1
    for i in range(J):
        for j in range(i, J):
            mi, mj = int(m[i]), int(m[j])
            offs, wts = _box_terms(mi, mj)
            lo_i, lo_j = 2 * mi - 1, 2 * mj - 1
            h_lo, h_hi = lo_j - hi, hi - lo_i  # where count_ij > 0
            if decay is None:  # W_i(t), W_j(t + h) share no sample (or, for quantization
                # noise, no draw) outside this range
                h_lo, h_hi = max(h_lo, -2 * mi - 1), min(h_hi, 2 * mj + 1)
            breaks = np.concatenate((-offs, [0.0, lo_j - lo_i, h_lo, h_hi]))
            breaks = np.unique(np.clip(breaks, h_lo, h_hi)).astype(np.int64)
            exact = [np.arange(b - _EXACT_HALF_WIDTH, b + _EXACT_HALF_WIDTH + 1) for b in breaks]
            pts = np.unique(np.clip(np.concatenate(exact), h_lo, h_hi))
            nodes, weights = [pts.astype(float)], [np.ones(pts.size)]
            gaps = np.flatnonzero(np.diff(pts) > 1)
            for g in gaps:
                u, v = int(pts[g]) + 1, int(pts[g + 1]) - 1
                if v - u + 1 < _EXACT_GAP:
                    nodes.append(np.arange(u, v + 1, dtype=float))
                    weights.append(np.ones(v - u + 1))
                    continue
                edges = _graded(u - 0.5, v + 0.5, decay)
                mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * (edges[1:] - edges[:-1])
                nodes.append((mid[:, None] + half[:, None] * _GAUSS_X[None, :]).ravel())
                weights.append((half[:, None] * _GAUSS_W[None, :]).ravel())
            h = np.concatenate(nodes)
            wq = np.concatenate(weights)
            c = second_sum(h[:, None] + offs[None, :]) @ wts
            count = np.minimum(hi, hi - h) - np.maximum(lo_i, lo_j - h) + 1.0
            total = float(np.einsum("i,i,i,i->", wq, np.maximum(count, 0.0), c, c))
            M_i, M_j = n - 2 * mi + 1, n - 2 * mj + 1
            out[i, j] = out[j, i] = 2.0 * total / (M_i * M_j)
    return out
