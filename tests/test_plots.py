"""The identify figures (noise/plots.py), checked by their properties, not their pixels: the
histogram's bins on the LSB grid, units in the Allan deviation titles, the fit named by its
method, legends clear of the curves, everything drawn inside the axes and the figure, and a
time overlay that sets like beside like."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from bmg160_emu.noise import NoiseGenerator, plots
from bmg160_emu.noise.identify import identify

RATE_HZ = 200.0
LSB_DPS = 1 / 16.384  # +-2000 deg/s range, binary sensitivity (32768 / 2000 LSB per deg/s)


@pytest.fixture(scope="module")
def record() -> np.ndarray:
    # 10 min of the paper's noise at 200 Hz: z gets one Gauss-Markov term (seed 5)
    return NoiseGenerator("paper", rate_hz=RATE_HZ, seed=5).generate(int(600 * RATE_HZ))


@pytest.fixture(scope="module")
def counts_record(record) -> np.ndarray:
    """The same noise as a chip outputs it: whole counts, divided by the sensitivity."""
    return np.rint(record / LSB_DPS) * LSB_DPS


@pytest.fixture(scope="module")
def result(record):
    return identify(record, RATE_HZ)


def _drawn(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def test_the_lsb_grid_is_found_in_counts_mdps_and_resd_units_and_not_in_real_numbers(
        record, counts_record):
    grid = plots.output_grid(counts_record[:, 0])
    assert grid is not None and grid.step == pytest.approx(LSB_DPS, rel=1e-9)
    firmware = np.rint(record[:, 1] * 1000.0) / 1000.0  # the UART stream's whole mdps
    grid = plots.output_grid(firmware)
    assert grid is not None and grid.step == pytest.approx(1e-3, rel=1e-9)
    # RESD stores counts / sensitivity again rounded to 1e-5 rad/s: off-grid by < 0.5 % LSB
    resd_unit = math.degrees(1e-5)
    resd = np.rint(counts_record[:, 2] / resd_unit) * resd_unit
    grid = plots.output_grid(resd)
    assert grid is not None and grid.step == pytest.approx(LSB_DPS, rel=1e-3)
    assert plots.output_grid(record[:, 0]) is None


def test_histogram_bins_of_a_quantized_record_are_whole_lsbs_centred_on_the_levels(
        counts_record):
    fig = plots.histogram_figure(counts_record, ("x", "y", "z"))
    ax = fig.axes[0]
    column = counts_record[:, 0]
    grid = plots.output_grid(column)
    edges = np.unique(ax.patches[0].get_path().vertices[:, 0])  # the drawn bar outline
    np.testing.assert_allclose(edges, plots.histogram_edges(column, grid))
    offsets = (edges - grid.origin) / grid.step + 0.5  # edges half an LSB off the levels
    np.testing.assert_allclose(offsets, np.rint(offsets), atol=1e-6)
    # every level lies inside a bin, well away from its edges
    inside = np.searchsorted(edges, column)
    assert inside.min() >= 1 and inside.max() < edges.size
    gap = np.minimum(column - edges[inside - 1], edges[inside] - column)
    assert gap.min() >= 0.49 * grid.step
    # no comb: the tallest bar is near the Gaussian's peak 1 / (sigma sqrt(2 pi)); the 200
    # bins of 0.2 LSB this replaced reached 5x it. 120,000 samples: a bar near the peak
    # holds ~11,000 of them, so its density is within 3 % (1 / sqrt(11000) = 1 %, 3 sigma).
    density, _ = np.histogram(column, bins=edges, density=True)
    peak = 1 / (column.std() * math.sqrt(2 * math.pi))
    assert density.max() == pytest.approx(peak, rel=0.03)
    assert "LSB 0.06104 deg/s" in ax.get_title()


def test_histogram_of_real_numbers_uses_a_bounded_number_of_bins(record):
    fig = plots.histogram_figure(record[:, :1], ("x",))
    edges = np.unique(fig.axes[0].patches[0].get_path().vertices[:, 0])
    assert 20 <= edges.size - 1 <= 200
    assert "quantized" not in fig.axes[0].get_title()


def test_adev_titles_give_n_b_t_k_with_their_units(result):
    fig = plots.adev_figure(result.axes)
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert len(titles) == 3
    for title, axis in zip(titles, result.axes):
        assert f"N = {axis.N.value:.3g} deg/s/\u221aHz" in title
        assert f"K = {axis.K.value:.3g} deg/s/\u221as" in title
        for term in axis.terms:
            assert f"B = {term.B.value:.3g} deg/s, T = {term.T.value:.3g} s" in title
    assert any(axis.terms for axis in result.axes)  # a B, T title was checked
    assert "no Gauss-Markov term" in titles[[bool(a.terms) for a in result.axes].index(False)]


def test_a_gmwm_fit_is_called_gmwm_in_its_figures(result):
    gmwm_axes = [dataclasses.replace(a, method="gmwm") for a in result.axes]
    for fig in (plots.adev_figure(gmwm_axes), plots.psd_figure(gmwm_axes, RATE_HZ)):
        texts = [t.get_text() for t in fig.findobj(lambda a: hasattr(a, "get_text"))]
        texts += [lab for ax in fig.axes for lab in ax.get_legend_handles_labels()[1]]
        assert any("GMWM" in t for t in texts)
        assert not any("WLS" in t for t in texts)
    wls = plots.adev_figure(result.axes)
    assert "WLS fit of the Allan variance" in wls.axes[0].get_title()


def _inside(inner, outer, slack=1.0) -> bool:
    return (inner.x0 >= outer.x0 - slack and inner.y0 >= outer.y0 - slack
            and inner.x1 <= outer.x1 + slack and inner.y1 <= outer.y1 + slack)


def _drawn_parts(fig, renderer):
    """Window boxes of what is drawn: each axes with its ticks, labels, title and legend (the
    tight box counts only the tick labels drawn), and the figure's own titles."""
    boxes = [ax.get_tightbbox(renderer) for ax in fig.axes]
    boxes += [t.get_window_extent(renderer) for t in fig.texts if t.get_text()]
    for text in (fig._suptitle, fig._supxlabel):
        if text is not None and text.get_text():
            boxes.append(text.get_window_extent(renderer))
    return [b for b in boxes if b is not None and b.width > 0]


