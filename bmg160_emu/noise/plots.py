"""The paper's figures for a record and its identification (Figs. 1-5 and 7-9).

Figures are built with matplotlib's object API (``matplotlib.figure.Figure``, no pyplot, so
no GUI backend and no global state) and written as PNG or SVG by the file suffix.

- time series (Fig. 1), histogram with the Gaussian of the mean and std (Fig. 2), its bins
  on the record's LSB grid when the record is quantized
- Allan deviation with its confidence band, the fitted model, the -1/2, 0 and +1/2 slope
  lines and the N, B, K read-off points (Fig. 3)
- one-sided PSD with the fitted asymptotes (Figs. 4-5)
- emulator against recording: Allan deviation, PSD, time series (Figs. 7-9)

Legends sit below their axes, so they never hide a curve, a read-off point or an asymptote.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bmg160_emu.noise.allan import FLICKER_ADEV_FACTOR, gauss_markov_avar
from bmg160_emu.noise.identification_result import AxisIdentification
from bmg160_emu.noise.output_stage import OutputGrid, output_grid
from bmg160_emu.noise.spectrum import (
    Spectrum,
    gauss_markov_psd,
    quantization_psd,
    ramp_psd,
    random_walk_psd,
    rounding_floor_psd,
    white_psd,
)

FIGURE_FORMATS = (".png", ".svg")
_PSD_LABEL = "one-sided PSD [(deg/s)$^2$/Hz]"
_PSD_CAPTION = "One-sided Welch PSD: white noise of density N reads 2 N$^2$ (IEEE 952 two-sided S = N$^2$)"
_MAX_POINTS = 20_000  # a time series is drawn as a min/max envelope beyond this
_OVERLAY_WINDOW = 2000  # samples of the time-domain overlay (10 s at 200 Hz)
_OVERLAY_ZOOM = 100  # samples of its zoomed panel, where single LSB steps can be seen
_UNIT = {"N": "deg/s/\u221aHz", "K": "deg/s/\u221as", "B": "deg/s"}  # profile.UNITS, as printed
FIT_LABELS = {"wls": "WLS fit of the Allan variance", "gmwm": "GMWM fit of the wavelet variance"}
_MIN_BINS, _MAX_BINS = 20, 200  # of a record of real numbers (numpy's Freedman-Diaconis)
_LSB_LINES = 60  # most LSB levels marked in the time overlay's zoom
_ADEV_DECADES_BELOW = 2.0  # of the Allan axes' range under the curve's lowest point
_PSD_DECADES_BELOW = 2.0  # an asymptote this far below the data is listed, not drawn
_PSD_SEEN_DECADES = 0.5  # of frequency over which every asymptote drawn can be seen


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


def _with_legends(ncols: int, size, legend_share: float) -> tuple[Figure, list, list]:
    """A row of ``ncols`` panels, each with a legend box of its own under it (``legend_share``
    of the height): legends there cover nothing drawn, and constrained layout keeps each
    panel's x label clear of its legend."""
    fig = Figure(figsize=size, layout="constrained")
    grid = fig.add_gridspec(2, ncols, height_ratios=(1.0 - legend_share, legend_share))
    axes = [fig.add_subplot(grid[0, i]) for i in range(ncols)]
    boxes = [fig.add_subplot(grid[1, i]) for i in range(ncols)]
    for box in boxes:
        box.set_axis_off()
    return fig, axes, boxes


def _legend_below(ax, box, ncols: int = 1) -> None:
    """``ax``'s legend, drawn in its legend box ``box`` (see _with_legends)."""
    handles, labels = ax.get_legend_handles_labels()
    box.legend(handles, labels, loc="upper center", ncols=ncols, fontsize="x-small",
               borderaxespad=0.0)


def _legend_right(ax) -> None:
    """The legend beside the axes, at their top right corner (outside: it covers nothing)."""
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", borderaxespad=0.0)


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
        _legend_right(ax)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("time [s]")
    fig.suptitle("Static record, time domain")
    return fig


