"""`bmg160-emu identify`: summary, JSON, profile file, figures, clear errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.noise import NoiseGenerator, load_profile


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rec")
    path = folder / "noise.npy"
    np.save(path, NoiseGenerator("paper", rate_hz=200.0, seed=7).generate(15 * 60 * 200))
    return path


def test_json_result_has_per_axis_parameters_in_their_units(record, capsys):
    assert main(["identify", str(record), "--rate", "200", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["rate_hz"] == 200.0 and result["samples"] == 180_000
    for axis in ("x", "y", "z"):
        ax = result["axes"][axis]
        for key, unit in (("N", "deg/s/sqrt(Hz)"), ("B", "deg/s"), ("K", "deg/s/sqrt(s)")):
            assert ax[key]["unit"] == unit
        assert {"T", "mean", "std", "ieee_readoffs", "fit", "psd"} <= set(ax)
        # 15 min at 200 Hz: N scatter ~0.1 %, 3 % is far outside it
        assert ax["N"]["value"] == pytest.approx(1.779073e-2, rel=0.03)
        assert ax["std"]["value"] == pytest.approx(0.2516, rel=0.05)


def test_summary_profile_and_adev_plot(record, tmp_path, capsys):
    profile = tmp_path / "mine.toml"
    plot = tmp_path / "adev.svg"
    args = ["identify", str(record), "--rate", "200", "--profile-out", str(profile)]
    assert main(args + ["--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "axis x:" in out and "IEEE 952 read-offs" in out and f"wrote {plot}" in out
    assert plot.read_text().lstrip().startswith("<?xml")
    back = load_profile(profile)
    assert back.x.N == pytest.approx(1.779073e-2, rel=0.03)
    NoiseGenerator(profile, seed=1).generate(3)


@pytest.mark.slow
def test_all_figures_with_emulator_overlays(record, tmp_path, capsys):
    folder = tmp_path / "figs"
    assert (
        main(["identify", str(record), "--rate", "200", "--figures", str(folder), "--compare"]) == 0
    )
    names = {p.name for p in folder.iterdir()}
    assert {"timeseries.png", "histogram.png", "adev.png", "psd.png"} <= names
    # the recording over the band of emulated records (issue 35: not one realisation), and
    # one record's time series
    assert {"compare.png", "overlay_time_y.png"} <= names
    assert "overlay_adev_x.png" not in names
    assert all((folder / n).read_bytes()[:4] == b"\x89PNG" for n in names)


@pytest.mark.parametrize(
    ("setup", "args", "message"),
    [
        (lambda p: None, ["--rate", "200"], "no such record file"),
        (lambda p: np.save(p, np.zeros((10, 3))), ["--rate", "200"], "too short: 10 samples"),
        (lambda p: np.save(p, np.random.default_rng(0).standard_normal((2000, 3))), [], r"give the sample rate \(--rate HZ\)"),
        (lambda p: np.save(p, np.full((2000, 1), np.nan)), ["--rate", "200"], "NaN or infinite"),
        (
            lambda p: np.save(p, np.random.default_rng(0).standard_normal((2000, 3))),
            ["--rate", "200", "--plot", "a.jpg"],
            "must end in .png or .svg",
        ),
        (
            lambda p: np.save(p, np.random.default_rng(0).standard_normal((2000, 3))),
            ["--rate", "200", "--columns", "x"],
            "--columns applies to CSV",
        ),
        (
            lambda p: np.save(p, np.random.default_rng(0).standard_normal((2000, 3))),
            ["--rate", "200", "--compare"],
            "--compare needs --figures",
        ),
    ],
)
def test_bad_input_is_a_one_line_error(tmp_path, capsys, setup, args, message):
    path = tmp_path / "rec.npy"
    setup(path)
    assert main(["identify", str(path), *args]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    import re

    assert re.search(message, err)


def test_progress_bar_only_on_a_terminal(record, capsys, monkeypatch):
    import sys

    assert main(["identify", str(record), "--rate", "200"]) == 0
    assert "identify:" not in capsys.readouterr().err  # not a terminal: no bar
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["identify", str(record), "--rate", "200"]) == 0
    err = capsys.readouterr().err
    assert "identify:" in err and "9/9" in err  # 3 axes x 3 stages
