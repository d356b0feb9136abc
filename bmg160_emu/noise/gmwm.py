"""Generalized Method of Wavelet Moments (GMWM) for composite gyroscope noise.

Guerrier, Skaloud, Stebler and Victoria-Feser (JASA 2013) and Stebler et al. (2012): the
parameters theta of a sum of latent processes are the minimizer of

    (nu_hat - nu(theta))' Omega^-1 (nu_hat - nu(theta)),

nu_hat the Haar wavelet variance of the record (wavelet.py), nu(theta) the model's exact
wavelet variance, Omega the covariance of nu_hat. Two steps: a first fit with the diagonal
chi-square weights 2 nu_hat^2 / edf, then Omega evaluated at that fit (the model's exact
finite-record covariance, wavelet.wv_covariance_finite: a consistent estimate when the model
holds, and cheap: no pass over the data) and the fit repeated with the full inverse; Omega is
then updated at the estimate twice more (iterated GMWM). The estimator is then
consistent and asymptotically normal with covariance (D' Omega^-1 D)^-1, D = d nu / d theta
(the asymptotic intervals below, in log parameters so that they stay positive); a parametric
bootstrap (simulate the fitted model, re-estimate) gives the other intervals.

The processes (white WN, quantization QN, Gauss-Markov GM, random walk RW, drift DR), their
exact wavelet variance and spectra are in gmwm_processes.py. Model selection: the Wavelet
Information Criterion in its asymptotic form
WIC = J + 2 p (J the minimized objective with efficient weights, p the number of
parameters; the optimism of J is 2 tr(D (D' Omega^-1 D)^-1 D' Omega^-1) = 2 p), smallest wins.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import least_squares, nnls
from scipy.stats import chi2

from bmg160_emu.noise.gmwm_processes import (
    COMPONENTS,
    PARAMETER_COUNT,
    GMWMError,
    Params,
    check_model,
    component_wv,
    model_second_sum,
    model_spectrum,
    model_wv,
    parameter_names,
    parse_model,
    simulate,
    wv_drift,
    wv_gauss_markov,
    wv_quantization,
    wv_random_walk,
    wv_white,
)
from bmg160_emu.noise.profile import UNITS
from bmg160_emu.noise.wavelet import (
    MIN_COEFFS_FRACTION,
    WaveletVariance,
    haar_wv,
    wv_covariance_finite,
)

__all__ = [
    "CANDIDATES",
    "COMPONENTS",
    "DEFAULT_MODEL",
    "GMWMError",
    "GMWMFit",
    "ParameterEstimate",
    "Params",
    "Selection",
    "bootstrap",
    "check_model",
    "gmwm_fit",
    "identify_gmwm",
    "model_spectrum",
    "model_wv",
    "omega_of",
    "parameter_names",
    "parse_model",
    "select_model",
    "simulate",
    "wv_drift",
    "wv_gauss_markov",
    "wv_quantization",
    "wv_random_walk",
    "wv_white",
]

DEFAULT_MODEL = ("WN", "GM", "RW")  # the generator's own model (noise-model.md)
CI_LEVEL = 0.95
OMEGA_UPDATES = 2  # Omega re-evaluated at the estimate and the fit repeated, after step 2
_Z95 = 1.959963984540054  # two-sided 95 % normal quantile


# -- the estimator ---------------------------------------------------------------------------


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter with its asymptotic (and, if asked, bootstrap) 95 % interval."""

    value: float
    ci_low: float
    ci_high: float
    unit: str
    boot_low: float | None = None
    boot_high: float | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "value": _jf(self.value),
            "ci95": [_jf(self.ci_low), _jf(self.ci_high)],
            "unit": self.unit,
        }
        if self.boot_low is not None and self.boot_high is not None:
            out["ci95_bootstrap"] = [_jf(self.boot_low), _jf(self.boot_high)]
        return out