def histogram_edges(values: np.ndarray, grid: OutputGrid | None) -> np.ndarray:
    """Bin edges: half an LSB either side of whole numbers of grid levels when the record is
    quantized (every bin holds the same number of levels: no comb), else numpy's rule."""
    x = np.asarray(values, dtype=float)
    low, high = float(x.min()), float(x.max())
    if grid is None:
        edges = np.histogram_bin_edges(x, bins="fd")
        if not _MIN_BINS <= edges.size - 1 <= _MAX_BINS:
            edges = np.histogram_bin_edges(x, bins=min(max(edges.size - 1, _MIN_BINS), _MAX_BINS))
        return edges
    first, last = grid.level(low), grid.level(high)
    per = grid.levels_per_bin(low, high)
    count = (last - first) // per + 1
    return grid.origin + (first + per * np.arange(count + 1) - 0.5) * grid.step


def histogram_figure(record: np.ndarray, names: Sequence[str]) -> Figure:
    """Fig. 2: histogram of each axis with the Gaussian of its mean and std."""
    data = np.asarray(record, dtype=float).reshape(record.shape[0], -1)
    fig, axes, boxes = _with_legends(data.shape[1], (4.0 * data.shape[1] + 0.5, 4.6), 0.14)
    for ax, box, col, name in zip(axes, boxes, data.T, names):
        grid = output_grid(col)
        edges = histogram_edges(col, grid)
        mu, sigma = float(col.mean()), float(col.std())
        if grid is None:
            what = f"samples, {edges.size - 1} bins"
            title = f"axis {name}"
        else:
            per = grid.levels_per_bin(float(col.min()), float(col.max()))
            what = (f"samples, bins of {per} LSB ({per * grid.step:.3g} deg/s)" if per > 1
                    else "samples, one bin per LSB")
            title = f"axis {name}: quantized, LSB {grid.step:.4g} deg/s"
        ax.hist(col, bins=edges, density=True, histtype="stepfilled", alpha=0.6, label=what)
        xs = np.linspace(mu - 5 * sigma, mu + 5 * sigma, 400)
        pdf = np.exp(-0.5 * ((xs - mu) / sigma) ** 2) / (sigma * math.sqrt(2 * math.pi))
        ax.plot(xs, pdf, "r", label=f"Gaussian: mean {mu:.4g} deg/s, std {sigma:.4g} deg/s")
        ax.set_xlabel("rate [deg/s]")
        ax.set_ylabel("density [1/(deg/s)]")
        ax.set_title(title, fontsize="medium")
        _legend_below(ax, box)
    fig.suptitle("Histogram and the Gaussian of the sample mean and std")
    return fig


