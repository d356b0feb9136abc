"""Identification of a static gyroscope record: N, K, Gauss-Markov terms (B_i, T_i) per axis.

Per axis: overlapping Allan deviation at octave taus (allan.octave_oadev, Greenhall
confidence intervals), the checks of diagnostics.py (the sensor's own filter, warm-up,
bias steps), a one-sided Welch PSD, and a fit of the closed-form Allan variance of the
generator's own model (fit.py: white + Gauss-Markov terms + random walk, plus quantization,
ramp and a 1/f bank when asked). Fitting that model is what makes the numbers returned the
numbers the generator takes (noise-model.md, "Two facts"); the IEEE read-offs are reported
beside it, labelled (readoffs.py).

Fit methods are looked up by name in FIT_METHODS ("wls", the default; other modules may
register theirs, e.g. a GMWM fit, with fit.fit_curve's signature: the curve, rate, sample
count, tau_range, with_q, with_r, poles, flicker, roll_off, and record = the samples or None
for a curve input; returning a fit.CurveFit).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmg160_emu.noise import diagnostics
from bmg160_emu.noise.allan import AllanCurve, allan_confidence, noise_alpha_from_slope
from bmg160_emu.noise.fit import CI_LEVEL, CurveFit, Estimate, FitError, Term, fit_curve
from bmg160_emu.noise.profile import AXES, UNITS, AxisNoise, Profile
from bmg160_emu.noise.readoffs import ieee_readoffs
from bmg160_emu.noise.spectrum import (
    PSD_CONVENTION,
    Spectrum,
    one_sided_psd,
    white_density_from_psd,
    white_level_band,
)

__all__ = [
    "CI_LEVEL", "FIT_METHODS", "AxisIdentification", "Estimate", "Identification",
    "IdentificationError", "Term", "identify", "identify_axis", "identify_curve",
    "ieee_readoffs",
]

STAGES_PER_AXIS = 3  # progress calls per axis: Allan deviation, fit, PSD
MIN_SAMPLES = 1000  # enough octave taus (9) to fit the white level and see its slope
POOR_FIT_CHI2 = 3.0  # reduced chi-square above which the fit is called poor
UNIT_SCALES = {"deg/s": 1.0, "rad/s": math.pi / 180.0}

RECORD_NEEDS = (
    "N needs at least 1000 samples (5 s at 200 Hz); B and T need a record of about 100 T "
    "(about 1 h for T = 33.9 s); K needs the rising +1/2 part of the Allan curve "
    "(several hours for a BMG160)"
)

FitMethod = Callable[..., CurveFit]
FIT_METHODS: dict[str, FitMethod] = {"wls": fit_curve}


class IdentificationError(ValueError):
    """A record that cannot be identified (too short, not finite, bad rate)."""


@dataclass
class AxisIdentification:
    """Everything identified on one axis."""

    axis: str
    fit: CurveFit
    mean: float
    std: float
    readoffs: dict[str, dict[str, Any]]
    tau_range_reason: str
    psd_white_N: float
    psd_band_hz: tuple[float, float]
    spectrum: Spectrum | None
    notes: list[str] = field(default_factory=list)
    method: str = "wls"

    # the fitted parameters, by name
    @property
    def N(self) -> Estimate:
        return self.fit.N

    @property
    def K(self) -> Estimate:
        return self.fit.K

    @property
    def Q(self) -> Estimate | None:
        return self.fit.Q

    @property
    def R(self) -> Estimate | None:
        return self.fit.R

    @property
    def terms(self) -> list[Term]:
        return self.fit.terms

    @property
    def B(self) -> Estimate:
        """B of the largest Gauss-Markov term (0 with an interval when there is none)."""
        if self.terms:
            return self._largest().B
        return Estimate(0.0, 0.0, 0.0, UNITS["B"])

    @property
    def T(self) -> Estimate:
        """T of the largest Gauss-Markov term (NaN when there is none)."""
        if self.terms:
            return self._largest().T
        return Estimate(math.nan, math.nan, math.nan, "s")

    def _largest(self) -> Term:
        return max(self.terms, key=lambda t: t.B.value)

    @property
    def allan(self) -> AllanCurve:
        return self.fit.curve

    @property
    def fit_tau_range_s(self) -> tuple[float, float]:
        return self.fit.tau_range_s

    @property
    def fit_points(self) -> int:
        return self.fit.points

    @property
    def chi2_reduced(self) -> float:
        return self.fit.chi2_reduced

    def to_axis_noise(self) -> AxisNoise:
        """The generator's parameters for this axis (bias = the record's mean): one term as
        B, T (the firmware's layout), several as a gm list."""
        terms = self.fit.gauss_markov_terms()
        B, T = terms[0] if len(terms) == 1 else (0.0, 0.0)
        return AxisNoise(
            N=self.N.value, B=B, T=T, K=self.K.value, bias=self.mean,
            Q=self.Q.value if self.Q else 0.0, R=self.R.value if self.R else 0.0,
            gm=terms if len(terms) > 1 else (),
        )

    def as_dict(self, units: str = "deg/s") -> dict[str, Any]:
        s = UNIT_SCALES[units]

        def unit(key: str) -> str:
            return UNITS[key].replace("deg", "rad") if units == "rad/s" else UNITS[key]

        out: dict[str, Any] = {"N": self.N.as_dict(s, unit("N")), "K": self.K.as_dict(s, unit("K"))}
        # B, T of the largest term (B 0 and T null without one), then every term
        out["B"] = self.B.as_dict(s, unit("B"))
        out["T"] = self.T.as_dict()
        out["terms"] = [
            {"B": t.B.as_dict(s, unit("B")), "T": t.T.as_dict(),
             "T_at_search_edge": t.T_at_search_edge} for t in self.terms
        ]
        for key, est in (("Q", self.Q), ("R", self.R)):
            if est is not None:
                out[key] = est.as_dict(s, unit(key))
        if self.fit.flicker is not None:
            out["flicker_B"] = self.fit.flicker.as_dict(s, unit("B"))
        readoffs = {}
        for name, item in self.readoffs.items():
            item = dict(item)
            if item["unit"] != "s" and item["value"] is not None:
                item["value"] *= s
                item["unit"] = item["unit"].replace("deg", "rad") if units == "rad/s" else item["unit"]
            readoffs[name] = item
        out.update(
            mean={"value": _json_float(self.mean * s), "unit": units},
            std={"value": _json_float(self.std * s), "unit": units},
            ieee_readoffs=readoffs,
            fit={
                "model": self.model_text(),
                "method": self.method,
                "tau_range_s": list(self.fit_tau_range_s),
                "tau_range_reason": self.tau_range_reason,
                "points": self.fit_points,
                "chi2_reduced": _json_float(self.chi2_reduced),
                "selection": self.fit.selection,
            },
            notes=self.notes,
        )
        if self.spectrum is not None:
            out["psd"] = {
                "convention": PSD_CONVENTION,
                "white_N": {"value": _json_float(self.psd_white_N * s), "unit": unit("N")},
                "frequency_range_hz": list(self.psd_band_hz),
                "segment_samples": self.spectrum.segment_samples,
            }
        return out

    def model_text(self) -> str:
        k = len(self.terms)
        text = f"white + {k} Gauss-Markov term{'s' if k != 1 else ''} + random walk"
        text += " + 1/f bank" if self.fit.flicker is not None else ""
        text += " + quantization" if self.Q is not None else ""
        return text + (" + rate ramp" if self.R is not None else "")


@dataclass
class Identification:
    """Result of identifying a record of one to three axes."""

    rate_hz: float
    samples: int
    axes: list[AxisIdentification]
    source: str = ""
    skipped_s: float = 0.0

    @property
    def duration_s(self) -> float:
        return self.samples / self.rate_hz

    def to_profile(self, name: str = "identified") -> Profile:
        """A profile the generator loads: record columns in order become x, y, z; axes
        missing from the record copy the first one."""
        noise = [a.to_axis_noise() for a in self.axes]
        noise += [noise[0]] * (3 - len(noise))
        return Profile(
            name, x=noise[0], y=noise[1], z=noise[2],
            description=f"identified from {self.source or 'a record'} "
            f"({self.duration_s:.0f} s at {self.rate_hz:g} Hz)",
        )

    def as_dict(self, units: str = "deg/s") -> dict[str, Any]:
        return {
            "source": self.source,
            "rate_hz": self.rate_hz,
            "samples": self.samples,
            "duration_s": self.duration_s,
            "skipped_s": self.skipped_s,
            "units": {k: (UNITS[k].replace("deg", "rad") if units == "rad/s" else UNITS[k])
                      for k in ("N", "B", "T", "K", "Q", "R")},
            "ci_level": CI_LEVEL,
            "axes": {a.axis: a.as_dict(units) for a in self.axes},
        }

    def summary(self, units: str = "deg/s") -> str:
        """A human summary: the fitted parameters with CIs, read-offs, ranges and notes."""
        s = UNIT_SCALES[units]
        u = (lambda k: UNITS[k].replace("deg", "rad")) if units == "rad/s" else UNITS.get
        head = (
            f"record: {self.source or '(array)'}, {self.samples} samples at {self.rate_hz:g} Hz "
            f"({_duration_text(self.duration_s)})"
            + (f", first {_duration_text(self.skipped_s)} skipped" if self.skipped_s else "")
        )
        lines = [head, ("fit: weighted least squares of the closed-form Allan variance; "
                 "95 % confidence intervals")]
        for a in self.axes:
            lines.append("")
            stats = (f"mean {a.mean * s:.6g} {units}, std {a.std * s:.6g} {units}"
                     if math.isfinite(a.std) else "from an Allan deviation curve")
            lines.append(f"axis {a.axis}: {stats}; model: {a.model_text()} ({a.method})")

            def row(key: str, est: Estimate, scale: float = s) -> str:
                return (f"  {key} = {est.value * scale:.4g} {u(key) if key != 'T' else 's'}   "
                        f"[{est.ci_low * scale:.3g}, {est.ci_high * scale:.3g}]")

            lines.append(row("N", a.N))
            for i, t in enumerate(a.terms, 1):
                lines.append(row("B", t.B).replace("  B =", f"  B{i} =") + "   "
                             + row("T", t.T, 1.0).strip().replace("T =", f"T{i} ="))
            if a.fit.flicker is not None:
                lines.append(row("B", a.fit.flicker).replace("  B =", "  flicker B ="))
            lines.append(row("K", a.K))
            for key, est in (("Q", a.Q), ("R", a.R)):
                if est is not None:
                    lines.append(row(key, est))
            lines.append(
                f"  fitted taus {a.fit_tau_range_s[0]:.3g} .. {a.fit_tau_range_s[1]:.3g} s "
                f"({a.fit_points} points), reduced chi-square {a.chi2_reduced:.2f}; "
                f"{a.tau_range_reason}"
            )
            table = ", ".join(f"{c['terms']}: {c['aicc']:.1f}"
                              for c in a.fit.selection.get("candidates", [])
                              if c["aicc"] is not None)
            if table:
                lines.append(f"  terms chosen by AICc (terms: AICc): {table}")
            lines.append("  IEEE 952 read-offs (labelled, not what the generator takes):")
            for item in a.readoffs.values():
                value = item["value"]
                scale = s if item["unit"] != "s" else 1.0
                unit_text = item["unit"].replace("deg", "rad") if (units == "rad/s" and scale != 1.0) else item["unit"]
                text = f"{value * scale:.4g} {unit_text}" if value is not None else "not found"
                lines.append(f"    {item['label']}: {text}")
            if a.spectrum is not None:
                lines.append(
                    f"  PSD white level: N = {a.psd_white_N * s:.4g} {u('N')} over "
                    f"{a.psd_band_hz[0]:g} .. {a.psd_band_hz[1]:g} Hz ({PSD_CONVENTION})"
                )
            for note in a.notes:
                lines.append(f"  note: {note}")
        return "\n".join(lines)


# -- the pipeline ----------------------------------------------------------------------------


def check_record(rate_dps: np.ndarray, rate_hz: float) -> np.ndarray:
    """The record as float64 (n,) or (n, k), or a clear IdentificationError (no copy of a
    float64 array: a day-long record is not duplicated)."""
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
    for col in range(data.shape[1]):  # column by column: no n x k boolean temporary
        bad = ~np.isfinite(data[:, col])
        if bad.any():
            row = int(np.argmax(bad))
            raise IdentificationError(
                f"record has {int(bad.sum())} NaN or infinite sample(s), first at sample {row} "
                f"of column {col}: remove or fill them before identification"
            )
        if data[:, col].min() == data[:, col].max():
            raise IdentificationError(
                f"column {col} is constant ({float(data[0, col])!r} throughout): "
                "a record without noise has nothing to identify"
            )
    return data


def _fit(method: str, curve: AllanCurve, rate_hz: float, n: int, tau_range, options,
         record: np.ndarray | None = None) -> CurveFit:
    try:
        fitter = FIT_METHODS[method]
    except KeyError:
        raise IdentificationError(
            f"unknown fit method {method!r}: use {', '.join(sorted(FIT_METHODS))}"
        ) from None
    try:
        return fitter(curve, rate_hz, n, tau_range=tau_range, record=record, **options)
    except FitError as exc:
        raise IdentificationError(f"{exc} ({RECORD_NEEDS})") from None


def _fit_curve_axis(
    axis: str, curve: AllanCurve, rate_hz: float, n: int, tau_range, options, method: str,
    record: np.ndarray | None = None,
) -> tuple[CurveFit, str, list[str]]:
    """The fit with the default tau range found from the curve, and its notes."""
    notes: list[str] = []
    lo, hi = tau_range
    if lo is None:
        found = diagnostics.white_region_start(curve)
        lo, reason = found.tau_min_s, found.reason
        if found.filtered:
            notes.append(f"sensor filter: {reason}; its remaining roll-off is fitted as a "
                         "-c / tau^2 term (the profile has no filter: generate --bandwidth "
                         "CODE adds the chip's)")
            options = {**options, "roll_off": True}
    else:
        reason = f"fitted from tau = {lo:g} s (--tau-min)"
    fit = _fit(method, curve, rate_hz, n, (lo, hi), options, record)
    notes += _fit_notes(fit, n / rate_hz)
    return fit, reason, notes


def identify_axis(
    rate_dps: np.ndarray,
    rate_hz: float,
    axis: str = "x",
    with_q: bool = False,
    with_r: bool = False,
    tau_range: tuple[float | None, float | None] = (None, None),
    psd_segment: int | None = None,
    progress: Callable[[str], None] | None = None,
    poles: int | None = None,
    flicker: bool = False,
    method: str = "wls",
) -> AxisIdentification:
    """Identify one axis (1-D array, or one column of a record, in deg/s at rate_hz).

    poles: number of Gauss-Markov terms (None: chosen by AICc); flicker: add a 1/f bank.
    progress, if given, is called with a short label after each of the STAGES_PER_AXIS
    stages (Allan deviation, fit, PSD): the command line's progress bar.
    """
    data = check_record(rate_dps, rate_hz)
    if data.shape[1] != 1:
        raise IdentificationError("identify_axis takes one axis; use identify() for several")
    x = data[:, 0]  # possibly a strided column: nothing below needs a contiguous copy
    n = x.shape[0]
    mean = float(x.mean())
    std = float(x.std())
    curve = _curve_from_record(x, rate_hz)
    if curve.taus.size < 4:
        raise IdentificationError(
            f"the Allan deviation of axis {axis} is zero or below double precision at almost "
            f"every tau (std {std:.3g} deg/s): scale the record to deg/s"
        )
    if progress is not None:
        progress(f"{axis}: Allan deviation")
    options = {"with_q": with_q, "with_r": with_r, "poles": poles, "flicker": flicker}
    fit, reason, notes = _fit_curve_axis(axis, curve, rate_hz, n, tau_range, options, method,
                                         record=x)
    if progress is not None:
        progress(f"{axis}: fit")
    for check in (diagnostics.warmup_check, diagnostics.step_check):
        warning = check(x, rate_hz)
        if warning:
            notes.append(warning)
    spectrum = one_sided_psd(x, rate_hz, psd_segment)
    if progress is not None:
        progress(f"{axis}: PSD")
    band = white_level_band(rate_hz)
    return AxisIdentification(
        axis=axis, fit=fit, mean=mean, std=std, readoffs=ieee_readoffs(fit.curve),
        tau_range_reason=reason, psd_white_N=white_density_from_psd(spectrum, band),
        psd_band_hz=band, spectrum=spectrum, notes=notes, method=method,
    )


def _curve_from_record(x: np.ndarray, rate_hz: float) -> AllanCurve:
    from bmg160_emu.noise.allan import overlapping_adev

    return overlapping_adev(x, rate_hz, taus="octave")


def identify_curve(
    taus_s: np.ndarray,
    adev_dps: np.ndarray,
    rate_hz: float,
    n_samples: int,
    axis: str = "x",
    ci: tuple[np.ndarray, np.ndarray] | None = None,
    tau_range: tuple[float | None, float | None] = (None, None),
    poles: int | None = None,
    flicker: bool = False,
    with_q: bool = False,
    with_r: bool = False,
    method: str = "wls",
    mean: float = 0.0,
) -> AxisIdentification:
    """Identify from an Allan deviation curve (deg/s) instead of samples: the sample count
    (or the record length times the rate) sets each point's degrees of freedom; a given
    interval (ci low, high at 68.3 %) is kept for the plots, the fit weights come from edf."""
    taus = np.asarray(taus_s, dtype=float)
    adev = np.asarray(adev_dps, dtype=float)
    n_terms = np.maximum(n_samples + 1 - 2 * np.rint(taus * rate_hz), 1).astype(int)
    curve = allan_confidence(taus, adev, n_terms, noise_alpha_from_slope(taus, adev),
                             int(n_samples), rate_hz)
    options = {"with_q": with_q, "with_r": with_r, "poles": poles, "flicker": flicker}
    fit, reason, notes = _fit_curve_axis(axis, curve, rate_hz, n_samples, tau_range, options,
                                         method)
    if ci is not None:
        fit.curve = AllanCurve(fit.curve.taus, fit.curve.adev, fit.curve.n_terms, fit.curve.edf,
                               np.asarray(ci[0], float), np.asarray(ci[1], float), fit.curve.ci)
    return AxisIdentification(
        axis=axis, fit=fit, mean=mean, std=math.nan, readoffs=ieee_readoffs(fit.curve),
        tau_range_reason=reason, psd_white_N=math.nan, psd_band_hz=(math.nan, math.nan),
        spectrum=None, notes=notes + [("identified from an Allan deviation curve: no mean, "
                                      "std or PSD (bias 0 in the profile)")], method=method,
    )


def _fit_notes(fit: CurveFit, duration_s: float) -> list[str]:
    notes = []
    if not fit.terms and fit.flicker is None:
        notes.append("no Gauss-Markov term found (B = 0): the bias is white noise and a random walk")
    longest = max((t.T.value for t in fit.terms), default=0.0)
    if fit.terms and duration_s < 100 * longest:
        notes.append(
            f"record ({_duration_text(duration_s)}) is shorter than 100 T of the longest term "
            f"({_duration_text(100 * longest)}): its B and T are poorly determined"
        )
    for i, t in enumerate(fit.terms, 1):
        if t.T_at_search_edge:
            lo, hi = fit.T_search_range_s
            where = "shortest" if t.T.value <= lo * 1.05 else "longest"
            hint = ("a filter or a term shorter than the fitted range: raise --tau-min"
                    if where == "shortest" else
                    "a term longer than the record looks like a random walk: record longer")
            notes.append(f"T{i} sits on the {where} T searched ({lo:.3g} .. {hi:.3g} s): {hint}")
    for key in ("N", "K"):
        e = getattr(fit, key)
        if e.value > 0 and (e.ci_high - e.ci_low) > e.value:
            notes.append(f"{key} is poorly determined (95 % interval wider than the value)")
        if e.value == 0:
            notes.append(f"{key} fitted as 0 (the term is not visible in this record)")
    if fit.chi2_reduced > POOR_FIT_CHI2:
        notes.append(
            f"poor fit: reduced chi-square {fit.chi2_reduced:.1f} (about 1 for a model that "
            "follows the curve within its scatter); look at the --plot figure, and try "
            "--poles with more terms, --flicker, a larger --tau-min (filter) or --skip "
            "(non-stationary start)"
        )
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
    poles: int | None = None,
    flicker: bool = False,
    method: str = "wls",
    skip_s: float = 0.0,
) -> Identification:
    """Identify every axis of a (n,) or (n, k<=3) record in deg/s sampled at rate_hz;
    skip_s drops the first seconds (warm-up) without copying the record."""
    data = check_record(rate_dps, rate_hz)
    skip = round(skip_s * rate_hz)
    if skip < 0:
        raise IdentificationError(f"skip must not be negative, got {skip_s} s")
    if skip:
        if skip + MIN_SAMPLES > data.shape[0]:
            raise IdentificationError(
                f"skipping {_duration_text(skip_s)} leaves {max(data.shape[0] - skip, 0)} of "
                f"the record's {data.shape[0]} samples: too short to identify"
            )
        data = check_record(data[skip:], rate_hz)
    names = list(axis_names) if axis_names is not None else list(AXES[: data.shape[1]])
    if len(names) != data.shape[1]:
        raise IdentificationError(f"{len(names)} axis names for {data.shape[1]} columns")
    axes = [
        identify_axis(data[:, i], rate_hz, name, with_q, with_r, tau_range, psd_segment,
                      progress, poles=poles, flicker=flicker, method=method)
        for i, name in enumerate(names)
    ]
    return Identification(float(rate_hz), data.shape[0], axes, source, skip / rate_hz)


def _duration_text(seconds: float) -> str:
    if seconds >= 3600:
        return f"{seconds / 3600:.3g} h"
    if seconds >= 60:
        return f"{seconds / 60:.3g} min"
    return f"{seconds:.3g} s"


def _json_float(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
