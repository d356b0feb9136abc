"""Identification of a static gyroscope record: N, K, Gauss-Markov terms (B_i, T_i) per axis,
and the sensor's output stage (its filter, quantization step and periodic lines).

Per axis: overlapping Allan deviation at octave taus (allan.octave_oadev, Greenhall
confidence intervals), a one-sided Welch PSD, the output stage it shows (output_stage.py:
the filter fitted on the PSD, the LSB grid of the values, PSD lines), the checks of
diagnostics.py (warm-up, bias steps; a shallow start where no filter was found), and a fit
of the closed-form Allan variance of the generator's own model (fit.py: white noise through
the output filter + Gauss-Markov terms + random walk + the lines, plus the quantization
floor, ramp and a 1/f bank when asked). Fitting that model is what makes the numbers
returned the numbers the generator takes (noise-model.md, "Two facts"); the IEEE read-offs
are reported beside it, labelled (readoffs.py). identification_result.py holds the results.

Fit methods are looked up by name in FIT_METHODS ("wls", the default; other modules may
register theirs, e.g. a GMWM fit, with fit.fit_curve's signature: the curve, rate, sample
count, tau_range, with_q, with_r, poles, flicker, roll_off, output_filter, lsb_dps, sines,
and record = the samples or None for a curve input; returning a fit.CurveFit).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from bmg160_emu.durations import duration_text
from bmg160_emu.noise import diagnostics
from bmg160_emu.noise.allan import AllanCurve, allan_confidence, noise_alpha_from_slope
from bmg160_emu.noise.blas_threads import with_one_blas_thread
from bmg160_emu.noise.fit import CurveFit, FitError, fit_curve
from bmg160_emu.noise.identification_result import AxisIdentification, Identification
from bmg160_emu.noise.output_stage import (
    FilterFit,
    Line,
    find_lines,
    fit_filter_curve,
    fit_filter_psd,
    output_grid,
)
from bmg160_emu.noise.profile import AXES
from bmg160_emu.noise.readoffs import ieee_readoffs
from bmg160_emu.noise.spectrum import one_sided_psd, white_density_from_psd, white_level_band

__all__ = ["FIT_METHODS", "IdentificationError", "check_record", "identify", "identify_axis",
           "identify_curve"]

STAGES_PER_AXIS = 3  # progress calls per axis: Allan deviation, fit, PSD
MIN_SAMPLES = 1000  # enough octave taus (9) to fit the white level and see its slope
POOR_FIT_CHI2 = 3.0  # reduced chi-square above which the fit is called poor
MAX_RECORD_DPS = 1e9  # a record beyond this is no rate record in deg/s (device.true_rate's cap)
# N of MEMS gyroscopes (IEEE 952 N = one-sided density / sqrt 2), deg/s/sqrt(Hz): from a
# tactical-grade part (ADIS16495, ARW 0.09 deg/sqrt(h): N = 0.0015) and the best consumer one
# (TDK ICM-42688-P, 0.0028 one-sided: N = 0.002) to a cheap analog one (ADXRS620, 0.05: N =
# 0.035), with margin; a curve read in the wrong one of deg/s and rad/s is 57 times off
MEMS_N_DPS = (3e-4, 0.08)
AICC_NO_EVIDENCE = 2.0  # an AICc difference below this is no evidence either way
# (Burnham and Anderson 2002, Model Selection and Multimodel Inference, sec. 2.6)

RECORD_NEEDS = (
    "N needs at least 1000 samples (5 s at 200 Hz); B and T need a record of about 100 T "
    "(about 1 h for T = 33.9 s); K needs the rising +1/2 part of the Allan curve "
    "(several hours for a BMG160)"
)

FitMethod = Callable[..., CurveFit]
FIT_METHODS: dict[str, FitMethod] = {"wls": fit_curve}


class IdentificationError(ValueError):
    """A record that cannot be identified (too short, not finite, bad rate)."""


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
        low, high = float(data[:, col].min()), float(data[:, col].max())
        if max(-low, high) > MAX_RECORD_DPS:
            raise IdentificationError(
                f"column {col} reaches {max(-low, high):.3g}: beyond +-{MAX_RECORD_DPS:g} "
                "deg/s no gyroscope record is in deg/s (check the units)")
        if low == high:
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


@dataclass(frozen=True)
class SensorOutput:
    """What the record shows of the sensor's output stage (output_stage.py)."""

    output_filter: FilterFit | None = None
    lsb_dps: float | None = None
    lines: tuple[Line, ...] = ()


