"""The paper's figures for a record and its identification (Figs. 1-5 and 7-9).

Figures are built with matplotlib's object API (``matplotlib.figure.Figure``, no pyplot, so
no GUI backend and no global state) and written as PNG or SVG by the file suffix.

- time series (Fig. 1), histogram with the fitted Gaussian (Fig. 2)
- Allan deviation with its confidence band, the fitted model, the -1/2, 0 and +1/2 slope
  lines and the N, B, K read-off points (Fig. 3)
- one-sided PSD with the fitted asymptotes (Figs. 4-5)
- emulator against recording: Allan deviation, PSD, time series (Figs. 7-9)
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bmg160_emu.noise.allan import FLICKER_ADEV_FACTOR, gauss_markov_avar
from bmg160_emu.noise.identification import AxisIdentification
from bmg160_emu.noise.spectrum import (
    PSD_CONVENTION,
    Spectrum,
    gauss_markov_psd,
    quantization_psd,
    ramp_psd,
    random_walk_psd,
    white_psd,
)

FIGURE_FORMATS = (".png", ".svg")
_PSD_LABEL = "one-sided PSD [(deg/s)$^2$/Hz]"
_MAX_POINTS = 20_000  # a time series is drawn as a min/max envelope beyond this
_OVERLAY_WINDOW = 2000  # samples of the time-domain overlay (10 s at 200 Hz)


def check_figure_path(path: str | Path) -> Path:
    """The path if its suffix is a supported figure format, else ValueError."""
    path = Path(path)
    if path.suffix.lower() not in FIGURE_FORMATS:
        raise ValueError(f"figure file must end in .png or .svg, not {path.name!r}")
    return path


def save(fig: Figure, path: str | Path) -> Path:
    path = check_figure_path(path)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    return path


def _new(nrows: int = 1, ncols: int = 1, size=(8.0, 5.0)) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=size, layout="constrained")
    axes = np.atleast_1d(fig.subplots(nrows, ncols, squeeze=False).ravel())
    return fig, axes


def _envelope(x: np.ndarray, rate_hz: float):
    """Time axis and (low, mid, high) of a long series reduced to at most _MAX_POINTS bins."""
    n = x.size
    t = np.arange(n) / rate_hz
    if n <= _MAX_POINTS:
        return t, x, x, x
    per = math.ceil(n / _MAX_POINTS)
    m = n // per
    bins = x[: m * per].reshape(m, per)
    return t[: m * per : per], bins.min(axis=1), bins.mean(axis=1), bins.max(axis=1)


def _draw_series(ax, x: np.ndarray, rate_hz: float, label: str, color=None) -> None:
    t, low, mid, high = _envelope(np.asarray(x, dtype=float), rate_hz)
    if low is mid:
        ax.plot(t, mid, lw=0.6, label=label, color=color)
    else:
        line = ax.plot(t, mid, lw=0.6, label=f"{label} (bin mean)", color=color)[0]
        ax.fill_between(
            t, low, high, color=line.get_color(), alpha=0.25, lw=0, label=f"{label} (bin min-max)"
        )


def time_series_figure(record: np.ndarray, rate_hz: float, names: Sequence[str]) -> Figure:
    """Fig. 1: the raw rate of each axis against time."""
    data = np.asarray(record, dtype=float).reshape(record.shape[0], -1)
    fig, axes = _new(data.shape[1], 1, size=(9.0, 2.4 * data.shape[1] + 0.6))
    for ax, col, name in zip(axes, data.T, names):
        _draw_series(ax, col, rate_hz, f"axis {name}")
        ax.set_ylabel("rate [deg/s]")
        ax.legend(loc="upper right", fontsize="small")
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Static record, time domain")
    return fig


def histogram_figure(record: np.ndarray, names: Sequence[str]) -> Figure:
    """Fig. 2: histogram of each axis with the Gaussian of its mean and std."""
    data = np.asarray(record, dtype=float).reshape(record.shape[0], -1)
    fig, axes = _new(1, data.shape[1], size=(4.0 * data.shape[1] + 0.5, 3.8))
    for ax, col, name in zip(axes, data.T, names):
        mu, sigma = float(col.mean()), float(col.std())
        ax.hist(col, bins=200, density=True, alpha=0.6, label="samples")
        xs = np.linspace(mu - 5 * sigma, mu + 5 * sigma, 400)
        pdf = np.exp(-0.5 * ((xs - mu) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
        ax.plot(xs, pdf, "r", label=f"Gaussian mu={mu:.4g}, sigma={sigma:.4g}")
        ax.set_xlabel(f"axis {name} rate [deg/s]")
        ax.set_ylabel("density [1/(deg/s)]")
        ax.legend(fontsize="x-small")
    fig.suptitle("Histogram and fitted Gaussian")
    return fig


def draw_adev(ax, result: AxisIdentification, color=None, label: str | None = None) -> None:
    """Allan deviation with confidence band, fitted model, slope lines and read-off points."""
    c = result.allan
    name = label or f"axis {result.axis}"
    line = ax.loglog(c.taus, c.adev, "o-", ms=3, color=color, label=f"{name}: ADEV")[0]
    color = line.get_color()
    ax.fill_between(
        c.taus,
        c.ci_low,
        c.ci_high,
        color=color,
        alpha=0.2,
        lw=0,
        label=f"{c.ci * 100:.0f} % confidence band",
    )
    tau = np.geomspace(c.taus[0], c.taus[-1], 300)
    N, K = result.N.value, result.K.value
    model = np.sqrt(result.fit.model_avar(tau))
    ax.loglog(tau, model, "-", color="k", lw=1.2, label=f"fitted model ({result.model_text()})")
    lo, _hi = result.fit_tau_range_s
    ax.axvspan(c.taus[0] * 0.9, lo, color="0.85", lw=0, zorder=0,
               label="not fitted (sensor filter)" if lo > c.taus[0] * 1.01 else None)
    for i, (B, T) in enumerate(result.fit.gauss_markov_terms()):
        if result.fit.flicker is None or i < len(result.terms):
            ax.loglog(tau, np.sqrt(gauss_markov_avar(B, T, tau)), ":", lw=0.8, color="0.4",
                      label="Gauss-Markov terms" if i == 0 else None)
    ax.loglog(tau, N / np.sqrt(tau), "--", color="tab:blue", lw=0.9, label="slope -1/2: N")
    ax.loglog(tau, K * np.sqrt(tau / 3.0), "--", color="tab:red", lw=0.9, label="slope +1/2: K")
    ro = result.readoffs
    b_flick = ro["B_flicker"]["value"]
    ax.axhline(
        b_flick * FLICKER_ADEV_FACTOR,
        color="tab:green",
        ls=":",
        lw=0.9,
        label="slope 0: minimum (flicker B x 0.664)",
    )
    ax.plot([1.0], [N], "s", color="tab:blue", ms=7, label=f"N = {N:.4g} at tau = 1 s")
    ax.plot([3.0], [K * 1.0], "^", color="tab:red", ms=7, label=f"K = {K:.4g} at tau = 3 s")
    ax.plot(
        [ro["B_flicker"]["tau_s"]],
        [b_flick * FLICKER_ADEV_FACTOR],
        "D",
        color="tab:green",
        ms=7,
        label=f"B flicker = {b_flick:.4g} (min / 0.664)",
    )
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")


def adev_figure(results: Sequence[AxisIdentification]) -> Figure:
    """Fig. 3: one panel per axis."""
    fig, axes = _new(1, len(results), size=(6.0 * len(results) + 0.5, 5.0))
    for ax, r in zip(axes, results):
        draw_adev(ax, r)
        terms = ", ".join(f"({t.B.value:.2g}, {t.T.value:.3g} s)" for t in r.terms)
        ax.set_title(
            f"axis {r.axis}: N {r.N.value:.3g}, K {r.K.value:.3g}, (B, T) {terms or 'none'}",
            fontsize="small",
        )
        ax.legend(fontsize="x-small", loc="lower left")
    fig.suptitle("Overlapping Allan deviation, fitted composite model and IEEE 952 read-offs")
    return fig


def _log_binned(spectrum: Spectrum, per_decade: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Average the PSD in log-spaced bins (readable plots of 30,000-point spectra)."""
    f, p = spectrum.frequency_hz, spectrum.psd
    edges = np.geomspace(f[0], f[-1] * 1.0001, int(per_decade * math.log10(f[-1] / f[0])) + 2)
    idx = np.digitize(f, edges)
    sums = np.bincount(idx, weights=p, minlength=edges.size + 1)
    counts = np.bincount(idx, minlength=edges.size + 1)
    fs = np.bincount(idx, weights=f, minlength=edges.size + 1)
    keep = counts > 0
    return fs[keep] / counts[keep], sums[keep] / counts[keep]


