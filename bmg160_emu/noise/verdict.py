"""Whether emulated noise is indistinguishable from a recording: the figures of
``bmg160-emu compare RECORDING PROFILE``, each against a stated threshold.

The profile is drawn ``seeds`` times at the recording's length and rate (what ``generate``
writes), and per axis the recording is set against the spread of those draws, not against
one draw (one draw's Allan deviation at L/10 rests on about 10 differences and scatters by a
factor 2-4 from seed to seed):

- std: median emulated std over the recording's, within STD_TOLERANCE;
- autocorrelation at lags 1-10: median emulated minus recorded, lags 1-5 within
  ACF_TOLERANCE (lags 6-10 printed);
- PSD: share of log-spaced bins (above rate/100, where every term the profile holds is
  visible) in which the emulated median lies inside the recording's 95 % chi-square band;
- Allan deviation at octave taus 0.2 s .. L/10: share of taus where the emulated median lies
  inside the recording's 95 % Greenhall band (forward), and where the recording lies inside
  the emulated 2.5-97.5 % range (reverse): the prediction interval of one more record from
  the seeds' spread (``prediction_range``), not their bare percentiles.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

STD_TOLERANCE = 0.03  # |emulated / recorded - 1|
ACF_TOLERANCE = 0.05  # |emulated - recorded| at lags 1-5
ACF_LAGS = 10
ADEV_FORWARD = 0.97  # share of taus, emulated median inside the recording's 95 % band
ADEV_REVERSE = 0.95  # share of taus, recording inside the emulated 2.5-97.5 % range
PSD_INSIDE = 0.90  # share of PSD bins, emulated median inside the recording's 95 % band
PSD_BINS = 48
TAU_MIN_S = 0.2
DEFAULT_SEEDS = 20


@dataclass
class AxisVerdict:
    axis: str
    std_recorded: float
    std_ratio: float
    acf_recorded: np.ndarray
    acf_emulated: np.ndarray
    psd_inside: float
    adev_forward: float
    adev_reverse: float
    taus: np.ndarray
    adev_recorded: np.ndarray
    adev_low95: np.ndarray
    adev_high95: np.ndarray
    adev_median: np.ndarray
    adev_range: tuple[np.ndarray, np.ndarray]
    psd_f: np.ndarray = field(default_factory=lambda: np.zeros(0))
    psd_recorded: np.ndarray = field(default_factory=lambda: np.zeros(0))
    psd_median: np.ndarray = field(default_factory=lambda: np.zeros(0))
    psd_range: tuple[np.ndarray, np.ndarray] = (np.zeros(0), np.zeros(0))

    def checks(self) -> dict[str, tuple[str, bool]]:
        d5 = float(np.max(np.abs(self.acf_emulated[:5] - self.acf_recorded[:5])))
        return {
            "std": (f"ratio {self.std_ratio:.4f} (within {STD_TOLERANCE:.0%})",
                    abs(self.std_ratio - 1.0) <= STD_TOLERANCE),
            "autocorrelation": (f"lags 1-5 max |diff| {d5:.3f} (within {ACF_TOLERANCE})",
                                d5 <= ACF_TOLERANCE),
            "psd": ((f"{self.psd_inside:.1%} of bins inside the recording's 95 % band "
                    f"(>= {PSD_INSIDE:.0%})"), self.psd_inside >= PSD_INSIDE),
            "adev forward": ((f"{self.adev_forward:.1%} of taus: emulated median inside the "
                             f"recording's 95 % band (>= {ADEV_FORWARD:.0%})"),
                             self.adev_forward >= ADEV_FORWARD),
            "adev reverse": ((f"{self.adev_reverse:.1%} of taus: recording inside the emulated "
                             f"2.5-97.5 % range (>= {ADEV_REVERSE:.0%})"),
                             self.adev_reverse >= ADEV_REVERSE),
        }

    @property
    def passed(self) -> bool:
        return all(ok for _, ok in self.checks().values())


@dataclass
class Verdict:
    seeds: int
    rate_hz: float
    samples: int
    axes: list[AxisVerdict]

    @property
    def passed(self) -> bool:
        return all(a.passed for a in self.axes)

    def text(self) -> str:
        lines = [(f"verdict over {self.seeds} emulated records of {self.samples} samples at "
                 f"{self.rate_hz:g} Hz (octave taus {TAU_MIN_S:g} s .. L/10)")]
        for a in self.axes:
            lines.append(f"axis {a.axis}: {'PASS' if a.passed else 'FAIL'}")
            for name, (text, ok) in a.checks().items():
                lines.append(f"  {'pass' if ok else 'FAIL'}  {name}: {text}")
            lines.append("        autocorrelation lags 1-10 recorded "
                         + " ".join(f"{v:+.3f}" for v in a.acf_recorded))
            lines.append("                             emulated "
                         + " ".join(f"{v:+.3f}" for v in a.acf_emulated))
        lines.append(f"verdict: {'PASS' if self.passed else 'FAIL'}")
        return "\n".join(lines)


def prediction_range(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The 2.5-97.5 % range of one more emulated record, per column of ``values`` (seeds x
    points): in logs, mean +- t(0.975, s - 1) sd sqrt(1 + 1/s) (the prediction interval of a
    normal sample; an Allan deviation point is close to log-normal). The plain percentiles of
    s seeds are too narrow for few seeds: with 8 a new record falls outside their range with
    chance 2/9, not 5 %."""
    from scipy.stats import t

    logs = np.log(np.maximum(values, 1e-300))
    s = logs.shape[0]
    if s < 2:
        return values[0], values[0]
    half = float(t.ppf(0.975, s - 1)) * np.std(logs, axis=0, ddof=1) * math.sqrt(1.0 + 1.0 / s)
    centre = np.mean(logs, axis=0)
    return np.exp(centre - half), np.exp(centre + half)


