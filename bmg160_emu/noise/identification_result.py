"""What identification found: per axis (AxisIdentification) and per record
(Identification), as a summary for people, a JSON-ready dict and a profile the generator
takes (identify.py is the procedure that finds it).

The profile carries the sensor's own output stage when one was found (issue 23): the
output filter (order and corner) and the quantization step go into its [output] table,
the sinusoidal lines into each axis's sine list, so generate reproduces the record.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmg160_emu.durations import duration_text
from bmg160_emu.noise.allan import AllanCurve
from bmg160_emu.noise.fit import CI_LEVEL, CurveFit, Estimate, Term
from bmg160_emu.noise.output_stage import FilterFit
from bmg160_emu.noise.profile import UNITS, AxisNoise, OutputStage, Profile
from bmg160_emu.noise.spectrum import PSD_CONVENTION, Spectrum

UNIT_SCALES = {"deg/s": 1.0, "rad/s": math.pi / 180.0}


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
    # the output stage of any shape read on the record's PSD (stage_identification.RecordStage:
    # the measured response, bands, lines); None: the Butterworth of output_stage, or none
    stage: Any = None

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

    @property
    def output_filter(self) -> FilterFit | None:
        """The sensor's output filter found on this axis (part of the white term)."""
        return self.fit.output_filter

    @property
    def lsb_dps(self) -> float | None:
        """The step the record's values sit on (None: real numbers)."""
        return self.fit.lsb_dps

    @property
    def sines(self) -> list[tuple[Estimate, float]]:
        """Sinusoidal terms: (amplitude A, frequency Hz)."""
        return self.fit.sines

    def to_axis_noise(self) -> AxisNoise:
        """The generator's parameters for this axis (bias = the record's mean): one term as
        B, T (the firmware's layout), several as a gm list."""
        terms = self.fit.gauss_markov_terms()
        B, T = terms[0] if len(terms) == 1 else (0.0, 0.0)
        stage = self.stage
        if stage is not None:  # lines before the response (A / |H(f)|), bands, the response
            sine = tuple(t for t in stage.sine_terms() if t[0] > 0)
        else:
            sine = tuple((A.value, f) for A, f in self.sines if A.value > 0)
        return AxisNoise(
            N=self.N.value, B=B, T=T, K=self.K.value, bias=self.mean,
            Q=self.Q.value if self.Q else 0.0, R=self.R.value if self.R else 0.0,
            gm=terms if len(terms) > 1 else (), sine=sine,
            band=stage.band_terms() if stage is not None else (),
            slow_band=stage.slow_band_terms() if stage is not None else (),
            response=stage.response.cosine if stage is not None and stage.carries_response
            else (),
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
        out["sines"] = [{"A": A.as_dict(s, units), "f_hz": f} for A, f in self.sines]
        flt = self.output_filter
        out["output_filter"] = None if flt is None else {
            "order": flt.order, "corner_hz": flt.corner_hz,
            "ci95_hz": [flt.corner_low_hz, flt.corner_high_hz], "how": flt.how}
        out["lsb"] = None if self.lsb_dps is None else {"value": self.lsb_dps * s, "unit": units}
        stage = self.stage
        out["output_response"] = None if stage is None or not stage.carries_response else {
            "taps": len(stage.response.cosine), "lag1": stage.response.lag1,
            "corner_hz": stage.response.corner_hz(), "rate_hz": stage.response.rate_hz,
            "cosine": list(stage.response.cosine),
            "broadband": {"taps": len(stage.findings.response.cosine),
                          "lag1": stage.findings.response.lag1}}
        out["bands"] = [] if stage is None else [
            {"centre_hz": b.centre_hz, "centre_ci95_half_hz": b.centre_half,
             "width_hz": b.width_hz, "width_ci95_half_hz": b.width_half,
             "B": {"value": b.B * s, "unit": units},
             "power": b.power * s * s, "power_ci95_half": b.power_half * s * s,
             "resonators": [{"f_hz": r.f0_hz, "width_hz": r.width_hz, "B": r.B * s}
                            for r in b.resonances]}
            for b in stage.findings.bands]
        if stage is not None and stage.slow_bands:  # below the response: drawn in every route
            out["bands"] += [
                {"centre_hz": b.centre_hz, "centre_ci95_half_hz": b.centre_half,
                 "width_hz": b.width_hz, "width_ci95_half_hz": b.width_half,
                 "B": {"value": b.B * s, "unit": units},
                 "power": b.power * s * s, "power_ci95_half": b.power_half * s * s,
                 "resonators": [{"f_hz": r.f0_hz, "width_hz": r.width_hz, "B": r.B * s}
                                for r in b.resonances], "slow": True}
                for b in stage.slow_bands]
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
        white = ("filtered white" if self.output_filter is not None or self.stage is not None
                 else "white")
        text = f"{white} + {k} Gauss-Markov term{'s' if k != 1 else ''} + random walk"
        text += " + 1/f bank" if self.fit.flicker is not None else ""
        m = len(self.sines)
        text += f" + {m} sinusoid{'s' if m != 1 else ''}" if m else ""
        text += " + quantization" if self.Q is not None else ""
        text += " + LSB rounding" if self.lsb_dps else ""
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

    def output_stage(self) -> OutputStage | None:
        """The sensor's output stage over its axes: the filter of the order most axes found
        at the median of their corners, and the quantization step; None when neither."""
        filters = [a.output_filter for a in self.axes if a.output_filter is not None]
        steps = [a.lsb_dps for a in self.axes if a.lsb_dps]
        measured = any(a.stage is not None and a.stage.carries_response for a in self.axes)
        if not filters and not steps and not measured:
            from bmg160_emu.noise.discretization import SUPPORTED_RATES_HZ

            # a rate the BMG160 does not offer: the profile still runs at the record's own
            return (None if self.rate_hz in SUPPORTED_RATES_HZ
                    else OutputStage(rate_hz=self.rate_hz))
        order = corner = None
        if filters:
            order = Counter(f.order for f in filters).most_common(1)[0][0]
            corner = float(np.median([f.corner_hz for f in filters if f.order == order]))
        lsb = float(np.median(steps)) if steps else None
        return OutputStage(order=order, corner_hz=corner, lsb_dps=lsb, rate_hz=self.rate_hz)

    def to_profile(self, name: str = "identified") -> Profile:
        """A profile the generator loads: record columns in order become x, y, z; axes
        missing from the record copy the first one; the output stage when found."""
        noise = [a.to_axis_noise() for a in self.axes]
        noise += [noise[0]] * (3 - len(noise))
        return Profile(
            name, x=noise[0], y=noise[1], z=noise[2],
            description=f"identified from {self.source or 'a record'} "
            f"({self.duration_s:.0f} s at {self.rate_hz:g} Hz)",
            output=self.output_stage(),
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
            f"({duration_text(self.duration_s)})"
            + (f", first {duration_text(self.skipped_s)} skipped" if self.skipped_s else "")
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
            for A, f in a.sines:
                lines.append(f"  sinusoid A = {A.value * s:.4g} {units} [{A.ci_low * s:.3g}, "
                             f"{A.ci_high * s:.3g}] at f = {f:.4g} Hz")
            if a.output_filter is not None:
                lines.append(f"  output filter: {a.output_filter.text()} Hz, "
                             f"{a.output_filter.how}")
            if a.stage is not None and a.stage.carries_response:
                broad = a.stage.findings.response
                lines.append(f"  output response (broadband, read on the PSD above "
                             f"{a.stage.response.rate_hz / 100:g} Hz): {broad.text()}")
                lines.append(f"  measured response generate draws (the record's whole fast "
                             f"spectrum, bands included): {a.stage.response.text()}")
            for band in (a.stage.findings.bands if a.stage is not None else []):
                lines.append(f"  {band.text().replace('deg/s', units)}; drawn by "
                             f"{len(band.resonances)} resonator"
                             f"{'s' if len(band.resonances) != 1 else ''}")
            for band in (a.stage.slow_bands if a.stage is not None else []):
                lines.append(f"  slow {band.text().replace('deg/s', units)} (below the "
                             "response: a resonator drawn in every route)")
            if a.lsb_dps:
                lines.append(f"  quantized: LSB {a.lsb_dps * s:.6g} {units} (its white floor "
                             "LSB^2/12 is in the model)")
            lines.append(
                f"  fitted taus {a.fit_tau_range_s[0]:.3g} .. {a.fit_tau_range_s[1]:.3g} s "
                f"({a.fit_points} points), reduced chi-square {a.chi2_reduced:.2f}; "
                f"{a.tau_range_reason}"
            )
            table = ", ".join(f"{c['terms']}{'*' if c.get('chosen') else ''}: {c['aicc']:.1f}"
                              for c in a.fit.selection.get("candidates", [])
                              if c["aicc"] is not None)
            if table:
                lines.append(f"  Gauss-Markov terms scored by AICc (terms: AICc, * taken): "
                             f"{table}")
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



def _json_float(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None
