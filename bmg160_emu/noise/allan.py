"""Overlapping Allan deviation with confidence intervals, and the closed-form Allan variances.

The closed forms (IEEE Std 952 Annex C; noise-model.md) are what identification fits:

    quantization Q          3 Q^2 / tau^2
    angle random walk N     N^2 / tau
    Gauss-Markov (B, T)     (2 B^2 T / tau) [1 - (T / 2 tau)(3 - 4 e^(-tau/T) + e^(-2 tau/T))]
    flicker B               (2 B^2 / pi) ln 2
    rate random walk K      K^2 tau / 3
    rate ramp R             R^2 tau^2 / 2
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import allantools
import numpy as np

from bmg160_emu.noise.blas_threads import one_blas_thread

# sqrt(2 ln 2 / pi): flat Allan deviation of flicker rate noise per unit B (IEEE Std 952)
FLICKER_ADEV_FACTOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.6643


@dataclass(frozen=True)
class AllanCurve:
    """Allan deviation of a rate record, deg/s, with confidence bounds: overlapping (this
    package's own curves) or not (``overlapping`` False: a curve read from a tool that
    averages disjoint clusters, allan_variance_ros).

    ci_low / ci_high bound the deviation at `ci` probability, from Greenhall's equivalent
    degrees of freedom (edf) of that estimator with the noise type read from the local slope
    of the curve.
    """

    taus: np.ndarray  # s
    adev: np.ndarray  # deg/s
    n_terms: np.ndarray  # number of overlapping differences behind each point
    edf: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    ci: float
    overlapping: bool = True

    @property
    def avar(self) -> np.ndarray:
        return self.adev**2

    @property
    def kind(self) -> str:
        return "overlapping" if self.overlapping else "non-overlapping"


_CHUNK = 1 << 16  # samples per step of the octave OADEV (its buffers stay in a 2 MB L2)
_SHORT_M = 1 << 12  # octaves m = 1 .. _SHORT_M are taken together in one pass over the record
_LARGEST = 1e100  # |rate| above which the sums of squared differences could overflow


def octave_oadev(rate_dps: np.ndarray, rate_hz: float) -> tuple[np.ndarray, ...]:
    """allantools.oadev(data_type="freq", taus="octave") in numpy, faster and in less memory.

    allantools forms the phase x = cumsum(y - mean) dt and each term x(n + 2m) - 2 x(n + m)
    + x(n). That term is dt times the difference of two adjacent sums of m samples,
    S_m(n + m) - S_m(n), and the sums of 2m samples follow from those of m in one addition,
    S_2m(n) = S_m(n) + S_m(n + m): each octave costs a subtraction, a dot product and an
    addition (the phase form takes five passes). The short octaves (m up to _SHORT_M) are
    all done on one chunk of the record while it is in cache, so the record is read once for
    them; each longer octave is one pass over S_m, updated in place. No term is the
    difference of two large phases, so the result is at least as exact as allantools' (a
    test checks agreement to 1e-12). Returns (taus, adev, n_terms) like allantools' first,
    second and fourth outputs.
    """
    y = np.asarray(rate_dps)
    n = y.shape[0]
    if n == 0:
        raise ValueError("an Allan deviation needs samples: the record is empty")
    with np.errstate(all="ignore"):  # inf - inf in the mean is a NaN: refused below
        peak = float(np.max(np.abs(y)))
    if not math.isfinite(peak):
        raise ValueError("an Allan deviation needs finite samples: the record has NaN or inf")
    if peak > _LARGEST:
        # squares of differences would overflow: the same sums on the record scaled by a
        # power of two (exact), the deviations scaled back
        scale = 2.0 ** math.ceil(math.log2(peak))
        taus_s, devs_s, counts_s = octave_oadev(y / scale, rate_hz)
        return taus_s, devs_s * scale, counts_s
    # the mean cancels in every difference, but removing it keeps the sums of long blocks
    # small beside their differences (as allantools does)
    mean = float(np.mean(y, dtype=float))
    ms = [1 << k for k in range(n.bit_length()) if 2 << k < n]  # 2m < n: at least 2 terms
    totals = dict.fromkeys(ms, 0.0)  # sum over n of (S_m(n + m) - S_m(n))^2
    with one_blas_thread():  # a dot of 64 k doubles would wake every BLAS thread
        long_sums = _short_octaves(y, mean, [m for m in ms if m <= _SHORT_M], totals)
        _long_octaves(long_sums, n, [m for m in ms if m > _SHORT_M], totals)
    terms = [n + 1 - 2 * m for m in ms]
    devs = [math.sqrt(totals[m] / (2.0 * t)) / m for m, t in zip(ms, terms)]
    dt = 1.0 / float(rate_hz)
    return np.array([m * dt for m in ms]), np.array(devs), np.array(terms)


def _short_octaves(y: np.ndarray, mean: float, ms: list[int], totals: dict[int, float]
                   ) -> np.ndarray | None:
    """Add each short octave's squared differences to totals, one chunk of the record at a
    time (the chunk and its halo of 2 max(ms) samples in cache for all of them); return
    S_2M, M = max(ms), for the long octaves (None when there are none)."""
    n = y.shape[0]
    if not ms:
        return None
    top = ms[-1]
    halo = 2 * top - 1
    out = np.empty(max(n - 2 * top + 1, 0)) if 4 * top < n else None
    a, b = np.empty(_CHUNK + halo), np.empty(_CHUNK + halo)
    buf = np.empty(_CHUNK)
    for start in range(0, n, _CHUNK):
        stop = min(start + _CHUNK + halo, n)
        # S_1 on start..stop, in double precision whatever the record's type (a float32
        # record minus a Python float would be subtracted in float32)
        s_m = np.subtract(y[start:stop], mean, out=a[: stop - start], signature="dd->d")
        other = b
        for m in ms:
            k = min(_CHUNK, n + 1 - 2 * m - start)  # this chunk's terms of octave m
            if k <= 0:
                break
            d = np.subtract(s_m[m : m + k], s_m[:k], out=buf[:k])
            totals[m] += float(np.dot(d, d))
            size = s_m.shape[0] - m
            s_m, other = np.add(s_m[:size], s_m[m : m + size], out=other[:size]), s_m.base
        if out is not None and start < out.shape[0]:
            k = min(_CHUNK, out.shape[0] - start)
            out[start : start + k] = s_m[:k]
    return out


def _long_octaves(sums: np.ndarray | None, n: int, ms: list[int], totals: dict[int, float]
                  ) -> None:
    """Add each long octave's squared differences to totals from S_m (``sums``, the first
    of them), turning it into S_2m in place."""
    if sums is None or not ms:
        return
    buf = np.empty(_CHUNK)
    for m in ms:
        terms = n + 1 - 2 * m
        for start in range(0, terms, _CHUNK):
            k = min(_CHUNK, terms - start)
            head, tail = sums[start : start + k], sums[start + m : start + m + k]
            d = np.subtract(tail, head, out=buf[:k])
            totals[m] += float(np.dot(d, d))
            # S_2m in place: chunks go forward, so the S_m a later chunk reads (from
            # start + k on) is not written yet (numpy buffers the overlap when m < k)
            np.add(head, tail, out=head)


def overlapping_adev(
    rate_dps: np.ndarray, rate_hz: float, taus: str | np.ndarray = "octave", ci: float = 0.683
) -> AllanCurve:
    """Overlapping ADEV of one axis (frequency data) with confidence bounds: octave taus by
    octave_oadev, others by allantools.oadev."""
    if isinstance(taus, str) and taus == "octave":
        taus_out, adev, n_terms = octave_oadev(rate_dps, rate_hz)
    else:
        taus_out, adev, _err, n_terms = allantools.oadev(
            rate_dps, rate=rate_hz, data_type="freq", taus=taus
        )
    taus_out = np.asarray(taus_out, dtype=float)
    adev = np.asarray(adev, dtype=float)
    keep = np.isfinite(adev) & (adev > 0)
    taus_out, adev, n_terms = taus_out[keep], adev[keep], np.asarray(n_terms)[keep]
    alphas = noise_alpha_from_slope(taus_out, adev)
    scale = 2.0 ** math.ceil(math.log2(adev.max())) if adev.size and adev.max() > _LARGEST else 1.0
    curve = allan_confidence(
        taus_out, adev / scale, np.asarray(n_terms), alphas, rate_dps.shape[0], rate_hz, ci
    )
    if scale == 1.0:
        return curve
    return AllanCurve(curve.taus, curve.adev * scale, curve.n_terms, curve.edf,
                      curve.ci_low * scale, curve.ci_high * scale, curve.ci)


def allan_confidence(
    taus: np.ndarray,
    adev: np.ndarray,
    n_terms: np.ndarray,
    alphas: np.ndarray,
    n_samples: int,
    rate_hz: float,
    ci: float = 0.683,
    overlapping: bool = True,
) -> AllanCurve:
    """The curve with Greenhall edf and chi-square bounds for the given noise types, of
    the overlapping estimator or (``overlapping`` False) the non-overlapping one."""
    edf = np.array(
        [_edf(int(a), round(t * rate_hz), n_samples, overlapping) for a, t in zip(alphas, taus)],
        dtype=float,
    )
    edf = np.maximum(edf, 1.0)
    low, high = np.empty_like(adev), np.empty_like(adev)
    for i, (dev, e) in enumerate(zip(adev, edf)):
        low[i], high[i] = allantools.confidence_interval(dev, e, ci=ci)
    return AllanCurve(taus, adev, n_terms, edf, low, high, ci, overlapping)


def _edf(alpha: int, m: int, n_samples: int, overlapping: bool = True) -> float:
    """Greenhall's edf of an ADEV point; the simple formula where it has no case."""
    try:
        return float(allantools.edf_greenhall(alpha=alpha, d=2, m=max(m, 1), N=n_samples,
                                              overlapping=overlapping))
    except (NotImplementedError, ValueError, ZeroDivisionError):
        simple = float(allantools.edf_simple(n_samples, max(m, 1), alpha))
        # edf_simple is the overlapping estimator's; disjoint clusters hold at most N/m - 1
        return simple if overlapping else min(simple, max(n_samples / max(m, 1) - 1.0, 1.0))