def _fit_curve_axis(
    axis: str, curve: AllanCurve, rate_hz: float, n: int, tau_range, options, method: str,
    record: np.ndarray | None = None, stage: SensorOutput = SensorOutput(),
) -> tuple[CurveFit, str, list[str]]:
    """The fit with the default tau range found from the curve, and its notes.

    With an output filter found, the white term is filtered white noise and every tau is
    fitted. A filter that is no Butterworth (a decimation's average, a Bessel) does not
    follow the first taus, where a long record knows the curve to a few 0.1 %: when that
    fit is poor and fitting from the white region as without a filter (its remaining
    roll-off a -c / tau^2 term) is much better, that fit is kept, and the filter is carried
    for generate (the closest Butterworth: the profile's filter), with a note."""
    notes: list[str] = []
    lo, hi = tau_range
    flt = stage.output_filter
    options = {**options, "lsb_dps": stage.lsb_dps,
               "sines": tuple((line.amplitude, line.frequency_hz) for line in stage.lines)}
    if lo is not None:
        reason = f"fitted from tau = {lo:g} s (--tau-min)"
        given = _fit(method, curve, rate_hz, n, (lo, hi), {**options, "output_filter": flt},
                     record)
        return given, reason, notes + _fit_notes(given, n / rate_hz)
    found = diagnostics.white_region_start(curve)
    if flt is None and found.filtered and record is None:
        # a curve alone: the filter from its shallow start, two octaves into the white
        flt = fit_filter_curve(curve, rate_hz, found.tau_min_s * 2.0, stage.lsb_dps)
    fit: CurveFit | None = None
    if flt is not None:
        fit = _fit(method, curve, rate_hz, n, (float(curve.taus[0]), hi),
                   {**options, "output_filter": flt}, record)
        reason = "every tau fitted: the output filter is part of the white term"
    if found.filtered and (fit is None or fit.chi2_reduced > POOR_FIT_CHI2):
        robust = _fit(method, curve, rate_hz, n, (found.tau_min_s, hi),
                      {**options, "roll_off": True}, record)
        if fit is None or fit.chi2_reduced > 2.0 * max(robust.chi2_reduced, 1.0):
            if fit is None:
                notes.append("the start is below the white-noise line but no output filter "
                             "was found: fitted from one octave above, its remaining roll-off "
                             "as a -c / tau^2 term")
            elif flt is not None:
                # the Butterworth that best gives the first taus with this fit's N: what
                # generate then draws (output_stage.fit_filter_curve)
                closest = fit_filter_curve(curve, rate_hz, found.tau_min_s * 2.0,
                                           stage.lsb_dps, white=robust.N.value**2) or flt
                notes.append(f"the sensor's filter is no Butterworth: the closest one from the "
                             f"PSD ({flt.text()} Hz) does not follow the first taus (reduced "
                             f"chi-square {fit.chi2_reduced:.1f}); fitted from one octave "
                             f"above the filter as without it, and the profile takes the "
                             f"Butterworth closest to the first taus ({closest.text()} Hz)")
                flt = closest
            fit, reason = robust, found.reason
            fit.output_filter = flt
    if fit is None:
        fit = _fit(method, curve, rate_hz, n, (found.tau_min_s, hi), options, record)
        reason = found.reason
    return fit, reason, notes + _fit_notes(fit, n / rate_hz)