@dataclass
class GMWMFit:
    """The GMWM fit of one model to one record's wavelet variance."""

    model: tuple[str, ...]
    names: list[str]
    params: np.ndarray  # physical values in `names` order
    log_cov: np.ndarray  # asymptotic covariance of the log parameters
    at_bound: np.ndarray  # parameters sitting on a search bound (term not resolved)
    wv: WaveletVariance
    omega: np.ndarray
    objective: float  # J: the minimized quadratic form with the efficient weights
    estimates: dict[str, ParameterEstimate] = field(default_factory=dict)
    bootstrap_samples: np.ndarray | None = None

    @property
    def dof(self) -> int:
        return int(self.wv.m.size - len(self.names))

    @property
    def wic(self) -> float:
        """Wavelet Information Criterion (module docstring): J + 2 p."""
        return float(self.objective + 2.0 * len(self.names))

    @property
    def p_value(self) -> float:
        """Goodness of fit: P(chi2(dof) > J) (Hansen's J test of the model)."""
        return float(chi2.sf(self.objective, self.dof)) if self.dof > 0 else math.nan

    def fitted_wv(self, m: np.ndarray | None = None) -> np.ndarray:
        m = self.wv.m if m is None else m
        return model_wv(self.model, self.params, m, 1.0 / self.wv.rate_hz)

    def value(self, name: str) -> float:
        return float(self.params[self.names.index(name)])

    def as_dict(self) -> dict[str, Any]:
        return {
            "model": "+".join(self.model),
            "method": "GMWM (Haar wavelet variance, efficient two-step weighting)",
            "parameters": {k: e.as_dict() for k, e in self.estimates.items()},
            "scales": int(self.wv.m.size),
            "tau_range_s": [float(self.wv.taus_s[0]), float(self.wv.taus_s[-1])],
            "objective_J": _jf(self.objective),
            "dof": self.dof,
            "p_value": _jf(self.p_value),
            "wic": _jf(self.wic),
        }


def _bounds(model, wv: WaveletVariance) -> tuple[np.ndarray, np.ndarray]:
    """Search box in log parameters: amplitudes over 20 decades around the data's level,
    T from one sample to ten record lengths."""
    dt = 1.0 / wv.rate_hz
    level = math.sqrt(float(wv.wv.max()))
    lo, hi = [], []
    for comp in model:
        if comp == "GM":
            lo += [math.log(level * 1e-10), math.log(dt)]
            hi += [math.log(level * 1e10), math.log(10.0 * wv.n_samples * dt)]
        else:
            lo.append(math.log(level * 1e-10 * (dt if comp == "QN" else 1.0)))
            hi.append(math.log(level * 1e10 * (1.0 / dt if comp == "DR" else 1.0) + 1e-300))
    return np.array(lo), np.array(hi)


def _unit_columns(model, T_values: Sequence[float], m: np.ndarray, dt: float) -> np.ndarray:
    cols, k = [], 0
    for comp in model:
        if comp == "GM":
            cols.append(wv_gauss_markov(m, dt, 1.0, T_values[k]))
            k += 1
        else:
            cols.append(component_wv(comp, (1.0,), m, dt))
    return np.column_stack(cols)


def _starts(model, wv: WaveletVariance, whiten, count: int = 3) -> list[np.ndarray]:
    """Starting points: a grid over the GM times with a non-negative least-squares solve for
    the squared amplitudes (the WV is linear in them, and so is the whitening: the residual
    is then the weighted objective profiled over the amplitudes), best `count` kept."""
    dt = 1.0 / wv.rate_hz
    n_gm = model.count("GM")
    grid = np.geomspace(2.0 * dt, wv.taus_s[-1] * 2.0, 24 if n_gm < 2 else 20)
    if n_gm == 0:
        combos: list[tuple[float, ...]] = [()]
    elif n_gm == 1:
        combos = [(t,) for t in grid]
    else:
        combos = [(a, b) for a in grid for b in grid if b >= 2.0 * a]
        if n_gm > 2:
            combos = [c + tuple(grid[-1:]) * (n_gm - 2) for c in combos]
    scored = []
    y = whiten(wv.wv)
    for Ts in combos:
        A = whiten(_unit_columns(model, Ts, wv.m, dt))
        scale = np.linalg.norm(A, axis=0)
        amp2, rnorm = nnls(A / scale, y)
        scored.append((rnorm, Ts, amp2 / scale))
    scored.sort(key=lambda s: s[0])
    lo, hi = _bounds(model, wv)
    starts = []
    for _, Ts, amp2 in scored[:count]:
        theta, k = [], 0
        for j, comp in enumerate(model):
            amp = math.sqrt(max(amp2[j], 0.0))
            theta.append(math.log(amp) if amp > 0 else -np.inf)
            if comp == "GM":
                theta.append(math.log(Ts[k]))
                k += 1
        starts.append(np.clip(np.array(theta), lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo)))
    return starts