def noise_alpha_from_slope(taus: np.ndarray, adev: np.ndarray) -> np.ndarray:
    """Power-law noise type alpha per point, from the local log-log slope mu of the variance.

    For frequency-type noise sigma^2 ~ tau^mu with mu = -alpha - 1 (white FM alpha = 0,
    flicker FM -1, random-walk FM -2); mu = -2 (quantization) is taken as white PM (alpha 2).
    """
    if taus.size < 2:
        return np.zeros(taus.size, dtype=int)
    with np.errstate(all="ignore"):  # a zero or non-finite point: white (alpha 0) there
        mu = np.gradient(2.0 * np.log(np.asarray(adev, dtype=float)), np.log(taus))
    mu = np.where(np.isfinite(mu), mu, -1.0)
    alpha = np.clip(np.rint(-mu - 1.0), -2, 2).astype(int)
    return alpha


def white_avar(N: float, tau: np.ndarray) -> np.ndarray:
    return N**2 / tau


def random_walk_avar(K: float, tau: np.ndarray) -> np.ndarray:
    return K**2 * tau / 3.0


def quantization_avar(Q: float, tau: np.ndarray) -> np.ndarray:
    return 3.0 * Q**2 / tau**2


def ramp_avar(R: float, tau: np.ndarray) -> np.ndarray:
    return R**2 * tau**2 / 2.0