@with_one_blas_thread
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
    output_stage: bool = True,
) -> AxisIdentification:
    """Identify one axis (1-D array, or one column of a record, in deg/s at rate_hz).

    poles: number of Gauss-Markov terms (None: chosen by AICc); flicker: add a 1/f bank;
    output_stage: find and fit the sensor's output filter, quantization and lines (False:
    the white term is N^2 / tau and the fit starts where the white slope does).
    progress, if given, is called with a short label after each of the STAGES_PER_AXIS
    stages (Allan deviation, PSD, fit): the command line's progress bar.
    """
    data = check_record(rate_dps, rate_hz)
    if data.shape[1] != 1:
        raise IdentificationError("identify_axis takes one axis; use identify() for several")
    x = data[:, 0]  # possibly a strided column: nothing below needs a contiguous copy
    n = x.shape[0]
    mean = float(x.mean())
    std = float(x.std())
    search_stage = output_stage and tau_range[0] is None and not with_q
    # (--with-q: angle quantization's PSD rises as f^2; a measured response would take it)
    with spectra_beside(x, rate_hz, psd_segment, search_stage) as spectra:
        curve = _curve_from_record(x, rate_hz)
        spectrum, staged = spectra()
    if curve.taus.size < 4:
        raise IdentificationError(
            f"the Allan deviation of axis {axis} is zero or below double precision at almost "
            f"every tau (std {std:.3g} deg/s): scale the record to deg/s"
        )
    if progress is not None:
        progress(f"{axis}: Allan deviation")
        progress(f"{axis}: PSD")
    options = {"with_q": with_q, "with_r": with_r, "poles": poles, "flicker": flicker}
    record_stage = None
    flat = False
    flat_stage = None
    if search_stage:
        # the stage of any shape, read on the PSD, and the fit through it (issue 37)
        from bmg160_emu.noise.stage_identification import Flat, fit_through_stage

        grid = output_grid(x)

        def fit_with(fit_range, **stage_options):
            return _fit(method, curve, rate_hz, n, fit_range, {**options, **stage_options}, x)

        through = fit_through_stage(
            x, rate_hz, curve, grid.step if grid is not None else None, fit_with, tau_range[1],
            spectrum, staged)
        flat = isinstance(through, (str, Flat))
        flat_stage = through if isinstance(through, Flat) else None
        if isinstance(through, tuple):
            fit, record_stage, notes = through
            reason = ("every tau fitted: the output filter is part of the white term (the "
                      "measured response is that filter)" if record_stage.family is not None
                      else "every tau fitted: white noise through the measured output response "
                      "(the record's whole fast spectrum)")
            notes += _fit_notes(fit, n / rate_hz)
    if record_stage is None:
        if output_stage and flat:  # the PSD is flat: no filter to search for
            stage = _sensor_output(x, rate_hz, spectrum, with_filter=False)
        else:
            stage = _sensor_output(x, rate_hz, spectrum) if output_stage else SensorOutput()
        fit, reason, notes = _fit_curve_axis(axis, curve, rate_hz, n, tau_range, options,
                                             method, record=x, stage=stage)
        if flat_stage is not None and fit.output_filter is None:
            from bmg160_emu.noise.stage_identification import slow_bands_of_flat

            slow = slow_bands_of_flat(flat_stage, fit, rate_hz, fit_with, tau_range[1])
            if slow is not None:  # the flat record's slow spectrum has a band: fitted with it
                fit, record_stage, found_notes = slow
                reason = ("every tau fitted: white noise (the PSD shows no output filter), "
                          "the slow bands known")
                notes = found_notes + _fit_notes(fit, n / rate_hz)
    if progress is not None:
        progress(f"{axis}: fit")
    for check in (diagnostics.warmup_check, diagnostics.step_check):
        warning = check(x, rate_hz)
        if warning:
            notes.append(warning)
    band = white_level_band(rate_hz)
    return AxisIdentification(
        axis=axis, fit=fit, mean=mean, std=std, readoffs=ieee_readoffs(fit.curve),
        tau_range_reason=reason, psd_white_N=white_density_from_psd(spectrum, band),
        psd_band_hz=band, spectrum=spectrum, notes=notes, method=method, stage=record_stage,
    )