def _diagonal_whitening(w: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """r -> W r for a vector or each column of a matrix (W = diag(w))."""
    return lambda r: (r.T * w).T


def _whitening(omega: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """r -> L^-1 r with Omega = L L' (on unit diagonal: the scales span decades)."""
    sd = np.sqrt(np.diag(omega))
    chol = np.linalg.cholesky(omega / np.outer(sd, sd))
    return lambda r: solve_triangular(chol, (r.T / sd).T, lower=True)


def _minimize(model, wv, whiten, starts) -> tuple[np.ndarray, float]:
    dt = 1.0 / wv.rate_hz
    lo, hi = _bounds(model, wv)

    def residual(theta: np.ndarray) -> np.ndarray:
        return whiten(wv.wv - model_wv(model, np.exp(theta), wv.m, dt))

    best: tuple[np.ndarray, float] | None = None
    margin = 1e-9 * (hi - lo)
    for start in starts:
        start = np.clip(start, lo + margin, hi - margin)  # a refit's box moves with its data
        res = least_squares(residual, start, bounds=(lo, hi), x_scale=1.0, method="trf")
        cost = float(res.fun @ res.fun)
        if best is None or cost < best[1]:
            best = (res.x, cost)
    assert best is not None
    return best


def _sorted_gm(model, theta: np.ndarray) -> np.ndarray:
    """Order several GM terms by correlation time (T1 < T2 < ...)."""
    offs = [o for o, comp in zip(_offsets(model), model) if comp == "GM"]
    if len(offs) < 2:
        return theta
    pairs = sorted((theta[o + 1], theta[o]) for o in offs)
    theta = theta.copy()
    for o, (lnT, lnB) in zip(offs, pairs):
        theta[o], theta[o + 1] = lnB, lnT
    return theta


def _offsets(model) -> list[int]:
    out, i = [], 0
    for comp in model:
        out.append(i)
        i += PARAMETER_COUNT[comp]
    return out


def omega_of(model, params, wv: WaveletVariance) -> np.ndarray:
    """Omega at the given parameters: the model's exact finite-record WV covariance
    (wavelet.wv_covariance_finite; the asymptotic form is 1.8x off at the top scale)."""
    P, decay = model_second_sum(model, params, 1.0 / wv.rate_hz)
    return wv_covariance_finite(wv.m, wv.n_samples, P, decay)


def gmwm_fit(
    wv: WaveletVariance,
    model: Sequence[str] = DEFAULT_MODEL,
    omega: np.ndarray | None = None,
    start: np.ndarray | None = None,
) -> GMWMFit:
    """Two-step GMWM of `model` on the wavelet variance `wv`, then OMEGA_UPDATES more
    updates of Omega at the estimate (iterated GMWM).

    omega fixed (and start given) skips the first step and the updates: the parametric
    bootstrap's refits and the model selection's common weights.
    """
    model = check_model(model)
    names = parameter_names(model)
    if wv.m.size <= len(names):
        raise GMWMError(
            f"{wv.m.size} wavelet scales for {len(names)} parameters of {'+'.join(model)}: "
            "the record is too short for this model"
        )
    theta1 = None
    if omega is None:
        # step 1: diagonal chi-square weights from the estimate itself
        w1 = np.sqrt(wv.edf() / 2.0) / wv.wv
        diag = _diagonal_whitening(w1)
        theta1, _ = _minimize(model, wv, diag, _starts(model, wv, diag))
        omega = omega_of(model, np.exp(theta1), wv)
    # step 2: the efficient weights (whitening by Omega's Cholesky factor); the grid starts
    # are scored with them too, so the global search is over the efficient objective
    whiten = _whitening(omega)
    if start is not None:
        starts = [start]
    else:
        starts = _starts(model, wv, whiten) + ([theta1] if theta1 is not None else [])
    theta, cost = _minimize(model, wv, whiten, starts)
    theta = _sorted_gm(model, theta)
    if theta1 is not None:
        # iterated GMWM: Omega at the last estimate, refit from it (measured on 60 records
        # of 6 h of the paper profile: K's interval covered 85 % after two steps, 88 % after
        # two more updates, RMSE of B, T, K 3-5 % lower; asymptotically the same estimator)
        for _ in range(OMEGA_UPDATES):
            omega = omega_of(model, np.exp(theta), wv)
            whiten = _whitening(omega)
            theta, cost = _minimize(model, wv, whiten, [theta])
            theta = _sorted_gm(model, theta)
    lo, hi = _bounds(model, wv)
    at_bound = (theta <= lo + 1e-3) | (theta >= hi - 1e-3)
    log_cov = _log_covariance(model, theta, wv, omega)
    fit = GMWMFit(model, names, np.exp(theta), log_cov, at_bound, wv, omega, cost)
    fit.estimates = _asymptotic_estimates(fit)
    return fit


def _log_covariance(model, theta, wv, omega) -> np.ndarray:
    """(D' Omega^-1 D)^-1 with D the derivative of nu in the log parameters."""
    dt = 1.0 / wv.rate_hz
    h = 1e-5
    D = np.empty((wv.m.size, theta.size))
    for k in range(theta.size):
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        D[:, k] = model_wv(model, np.exp(up), wv.m, dt) - model_wv(model, np.exp(down), wv.m, dt)
        D[:, k] /= 2.0 * h
    sd = np.sqrt(np.diag(omega))
    factor = cho_factor(omega / np.outer(sd, sd))
    Dn = D / sd[:, None]
    info = Dn.T @ cho_solve(factor, Dn)
    try:
        return np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(info)


def _unit(name: str) -> str:
    return UNITS[name.rstrip("0123456789")]


def _asymptotic_estimates(fit: GMWMFit) -> dict[str, ParameterEstimate]:
    out = {}
    sd = np.sqrt(np.clip(np.diag(fit.log_cov), 0.0, None))
    for k, name in enumerate(fit.names):
        v = float(fit.params[k])
        spread = math.exp(min(_Z95 * sd[k], 700.0))  # an unidentified term: sd is enormous
        low, high = v / spread, v * spread
        if fit.at_bound[k]:  # an unresolved term: its interval runs to the open end
            is_amp = not name.startswith("T")
            low, high = (0.0, high) if is_amp else (low, math.inf)
        out[name] = ParameterEstimate(v, low, high, _unit(name))
    return out


def bootstrap(
    fit: GMWMFit, replicates: int = 100, seed: int | None = None, level: float = CI_LEVEL,
    progress: Callable[[int], None] | None = None,
) -> GMWMFit:
    """Parametric bootstrap: records simulated from the fit, re-estimated with the fit's
    Omega; percentile intervals written into fit.estimates (boot_low, boot_high).
    ``progress(done)`` is told after each replicate (each is a fit: 10,000 took hours)."""
    rng = np.random.default_rng(seed)
    wv = fit.wv
    m_max = int(wv.m[-1])
    theta0 = np.log(fit.params)
    samples = np.empty((replicates, fit.params.size))
    for r in range(replicates):
        x = simulate(fit.model, fit.params, wv.n_samples, wv.rate_hz, rng)
        wv_r = haar_wv(x, wv.rate_hz).up_to(m_max)
        refit = _refit_fixed(fit.model, wv_r, fit.omega, theta0)
        samples[r] = refit
        if progress is not None:
            progress(r + 1)
    a = (1.0 - level) / 2.0
    lows = np.quantile(samples, a, axis=0)
    highs = np.quantile(samples, 1.0 - a, axis=0)
    fit.bootstrap_samples = samples
    fit.estimates = {
        name: ParameterEstimate(e.value, e.ci_low, e.ci_high, e.unit, float(lo), float(hi))
        for (name, e), lo, hi in zip(fit.estimates.items(), lows, highs)
    }
    return fit


def _refit_fixed(model, wv, omega, theta0) -> np.ndarray:
    theta, _ = _minimize(model, wv, _whitening(omega), [theta0])
    return np.exp(_sorted_gm(model, theta))


def identify_gmwm(
    rate_dps: np.ndarray,
    rate_hz: float,
    model: Sequence[str] = DEFAULT_MODEL,
    min_coeffs_fraction: float = MIN_COEFFS_FRACTION,
) -> GMWMFit:
    """GMWM of one axis: Haar WV at the dyadic scales with at least that fraction of the
    record as coefficients (default half: the top scales' asymptotics hold), then the fit."""
    wv = haar_wv(np.asarray(rate_dps, dtype=float), rate_hz, min_coeffs_fraction)
    return gmwm_fit(wv, model)


@dataclass(frozen=True)
class Selection:
    """Candidate models ranked by WIC (smallest first)."""

    fits: list[GMWMFit]

    @property
    def best(self) -> GMWMFit:
        return self.fits[0]

    def table(self) -> list[dict[str, Any]]:
        return [
            {"model": "+".join(f.model), "wic": f.wic, "J": f.objective, "p": len(f.names)}
            for f in self.fits
        ]


CANDIDATES = (
    ("WN", "RW"),
    ("WN", "GM"),
    ("WN", "GM", "RW"),
    ("WN", "GM", "GM"),
    ("WN", "GM", "GM", "RW"),
    ("WN", "QN", "GM", "RW"),
    ("WN", "GM", "RW", "DR"),
)


def select_model(
    wv: WaveletVariance, candidates: Sequence[Sequence[str]] = CANDIDATES
) -> Selection:
    """Fit every candidate and rank them by WIC.

    The objectives are only comparable with one weight matrix: Omega is taken from the
    two-step fit of the richest candidate (most parameters; it nests the others when the
    list is nested), and every candidate is fitted with it."""
    models = []
    for cand in candidates:
        model = check_model(cand)
        if wv.m.size > len(parameter_names(model)):
            models.append(model)
    if not models:
        raise GMWMError("no candidate model can be fitted to this record (too few scales)")
    richest = max(models, key=lambda mod: len(parameter_names(mod)))
    omega = gmwm_fit(wv, richest).omega
    fits = [gmwm_fit(wv, model, omega=omega) for model in models]
    fits.sort(key=lambda f: f.wic)
    return Selection(fits)


def _jf(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