def draw_psd(
    ax,
    result: AxisIdentification,
    rate_hz: float,
    color=None,
    label: str | None = None,
    asymptotes: bool = True,
) -> None:
    """One-sided PSD (log-binned) with the fitted model's one-sided asymptotes."""
    if result.spectrum is None:  # identified from an Allan curve: no spectrum to draw
        return
    f, p = _log_binned(result.spectrum)
    name = label or f"axis {result.axis}"
    ax.loglog(f, p, lw=0.9, color=color, label=f"{name}: Welch PSD")
    if not asymptotes:
        return
    N, K = result.N.value, result.K.value
    terms = result.fit.gauss_markov_terms()
    ax.loglog(f, white_psd(N, f), "--", color="tab:blue", lw=0.9, label="white 2 N$^2$")
    for i, (B, T) in enumerate(terms):
        ax.loglog(
            f,
            gauss_markov_psd(B, T, f),
            "--",
            color="tab:green",
            lw=0.9,
            label="Gauss-Markov 4 B$^2$ T / (1 + (2 pi f T)$^2$)" if i == 0 else None,
        )
    if K > 0:
        ax.loglog(
            f,
            random_walk_psd(K, f),
            "--",
            color="tab:red",
            lw=0.9,
            label="random walk 2 (K / 2 pi)$^2$ / f$^2$",
        )
    total = white_psd(N, f) + random_walk_psd(K, f)
    for B, T in terms:
        total = total + gauss_markov_psd(B, T, f)
    if result.Q:
        total = total + quantization_psd(result.Q.value, f, rate_hz)
    if result.R:
        total = total + ramp_psd(result.R.value, f)
    ax.loglog(f, total, "-", color="k", lw=1.1, label="fitted model, one-sided")
    ax.set_ylim(bottom=max(float(p.min()) * 0.3, 1e-12))
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_PSD_LABEL)
    ax.grid(alpha=0.3, which="both")


