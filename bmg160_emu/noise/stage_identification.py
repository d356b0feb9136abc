"""How a record's output stage enters its identification (issue 37): the stage is read on the
PSD, the Allan fit is made through it, and the profile carries it so that generate
reproduces the record sample statistic for sample statistic.

1. The PSD (Welch, segments of 4096 samples or n/16: 0.024 Hz at 100 Hz) shows the stage:
   the broadband response, the bands and the lines (output_response.find_output_stage).
2. A first Allan fit: white noise through the broadband response, the bands' Allan variance
   known (their autocovariance through the response), the lines known; from the first tau
   where the bands hold under BAND_SHARE of the white term's Allan variance (below it a
   small misfit of a band's shape, which a million samples resolve to 0.1 %, would bend N).
   It gives the slow terms.
3. The whole fast shape (output_response.fit_fast_shape): the PSD from rate/300 up less the
   slow terms' spectrum, bands included, as one measured response; the final Allan fit is
   white noise through it, with the slow terms and lines, from the first tau. Twice: the
   slow terms of the second fit refine the shape's low end.

Why the bands go into the shape for the record's own rate: a band's shape is what the
sensor's mechanics make it (the shared ADIS16405's z band is skewed, its wings reach 6 Hz
each side); resonators follow it to a few per cent, the measured shape exactly. The
resonators (centre, width, B) are carried beside it for the chip, which draws them before
its own filter at any output data rate (docs/noise-engine.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bmg160_emu.noise.allan import AllanCurve
from bmg160_emu.noise.estimate import Estimate
from bmg160_emu.noise.fit import CurveFit
from bmg160_emu.noise.output_response import (
    OutputResponse,
    SpectralFindings,
    bands_autocovariance,
    find_output_stage,
    fit_fast_shape,
)
from bmg160_emu.noise.spectrum import (
    gauss_markov_psd,
    one_sided_psd,
    random_walk_psd,
    rounding_floor_psd,
)

FAMILY_ACF = 0.01  # a Butterworth within this of the measured autocorrelation (lags 1-5) is it
BAND_SHARE = 0.25  # of the white term's Allan variance: where the first fit starts
STAGE_SEGMENT = 4096  # samples per Welch segment of the stage's PSD (0.024 Hz at 100 Hz)
SHAPE_PASSES = 2
FLAT = "flat"  # fit_through_stage's answer for a record whose PSD shows no stage


@dataclass
class Flat:
    """fit_through_stage's answer for a record whose PSD shows no stage: what the PSD shows
    (lines, no response) and what the slow-band search needs after the caller's own fit
    (slow_bands_of_flat)."""

    found: SpectralFindings
    fine: Any
    segments: float
    line_spans: tuple[tuple[float, float], ...]
    lsb_dps: float | None
MIN_SEGMENTS = 16  # Welch segments below which the PSD cannot tell a shape (the firmware's
# 6 s capture: 8 segments of 256 read a spurious shape that took N 22 % low)


@dataclass
class RecordStage:
    """The output stage identified on one axis."""

    findings: SpectralFindings  # broadband response, bands, lines (A, f, half-width)
    response: OutputResponse  # the whole fast shape, bands included, at the record's rate
    lsb_dps: float | None
    # the family that fits where one does: a Butterworth (output_stage.FilterFit) whose
    # autocorrelation is the measured one's within FAMILY_ACF, no band: the profile carries it
    # (a corner in Hz holds at any rate); None: the measured response
    family: Any = None
    # bands of the slow spectrum (slow_bands.py): never inside the response, drawn everywhere
    slow_bands: list = field(default_factory=list)

    @property
    def carries_response(self) -> bool:
        return self.family is None and self.response.order > 0

    @property
    def sines(self) -> tuple[tuple[Estimate, float], ...]:
        """The lines as the fit takes them: (amplitude with its 95 % interval, Hz)."""
        return tuple((Estimate(a, max(a - h, 0.0), a + h, "deg/s"), f)
                     for a, f, h in self.findings.lines)

    def sine_terms(self) -> tuple[tuple[float, float], ...]:
        """The lines as the generator draws them, before the response: A / |H(f)|."""
        out = []
        for amplitude, frequency, _ in self.findings.lines:
            gain = float(self.response.power(np.array([frequency]))[0])
            out.append((amplitude / math.sqrt(max(gain, 1e-6)), frequency))
        return tuple(out)

    def band_terms(self) -> tuple[tuple[float, float, float], ...]:
        """Every resonator of every band: (centre Hz, width Hz, B deg/s)."""
        return tuple((r.f0_hz, r.width_hz, r.B) for b in self.findings.bands
                     for r in b.resonances)

    def slow_band_terms(self) -> tuple[tuple[float, float, float], ...]:
        """Every resonator of every slow band: (centre Hz, width Hz, B deg/s)."""
        return tuple((r.f0_hz, r.width_hz, r.B) for b in self.slow_bands
                     for r in b.resonances)


def stage_spectrum(x: np.ndarray, rate_hz: float):
    """The Welch PSD the stage is read on, and its number of half-overlapping segments."""
    n = x.shape[0]
    segment = int(min(STAGE_SEGMENT, max(256, 2 ** int(math.log2(max(n // 16, 256))))))
    spectrum = one_sided_psd(x, rate_hz, segment)
    segments = max((n - segment) / (segment - segment // 2) + 1, 1.0)
    return spectrum, segments


def fit_through_stage(x: np.ndarray, rate_hz: float, curve: AllanCurve, lsb_dps: float | None,
                      fit: Callable[..., CurveFit], tau_max: float | None, fine: Any,
                      staged: tuple[Any, float]
                      ) -> tuple[CurveFit, RecordStage, list[str]] | Flat | str | None:
    """The final Allan fit through the record's output stage, the stage, and notes; a Flat
    (FLAT without the long-segment PSD) when the PSD shows no stage (flat, no band: the
    caller fits white noise, no filter searched, then slow_bands_of_flat), None when the
    record is too short to tell (the caller's former route).
    ``fit(tau_range, **stage options)`` is the identification's fit method; ``fine``, the
    record's long-segment PSD (spectrum.one_sided_psd), locates lines to its finer bins
    (output_stage.find_lines: A and f of a 1.3 Hz line to 10 % and 0.003 Hz on 20 min);
    ``staged``, stage_spectrum(x, rate_hz): the PSD the stage is read on and its number of
    segments (the caller computes it beside the Allan deviation)."""
    spectrum, segments = staged
    if segments < MIN_SEGMENTS:
        return None
    f, psd = spectrum.frequency_hz, spectrum.psd
    found = find_output_stage(f, psd, segments, rate_hz, lsb_dps)
    if fine is not None:
        from bmg160_emu.noise.output_stage import find_lines

        step = fine.segment_samples - fine.segment_samples // 2
        count = max((x.shape[0] - fine.segment_samples) / step + 1, 1.0)
        spans = [(b.centre_hz - 4.0 * b.width_hz, b.centre_hz + 4.0 * b.width_hz)
                 for b in found.bands]
        every_line = find_lines(fine, rate_hz, count)
        found.lines = [
            (line.amplitude.value, line.frequency_hz,
             line.amplitude.ci_high - line.amplitude.value)
            for line in every_line
            if line.frequency_hz >= rate_hz / 100.0
            and not any(lo <= line.frequency_hz <= hi for lo, hi in spans)]
        df = float(fine.frequency_hz[0])
        line_spans = tuple((line.frequency_hz - 4.0 * df, line.frequency_hz + 4.0 * df)
                           for line in every_line)
    stage = RecordStage(found, found.response, lsb_dps)
    sines = stage.sines
    if found.response.order == 0 and not found.bands:
        # flat: white noise; the slow spectrum is searched for bands after the caller's fit
        return FLAT if fine is None else Flat(found, fine, count, line_spans, lsb_dps)
    if not found.bands and found.response.order > 0:
        from bmg160_emu.noise.output_stage import fit_filter_psd

        butterworth = fit_filter_psd(spectrum, rate_hz, lsb_dps)
        if butterworth is not None:
            stats = butterworth.design.white_stats()
            measured = found.response.autocovariance()
            measured = np.r_[measured, np.zeros(6)] / measured[0]
            gap = max(abs(stats.correlation(k) - measured[k]) for k in range(1, 6))
            if gap < FAMILY_ACF:
                stage.family = butterworth
                final = fit((None, tau_max), output_filter=butterworth, sines=sines,
                            lsb_dps=lsb_dps)
                notes = [(f"the measured output response is that filter (autocorrelation at "
                          f"lags 1-5 within {gap:.3f}): the profile carries it")]
                if fine is not None:
                    stage.slow_bands = _slow_bands(fine, count, rate_hz, final, found, lsb_dps,
                                                   line_spans)
                if stage.slow_bands:
                    slow = _known(stage.slow_bands, found.response, rate_hz)
                    final = fit((None, tau_max), output_filter=butterworth, known_avar=slow,
                                sines=sines, lsb_dps=lsb_dps)
                    notes.append(_slow_note(stage.slow_bands))
                return final, stage, notes
    known = None
    start = None
    if found.bands:
        bands_stats = _stats_of(found.bands, found.response, rate_hz)

        def known(tau: np.ndarray) -> np.ndarray:
            return _avar(bands_stats, tau, rate_hz)

        share = known(curve.taus) / (found.response.white_avar_unit(curve.taus)
                                      * found.N_psd**2)
        below = np.flatnonzero(share < BAND_SHARE)
        start = float(curve.taus[below[0]]) if below.size else None
    first = fit((start, tau_max), response=found.response, known_avar=known, sines=sines,
                lsb_dps=lsb_dps)
    slow_bands: list = []
    if fine is not None:
        slow_bands = _slow_bands(fine, count, rate_hz, first, found, lsb_dps, line_spans)
    slow_known = None
    if slow_bands:
        stage.slow_bands = slow_bands
        slow_first = _known(slow_bands, found.response, rate_hz)

        def with_slow(tau: np.ndarray) -> np.ndarray:
            out = slow_first(tau)
            return out if known is None else out + known(tau)

        first = fit((start, tau_max), response=found.response, known_avar=with_slow,
                    sines=sines, lsb_dps=lsb_dps)
    current = first
    for _ in range(SHAPE_PASSES):
        slow = random_walk_psd(current.K.value, f) + sum(
            (gauss_markov_psd(B, T, f) for B, T in current.gauss_markov_terms()),
            np.zeros(f.size)) + _bands_psd(slow_bands, f, rate_hz)
        response, _level = fit_fast_shape(f, psd, segments, rate_hz, lsb_dps, slow,
                                          found.lines)
        if slow_bands:
            slow_known = _known(slow_bands, response, rate_hz)
        current = fit((None, tau_max), response=response, known_avar=slow_known, sines=sines,
                      lsb_dps=lsb_dps)
    stage.response = response
    notes = []
    if found.bands:
        notes.append("the bands are drawn inside the measured response at the record's rate "
                     "(generate); the chip draws their resonators before its own filter")
    if slow_bands:
        notes.append(_slow_note(slow_bands))
    return current, stage, notes


def slow_bands_of_flat(flat: Flat, fit_done: CurveFit, rate_hz: float,
                       fit: Callable[..., CurveFit], tau_max: float | None
                       ) -> tuple[CurveFit, RecordStage, list[str]] | None:
    """A flat record's slow bands against the caller's own fit (white noise, Gauss-Markov
    terms, random walk): None when there is none (the caller's fit stands, and this cost one
    scan, about 50 ms), else the fit with them known, the stage that carries them, a note."""
    bands = _slow_bands(flat.fine, flat.segments, rate_hz, fit_done, flat.found, flat.lsb_dps,
                        flat.line_spans)
    if not bands:
        return None
    stage = RecordStage(flat.found, flat.found.response, flat.lsb_dps, slow_bands=bands)
    final = fit((None, tau_max), response=flat.found.response,
                known_avar=_known(bands, flat.found.response, rate_hz),
                sines=stage.sines, lsb_dps=flat.lsb_dps)
    return final, stage, [_slow_note(bands)]


def _slow_note(bands: list) -> str:
    return (f"{len(bands)} slow band{'s' if len(bands) > 1 else ''} below the output stage's "
            "range (slow_bands.py): drawn as resonators in every route")


def _known(bands: list, response: OutputResponse, rate_hz: float
           ) -> Callable[[np.ndarray], np.ndarray]:
    """The bands' Allan variance at tau through the response, a known term of the fit."""
    stats = _stats_of(bands, response, rate_hz)

    def known(tau: np.ndarray) -> np.ndarray:
        return _avar(stats, tau, rate_hz)

    return known


def _stats_of(bands: list, response: OutputResponse, rate_hz: float) -> Any:
    """The bands' resonators through the response: their autocovariance's statistics (long
    enough for the slowest resonator to decay to 1e-6: 4.4 / (pi width) s)."""
    from bmg160_emu.noise.butterworth import WhiteThroughFilter

    narrowest = min(r.width_hz for b in bands for r in b.resonances)
    lags = int(min(max(8192, math.ceil(4.4 * rate_hz / (math.pi * narrowest))), 1 << 20))
    return WhiteThroughFilter(bands_autocovariance(bands, response, rate_hz, lags))


def _avar(stats: Any, tau: np.ndarray, rate_hz: float) -> np.ndarray:
    m = np.maximum(np.rint(np.asarray(tau, dtype=float) * rate_hz), 1)
    return np.asarray(stats.avar_unit(m.astype(np.int64)))


def _bands_psd(bands: list, f: np.ndarray, rate_hz: float) -> np.ndarray:
    out = np.zeros(np.shape(f))
    for band in bands:
        for r in band.resonances:
            out = out + r.psd(f, rate_hz)
    return out


def _slow_bands(fine: Any, segments: float, rate_hz: float, first: CurveFit,
                found: SpectralFindings, lsb_dps: float | None,
                lines: tuple[tuple[float, float], ...]) -> list:
    """Bands below the output stage's range on the long-segment PSD (slow_bands.py), against
    the first fit's model through the broadband response."""
    from bmg160_emu.noise.slow_bands import find_slow_bands

    floor = rounding_floor_psd(lsb_dps, rate_hz)

    def fixed(fr: np.ndarray) -> np.ndarray:
        return floor + _bands_psd(found.bands, fr, rate_hz) * found.response.power(fr)

    def columns(fr: np.ndarray) -> list[np.ndarray]:
        cols = [2.0 * found.response.power(fr), random_walk_psd(1.0, fr)]
        return cols + [gauss_markov_psd(1.0, T, fr) for _, T in first.gauss_markov_terms()]

    return find_slow_bands(fine.frequency_hz, fine.psd, segments, rate_hz, fixed, columns,
                           lines)
