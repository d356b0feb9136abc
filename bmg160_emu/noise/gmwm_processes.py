"""The latent processes of the GMWM: their exact Haar wavelet variance, spectral density and
a simulator (the discrete processes the generator draws, engine.py / discretization.py).

dt = 1 / rate_hz, tau = m dt:

    WN  white, sample std N / sqrt(dt)          nu^2 = N^2 / (2 tau)
    QN  quantization Q (w_k - w_k-1) / dt       nu^2 = 3 Q^2 / (2 tau^2)
    GM  AR(1), std B, phi = exp(-dt / T)        nu^2 = B^2 b(m, a) / (2 m^2 (1 - phi)^2), a = dt/T
        b = m (1 - e^-2a) - 3 e^-a + 4 e^-(m+1)a - e^-(2m+1)a
    RW  random walk, step K sqrt(dt)            nu^2 = K^2 dt (2 m^2 + 1) / (12 m)
    DR  drift (rate ramp) R t                   nu^2 = R^2 tau^2 / 4

Each is the variance of the Haar filter applied to the process, summed in closed form (the
AR(1) sum over its autocovariance B^2 phi^|h|; for (2m + 1) a < 1 its Taylor series, since
the closed form cancels to O(a^3) there). Twice each is the Allan variance; for large m they
become noise-model.md's continuous closed forms.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy.signal import lfilter

COMPONENTS = ("WN", "QN", "GM", "RW", "DR")
Params = Sequence[float] | np.ndarray  # physical values in parameter_names() order
Spectrum = Callable[[np.ndarray], np.ndarray]
_SERIES_TERMS = 30  # Taylor terms of b(m, a) where (2m + 1) a < 1: last term < 1 / 30!


class GMWMError(ValueError):
    """A model or record the estimator cannot take (unknown component, too few scales)."""


# -- exact wavelet variance of each process --------------------------------------------------


def wv_white(m: np.ndarray, dt: float, N: float) -> np.ndarray:
    return N * N / (2.0 * np.asarray(m, dtype=float) * dt)


def wv_quantization(m: np.ndarray, dt: float, Q: float) -> np.ndarray:
    tau = np.asarray(m, dtype=float) * dt
    return 1.5 * Q * Q / tau**2


def wv_random_walk(m: np.ndarray, dt: float, K: float) -> np.ndarray:
    mf = np.asarray(m, dtype=float)
    return K * K * dt * (2.0 * mf * mf + 1.0) / (12.0 * mf)


def wv_drift(m: np.ndarray, dt: float, R: float) -> np.ndarray:
    tau = np.asarray(m, dtype=float) * dt
    return R * R * tau**2 / 4.0


def wv_gauss_markov(m: np.ndarray, dt: float, B: float, T: float) -> np.ndarray:
    """Haar WV of the AR(1) x_k = phi x_k-1 + B sqrt(1 - phi^2) w_k (stationary std B)."""
    mf = np.asarray(m, dtype=float)
    a = dt / T
    x = (2.0 * mf + 1.0) * a
    b = np.empty_like(mf)
    small = x < 1.0
    if small.any():  # the closed form cancels to O(a^3): its Taylor series from k = 3
        ms = mf[small]
        acc = np.zeros_like(ms)
        fact = 1.0
        for k in range(1, _SERIES_TERMS + 1):
            fact *= k
            if k < 3:
                continue
            term = (
                4.0 * ((ms + 1.0) * a) ** k
                - ((2.0 * ms + 1.0) * a) ** k
                - ms * (2.0 * a) ** k
                - 3.0 * a**k
            )
            acc += (-1.0) ** k * term / fact
        b[small] = acc
    big = ~small
    if big.any():
        mb = mf[big]
        b[big] = (
            -mb * np.expm1(-2.0 * a)
            - 3.0 * math.exp(-a)
            + 4.0 * np.exp(-(mb + 1.0) * a)
            - np.exp(-(2.0 * mb + 1.0) * a)
        )
    one_minus_phi = -math.expm1(-a)
    return B * B * b / (2.0 * mf * mf * one_minus_phi**2)


# -- two-sided spectral densities (f in cycles per sample), for Omega ------------------------


def _spectrum_terms(model: Sequence[str], params: Params, dt: float) -> list[Spectrum]:
    terms: list[Spectrum] = []
    for comp, p in zip(model, _split(model, params)):
        if comp == "WN":
            terms.append(_white_spectrum(p[0] ** 2 / dt))
        elif comp == "QN":
            terms.append(_quantization_spectrum((p[0] / dt) ** 2))
        elif comp == "GM":
            terms.append(_gauss_markov_spectrum(p[0], dt / p[1]))
        elif comp == "RW":
            terms.append(_random_walk_spectrum(p[0] ** 2 * dt))
        # DR is deterministic: it adds no variance to the estimate (to first order)
    return terms


def _white_spectrum(variance: float) -> Spectrum:
    return lambda f: np.full_like(f, variance)


def _quantization_spectrum(variance: float) -> Spectrum:
    return lambda f: variance * 4.0 * np.sin(np.pi * f) ** 2  # differenced white noise


def _random_walk_spectrum(step_variance: float) -> Spectrum:
    return lambda f: step_variance / (4.0 * np.sin(np.pi * f) ** 2)


def _gauss_markov_spectrum(B: float, a: float) -> Spectrum:
    """B^2 (1 - phi^2) / |1 - phi e^(-2 pi i f)|^2 with 1 - phi kept exact (phi = e^-a)."""
    phi, omp = math.exp(-a), -math.expm1(-a)
    return lambda f: B * B * omp * (1.0 + phi) / (omp * omp + 4.0 * phi * np.sin(np.pi * f) ** 2)


# -- models ----------------------------------------------------------------------------------

PARAMETER_COUNT = {"WN": 1, "QN": 1, "GM": 2, "RW": 1, "DR": 1}  # parameters of each process
_NAMES = {"WN": ("N",), "QN": ("Q",), "GM": ("B", "T"), "RW": ("K",), "DR": ("R",)}


def check_model(model: Sequence[str]) -> tuple[str, ...]:
    """The model as a canonical tuple (components in COMPONENTS order, GM terms together)."""
    model = tuple(str(c).upper() for c in model)
    bad = [c for c in model if c not in COMPONENTS]
    if bad:
        raise GMWMError(f"unknown model component {bad[0]!r}: use {', '.join(COMPONENTS)}")
    if not model:
        raise GMWMError("the model needs at least one component")
    for c in ("WN", "QN", "RW", "DR"):
        if model.count(c) > 1:
            raise GMWMError(f"component {c} appears {model.count(c)} times: only GM may repeat")
    return tuple(sorted(model, key=COMPONENTS.index))


def parse_model(text: str) -> tuple[str, ...]:
    """'WN+GM+GM+RW' or 'WN+2GM+RW' -> ('WN', 'GM', 'GM', 'RW')."""
    out: list[str] = []
    for part in text.replace(",", "+").split("+"):
        part = part.strip().upper()
        digits = len(part) - len(part.lstrip("0123456789"))
        count = int(part[:digits]) if digits else 1
        if part:
            out.extend([part[digits:]] * count)
    return check_model(out)


def parameter_names(model: Sequence[str]) -> list[str]:
    """Names in theta order; several GM terms are numbered B1, T1, B2, T2 (T1 < T2)."""
    n_gm = list(model).count("GM")
    names, k = [], 0
    for comp in model:
        if comp == "GM" and n_gm > 1:
            k += 1
            names += [f"B{k}", f"T{k}"]
        else:
            names += list(_NAMES[comp])
    return names


def _split(model: Sequence[str], params: Params) -> list[tuple[float, ...]]:
    out, i = [], 0
    for comp in model:
        out.append(tuple(params[i : i + PARAMETER_COUNT[comp]]))
        i += PARAMETER_COUNT[comp]
    return out


def model_wv(model: Sequence[str], params: Params, m: np.ndarray, dt: float) -> np.ndarray:
    """Wavelet variance of the sum of the model's independent processes (physical params)."""
    total = np.zeros(np.asarray(m).shape)
    for comp, p in zip(model, _split(model, params)):
        total += component_wv(comp, p, m, dt)
    return total