def autocorrelation(x: np.ndarray, lags: int = ACF_LAGS) -> np.ndarray:
    """Sample autocorrelation at lags 1 .. lags (the mean removed; biased estimator)."""
    y = np.asarray(x, dtype=float) - float(np.mean(x))
    v = float(y @ y)
    return np.array([float(y[:-k] @ y[k:]) / v for k in range(1, lags + 1)])


def _log_psd(x: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    from scipy.signal import welch

    n = x.shape[0]
    seg = int(min(4096, max(256, 2 ** int(math.log2(max(n // 16, 256))))))
    f, s = welch(np.asarray(x, float) - float(np.mean(x)), rate_hz, nperseg=seg)
    f, s = f[1:], s[1:]
    segments = max((n - seg) / (seg // 2) + 1, 1.0)
    edges = np.geomspace(rate_hz / 100.0, rate_hz / 2.0 * (1 + 1e-9), PSD_BINS + 1)
    idx = np.searchsorted(edges, f, side="right") - 1
    ok = (idx >= 0) & (idx < PSD_BINS)
    cnt = np.bincount(idx[ok], minlength=PSD_BINS)
    mean = np.bincount(idx[ok], s[ok], PSD_BINS) / np.maximum(cnt, 1)
    fc = np.sqrt(edges[:-1] * edges[1:])
    dof = 0.95 * segments * np.maximum(cnt, 1)  # Hann, 50 % overlap; neighbours share data
    return fc[cnt > 0], mean[cnt > 0], dof[cnt > 0]


def compare(record: np.ndarray, rate_hz: float, draw: Callable[[int], np.ndarray],
            seeds: int = DEFAULT_SEEDS, axis_names: tuple[str, ...] = ("x", "y", "z"),
            progress: Callable[[int], None] | None = None) -> Verdict:
    """The verdict of ``draw(seed)`` (an (n, k) array at ``rate_hz``, the recording's
    shape) against ``record``."""
    from scipy.stats import chi2

    from bmg160_emu.noise.allan import overlapping_adev

    data = np.asarray(record, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    n, k = data.shape
    length_s = n / rate_hz
    rec_curves = [overlapping_adev(data[:, i], rate_hz, ci=0.95) for i in range(k)]
    stds: list[list[float]] = [[] for _ in range(k)]
    acfs: list[list[np.ndarray]] = [[] for _ in range(k)]
    adevs: list[list[np.ndarray]] = [[] for _ in range(k)]
    psds: list[list[np.ndarray]] = [[] for _ in range(k)]
    for s in range(seeds):
        emu = np.asarray(draw(s), dtype=float).reshape(n, -1)
        for i in range(k):
            y = emu[:, i]
            stds[i].append(float(np.std(y)))
            acfs[i].append(autocorrelation(y))
            c = overlapping_adev(y, rate_hz)
            adevs[i].append(np.exp(np.interp(np.log(rec_curves[i].taus), np.log(c.taus),
                                             np.log(c.adev))))
            psds[i].append(_log_psd(y, rate_hz)[1])
        if progress is not None:
            progress(s + 1)
    axes = []
    for i in range(k):
        x = data[:, i]
        curve = rec_curves[i]
        sel = (curve.taus >= TAU_MIN_S * (1 - 1e-9)) & (curve.taus <= length_s / 10 * (1 + 1e-9))
        a = np.array(adevs[i])
        med = np.median(a, axis=0)
        lo, hi = prediction_range(a)
        fwd = (med >= curve.ci_low) & (med <= curve.ci_high)
        rev = (curve.adev >= lo) & (curve.adev <= hi)
        fc, ps, dof = _log_psd(x, rate_hz)
        pe = np.array(psds[i])
        pm = np.median(pe, axis=0)
        band_lo = ps * dof / chi2.isf(0.025, dof)
        band_hi = ps * dof / chi2.ppf(0.025, dof)
        inside = (pm >= band_lo) & (pm <= band_hi)
        axes.append(AxisVerdict(
            axis=axis_names[i] if i < len(axis_names) else str(i),
            std_recorded=float(np.std(x)), std_ratio=float(np.median(stds[i]) / np.std(x)),
            acf_recorded=autocorrelation(x), acf_emulated=np.median(np.array(acfs[i]), axis=0),
            psd_inside=float(inside.mean()) if inside.size else math.nan,
            adev_forward=float(fwd[sel].mean()) if sel.any() else math.nan,
            adev_reverse=float(rev[sel].mean()) if sel.any() else math.nan,
            taus=curve.taus, adev_recorded=curve.adev, adev_low95=curve.ci_low,
            adev_high95=curve.ci_high, adev_median=med, adev_range=(lo, hi),
            psd_f=fc, psd_recorded=ps, psd_median=pm,
            psd_range=prediction_range(pe),
        ))
    return Verdict(seeds, float(rate_hz), n, axes)


def verdict_figure(verdict: Verdict):
    """The recording over the emulated band (median and 2.5-97.5 %): Allan deviation and
    PSD per axis (matplotlib's object API, no display)."""
    from matplotlib.figure import Figure

    k = len(verdict.axes)
    fig = Figure(figsize=(5.0 * k, 8.0), layout="constrained")
    axs = fig.subplots(2, k, squeeze=False)
    for j, a in enumerate(verdict.axes):
        ax = axs[0, j]
        ax.fill_between(a.taus, a.adev_range[0], a.adev_range[1], color="tab:orange", alpha=0.3,
                        label=f"emulated 2.5-97.5 % ({verdict.seeds} seeds)")
        ax.loglog(a.taus, a.adev_median, color="tab:orange", label="emulated median")
        ax.fill_between(a.taus, a.adev_low95, a.adev_high95, color="tab:blue", alpha=0.15,
                        label="recording's 95 % band")
        ax.loglog(a.taus, a.adev_recorded, "k.-", lw=1, label="recording")
        ax.set_title(f"axis {a.axis}: {'pass' if a.passed else 'FAIL'}")
        ax.set_xlabel("tau (s)")
        ax.set_ylabel("Allan deviation (deg/s)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=2)
        ax = axs[1, j]
        ax.fill_between(a.psd_f, a.psd_range[0], a.psd_range[1], color="tab:orange", alpha=0.3,
                        label="emulated 2.5-97.5 %")
        ax.loglog(a.psd_f, a.psd_median, color="tab:orange", label="emulated median")
        ax.loglog(a.psd_f, a.psd_recorded, "k.-", lw=1, label="recording")
        ax.set_xlabel("frequency (Hz)")
        ax.set_ylabel("PSD, one-sided ((deg/s)^2/Hz)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.15), ncol=3)
    return fig


def compare_profile(record: np.ndarray, rate_hz: float, profile, seeds: int = DEFAULT_SEEDS,
                    axis_names: tuple[str, ...] = ("x", "y", "z"),
                    progress: Callable[[int], None] | None = None) -> Verdict:
    """The verdict of ``profile`` (a name, path or Profile) drawn as ``generate`` writes it
    (its output stage included) at the recording's rate, seeds 0 .. seeds - 1, against
    ``record`` ((n,) or (n, k <= 3), deg/s): column i against the profile's axis i."""
    from bmg160_emu.noise.sensor_noise import profile_noise

    data = np.asarray(record, dtype=float)
    if data.ndim == 1:
        data = data[:, None]
    n, k = data.shape

    def draw(seed: int) -> np.ndarray:
        return profile_noise(profile, rate_hz, seed=seed).generate(n)[:, :k]

    return compare(data, rate_hz, draw, seeds, axis_names, progress)


def verdict_dict(verdict: Verdict) -> dict:
    """The verdict as strict JSON: per axis every figure, its threshold and pass/fail."""
    def finite(v: float) -> float | None:
        return float(v) if math.isfinite(v) else None

    axes = {}
    for a in verdict.axes:
        axes[a.axis] = {
            "passed": a.passed,
            "checks": {name: {"text": text, "passed": ok}
                       for name, (text, ok) in a.checks().items()},
            "std_recorded": a.std_recorded, "std_ratio": a.std_ratio,
            "autocorrelation_recorded": [float(v) for v in a.acf_recorded],
            "autocorrelation_emulated": [float(v) for v in a.acf_emulated],
            "psd_inside": finite(a.psd_inside), "adev_forward": finite(a.adev_forward),
            "adev_reverse": finite(a.adev_reverse),
            "taus_s": [float(v) for v in a.taus],
            "adev_recorded": [float(v) for v in a.adev_recorded],
            "adev_emulated_median": [float(v) for v in a.adev_median],
        }
    return {"seeds": verdict.seeds, "rate_hz": verdict.rate_hz, "samples": verdict.samples,
            "thresholds": {"std": STD_TOLERANCE, "autocorrelation_lags_1_5": ACF_TOLERANCE,
                           "psd_inside": PSD_INSIDE, "adev_forward": ADEV_FORWARD,
                           "adev_reverse": ADEV_REVERSE, "tau_min_s": TAU_MIN_S},
            "passed": verdict.passed, "axes": axes}