def fit_label(method: str) -> str:
    """How a figure names the fit that gave N, B, T, K (AxisIdentification.method)."""
    return FIT_LABELS.get(method, f"{method.upper()} fit")


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
    if result.fit.rate_hz:  # a record's model lives at whole samples (the filtered white term)
        rate = result.fit.rate_hz
        tau = np.unique(np.maximum(np.rint(tau * rate), 1.0)) / rate
    N, K = result.N.value, result.K.value
    model = np.sqrt(result.fit.model_avar(tau))
    ax.loglog(tau, model, "-", color="k", lw=1.2,
              label=f"{fit_label(result.method)}: {result.model_text()}")
    lo, _hi = result.fit_tau_range_s
    if lo > c.taus[0] * 1.01:
        ax.axvspan(c.taus[0] * 0.9, lo, color="0.85", lw=0, zorder=0,
                   label="not fitted (sensor filter)")
    lowest = [float(np.nanmin(c.adev)), float(model.min())]  # what sets the bottom of the axes
    for i, (B, T) in enumerate(result.fit.gauss_markov_terms()):
        if result.fit.flicker is None or i < len(result.terms):
            term = np.sqrt(gauss_markov_avar(B, T, tau))
            ax.loglog(tau, term, ":", lw=0.8, color="0.4",
                      label="Gauss-Markov terms" if i == 0 else None)
            lowest.append(float(term.max()))
    ax.loglog(tau, N / np.sqrt(tau), "--", color="tab:blue", lw=0.9, label="slope -1/2: N")
    ro = result.readoffs
    b_flick = ro["B_flicker"]["value"]
    ax.axhline(
        b_flick * FLICKER_ADEV_FACTOR,
        color="tab:green",
        ls=":",
        lw=0.9,
        label="slope 0: minimum (flicker B x 0.664)",
    )
    ax.plot([1.0], [N], "s", color="tab:blue", ms=7,
            label=f"N (fit) = {N:.4g} {_UNIT['N']}: the fitted -1/2 line at tau 1 s")
    # the marker sits at the value its legend names (issue 23): flicker B itself, at the tau
    # of the minimum it is read from, 1 / 0.664 above the dotted minimum line
    ax.plot(
        [ro["B_flicker"]["tau_s"]],
        [b_flick],
        "D",
        color="tab:green",
        ms=7,
        label=f"flicker B = {b_flick:.4g} deg/s (minimum / 0.664, at tau of the minimum)",
    )
    lowest.append(b_flick * FLICKER_ADEV_FACTOR)
    # the bottom: the lowest of the curve, the model, the terms' peaks and the K point, but
    # no more than _ADEV_DECADES_BELOW under the curve; a K point under that is named only
    floor = float(np.nanmin(c.adev)) / 10**_ADEV_DECADES_BELOW
    if K > 0 and K >= floor:
        ax.loglog(tau, K * np.sqrt(tau / 3.0), "--", color="tab:red", lw=0.9,
                  label="slope +1/2: K")
        ax.plot([3.0], [K], "^", color="tab:red", ms=7,
                label=f"K (fit) = {K:.4g} {_UNIT['K']}: the fitted +1/2 line at tau 3 s")
        lowest.append(K)
    elif K > 0:
        ax.plot([], [], " ", label=f"K = {K:.3g} {_UNIT['K']}: its +1/2 line is far under "
                f"the curve (below {floor:.1g} deg/s)")
    else:
        ax.plot([], [], " ", label="K = 0: no +1/2 slope (random walk) in this record")
    # the IEEE 952 K read-off as the summary gives it: a point where a +1/2 segment was
    # found, else said not found (the fitted K above is no read-off; issue 35)
    k_read = ro["K_at_tau_3s"]["value"]
    if k_read is not None:
        ax.plot([3.0], [k_read], "v", color="tab:purple", ms=6,
                label=f"K read-off = {k_read:.4g} {_UNIT['K']} (+1/2 segment at tau 3 s)")
        lowest.append(k_read)
    else:
        ax.plot([], [], " ", label="K read-off (IEEE 952): not found, no +1/2 segment")
    top = float(np.nanmax(np.where(np.isfinite(c.ci_high), c.ci_high, c.adev))) * 2.0
    ax.set_ylim(bottom=max(min(lowest) / 2.0, floor), top=top)
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")


def adev_title(result: AxisIdentification) -> str:
    """Panel title: the axis, the fit, and N, K, (B, T) each with its unit."""
    terms = "; ".join(
        f"B = {t.B.value:.3g} {_UNIT['B']}, T = {t.T.value:.3g} s" for t in result.terms
    )
    return (f"axis {result.axis}, {fit_label(result.method)}\n"
            f"N = {result.N.value:.3g} {_UNIT['N']}, K = {result.K.value:.3g} {_UNIT['K']}\n"
            f"{terms or 'no Gauss-Markov term'}")