def _sensor_output(x: np.ndarray, rate_hz: float, spectrum, with_filter: bool = True
                   ) -> SensorOutput:
    """The output stage the record shows: its LSB grid, its filter (on the PSD), its lines."""
    grid = output_grid(x)
    lsb = grid.step if grid is not None else None
    step = spectrum.segment_samples - spectrum.segment_samples // 2
    segments = max((x.shape[0] - spectrum.segment_samples) / step + 1, 1.0)
    flt = fit_filter_psd(spectrum, rate_hz, lsb) if with_filter else None
    return SensorOutput(flt, lsb, tuple(find_lines(spectrum, rate_hz, segments)))


# A record this long has its spectra computed on a second thread beside its Allan
# deviation (numpy, BLAS and pocketfft release the GIL): 0.1 s and more of each on a day at
# 200 Hz; on a shorter record a thread costs more than it saves
SPECTRA_THREAD_SAMPLES = 1 << 20


@contextlib.contextmanager
def spectra_beside(x: np.ndarray, rate_hz: float, psd_segment: int | None, stage: bool
                   ) -> Iterator[Callable[[], tuple[Any, Any]]]:
    """The record's long-segment PSD and (``stage``) the PSD the output stage is read on,
    computed beside the block: on a second thread when the record is long and the process
    may run on a second CPU (worker_thread.usable_cpus: its affinity), else in the caller's
    thread when asked for. Yields the function that returns both (staged is None without
    ``stage``); the numbers are the same either way."""
    from bmg160_emu.noise.stage_identification import stage_spectrum
    from bmg160_emu.noise.worker_thread import usable_cpus

    def both() -> tuple[Any, Any]:
        return (one_sided_psd(x, rate_hz, psd_segment),
                stage_spectrum(x, rate_hz) if stage else None)

    if x.shape[0] < SPECTRA_THREAD_SAMPLES or usable_cpus() < 2:
        yield both
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="bmg160-spectra") as pool:
        future = pool.submit(both)
        yield future.result


def _curve_from_record(x: np.ndarray, rate_hz: float) -> AllanCurve:
    from bmg160_emu.noise.allan import overlapping_adev

    return overlapping_adev(x, rate_hz, taus="octave")


