"""Weighted least-squares fit of the Allan variance by white + Gauss-Markov terms + random walk.

The model (allan.py, IEEE Std 952 Annex C) is linear in N^2, B_i^2, K^2 (Q^2, R^2) for given
correlation times T_i. The fit, per axis:

1. Weighted non-negative least squares (NNLS) with one Gauss-Markov column per T of a log grid
   (factor 2 from the shortest to the longest fitted tau): the NNLS solution is sparse, its
   non-zero columns are the candidate terms.
2. Backward elimination: the term whose removal raises the cost least is dropped, one at a
   time, giving one nested set of terms per count.
3. Each set's T_i are refined continuously (variable projection: the linear part solved by
   NNLS inside a bounded search in ln T).
4. The count is chosen by the small-sample corrected Akaike criterion
   AICc = chi^2 + 2p + 2p(p + 1) / (n - p - 1), p = 2 + 2 terms (+ Q, R): with 12-20 octave
   points plain AIC overfits and BIC's ln n is not much different; AICc is the rule that
   keeps a term only when it pays for its two parameters on so few points. The octave
   points are correlated, so chi^2 is not exactly chi-square: it is a rule, not a test.

The sensor's output stage (output_stage.py) enters the model as it is found: white noise
through the output filter (the exact discrete Allan variance of filtered white noise,
butterworth.white_avar_unit, instead of N^2 / tau, so the fit starts at the first tau),
and as known terms the quantization's white floor LSB^2 / 12 after the filter and each
sinusoidal line (IEEE 952; amplitude and frequency from the PSD, which holds a line in a few
bins where the Allan variance spreads it under the white noise).

Weights are 1 / sd(AVAR estimate) = sqrt(edf / 2) / AVAR_model, iterated from the model.
Intervals come from the weighted Jacobian in (N^2, B_i^2, ln T_i, K^2, ...), scaled by the
reduced chi-square when it exceeds 1 and widened by factors measured by simulation
(docs/identification.md); every interval is finite and ordered: B, N, K are capped where the
term alone would exceed the curve's upper bound, T is limited to the searched range, and is
the whole searched range when B's interval reaches 0 (a term that may be absent has no T).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear, minimize, nnls

from bmg160_emu.noise.allan import (
    FLICKER_ADEV_FACTOR,
    AllanCurve,
    allan_confidence,
    gauss_markov_avar_unit,
)
from bmg160_emu.noise.butterworth import white_avar_unit
from bmg160_emu.noise.estimate import Estimate
from bmg160_emu.noise.output_stage import FilterFit, quantization_avar, sine_avar_unit
from bmg160_emu.noise.profile import UNITS

# Widening of the linearized intervals (octave ADEV points are correlated): the 95th
# percentile of |error| / half-width over 30 records each of 1 h and 6 h of the paper
# profile at 200 Hz (docs/identification.md); used for every term of a multi-term fit.
CI_WIDENING = {"N": 1.5, "B": 1.8, "lnT": 3.0, "K": 3.0, "Q": 1.5, "R": 3.0, "F": 1.8,
               "filter": 1.0}
CI_LEVEL = 0.95
Z95 = 1.959963984540054  # two-sided 95 % normal quantile
MAX_TERMS = 5  # Gauss-Markov terms considered at most
GRID_STEP = 2.0  # ratio of neighbouring T of the NNLS grid
FLICKER_BANK_STEP = 4.0  # ratio of neighbouring T of the fixed 1/f bank
_FLICKER_AVAR = FLICKER_ADEV_FACTOR**2  # Allan variance of flicker per unit B^2


class FitError(ValueError):
    """A curve that cannot be fitted (too few points in the tau range)."""


@dataclass(frozen=True)
class Term:
    """One Gauss-Markov term: stationary std B (deg/s) and correlation time T (s)."""

    B: Estimate
    T: Estimate
    T_at_search_edge: bool = False


@dataclass
class CurveFit:
    """The fitted model of one Allan deviation curve."""

    N: Estimate
    K: Estimate
    terms: list[Term]
    Q: Estimate | None
    R: Estimate | None
    flicker: Estimate | None  # B of the 1/f bank (IEEE flicker B), when fitted
    flicker_poles: tuple[tuple[float, float], ...]  # (B_i, T_i) of that bank
    curve: AllanCurve  # the input with its confidence bounds from the model's noise types
    tau_range_s: tuple[float, float]
    points: int
    chi2_reduced: float
    T_search_range_s: tuple[float, float]
    selection: dict[str, Any] = field(default_factory=dict)
    rate_hz: float = 0.0  # the record's (0: N^2 / tau for the white term)
    output_filter: FilterFit | None = None  # the sensor's filter, part of the white term
    lsb_dps: float | None = None  # the output's quantization step (a known white floor)
    sines: list[tuple[Estimate, float]] = field(default_factory=list)  # (A, f Hz) per line
    # the record's measured output response (noise.output_response): the white term through it
    response: Any = None
    known_avar: Callable[[np.ndarray], np.ndarray] | None = None  # e.g. resonant bands

    def gauss_markov_terms(self) -> tuple[tuple[float, float], ...]:
        """(B, T) of every term the generator draws, the flicker bank included."""
        own = tuple((t.B.value, t.T.value) for t in self.terms if t.B.value > 0)
        return own + self.flicker_poles

    def white_avar(self, tau: np.ndarray) -> np.ndarray:
        """The white term alone: N^2 / tau, through the output filter when there is one."""
        if self.response is not None and self.rate_hz:
            return self.N.value**2 * self.response.white_avar_unit(tau)
        flt = self.output_filter.design if self.output_filter is not None else None
        if flt is None or not self.rate_hz:
            return self.N.value**2 / np.asarray(tau, dtype=float)
        return self.N.value**2 * white_avar_unit(tau, self.rate_hz, flt)

    def model_avar(self, tau: np.ndarray) -> np.ndarray:
        tau = np.asarray(tau, dtype=float)
        out = self.white_avar(tau) + self.K.value**2 * tau / 3.0
        if self.rate_hz:
            out = out + quantization_avar(self.lsb_dps, self.rate_hz, tau)
        for amplitude, frequency in self.sines:
            out = out + amplitude.value**2 * sine_avar_unit(tau, frequency, self.rate_hz or None)
        if self.known_avar is not None:
            out = out + self.known_avar(tau)
        for B, T in self.gauss_markov_terms():
            out = out + B * B * gauss_markov_avar_unit(tau, T)
        if self.Q is not None:
            out = out + 3.0 * self.Q.value**2 / tau**2
        if self.R is not None:
            out = out + self.R.value**2 * tau**2 / 2.0
        return out


@dataclass(frozen=True)
class _Design:
    tau: np.ndarray
    with_q: bool
    with_r: bool
    bank: np.ndarray | None  # flicker column (unit: ADEV level 1 per unit coefficient)
    roll_off: bool = False  # a sensor filter's deficit -c / tau^2 (see fit_curve)
    white: np.ndarray | None = None  # the white column (None: 1 / tau)
    fixed: np.ndarray | None = None  # the known part of the Allan variance (rounding, lines)
    free_sines: tuple[float, ...] = ()  # lines of these frequencies (Hz), amplitude fitted
    rate_hz: float = 0.0  # the samples' rate (the free lines' Allan variance is of samples)

    def extras(self) -> list[str]:
        """Names of the columns after the Gauss-Markov ones, in order."""
        names = ["F"] if self.bank is not None else []
        names += ["filter"] if self.roll_off else []
        names += [f"S{i}" for i in range(len(self.free_sines))]
        return names + (["Q"] if self.with_q else []) + (["R"] if self.with_r else [])

    def matrix(self, Ts: np.ndarray) -> np.ndarray:
        tau = self.tau
        cols = [1.0 / tau if self.white is None else self.white, tau / 3.0]
        cols += [gauss_markov_avar_unit(tau, T) for T in Ts]
        extra = {"filter": -1.0 / tau**2, "Q": 3.0 / tau**2, "R": tau**2 / 2.0}
        if self.bank is not None:
            extra["F"] = self.bank
        for i, frequency in enumerate(self.free_sines):
            extra[f"S{i}"] = sine_avar_unit(tau, frequency, self.rate_hz or None)
        cols += [extra[name] for name in self.extras()]
        return np.column_stack(cols)

    def target(self, avar: np.ndarray) -> np.ndarray:
        """The part of the Allan variance the columns fit (the known part taken off)."""
        return avar if self.fixed is None else avar - self.fixed

    @property
    def n_fixed(self) -> int:  # N, K and the extra columns (a free line: A and f)
        return 2 + len(self.extras()) + len(self.free_sines)


def _solve(design: _Design, avar: np.ndarray, w: np.ndarray, Ts) -> tuple[np.ndarray, float]:
    avar = design.target(avar)
    A = design.matrix(np.asarray(Ts, dtype=float)) * w[:, None]
    scale = np.linalg.norm(A, axis=0)  # columns span ~10 decades: solve on unit columns
    scale[scale == 0] = 1.0
    try:
        theta, rnorm = nnls(A / scale, avar * w, maxiter=50 * A.shape[1])
    except RuntimeError:  # NNLS did not converge: the bounded least-squares solver instead
        sol = lsq_linear(A / scale, avar * w, bounds=(0.0, np.inf))
        theta, rnorm = sol.x, float(np.linalg.norm(sol.fun))
    return theta / scale, float(rnorm**2)


def _refine(design, avar, w, Ts, bounds) -> tuple[np.ndarray, np.ndarray, float]:
    """Continuous T_i (variable projection) from the grid values Ts."""
    Ts = np.sort(np.asarray(Ts, dtype=float))
    if Ts.size == 0:
        theta, c0 = _solve(design, avar, w, Ts)
        return Ts, theta, c0
    lo, hi = math.log(bounds[0]), math.log(bounds[1])

    def cost(u: np.ndarray) -> float:
        return _solve(design, avar, w, np.exp(u))[1]

    u0 = np.clip(np.log(Ts), lo, hi)
    res = minimize(cost, u0, method="L-BFGS-B", bounds=[(lo, hi)] * Ts.size,
                   options={"maxiter": 200})
    u = res.x if res.fun <= cost(u0) else u0
    Ts = np.sort(np.clip(np.exp(u), bounds[0], bounds[1]))  # exp(log(b)) may round past b
    theta, c = _solve(design, avar, w, Ts)
    return Ts, theta, c


def _aicc(chi2: float, p: int, n: int) -> float:
    if n - p - 1 <= 0:
        return math.inf
    return chi2 + 2.0 * p + 2.0 * p * (p + 1) / (n - p - 1)


def _select(design, avar, w, bounds, poles: int | None) -> dict[str, Any]:
    """Candidate sets by NNLS on the grid and backward elimination; the chosen set refined."""
    n = avar.size
    grid = np.geomspace(bounds[0], bounds[1], max(2, round(math.log(bounds[1] / bounds[0],
                                                                     GRID_STEP)) + 1))
    theta, _ = _solve(design, avar, w, grid)
    n_lin = 2
    active = [grid[i] for i in range(grid.size) if theta[n_lin + i] > 0]
    sets: dict[int, list[float]] = {}
    current = list(active)
    while True:
        if len(current) <= MAX_TERMS:
            sets[len(current)] = list(current)
        if not current:
            break
        costs = [_solve(design, avar, w, current[:i] + current[i + 1 :])[1]
                 for i in range(len(current))]
        current.pop(int(np.argmin(costs)))
    if poles is not None:
        while max(sets) < poles:  # more terms asked than the grid found: split the longest
            base = sets[max(sets)]
            extra = [T for T in grid if T not in base]
            costs = [_solve(design, avar, w, base + [T])[1] for T in extra] or [math.inf]
            sets[len(base) + 1] = base + [extra[int(np.argmin(costs))]] if extra else base
            if not extra:
                break
    table = []
    best: dict[str, Any] | None = None
    for k in sorted(sets):  # every count is scored (and listed), --poles picks its own
        Ts, theta_k, cost = _refine(design, avar, w, sets[k], bounds)
        p = design.n_fixed + 2 * k
        score = _aicc(cost, p, n)
        table.append({"terms": int(k), "chi2": _json_float(cost), "aicc": _json_float(score),
                      "T_s": [float(T) for T in Ts]})
        if poles is not None:
            if k == poles:
                best = {"Ts": Ts, "theta": theta_k, "cost": cost, "aicc": score, "terms": k}
        elif best is None or score < best["aicc"]:
            best = {"Ts": Ts, "theta": theta_k, "cost": cost, "aicc": score, "terms": k}
    assert best is not None
    for row in table:
        row["chosen"] = row["terms"] == best["terms"]
    best["table"] = table
    best["forced"] = poles is not None
    return best


def _flicker_bank(tau: np.ndarray, bounds: tuple[float, float]) -> tuple[np.ndarray, np.ndarray]:
    """T of the fixed 1/f bank (a decade beyond the fitted range each way) and its column,
    normalised to a mean of 1 over the fitted taus (its coefficient is the flat ADEV^2)."""
    Ts = np.geomspace(bounds[0] / 10.0, bounds[1] * 10.0,
                      round(math.log(100.0 * bounds[1] / bounds[0], FLICKER_BANK_STEP)) + 1)
    col = np.sum([gauss_markov_avar_unit(tau, T) for T in Ts], axis=0)
    return Ts, col / float(np.mean(col))


def fit_curve(
    curve: AllanCurve,
    rate_hz: float,
    n_samples: int,
    with_q: bool = False,
    with_r: bool = False,
    tau_range: tuple[float | None, float | None] = (None, None),
    poles: int | None = None,
    flicker: bool = False,
    roll_off: bool = False,
    record: np.ndarray | None = None,
    output_filter: FilterFit | None = None,
    lsb_dps: float | None = None,
    sines: tuple[tuple[Estimate, float], ...] = (),
    response: Any = None,
    known_avar: Callable[[np.ndarray], np.ndarray] | None = None,
    free_sines: tuple[float, ...] = (),
) -> CurveFit:
    """Fit the curve; poles = None chooses the number of Gauss-Markov terms by AICc;
    roll_off adds the first-order deficit of a sensor filter (a term -c / tau^2) where the
    filter itself is not known; output_filter makes the white term filtered white noise,
    lsb_dps adds its quantization floor, sines (amplitude, Hz) the known lines; response (an
    output_response.OutputResponse: any measured shape) makes the white term white noise
    through it instead, known_avar(tau) adds a known Allan variance (resonant bands);
    free_sines (Hz) adds lines whose amplitude is fitted (a curve's periodic shoulder).

    record (the samples, None for a curve input) is part of the signature every method of
    identification.FIT_METHODS takes, for methods that fit the samples themselves; this
    one fits the curve only."""
    sel = np.ones(curve.taus.size, dtype=bool)
    if tau_range[0] is not None:
        sel &= curve.taus >= tau_range[0] * (1 - 1e-9)
    if tau_range[1] is not None:
        sel &= curve.taus <= tau_range[1] * (1 + 1e-9)
    tau, avar = curve.taus[sel], curve.avar[sel]
    need = 3 + with_q + with_r + flicker + roll_off + 2 * (poles or 0)
    if tau.size < need + 1:
        raise FitError(
            f"only {tau.size} Allan points in the fitted tau range; the fit needs at least "
            f"{need + 1}: widen the range or use a longer record"
        )
    # a Gauss-Markov term of T well below the first fitted tau adds 2 B^2 T to N^2 there
    # (it is white noise to the fit), and near it trades with a filter's roll-off; longer
    # than the longest tau it is a random walk: T is searched from two octaves above the
    # first fitted tau (at least two samples) to the last one
    bounds = (max(4.0 * float(tau[0]), 2.0 / rate_hz), max(float(tau[-1]), 8.0 / rate_hz))
    bank_Ts, bank = _flicker_bank(tau, bounds) if flicker else (None, None)
    # Above a low-pass of bandwidth BW the Allan variance of white noise falls short of
    # N^2 / tau by about N^2 c / tau^2 (c ~ 0.15 / BW for a 2nd-order filter: the missing
    # power above BW seen through the Allan transfer function): a column -1 / tau^2 takes
    # that deficit instead of N or a short Gauss-Markov term
    stage = (output_filter, lsb_dps, sines, response, known_avar, free_sines)
    design = _make_design(tau, rate_hz, with_q, with_r, bank, roll_off, *stage)
    w = np.sqrt(curve.edf[sel] / 2.0) / avar
    best = _select(design, avar, w, bounds, poles)
    for _ in range(3):  # weights from the model, not the noisy estimate (less bias)
        model = design.matrix(best["Ts"]) @ best["theta"]
        model = np.maximum(model if design.fixed is None else model + design.fixed, 1e-300)
        full = np.maximum(_design_all(curve.taus, design, best, rate_hz, *stage), 1e-300)
        curve = allan_confidence(curve.taus, curve.adev, curve.n_terms,
                                 _alphas(curve.taus, full), n_samples, rate_hz, curve.ci,
                                 curve.overlapping)
        w = np.sqrt(curve.edf[sel] / 2.0) / model
        best = _select(design, avar, w, bounds, poles)
    dof = max(tau.size - design.n_fixed - 2 * best["terms"], 1)
    chi2_red = best["cost"] / dof
    fit = _estimates(design, avar, w, best, bounds, max(chi2_red, 1.0), curve, sel, chi2_red,
                     bank_Ts)
    fit.rate_hz, fit.output_filter, fit.lsb_dps = float(rate_hz), output_filter, lsb_dps
    fit.response, fit.known_avar = response, known_avar
    fit.sines = list(sines) + fit.sines  # the known lines, then the fitted ones
    return fit


def _make_design(tau, rate_hz, with_q, with_r, bank, roll_off, output_filter, lsb_dps,
                 sines, response=None, known_avar=None, free_sines=()) -> _Design:
    white = (None if output_filter is None
             else white_avar_unit(tau, rate_hz, output_filter.design))
    if response is not None:
        white = response.white_avar_unit(tau)
    fixed = None
    if known_avar is not None:
        fixed = known_avar(tau)
    if lsb_dps or sines:
        fixed = quantization_avar(lsb_dps, rate_hz, tau) + (0.0 if fixed is None else fixed)
        for amplitude, frequency in sines:
            fixed = fixed + amplitude.value**2 * sine_avar_unit(tau, frequency, rate_hz or None)
    return _Design(tau, with_q, with_r, bank, roll_off, white, fixed, tuple(free_sines),
                   float(rate_hz))


def _design_all(taus: np.ndarray, design: _Design, best: dict[str, Any],
                rate_hz: float, output_filter: FilterFit | None, lsb_dps: float | None,
                sines: tuple = (), response: Any = None, known_avar: Any = None,
                free_sines: tuple = ()) -> np.ndarray:
    """The fitted model at every tau of the curve (for the noise types of the intervals)."""
    bank = None
    if design.bank is not None:
        bank = np.interp(np.log(taus), np.log(design.tau), design.bank)
    whole = _make_design(taus, rate_hz, design.with_q, design.with_r, bank, design.roll_off,
                         output_filter, lsb_dps, sines, response, known_avar, free_sines)
    model = whole.matrix(best["Ts"]) @ best["theta"]
    return model if whole.fixed is None else model + whole.fixed


def _alphas(taus: np.ndarray, model: np.ndarray) -> np.ndarray:
    if taus.size < 2:
        return np.zeros(taus.size, dtype=int)
    mu = np.gradient(np.log(model), np.log(taus))
    return np.clip(np.rint(-mu - 1.0), -2, 2).astype(int)


def _estimates(design, avar, w, best, bounds, scale, curve, sel, chi2_red, bank_Ts) -> CurveFit:
    tau, Ts, theta = design.tau, best["Ts"], best["theta"]
    A = design.matrix(Ts)
    k = Ts.size
    h = 1e-4
    cols, names = [A[:, 0], A[:, 1]], ["N", "K"]
    for i, T in enumerate(Ts):
        cols.append(A[:, 2 + i])
        names.append("B")
        dg = (gauss_markov_avar_unit(tau, T * math.exp(h))
              - gauss_markov_avar_unit(tau, T * math.exp(-h))) / (2 * h)
        cols.append(theta[2 + i] * dg)
        names.append("lnT")
    for j in range(2 + k, A.shape[1]):
        cols.append(A[:, j])
    names += design.extras()
    J = np.column_stack(cols) * w[:, None]
    norms = np.linalg.norm(J, axis=0)
    sd = np.full(J.shape[1], np.inf)
    usable = norms > 0  # a parameter with no effect on the curve: capped interval below
    usable &= np.isfinite(norms)
    Jn = J[:, usable] / norms[usable]
    try:
        cov = np.linalg.pinv(Jn.T @ Jn)
        sd[usable] = np.sqrt(np.clip(np.diag(cov), 0.0, None) * scale) / norms[usable]
    except (np.linalg.LinAlgError, ValueError):
        pass  # no linearized interval: every one is capped below
    sd = np.array([s * CI_WIDENING.get(nm, CI_WIDENING["B"]) for s, nm in zip(sd, names)])
    # the largest value each term could take alone under the curve's upper bound
    upper = (curve.ci_high[sel] ** 2) * 4.0

    def square_root_estimate(value2: float, s: float, column: np.ndarray, unit: str) -> Estimate:
        cap = float(np.min(upper / np.maximum(column, 1e-300)))
        half = Z95 * s if math.isfinite(s) else math.inf
        hi2 = min(value2 + half, max(cap, value2))
        return Estimate(math.sqrt(value2), math.sqrt(max(value2 - half, 0.0)), math.sqrt(hi2), unit)

    N = square_root_estimate(theta[0], sd[0], A[:, 0], UNITS["N"])
    K = square_root_estimate(theta[1], sd[1], A[:, 1], UNITS["K"])
    terms = []
    for i, T in enumerate(Ts):
        B = square_root_estimate(theta[2 + i], sd[2 + 2 * i], A[:, 2 + i], UNITS["B"])
        s = sd[3 + 2 * i]
        half = min(Z95 * s, math.log(1e6)) if math.isfinite(s) else math.log(1e6)
        on_lo, on_hi = T <= bounds[0] * 1.05, T >= bounds[1] / 1.05
        lo = bounds[0] if on_lo else min(max(T * math.exp(-half), bounds[0]), T)
        hi = bounds[1] if on_hi else max(min(T * math.exp(half), bounds[1]), T)
        if not B.ci_low > 0:  # the term may be absent (B = 0): then any T fits as well, and
            lo, hi = bounds  # an interval round this T would leave out plausible ones
        terms.append(Term(B, Estimate(float(T), float(lo), float(hi), "s"), bool(on_lo or on_hi)))
    # a term of size 0 is no term: left out (--poles N may ask for more than the curve holds)
    zero = sum(1 for t in terms if not t.B.value > 0)
    terms = sorted((t for t in terms if t.B.value > 0), key=lambda t: t.T.value)
    j = 2 + 2 * k
    extra: dict[str, Estimate] = {}
    for c, nm in enumerate(names[j:], start=j):
        column = A[:, 2 + k + (c - j)]
        if nm == "filter":  # a deficit: no cap from the curve's upper bound
            continue
        unit = UNITS["B"] if nm == "F" or nm.startswith("S") else UNITS[nm]
        extra[nm] = square_root_estimate(theta[2 + k + (c - j)], sd[c], column, unit)
    fitted_sines = [(extra.pop(f"S{i}"), float(fr)) for i, fr in enumerate(design.free_sines)]
    flicker = poles_f = None
    if "F" in extra:  # coefficient = flat ADEV^2 = 0.664^2 B_flicker^2
        f = extra.pop("F")
        r = 1.0 / FLICKER_ADEV_FACTOR
        flicker = Estimate(f.value * r, f.ci_low * r, f.ci_high * r, UNITS["B"])
        # the bank column is sum_i g(tau, T_i) / mean: per pole B_i^2 = coefficient / mean
        raw = np.sum([gauss_markov_avar_unit(tau, T) for T in bank_Ts], axis=0)
        b2 = f.value**2 / float(np.mean(raw))
        poles_f = tuple((math.sqrt(b2), float(T)) for T in bank_Ts) if b2 > 0 else ()
    return CurveFit(
        N=N, K=K, terms=terms, Q=extra.get("Q"), R=extra.get("R"), flicker=flicker,
        flicker_poles=poles_f or (), curve=curve,
        tau_range_s=(float(tau[0]), float(tau[-1])), points=int(tau.size),
        chi2_reduced=float(chi2_red), T_search_range_s=(float(bounds[0]), float(bounds[1])),
        selection={"criterion": "AICc", "candidates": best["table"], "terms": best["terms"],
                   "zero_terms_left_out": zero, "asked": bool(best.get("forced"))},
        sines=fitted_sines,
    )


def _json_float(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