def _plot_axes(fig):
    return [ax for ax in fig.axes if ax.axison]


def test_psd_every_listed_asymptote_is_seen(result):
    fig = plots.psd_figure(result.axes, RATE_HZ)
    _drawn(fig)
    axes = _plot_axes(fig)
    assert len(axes) == 3
    asymptotes = 0
    for ax in axes:
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        for line in ax.get_lines():
            x, y = (np.asarray(v, dtype=float) for v in line.get_data())
            if x.size == 0:  # a legend note: an asymptote under the plotted range
                assert "below" in line.get_label()
                continue
            seen = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
            # every curve is seen inside the axes' limits over half a decade of frequency
            # at least (the lowest; a 1/f^2 asymptote falls out of sight above it)
            decades = math.log10(x[seen].max() / x[seen].min()) if seen.sum() > 1 else 0.0
            assert decades >= 0.45, (ax.get_title(), line.get_label(), decades)
            asymptotes += line.get_linestyle() == "--"
    assert asymptotes >= 4  # white on each axis, and the Gauss-Markov or random walk ones
    title = fig.get_suptitle()
    assert len(title) <= 40 and fig._suptitle.get_fontsize() >= 11


@pytest.mark.parametrize("name", ["histogram", "adev", "psd", "timeseries", "overlay_adev",
                                  "overlay_psd", "overlay_time"])