@with_one_blas_thread
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
    overlapping: bool = True,
    periodic: bool = True,
) -> AxisIdentification:
    """Identify from an Allan deviation curve (deg/s) instead of samples: the sample count
    (or the record length times the rate) sets each point's degrees of freedom, of the
    overlapping estimator or (``overlapping`` False) of disjoint clusters; a given interval
    (ci low, high at 68.3 %) is kept for the plots, the fit weights come from edf.

    ``periodic``: look for lines in the curve's shoulders and ripple (curve_periodic.py).

    A dense curve (allan_variance_ros writes 9,999 taus 0.1 s apart) is thinned to taus a
    factor 2 apart first: neighbouring points share nearly all their data, so weighting
    each as independent counted the same information hundreds of times."""
    if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
        raise IdentificationError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
    taus = np.asarray(taus_s, dtype=float)
    adev = np.asarray(adev_dps, dtype=float)
    keep = thin_taus(taus)
    notes = []
    if keep.size < taus.size:
        notes.append(f"the curve's {taus.size:,} taus thinned to {keep.size} a factor 2 apart: "
                     "closely spaced points share their data (not independent)")
        taus, adev = taus[keep], adev[keep]
        if ci is not None:
            ci = (np.asarray(ci[0], float)[keep], np.asarray(ci[1], float)[keep])
    m = np.maximum(np.rint(taus * rate_hz), 1)
    if overlapping:
        n_terms = np.maximum(n_samples + 1 - 2 * m, 1).astype(int)
    else:
        n_terms = np.maximum(np.floor(n_samples / m) - 1, 1).astype(int)
    curve = allan_confidence(taus, adev, n_terms, noise_alpha_from_slope(taus, adev),
                             int(n_samples), rate_hz, overlapping=overlapping)
    options = {"with_q": with_q, "with_r": with_r, "poles": poles, "flicker": flicker}
    fit, reason, fit_notes = _fit_curve_axis(axis, curve, rate_hz, n_samples, tau_range,
                                             options, method)
    if periodic:
        from bmg160_emu.noise.curve_periodic import find_periodic_terms

        def search(base: CurveFit, fit_range, notes_so_far):
            def fit_with(frequencies: tuple[float, ...]) -> CurveFit:
                return _fit(method, curve, rate_hz, n_samples, fit_range,
                            {**options,
                             "output_filter": base.output_filter, "free_sines": frequencies})

            lined, found_notes = find_periodic_terms(fit_with, base, rate_hz, float(taus[-1]))
            if not found_notes:
                return base, notes_so_far, False
            # the count of terms chosen again with the lines in the model
            lined = _fit(method, curve, rate_hz, n_samples, fit_range,
                         {**options, "output_filter": base.output_filter,
                          "free_sines": tuple(f for _, f in lined.sines)})
            return lined, _fit_notes(lined, n_samples / rate_hz) + found_notes, True

        fit, fit_notes, lined = search(fit, fit.tau_range_s, fit_notes)
        first = float(curve.taus[0])
        if not lined and fit.tau_range_s[0] > first * 1.01 and tau_range[0] is None:
            # a start left out as a filter may be a line's ripple (near the Nyquist frequency
            # it ripples the first taus): the whole curve with lines, kept if it fits
            try:
                whole = _fit(method, curve, rate_hz, n_samples, (first, tau_range[1]), options)
                whole, whole_notes, lined = search(whole, whole.tau_range_s, [])
            except IdentificationError:
                lined = False
            if lined and whole.chi2_reduced < POOR_FIT_CHI2:
                fit, fit_notes = whole, whole_notes
                reason = ("every tau fitted: the start below the white line is the ripple of "
                          "periodic terms")
    if ci is not None:
        fit.curve = AllanCurve(fit.curve.taus, fit.curve.adev, fit.curve.n_terms, fit.curve.edf,
                               np.asarray(ci[0], float), np.asarray(ci[1], float), fit.curve.ci,
                               fit.curve.overlapping)
    notes += fit_notes
    if not MEMS_N_DPS[0] <= fit.N.value <= MEMS_N_DPS[1]:
        notes.append(
            f"implausible N = {fit.N.value:.3g} deg/s/sqrt(Hz) for a MEMS gyroscope (they lie "
            f"within {MEMS_N_DPS[0]:g} .. {MEMS_N_DPS[1]:g}): check the curve's units "
            "(--curve-units; allan_variance_ros writes deg/s, a rad/s curve read as deg/s "
            "gives N 57 times too low, and the other way round 57 times too high)")
    return AxisIdentification(
        axis=axis, fit=fit, mean=mean, std=math.nan, readoffs=ieee_readoffs(fit.curve),
        tau_range_reason=reason, psd_white_N=math.nan, psd_band_hz=(math.nan, math.nan),
        spectrum=None, notes=notes + [(f"identified from {'an' if overlapping else 'a'} "
                                       f"{curve.kind} Allan deviation curve: no mean, std or "
                                       "PSD (bias 0 in the profile)")],
        method=method,
    )


def thin_taus(taus: np.ndarray, factor: float = 2.0) -> np.ndarray:
    """Indices of taus at least ``factor`` apart, from the first (an octave curve keeps all)."""
    kept = [0] if taus.size else []
    for i in range(1, taus.size):
        if taus[i] >= taus[kept[-1]] * factor * (1 - 1e-6):
            kept.append(i)
    return np.asarray(kept, dtype=int)