def adev_figure(results: Sequence[AxisIdentification]) -> Figure:
    """Fig. 3: one panel per axis."""
    fig, axes, boxes = _with_legends(len(results), (6.0 * len(results) + 0.5, 8.5), 0.27)
    for ax, box, r in zip(axes, boxes, results):
        draw_adev(ax, r)
        ax.set_title(adev_title(r), fontsize="medium")
        _legend_below(ax, box)
    fig.suptitle("Overlapping Allan deviation, fitted model and IEEE 952 read-offs")
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
    """One-sided PSD (log-binned) with the fitted model's one-sided asymptotes.

    The y range is the data's (and the fitted total's where it meets the data); an asymptote
    that would lie wholly under it is named in the legend, not drawn out of sight."""
    if result.spectrum is None:  # identified from an Allan curve: no spectrum to draw
        return
    f, p = _log_binned(result.spectrum)
    name = label or f"axis {result.axis}"
    ax.loglog(f, p, lw=0.9, color=color, label=f"{name}: Welch PSD")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel(_PSD_LABEL)
    ax.grid(alpha=0.3, which="both")
    if not asymptotes:
        return
    N, K = result.N.value, result.K.value
    terms = result.fit.gauss_markov_terms()
    white = white_psd(N, f)
    white_text = f"white 2N$^2$ = {2 * N * N:.3g}"
    if result.output_filter is not None:  # the sensor's own filter shapes the white term
        white = white * result.output_filter.design.power(f)
        white_text = (f"white through the output filter 2N$^2$|H|$^2$, "
                      f"{result.output_filter.text()} Hz")
    total = white + random_walk_psd(K, f)
    if result.lsb_dps:  # the rounding's white floor after the filter, LSB^2 / 12
        total = total + rounding_floor_psd(result.lsb_dps, rate_hz)
    for B, T in terms:
        total = total + gauss_markov_psd(B, T, f)
    if result.Q:
        total = total + quantization_psd(result.Q.value, f, rate_hz)
    if result.R:
        total = total + ramp_psd(result.R.value, f)
    bottom = float(p.min()) / 3.0
    top = 3.0 * max(float(p.max()), min(float(total.max()), 30.0 * float(p.max())))
    lines = [(white, "tab:blue", "white", white_text)]
    for B, T in terms:
        lines.append((gauss_markov_psd(B, T, f), "tab:green", "gm",
                      f"Gauss-Markov $4B^2T/(1+(2\\pi fT)^2)$, T = {T:.3g} s"))
    if K > 0:
        lines.append((random_walk_psd(K, f), "tab:red", "rw", "random walk $2(K/2\\pi)^2/f^2$"))
    floor = bottom / 10**_PSD_DECADES_BELOW
    # each asymptote drawn is seen over the lowest _PSD_SEEN_DECADES of frequency at least
    # (where it is largest): the y range is lowered to its value there, down to ``floor``
    seen_f = f[0] * 10**_PSD_SEEN_DECADES
    drawn: dict[str, list[str]] = {}
    hidden: dict[str, list[str]] = {}
    for values, colour, group, text in lines:
        reach = float(np.interp(math.log10(seen_f), np.log10(f), values))
        if not reach >= floor:
            hidden.setdefault(group, []).append(text)
            continue
        bottom = min(bottom, reach / 1.5)
        first = group not in drawn
        drawn.setdefault(group, []).append(text)
        ax.loglog(f, values, "--", color=colour, lw=0.9, label=text if first else None)
    for group, texts in hidden.items():  # one legend line a kind (a 1/f bank has many terms)
        more = f" and {len(texts) - 1} more" if len(texts) > 1 else ""
        ax.plot([], [], " ", label=f"{texts[0]}{more}: below {floor:.1g}")
    for line in ax.get_lines():  # several Gauss-Markov terms drawn: one legend line says so
        if drawn.get("gm") and line.get_label() == drawn["gm"][0] and len(drawn["gm"]) > 1:
            extra = len(drawn["gm"]) - 1
            line.set_label(f"{drawn['gm'][0]} and {extra} more term{'s' if extra > 1 else ''}")
    ax.loglog(f, total, "-", color="k", lw=1.1, label=f"{fit_label(result.method)}, one-sided")
    ax.set_ylim(bottom=max(bottom, 1e-300), top=top)
    ax.set_xlim(f[0], f[-1])


def psd_figure(results: Sequence[AxisIdentification], rate_hz: float) -> Figure:
    """Figs. 4-5: one panel per axis, the one-sided convention in the caption."""
    fig, axes, boxes = _with_legends(len(results), (6.0 * len(results) + 0.5, 6.5), 0.19)
    for ax, box, r in zip(axes, boxes, results):
        draw_psd(ax, r, rate_hz)
        ax.set_title(f"axis {r.axis}", fontsize="medium")
        _legend_below(ax, box)
    fig.suptitle("PSD and fitted asymptotes")
    fig.supxlabel(_PSD_CAPTION, fontsize="small")
    return fig


def overlay_time_figure(recording: np.ndarray, emulated: np.ndarray, rate_hz: float,
                        axis: str) -> Figure:
    """The recording and one emulated record against time (Fig. 9): the look of the series;
    their statistics are compared over many records (noise.verdict)."""
    return _overlay_time(recording, emulated, rate_hz, axis)