def flicker_avar(B: float, tau: np.ndarray) -> np.ndarray:
    return np.full_like(np.asarray(tau, dtype=float), FLICKER_ADEV_FACTOR**2 * B**2)


def gauss_markov_avar_unit(tau: np.ndarray, T: float) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov process of unit std and correlation time T.

    (2 T / tau) [1 - (T / 2 tau)(3 - 4 e^(-x) + e^(-2x))], x = tau / T; for small x the
    bracket cancels, so the series 2x/3 - x^2/2 + 7x^3/30 is used below x = 1e-3.
    """
    x = np.asarray(tau, dtype=float) / T
    out = np.empty_like(x)
    small = x < 1e-3
    xs = x[small]
    out[small] = 2.0 * xs / 3.0 - xs**2 / 2.0 + 7.0 * xs**3 / 30.0
    xl = x[~small]
    bracket = 1.0 - (-4.0 * np.expm1(-xl) + np.expm1(-2.0 * xl)) / (2.0 * xl)
    out[~small] = 2.0 / xl * bracket
    return out


def gauss_markov_avar(B: float, T: float, tau: np.ndarray) -> np.ndarray:
    """Allan variance of a Gauss-Markov term of stationary std B (deg/s) and time T (s)."""
    if B == 0 or not T > 0:
        return np.zeros_like(np.asarray(tau, dtype=float))
    return B**2 * gauss_markov_avar_unit(tau, T)


def composite_avar(
    tau: np.ndarray, N: float, B: float, T: float, K: float, Q: float = 0.0, R: float = 0.0
) -> np.ndarray:
    """Allan variance of white + Gauss-Markov + random walk (+ quantization + ramp)."""
    tau = np.asarray(tau, dtype=float)
    return (
        white_avar(N, tau)
        + gauss_markov_avar(B, T, tau)
        + random_walk_avar(K, tau)
        + quantization_avar(Q, tau)
        + ramp_avar(R, tau)
    )