def _fit_notes(fit: CurveFit, duration_s: float) -> list[str]:
    notes = []
    dropped = fit.selection.get("zero_terms_left_out", 0)
    if dropped:
        notes.append(f"{dropped} of the {fit.selection['terms']} Gauss-Markov terms asked for "
                     "came out of size 0 and are left out: the curve holds no more")
    notes += _selection_notes(fit)
    if not fit.terms and fit.flicker is None:
        notes.append("no Gauss-Markov term found (B = 0): the bias is white noise and a random walk")
    longest = max((t.T.value for t in fit.terms), default=0.0)
    if fit.terms and duration_s < 100 * longest:
        notes.append(
            f"record ({duration_text(duration_s)}) is shorter than 100 T of the longest term "
            f"({duration_text(100 * longest)}): its B and T are poorly determined"
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


def _selection_notes(fit: CurveFit) -> list[str]:
    """Say when the count of terms taken is not supported over a simpler one (an AICc
    difference under AICC_NO_EVIDENCE), and which terms' intervals then mislead."""
    rows = [r for r in fit.selection.get("candidates", []) if r["aicc"] is not None]
    taken = next((r for r in rows if r.get("chosen")), None)
    if taken is None:
        return []
    simpler = [r for r in rows if r["terms"] < taken["terms"]
               and r["aicc"] - taken["aicc"] < AICC_NO_EVIDENCE]
    if not simpler:
        return []
    other = min(simpler, key=lambda r: r["terms"])
    gap = other["aicc"] - taken["aicc"]
    kept = other.get("T_s", [])
    extra = [t for t in fit.terms
             if not any(abs(math.log(t.T.value / T)) < math.log(2.0) for T in kept)]
    plural = "s" if taken["terms"] != 1 else ""
    if gap < 0:  # a count asked for (--poles) that AICc does not prefer: say so the right way
        best = min(rows, key=lambda r: r["aicc"])
        dropped = fit.selection.get("zero_terms_left_out", 0)
        text = (f"{taken['terms']} Gauss-Markov term{plural} asked for (--poles); AICc prefers "
                f"{best['terms']} by {taken['aicc'] - best['aicc']:.1f} (AICc {best['aicc']:.1f} "
                f"against {taken['aicc']:.1f}); kept: {len(fit.terms)} term"
                f"{'s' if len(fit.terms) != 1 else ''}"
                + (f" ({dropped} came out of size 0)" if dropped else ""))
        return [text]
    text = (f"{taken['terms']} Gauss-Markov term{plural} {'is' if not plural else 'are'} taken "
            f"by {gap:.1f} AICc over {other['terms']} (a difference under "
            f"{AICC_NO_EVIDENCE:g} is no evidence either way): the simpler model is as "
            "plausible")
    firm = [t for t in extra if t.B.ci_low > 0]  # intervals that leave out the simpler model
    if firm:
        parts = [f"T = {t.T.value:.3g} s (B [{t.B.ci_low:.3g}, {t.B.ci_high:.3g}], "
                 f"T [{t.T.ci_low:.3g}, {t.T.ci_high:.3g}])" for t in firm]
        text += ("; the interval" + ("s of the terms " if len(parts) > 1 else " of the term ")
                 + ", ".join(parts) + " leave out B = 0, which that model holds: read them "
                 "with that in mind")
    loose = [t for t in extra if not t.B.ci_low > 0]
    if loose:
        text += ("; " + ", ".join(f"T = {t.T.value:.3g} s" for t in loose)
                 + ": B's interval reaches 0, so T's is the whole range searched")
    return [text]


@with_one_blas_thread
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
    output_stage: bool = True,
) -> Identification:
    """Identify every axis of a (n,) or (n, k<=3) record in deg/s sampled at rate_hz;
    skip_s drops the first seconds (warm-up) without copying the record; output_stage as
    in identify_axis."""
    data = check_record(rate_dps, rate_hz)
    skip = round(skip_s * rate_hz)
    if skip < 0:
        raise IdentificationError(f"skip must not be negative, got {skip_s} s")
    if skip:
        if skip + MIN_SAMPLES > data.shape[0]:
            raise IdentificationError(
                f"skipping {duration_text(skip_s)} leaves {max(data.shape[0] - skip, 0)} of "
                f"the record's {data.shape[0]} samples: too short to identify"
            )
        data = check_record(data[skip:], rate_hz)
    names = list(axis_names) if axis_names is not None else list(AXES[: data.shape[1]])
    if len(names) != data.shape[1]:
        raise IdentificationError(f"{len(names)} axis names for {data.shape[1]} columns")
    axes = [
        identify_axis(data[:, i], rate_hz, name, with_q, with_r, tau_range, psd_segment,
                      progress, poles=poles, flicker=flicker, method=method,
                      output_stage=output_stage)
        for i, name in enumerate(names)
    ]
    return Identification(float(rate_hz), data.shape[0], axes, source, skip / rate_hz)