def overlay_figures(
    recording: np.ndarray,
    emulated: np.ndarray,
    rate_hz: float,
    rec_result: AxisIdentification,
    emu_result: AxisIdentification,
) -> dict[str, Figure]:
    """Figs. 7-9 for one axis: Allan deviation, PSD and time series, emulator vs recording.

    The time series compares like with like: a quantized recording (a chip's counts, the
    firmware's mdps) is set beside the emulator record rounded to the same LSB grid, as the
    chip's ADC would round it. The Allan deviation and PSD use the emulator record as
    generated: the N identified from a quantized record already holds the quantization's
    white noise (LSB^2 / 12), and rounding the emulator again would count it twice."""
    figs = {}
    fig, (ax,), (box,) = _with_legends(1, (8.0, 6.0), 0.1)
    for res, lab, col in (
        (rec_result, "recording", "tab:blue"),
        (emu_result, "emulator", "tab:orange"),
    ):
        c = res.allan
        ax.loglog(c.taus, c.adev, "o-", ms=3, color=col, label=f"{lab}: ADEV")
        ax.fill_between(c.taus, c.ci_low, c.ci_high, color=col, alpha=0.2, lw=0,
                        label=f"{lab}: {c.ci * 100:.0f} % confidence band")
    ax.set_xlabel("tau [s]")
    ax.set_ylabel("Allan deviation [deg/s]")
    ax.grid(alpha=0.3, which="both")
    _legend_below(ax, box, ncols=2)
    ax.set_title(f"axis {rec_result.axis}: emulator against recording, Allan deviation")
    figs["overlay_adev"] = fig

    fig, (ax,), (box,) = _with_legends(1, (8.0, 6.0), 0.06)
    draw_psd(ax, rec_result, rate_hz, color="tab:blue", label="recording", asymptotes=False)
    draw_psd(ax, emu_result, rate_hz, color="tab:orange", label="emulator", asymptotes=False)
    _legend_below(ax, box, ncols=2)
    ax.set_title(f"axis {rec_result.axis}: emulator against recording, PSD")
    fig.supxlabel(_PSD_CAPTION, fontsize="small")
    figs["overlay_psd"] = fig

    figs["overlay_time"] = _overlay_time(recording, emulated, rate_hz, rec_result.axis)
    return figs


def _overlay_time(recording: np.ndarray, emulated: np.ndarray, rate_hz: float,
                  axis: str) -> Figure:
    recording = np.asarray(recording, dtype=float)
    grid = output_grid(recording)
    emulator = np.asarray(emulated, dtype=float)
    if grid is not None:
        emulator = grid.snap(emulator)
        how = f"emulator rounded to the recording's LSB, {grid.step:.4g} deg/s"
    else:
        how = "neither is quantized"
    window = min(recording.shape[0], emulator.shape[0], _OVERLAY_WINDOW)
    zoom = min(window, _OVERLAY_ZOOM)
    fig, axes = _new(2, 1, size=(9.0, 6.5))
    t = np.arange(window) / rate_hz
    for ax, n, style in ((axes[0], window, "-"), (axes[1], zoom, ".-")):
        ax.plot(t[:n], recording[:n], style, lw=0.6, ms=3, color="tab:blue", label="recording")
        ax.plot(t[:n], emulator[:n], style, lw=0.6, ms=3, color="tab:orange", alpha=0.8,
                label="emulator")
        ax.set_ylabel("rate [deg/s]")
        ax.grid(alpha=0.3)
        ax.set_title(f"first {n} samples ({n / rate_hz:.3g} s)", fontsize="medium")
    if grid is not None:  # the zoom's minor grid: one line per LSB level, where few enough
        low = min(recording[:zoom].min(), emulator[:zoom].min())
        high = max(recording[:zoom].max(), emulator[:zoom].max())
        if grid.level(high) - grid.level(low) <= _LSB_LINES:
            levels = np.arange(grid.level(low), grid.level(high) + 1)
            axes[1].set_yticks(grid.origin + levels * grid.step, minor=True)
            axes[1].grid(which="minor", axis="y", alpha=0.15)
    axes[1].set_xlabel("time [s]")
    _legend_right(axes[0])
    fig.suptitle(f"axis {axis}: emulator against recording ({how})")
    return fig
