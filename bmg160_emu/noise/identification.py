"""Identification of N, B, T, K (and Q, R on request) from a static gyroscope record.

Per axis: overlapping Allan deviation (allantools, octave taus, Greenhall confidence
intervals), one-sided Welch PSD, and a weighted least-squares fit of the closed-form Allan
variance of the generator's own model (white + first-order Gauss-Markov + random walk, plus
quantization and ramp when asked). Fitting that model is what makes the numbers returned
the numbers the generator takes (noise-model.md, "Two facts"): the IEEE read-offs (N at
tau = 1 s, K at tau = 3 s, flicker B = minimum / 0.664) are reported beside it, labelled.

The fit: the variance is linear in N^2, B^2, K^2 (Q^2, R^2) for a given T, so T is found by
a profile search (log grid, then a bounded refinement) with a non-negative least-squares
solve inside; weights are 1 / sd(AVAR estimate) = sqrt(edf / 2) / AVAR_model, iterated.
Confidence intervals come from the weighted Jacobian (scaled by the reduced chi-square when
it exceeds 1); they are approximate because overlapping ADEV points are correlated.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import minimize_scalar, nnls

from bmg160_emu.noise.allan import (
    FLICKER_ADEV_FACTOR,
    AllanCurve,
    allan_confidence,
    gauss_markov_avar_unit,
    overlapping_adev,
)
from bmg160_emu.noise.profile import AXES, UNITS, AxisNoise, Profile
from bmg160_emu.noise.spectrum import (
    PSD_CONVENTION,
    Spectrum,
    one_sided_psd,
    white_density_from_psd,
    white_level_band,
)

# The weighted least-squares intervals treat the octave ADEV points as independent; they are
# not (overlapping estimates share data), so the linearized intervals are too narrow. Each is
# widened by a factor measured by simulation (paper profile, 1 h and 6 h records at 200 Hz,
# 30 records each: the 95th percentile of |error| / half-width; docs/identification.md).
CI_WIDENING = {"N": 1.5, "B": 1.8, "lnT": 3.0, "K": 3.0, "Q": 1.5, "R": 3.0}
STAGES_PER_AXIS = 3  # progress calls per axis: Allan deviation, fit, PSD
MIN_SAMPLES = 1000  # enough octave taus (9) to fit the white level and see its slope
CI_LEVEL = 0.95
_Z95 = 1.959963984540054  # two-sided 95 % normal quantile

RECORD_NEEDS = (
    "N needs at least 1000 samples (5 s at 200 Hz); B and T need a record of about 100 T "
    "(about 1 h for T = 33.9 s); K needs the rising +1/2 part of the Allan curve "
    "(several hours for a BMG160)"
)


class IdentificationError(ValueError):
    """A record that cannot be identified (too short, not finite, bad rate)."""


@dataclass(frozen=True)
class Estimate:
    """One identified parameter with its 95 % confidence interval."""

    value: float
    ci_low: float
    ci_high: float
    unit: str

    def as_dict(self) -> dict[str, Any]:
        return {
            "value": _json_float(self.value),
            "ci95": [_json_float(self.ci_low), _json_float(self.ci_high)],
            "unit": self.unit,
        }


@dataclass
class AxisIdentification:
    """Everything identified on one axis."""

    axis: str
    N: Estimate
    B: Estimate
    T: Estimate
    K: Estimate
    Q: Estimate | None
    R: Estimate | None
    mean: float
    std: float
    readoffs: dict[str, dict[str, Any]]
    fit_tau_range_s: tuple[float, float]
    fit_points: int
    chi2_reduced: float
    psd_white_N: float
    psd_band_hz: tuple[float, float]
    allan: AllanCurve
    spectrum: Spectrum
    notes: list[str] = field(default_factory=list)

    def to_axis_noise(self) -> AxisNoise:
        """The generator's parameters for this axis (bias = the record's mean)."""
        B = self.B.value if math.isfinite(self.T.value) else 0.0
        T = self.T.value if math.isfinite(self.T.value) else 0.0
        return AxisNoise(
            N=self.N.value,
            B=B,
            T=T,
            K=self.K.value,
            bias=self.mean,
            Q=self.Q.value if self.Q else 0.0,
            R=self.R.value if self.R else 0.0,
        )

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "N": self.N.as_dict(),
            "B": self.B.as_dict(),
            "T": self.T.as_dict(),
            "K": self.K.as_dict(),
        }
        if self.Q is not None:
            out["Q"] = self.Q.as_dict()
        if self.R is not None:
            out["R"] = self.R.as_dict()
        out.update(
            mean={"value": self.mean, "unit": "deg/s"},
            std={"value": self.std, "unit": "deg/s"},
            ieee_readoffs=self.readoffs,
            fit={
                "model": "white + first-order Gauss-Markov + random walk"
                + (" + quantization" if self.Q is not None else "")
                + (" + rate ramp" if self.R is not None else ""),
                "method": "weighted least squares on the overlapping Allan variance",
                "tau_range_s": list(self.fit_tau_range_s),
                "points": self.fit_points,
                "chi2_reduced": _json_float(self.chi2_reduced),
            },
            psd={
                "convention": PSD_CONVENTION,
                "white_N": {"value": _json_float(self.psd_white_N), "unit": UNITS["N"]},
                "frequency_range_hz": list(self.psd_band_hz),
                "segment_samples": self.spectrum.segment_samples,
            },
            notes=self.notes,
        )
        return out


@dataclass
class Identification:
    """Result of identifying a record of one to three axes."""

    rate_hz: float
    samples: int
    axes: list[AxisIdentification]
    source: str = ""

    @property
    def duration_s(self) -> float:
        return self.samples / self.rate_hz

    def to_profile(self, name: str = "identified") -> Profile:
        """A profile the generator loads: record columns in order become x, y, z; axes
        missing from the record copy the first one."""
        noise = [a.to_axis_noise() for a in self.axes]
        noise += [noise[0]] * (3 - len(noise))
        return Profile(
            name,
            x=noise[0],
            y=noise[1],
            z=noise[2],
            description=f"identified from {self.source or 'a record'} "
            f"({self.duration_s:.0f} s at {self.rate_hz:g} Hz)",
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "rate_hz": self.rate_hz,
            "samples": self.samples,
            "duration_s": self.duration_s,
            "units": {k: UNITS[k] for k in ("N", "B", "T", "K", "Q", "R")},
            "ci_level": CI_LEVEL,
            "axes": {a.axis: a.as_dict() for a in self.axes},
        }

    def summary(self) -> str:
        """A human summary: the fitted parameters with CIs, read-offs, ranges and notes."""
        head = (
            f"record: {self.source or '(array)'}, {self.samples} samples at {self.rate_hz:g} Hz "
            f"({_duration_text(self.duration_s)})"
        )
        fit = (
            "fit: weighted least squares of the closed-form Allan variance "
            "(white + Gauss-Markov + random walk); 95 % confidence intervals"
        )
        lines = [head, fit]
        for a in self.axes:
            lines.append("")
            lines.append(f"axis {a.axis}: mean {a.mean:.6g} deg/s, std {a.std:.6g} deg/s")
            for key, est in (
                ("N", a.N),
                ("B", a.B),
                ("T", a.T),
                ("K", a.K),
                ("Q", a.Q),
                ("R", a.R),
            ):
                if est is None:
                    continue
                lines.append(
                    f"  {key} = {est.value:.4g} {est.unit}   [{est.ci_low:.3g}, {est.ci_high:.3g}]"
                )
            lines.append(
                f"  fitted taus {a.fit_tau_range_s[0]:.3g} .. {a.fit_tau_range_s[1]:.3g} s "
                f"({a.fit_points} points), reduced chi-square {a.chi2_reduced:.2f}"
            )
            lines.append("  IEEE 952 read-offs (labelled, not what the generator takes):")
            for item in a.readoffs.values():
                value = item["value"]
                text = f"{value:.4g} {item['unit']}" if value is not None else "not found"
                lines.append(f"    {item['label']}: {text}")
            lines.append(
                f"  PSD white level: N = {a.psd_white_N:.4g} deg/s/sqrt(Hz) over "
                f"{a.psd_band_hz[0]:g} .. {a.psd_band_hz[1]:g} Hz ({PSD_CONVENTION})"
            )
            for note in a.notes:
                lines.append(f"  note: {note}")
        return "\n".join(lines)


# -- the closed-form fit ---------------------------------------------------------------------


@dataclass(frozen=True)
class _Fit:
    theta: np.ndarray  # N^2, B^2, K^2 [, Q^2] [, R^2]
    T: float
    cost: float


def _design(tau: np.ndarray, T: float, with_q: bool, with_r: bool) -> np.ndarray:
    cols = [1.0 / tau, gauss_markov_avar_unit(tau, T), tau / 3.0]
    if with_q:
        cols.append(3.0 / tau**2)
    if with_r:
        cols.append(tau**2 / 2.0)
    return np.column_stack(cols)


def _solve(tau, avar, w, T, with_q, with_r) -> _Fit:
    A = _design(tau, T, with_q, with_r) * w[:, None]
    scale = np.linalg.norm(A, axis=0)  # columns span ~10 decades: solve on unit columns
    scale[scale == 0] = 1.0
    theta, rnorm = nnls(A / scale, avar * w)
    return _Fit(theta / scale, T, rnorm**2)


def _best_T(tau, avar, w, with_q, with_r, t_bounds) -> _Fit:
    grid = np.geomspace(t_bounds[0], t_bounds[1], 60)
    fits = [_solve(tau, avar, w, T, with_q, with_r) for T in grid]
    i = int(np.argmin([f.cost for f in fits]))
    lo, hi = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
    if hi > lo:
        res = minimize_scalar(
            lambda lt: _solve(tau, avar, w, math.exp(lt), with_q, with_r).cost,
            bounds=(math.log(lo), math.log(hi)),
            method="bounded",
            options={"xatol": 1e-4},
        )
        refined = _solve(tau, avar, w, math.exp(res.x), with_q, with_r)
        if refined.cost <= fits[i].cost:
            return refined
    return fits[i]


def _model(tau, fit: _Fit, with_q, with_r) -> np.ndarray:
    return _design(tau, fit.T, with_q, with_r) @ fit.theta


def fit_allan_variance(
    curve: AllanCurve,
    rate_hz: float,
    n_samples: int,
    with_q: bool = False,
    with_r: bool = False,
    tau_range: tuple[float | None, float | None] = (None, None),
) -> tuple[dict[str, Estimate], AllanCurve, dict[str, Any]]:
    """Weighted least-squares fit of the composite Allan variance to the curve.

    Returns the estimates (N, B, T, K [, Q, R]), the curve with its confidence bounds
    recomputed from the fitted model's noise types, and fit information.
    """
    sel = np.ones(curve.taus.size, dtype=bool)
    if tau_range[0] is not None:
        sel &= curve.taus >= tau_range[0]
    if tau_range[1] is not None:
        sel &= curve.taus <= tau_range[1]
    n_params = 4 + with_q + with_r
    if sel.sum() < n_params + 1:
        raise IdentificationError(
            f"only {int(sel.sum())} Allan points in the tau range; the fit needs at least "
            f"{n_params + 1}: widen the range or use a longer record ({RECORD_NEEDS})"
        )
    tau, avar = curve.taus[sel], curve.avar[sel]
    # a Gauss-Markov time shorter than two samples is white noise; longer than the longest
    # tau it is a random walk: T is searched between the second and the last fitted tau
    t_bounds = (max(tau[1], 2.0 / rate_hz), max(tau[-1], 4.0 / rate_hz))
    edf = curve.edf[sel]
    w = np.sqrt(edf / 2.0) / avar
    fit = _best_T(tau, avar, w, with_q, with_r, t_bounds)
    for _ in range(3):  # weights from the model, not the noisy estimate (less bias)
        model = np.maximum(_model(tau, fit, with_q, with_r), 1e-300)
        alphas = _alphas_from_model(curve.taus, fit, with_q, with_r)
        curve = allan_confidence(
            curve.taus, curve.adev, curve.n_terms, alphas, n_samples, rate_hz, curve.ci
        )
        edf = curve.edf[sel]
        w = np.sqrt(edf / 2.0) / model
        fit = _best_T(tau, avar, w, with_q, with_r, t_bounds)

    dof = max(tau.size - n_params, 1)
    chi2_red = fit.cost / dof
    estimates = _estimates(tau, w, fit, with_q, with_r, max(chi2_red, 1.0))
    t_est = estimates["T"]
    at_edge = math.isfinite(t_est.value) and not (
        t_bounds[0] * 1.05 < t_est.value < t_bounds[1] / 1.05
    )
    if math.isfinite(t_est.value):
        # the record says nothing about T outside the searched range: the interval is limited
        # to it (finite and ordered), and runs to the bound when the optimum sits on it
        low_edge = t_est.value <= t_bounds[0] * 1.05
        high_edge = t_est.value >= t_bounds[1] / 1.05
        lo = t_bounds[0] if low_edge else min(max(t_est.ci_low, t_bounds[0]), t_est.value)
        hi = t_bounds[1] if high_edge else max(min(t_est.ci_high, t_bounds[1]), t_est.value)
        estimates["T"] = Estimate(float(t_est.value), float(lo), float(hi), "s")
    info = {
        "T_at_search_edge": bool(at_edge),
        "T_search_range_s": (float(t_bounds[0]), float(t_bounds[1])),
        "tau_range_s": (float(tau[0]), float(tau[-1])),
        "points": int(tau.size),
        "chi2_reduced": float(chi2_red),
    }
    return estimates, curve, info


def _alphas_from_model(taus, fit: _Fit, with_q, with_r) -> np.ndarray:
    model = np.maximum(_model(taus, fit, with_q, with_r), 1e-300)
    if taus.size < 2:
        return np.zeros(taus.size, dtype=int)
    mu = np.gradient(np.log(model), np.log(taus))
    return np.clip(np.rint(-mu - 1.0), -2, 2).astype(int)


def _estimates(tau, w, fit: _Fit, with_q, with_r, scale: float) -> dict[str, Estimate]:
    """Values and 95 % intervals from the weighted Jacobian in (N^2, B^2, ln T, K^2, ...)."""
    design = _design(tau, fit.T, with_q, with_r)
    B2 = fit.theta[1]
    h = 1e-4
    dg = (
        gauss_markov_avar_unit(tau, fit.T * math.exp(h))
        - gauss_markov_avar_unit(tau, fit.T * math.exp(-h))
    ) / (2 * h)
    has_gm = B2 > 0
    cols = [design[:, 0], design[:, 1]]
    if has_gm:
        cols.append(B2 * dg)
    cols.extend(design[:, j] for j in range(2, design.shape[1]))
    J = np.column_stack(cols) * w[:, None]
    norms = np.linalg.norm(J, axis=0)
    sd = np.full(J.shape[1], np.inf)
    usable = norms > 0  # a parameter with no effect on the curve has an unbounded interval
    Jn = J[:, usable] / norms[usable]
    try:
        cov_n = np.linalg.inv(Jn.T @ Jn)
        sd[usable] = np.sqrt(np.clip(np.diag(cov_n), 0.0, None) * scale) / norms[usable]
    except np.linalg.LinAlgError:
        pass
    names = ["N", "B"] + (["lnT"] if has_gm else []) + ["K"] + (["Q"] if with_q else [])
    names += ["R"] if with_r else []
    sd_of = {name: s * CI_WIDENING[name] for name, s in zip(names, sd)}
    theta_names = ["N", "B", "K"] + (["Q"] if with_q else []) + (["R"] if with_r else [])
    out: dict[str, Estimate] = {}
    for name, value in zip(theta_names, fit.theta):
        s = sd_of[name]
        out[name] = Estimate(
            math.sqrt(value),
            math.sqrt(max(value - _Z95 * s, 0.0)),
            math.sqrt(value + _Z95 * s),
            UNITS[name],
        )
    if has_gm:
        s = sd_of["lnT"]
        # in ln T; capped at a factor 1e6 either way (exp would overflow on an unresolved
        # term); fit_allan_variance then limits it to the searched range
        half = min(_Z95 * s, math.log(1e6)) if math.isfinite(s) else math.log(1e6)
        out["T"] = Estimate(fit.T, fit.T * math.exp(-half), fit.T * math.exp(half), "s")
    else:
        out["T"] = Estimate(math.nan, math.nan, math.nan, "s")
    return out


# -- IEEE 952 read-offs ----------------------------------------------------------------------


def ieee_readoffs(curve: AllanCurve) -> dict[str, dict[str, Any]]:
    """The classic slope read-offs of the Allan deviation, each labelled with how it was read."""
    taus, adev = curve.taus, curve.adev
    i_min = int(np.argmin(adev))
    out: dict[str, dict[str, Any]] = {
        "B_flicker": {
            "label": "B flicker = min ADEV / 0.664",
            "value": float(adev[i_min] / FLICKER_ADEV_FACTOR),
            "unit": UNITS["B"],
            "tau_s": float(taus[i_min]),
        },
        "tau_at_minimum": {
            "label": "tau at the Allan minimum",
            "value": float(taus[i_min]),
            "unit": "s",
        },
    }
    slopes = np.diff(np.log(adev)) / np.diff(np.log(taus))
    mid_tau = np.sqrt(taus[1:] * taus[:-1])
    mid_dev = np.sqrt(adev[1:] * adev[:-1])
    n_value = k_value = None
    n_tau = k_tau = None
    before = np.arange(slopes.size) < i_min
    if before.any():
        j = int(np.argmin(np.where(before, np.abs(slopes + 0.5), np.inf)))
        if abs(slopes[j] + 0.5) < 0.25:
            n_value = float(mid_dev[j] * math.sqrt(mid_tau[j]))  # -1/2 line at tau = 1 s
            n_tau = float(mid_tau[j])
    after = np.arange(slopes.size) >= i_min
    if after.any():
        j = int(np.argmin(np.where(after, np.abs(slopes - 0.5), np.inf)))
        if abs(slopes[j] - 0.5) < 0.25:
            k_value = float(mid_dev[j] * math.sqrt(3.0 / mid_tau[j]))  # +1/2 line at tau = 3 s
            k_tau = float(mid_tau[j])
    out["N_at_tau_1s"] = {
        "label": "N = -1/2 slope line at tau = 1 s",
        "value": n_value,
        "unit": UNITS["N"],
        "line_through_tau_s": n_tau,
    }
    out["K_at_tau_3s"] = {
        "label": "K = +1/2 slope line at tau = 3 s",
        "value": k_value,
        "unit": UNITS["K"],
        "line_through_tau_s": k_tau,
    }
    return out


# -- the pipeline ----------------------------------------------------------------------------


def check_record(rate_dps: np.ndarray, rate_hz: float) -> np.ndarray:
    """The record as float64 (n,) or (n, k), or a clear IdentificationError."""
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise IdentificationError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
    data = np.asarray(rate_dps)
    if data.dtype.kind not in "fiu":
        raise IdentificationError(f"record must hold numbers, not {data.dtype}")
    data = data.astype(float, copy=False)
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or not 1 <= data.shape[1] <= 3:
        raise IdentificationError(
            f"record must be one column per axis (1 to 3 axes), got shape {data.shape}"
        )
    n = data.shape[0]
    if n == 0:
        raise IdentificationError(f"record is empty: {RECORD_NEEDS}")
    if n < MIN_SAMPLES:
        raise IdentificationError(
            f"record too short: {n} samples ({n / rate_hz:.3g} s at {rate_hz:g} Hz); {RECORD_NEEDS}"
        )
    bad = ~np.isfinite(data)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise IdentificationError(
            f"record has {int(bad.sum())} NaN or infinite sample(s), first at sample {row} "
            f"of column {col}: remove or fill them before identification"
        )
    flat = np.flatnonzero(np.ptp(data, axis=0) == 0)
    if flat.size:
        raise IdentificationError(
            f"column {int(flat[0])} is constant ({float(data[0, flat[0]])!r} throughout): "
            "a record without noise has nothing to identify"
        )
    return data


def identify_axis(
    rate_dps: np.ndarray,
    rate_hz: float,
    axis: str = "x",
    with_q: bool = False,
    with_r: bool = False,
    tau_range: tuple[float | None, float | None] = (None, None),
    psd_segment: int | None = None,
    progress: Callable[[str], None] | None = None,
) -> AxisIdentification:
    """Identify one axis (1-D array in deg/s sampled at rate_hz).

    progress, if given, is called with a short label after each of the STAGES_PER_AXIS
    stages (Allan deviation, fit, PSD): the command line's progress bar.
    """
    data = check_record(rate_dps, rate_hz)
    if data.shape[1] != 1:
        raise IdentificationError("identify_axis takes one axis; use identify() for several")
    x = np.ascontiguousarray(data[:, 0])
    n = x.size
    mean = float(x.mean())
    std = float(x.std())
    raw_curve = overlapping_adev(x, rate_hz, taus="octave")
    if progress is not None:
        progress(f"{axis}: Allan deviation")
    estimates, curve, info = fit_allan_variance(raw_curve, rate_hz, n, with_q, with_r, tau_range)
    if progress is not None:
        progress(f"{axis}: fit")
    spectrum = one_sided_psd(x, rate_hz, psd_segment)
    if progress is not None:
        progress(f"{axis}: PSD")
    band = white_level_band(rate_hz)
    notes = _notes(estimates, n / rate_hz)
    if info["T_at_search_edge"]:
        lo, hi = info["T_search_range_s"]
        notes.append(
            f"T sits at the edge of the searched range {lo:.3g} .. {hi:.3g} s: "
            "the Gauss-Markov term is not resolved by this record"
        )
    return AxisIdentification(
        axis=axis,
        N=estimates["N"],
        B=estimates["B"],
        T=estimates["T"],
        K=estimates["K"],
        Q=estimates.get("Q"),
        R=estimates.get("R"),
        mean=mean,
        std=std,
        readoffs=ieee_readoffs(curve),
        fit_tau_range_s=info["tau_range_s"],
        fit_points=info["points"],
        chi2_reduced=info["chi2_reduced"],
        psd_white_N=white_density_from_psd(spectrum, band),
        psd_band_hz=band,
        allan=curve,
        spectrum=spectrum,
        notes=notes,
    )


def _notes(est: dict[str, Estimate], duration_s: float) -> list[str]:
    notes = []
    T = est["T"].value
    if not math.isfinite(T):
        notes.append("no Gauss-Markov term found (B = 0): T is undefined")
    elif duration_s < 100 * T:
        notes.append(
            f"record ({_duration_text(duration_s)}) is shorter than 100 T "
            f"({_duration_text(100 * T)}): B and T are poorly determined"
        )
    for key in ("N", "B", "K"):
        e = est[key]
        if e.value > 0 and (e.ci_high - e.ci_low) > e.value:
            notes.append(f"{key} is poorly determined (95 % interval wider than the value)")
        if e.value == 0:
            notes.append(f"{key} fitted as 0 (the term is not visible in this record)")
    return notes


def identify(
    rate_dps: np.ndarray,
    rate_hz: float,
    axis_names: Sequence[str] | None = None,
    with_q: bool = False,
    with_r: bool = False,
    tau_range: tuple[float | None, float | None] = (None, None),
    psd_segment: int | None = None,
    source: str = "",
    progress: Callable[[str], None] | None = None,
) -> Identification:
    """Identify every axis of a (n,) or (n, k<=3) record in deg/s sampled at rate_hz."""
    data = check_record(rate_dps, rate_hz)
    names = list(axis_names) if axis_names is not None else list(AXES[: data.shape[1]])
    if len(names) != data.shape[1]:
        raise IdentificationError(f"{len(names)} axis names for {data.shape[1]} columns")
    axes = []
    for i, name in enumerate(names):
        axes.append(
            identify_axis(
                data[:, i], rate_hz, name, with_q, with_r, tau_range, psd_segment, progress
            )
        )
    return Identification(float(rate_hz), data.shape[0], axes, source)


def _duration_text(seconds: float) -> str:
    if seconds >= 3600:
        return f"{seconds / 3600:.3g} h"
    if seconds >= 60:
        return f"{seconds / 60:.3g} min"
    return f"{seconds:.3g} s"


def _json_float(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