def test_no_legend_covers_a_plot_and_all_is_inside_the_figure(name, result, counts_record):
    if name.startswith("overlay"):
        fig = plots.overlay_figures(counts_record[:, 0], counts_record[::-1, 0], RATE_HZ,
                                    result.axes[0], result.axes[0])[name]
    else:
        fig = {
            "histogram": lambda: plots.histogram_figure(counts_record, "xyz"),
            "adev": lambda: plots.adev_figure(result.axes),
            "psd": lambda: plots.psd_figure(result.axes, RATE_HZ),
            "timeseries": lambda: plots.time_series_figure(counts_record, RATE_HZ, "xyz"),
        }[name]()
    renderer = _drawn(fig)
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    assert legends
    for legend in legends:  # beside or under the plots, never over a line or a point
        for ax in _plot_axes(fig):
            assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    parts = _drawn_parts(fig, renderer)  # and nothing is cut off by the figure's edge
    assert len(parts) >= len(fig.axes)
    for box in parts:
        assert _inside(box, fig.bbox), (box, fig.bbox)


def test_adev_every_listed_point_and_line_is_seen(result):
    fig = plots.adev_figure(result.axes)
    _drawn(fig)
    points = 0
    for ax in _plot_axes(fig):
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        for line in ax.get_lines():
            if line.get_label().startswith("_") or line.get_transform() != ax.transData:
                continue  # unlabelled, or the flicker line (drawn across the axes)
            x, y = (np.asarray(v, dtype=float) for v in line.get_data())
            if x.size == 0:  # a legend note: K too small to be drawn, or 0; no K read-off
                assert line.get_label().startswith(("K = ", "K read-off (IEEE 952): not found")
                                                   ), line.get_label()
                continue
            seen = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
            assert seen.any(), (ax.get_title(), line.get_label())
            points += x.size == 1
    # N, flicker B (and K and the K read-off when drawn) on each axis
    assert points in (3 * 3, 3 * 4) or points >= 6


def test_a_random_walk_of_zero_or_far_below_the_curve_is_named_not_drawn(result):
    axes = [dataclasses.replace(result.axes[0], fit=dataclasses.replace(
        result.axes[0].fit, K=dataclasses.replace(result.axes[0].fit.K, value=k)))
        for k in (0.0, 1e-9)]
    fig = plots.adev_figure(axes)
    notes = [[line.get_label() for line in ax.get_lines() if not np.size(line.get_xdata())
              and not line.get_label().startswith("K read-off")] for ax in _plot_axes(fig)]
    assert notes[0] == ["K = 0: no +1/2 slope (random walk) in this record"]
    assert len(notes[1]) == 1 and notes[1][0].startswith("K = 1e-09 deg/s/\u221as: its +1/2 line")
    for ax in _plot_axes(fig):  # the axes keep to the curve: 2 decades under it at most
        assert ax.get_ylim()[0] >= np.nanmin(result.axes[0].allan.adev) / 100 * (1 - 1e-9)


def test_time_overlay_rounds_the_emulator_to_a_quantized_recordings_lsb(counts_record, record,
                                                                         result):
    emulated = NoiseGenerator(result.to_profile(), rate_hz=RATE_HZ, seed=9).generate(4000)
    axis = result.axes[0]
    fig = plots.overlay_figures(counts_record[:, 0], emulated[:, 0], RATE_HZ, axis,
                                axis)["overlay_time"]
    top = fig.axes[0]
    recording_line, emulator_line = top.get_lines()
    np.testing.assert_array_equal(recording_line.get_ydata(), counts_record[:2000, 0])
    steps = emulator_line.get_ydata() / LSB_DPS
    np.testing.assert_allclose(steps, np.rint(steps), atol=1e-9)  # on the chip's grid
    assert np.abs(emulator_line.get_ydata() - emulated[:2000, 0]).max() <= LSB_DPS / 2 + 1e-12
    assert "rounded to the recording's LSB" in fig.get_suptitle()
    # a recording of real numbers is compared with the emulator as generated
    fig = plots.overlay_figures(record[:, 0], emulated[:, 0], RATE_HZ, axis, axis)["overlay_time"]
    np.testing.assert_array_equal(fig.axes[0].get_lines()[1].get_ydata(), emulated[:2000, 0])
    assert "neither is quantized" in fig.get_suptitle()