def component_wv(comp: str, p: tuple[float, ...], m: np.ndarray, dt: float) -> np.ndarray:
    """The Haar wavelet variance of one process ``comp`` with parameters ``p`` at scales
    ``m`` (samples) for sample period ``dt`` s."""
    if comp == "WN":
        return wv_white(m, dt, p[0])
    if comp == "QN":
        return wv_quantization(m, dt, p[0])
    if comp == "GM":
        return wv_gauss_markov(m, dt, p[0], p[1])
    if comp == "RW":
        return wv_random_walk(m, dt, p[0])
    return wv_drift(m, dt, p[0])


def model_spectrum(model: Sequence[str], params: Params, dt: float):
    """The model's two-sided spectral density S(f), f in cycles per sample."""
    terms = _spectrum_terms(model, params, dt)

    def spectrum(f: np.ndarray) -> np.ndarray:
        total = np.zeros_like(f)
        for term in terms:
            total += term(f)
        return total

    return spectrum


def simulate(
    model: Sequence[str],
    params: Params,
    n: int,
    rate_hz: float,
    rng: np.random.Generator,
) -> np.ndarray:
    """A record of the model drawn as the generator draws it (stationary GM start, random
    walk from 0, drift R t from t = dt); deg/s."""
    dt = 1.0 / rate_hz
    out = np.zeros(n)
    for comp, p in zip(model, _split(model, params)):
        if comp == "WN":
            out += rng.standard_normal(n) * (p[0] / math.sqrt(dt))
        elif comp == "QN":
            w = rng.standard_normal(n + 1)
            out += np.diff(w) * (p[0] / dt)
        elif comp == "GM":
            B, T = p
            phi = math.exp(-dt / T)
            w = rng.standard_normal(n)
            start = B * float(rng.standard_normal())
            gm, _ = lfilter([B * math.sqrt(1.0 - phi * phi)], [1.0, -phi], w, zi=[phi * start])
            out += gm
        elif comp == "RW":
            out += np.cumsum(rng.standard_normal(n) * (p[0] * math.sqrt(dt)))
        else:
            out += p[0] * dt * np.arange(1, n + 1)
    return out