def psd_figure(results: Sequence[AxisIdentification], rate_hz: float) -> Figure:
    """Figs. 4-5: one panel per axis, convention in the caption."""
    fig, axes = _new(1, len(results), size=(6.0 * len(results) + 0.5, 5.0))
    for ax, r in zip(axes, results):
        draw_psd(ax, r, rate_hz)
        ax.set_title(f"axis {r.axis}", fontsize="small")
        ax.legend(fontsize="x-small", loc="lower left")
    fig.suptitle(f"PSD with fitted asymptotes ({PSD_CONVENTION})", fontsize="small")
    return fig


def overlay_figures(
    recording: np.ndarray,
    emulated: np.ndarray,
    rate_hz: float,
    rec_result: AxisIdentification,
    emu_result: AxisIdentification,
) -> dict[str, Figure]:
    """Figs. 7-9 for one axis: Allan deviation, PSD and time series, emulator vs recording."""
    figs = {}
    fig, (ax,) = _new()
    for res, lab, col in (
        (rec_result, "recording", "tab:blue"),
        (emu_result, "emulator", "tab:orange"),
    ):
        c = res.allan
        ax.loglog(c.taus, c.adev, "o-", ms=3, color=col, label=f"{lab}: ADEV")
        ax.fill_between(c.taus, c.ci_low, c.ci_high, color=col, alpha=0.2, lw=0)
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax.set_title(f"axis {rec_result.axis}: emulator against recording (Allan deviation)")
    figs["overlay_adev"] = fig

    fig, (ax,) = _new()
    draw_psd(ax, rec_result, rate_hz, color="tab:blue", label="recording", asymptotes=False)
    draw_psd(ax, emu_result, rate_hz, color="tab:orange", label="emulator", asymptotes=False)
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_PSD_LABEL)
    ax.grid(alpha=0.3, which="both")
    ax.legend()
    ax.set_title(f"emulator against recording ({PSD_CONVENTION})", fontsize="small")
    figs["overlay_psd"] = fig

    fig, (ax,) = _new(size=(9.0, 4.0))
    window = min(recording.shape[0], _OVERLAY_WINDOW)  # raw samples, as the paper's Fig. 9
    t = np.arange(window) / rate_hz
    ax.plot(t, recording[:window], lw=0.6, color="tab:blue", label="recording")
    ax.plot(t, emulated[:window], lw=0.6, color="tab:orange", alpha=0.8, label="emulator")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("rate [deg/s]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    ax.set_title(f"axis {rec_result.axis}: emulator against recording, first {window} samples")
    figs["overlay_time"] = fig
    return figs