def test_identify_figures_of_a_firmware_capture_are_written_whole(tmp_path, capsys):
    from pathlib import Path

    from bmg160_emu import cli

    capture = Path(__file__).parent / "data" / "firmware_capture.txt"
    folder = tmp_path / "figs"
    assert cli.main(["identify", str(capture), "--figures", str(folder), "--compare",
                     "--seed", "1"]) == 0
    out = capsys.readouterr().out
    names = sorted(p.name for p in folder.iterdir())
    # --compare: the recording over the band of emulated records (compare.png) and one
    # emulated time series per axis beside the recording's
    assert names == sorted(["adev.png", "compare.png", "histogram.png", "psd.png",
                            "timeseries.png"] + [f"overlay_time_{a}.png" for a in "xyz"])
    for name in names:  # each a whole PNG, announced, no temporary file left beside it
        assert (folder / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"wrote {folder / name}" in out


def test_several_gauss_markov_terms_take_one_legend_line(result):
    # a 1/f bank adds many poles: the PSD legend names the kind once (and the hidden ones
    # once), not one line a pole
    axis = result.axes[0]
    poles = ((0.004, 0.5), (0.004, 5.0), (0.004, 50.0), (1e-6, 0.05), (1e-6, 0.5))
    axis = dataclasses.replace(axis, fit=dataclasses.replace(axis.fit, flicker_poles=poles))
    terms = axis.fit.gauss_markov_terms()
    fig = plots.psd_figure([axis], RATE_HZ)
    ax = fig.axes[0]
    labels = [label for label in ax.get_legend_handles_labels()[1]
              if label.startswith("Gauss-Markov")]
    drawn = [line for line in ax.get_lines() if line.get_color() == "tab:green"]
    hidden = [label for label in labels if "below" in label]
    shown = [label for label in labels if "below" not in label]
    assert len(shown) == 1 and len(hidden) == 1
    assert shown[0].endswith(f"and {len(drawn) - 1} more terms")
    assert hidden[0].split(" and ")[1].startswith("1 more")  # the two 1e-6 poles
    assert len(drawn) + 2 == len(terms)


def test_each_read_off_marker_sits_at_the_value_its_legend_names(result):
    # issue 23: the flicker-B marker was drawn at the minimum (0.664 B) and labelled B
    import re

    fig = plots.adev_figure(result.axes)
    checked = 0
    for ax in _plot_axes(fig):
        for line in ax.get_lines():
            match = re.match(r"(flicker B|N \(fit\)|K \(fit\)|K read-off) = ([0-9.e+-]+) ",
                             line.get_label())
            if match and np.size(line.get_ydata()) == 1:
                named = float(match.group(2))
                assert float(line.get_ydata()[0]) == pytest.approx(named, rel=1e-3), line.get_label()
                checked += 1
    assert checked >= 2 * len(result.axes)  # N and flicker B on every axis


def test_the_k_read_off_is_labelled_as_the_summary_gives_it(result):
    # issue 35: the figure labelled the fitted K as if read off where the summary said the
    # read-off was not found; now the fitted K and the read-off are told apart
    fig = plots.adev_figure(result.axes)
    for ax, axis in zip(_plot_axes(fig), result.axes):
        labels = [line.get_label() for line in ax.get_lines()]
        found = axis.readoffs["K_at_tau_3s"]["value"]
        if found is None:
            assert "K read-off (IEEE 952): not found, no +1/2 segment" in labels
        else:
            assert any(label.startswith(f"K read-off = {found:.4g}") for label in labels)
        assert not any(label.startswith("K = ") and "(tau 3 s)" in label for label in labels)