# -- second sums of the (generalized) autocovariance, for the exact finite-record Omega ------


def _linear_p(s2: float) -> Spectrum:  # white noise: gamma = s2 delta(j)
    return lambda j: 0.5 * s2 * np.abs(j)


def _impulse_p(s2: float) -> Spectrum:  # quantization: gamma = s2 (2, -1 at lags 0, +-1)
    return lambda j: np.where(j == 0, -s2, 0.0)


def _ar1_p(c: float, alpha: float, a: float) -> Spectrum:  # gamma = B^2 e^(-a |j|)
    return lambda j: c * np.exp(-a * np.abs(j)) + alpha * np.abs(j)


def _cubic_p(q: float) -> Spectrum:  # random walk: generalized gamma = -q |j| / 2
    return lambda j: -q * (np.abs(j) ** 3 - np.abs(j)) / 12.0


def _second_sum_terms(model: Sequence[str], params: Params, dt: float):
    """P(j) with P(j+1) - 2 P(j) + P(j-1) = gamma(j), gamma the autocovariance of each
    process (for the random walk its generalized one, -q |j| / 2, which zero-sum filters
    such as Haar's see as the covariance), as (P, decay in samples or None)."""
    terms: list[tuple[Spectrum, float | None]] = []
    for comp, p in zip(model, _split(model, params)):
        if comp == "WN":
            terms.append((_linear_p(p[0] ** 2 / dt), None))
        elif comp == "QN":
            terms.append((_impulse_p((p[0] / dt) ** 2), None))
        elif comp == "GM":
            B, T = p
            a = dt / T
            phi, omp = math.exp(-a), -math.expm1(-a)
            # c phi^|j| matches gamma off lag 0, alpha |j| adds what lag 0 lacks
            c = B * B * phi / (omp * omp)
            alpha = 0.5 * B * B * (1.0 + phi) / omp
            terms.append((_ar1_p(c, alpha, a), T / dt))
        elif comp == "RW":
            terms.append((_cubic_p(p[0] ** 2 * dt), None))
        # DR is deterministic: no variance (as in the spectra above)
    return terms


def model_second_sum(model: Sequence[str], params: Params, dt: float):
    """(P, shortest decay in samples or None) of the model's sum (see _second_sum_terms)."""
    terms = _second_sum_terms(model, params, dt)
    decays = [d for _, d in terms if d is not None]

    def P(j: np.ndarray) -> np.ndarray:
        total = np.zeros(np.shape(j))
        for term, _ in terms:
            total = total + term(j)
        return total

    return P, (min(decays) if decays else None)
