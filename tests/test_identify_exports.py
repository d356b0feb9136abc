"""identify's curves in and out, Kalibr and MATLAB exports and imports, --units, --skip,
--poles, and generate --bandwidth."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.noise import NoiseGenerator, load_profile
from bmg160_emu.noise.allan import FLICKER_ADEV_FACTOR, gauss_markov_avar
from bmg160_emu.noise.interop import flicker_poles, read_adev_csv
from bmg160_emu.noise.sensor_noise import profile_noise

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    path = tmp_path_factory.mktemp("exp") / "rec.npy"
    np.save(path, NoiseGenerator("paper", rate_hz=200.0, seed=12).generate(30 * 60 * 200))
    return path


def run_json(capsys, *args):
    assert main(["identify", *map(str, args), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_units_rad_s_scales_every_rate_quantity(record, capsys):
    deg = run_json(capsys, record, "--rate", "200")
    rad = run_json(capsys, record, "--rate", "200", "--units", "rad/s")
    for key in ("N", "K"):
        assert rad["axes"]["x"][key]["value"] == pytest.approx(deg["axes"]["x"][key]["value"] * DEG)
        assert rad["axes"]["x"][key]["unit"].startswith("rad/s")
    assert rad["axes"]["y"]["mean"]["value"] == pytest.approx(deg["axes"]["y"]["mean"]["value"] * DEG)
    flick = "B_flicker"
    assert rad["axes"]["z"]["ieee_readoffs"][flick]["value"] == pytest.approx(
        deg["axes"]["z"]["ieee_readoffs"][flick]["value"] * DEG)
    assert rad["axes"]["z"]["ieee_readoffs"][flick]["unit"] == "rad/s"


def test_adev_out_read_back_as_a_curve_gives_the_same_fit(record, tmp_path, capsys):
    curve = tmp_path / "adev.csv"
    first = run_json(capsys, record, "--rate", "200", "--adev-out", curve, "--units", "rad/s")
    _taus, axes = read_adev_csv(curve, units="rad/s")
    assert [a["name"] for a in axes] == ["x", "y", "z"] and axes[0]["ci"] is not None
    again = run_json(capsys, curve, "--curve", "--rate", "200", "--duration", "30min",
                     "--curve-units", "rad/s", "--units", "rad/s")
    for axis in ("x", "y", "z"):
        # the same points and the same edf: the same fit, to the CSV's 10 digits
        assert again["axes"][axis]["N"]["value"] == pytest.approx(
            first["axes"][axis]["N"]["value"], rel=1e-6)


def test_an_allan_variance_ros_layout_uses_its_gyroscope_columns(tmp_path, capsys):
    taus = 0.01 * 2.0 ** np.arange(14)
    gyro = 1e-3 / np.sqrt(taus)  # rad/s: white N = 1e-3 rad/s/sqrt(Hz)
    table = np.column_stack([taus, gyro * 5, gyro * 5, gyro * 5, gyro, gyro * 1.1, gyro * 0.9])
    path = tmp_path / "allan_variance.csv"
    np.savetxt(path, table, delimiter=",")
    out = run_json(capsys, path, "--curve", "--rate", "100", "--samples", "1000000",
                   "--curve-units", "rad/s")
    assert out["axes"]["x"]["N"]["value"] == pytest.approx(1e-3 / DEG, rel=1e-3)
    assert out["axes"]["y"]["N"]["value"] == pytest.approx(1.1e-3 / DEG, rel=1e-3)


def test_kalibr_export_and_import(record, tmp_path, capsys):
    yaml = tmp_path / "imu.yaml"
    out = run_json(capsys, record, "--rate", "200", "--kalibr-out", yaml)
    text = yaml.read_text()
    N = max(out["axes"][a]["N"]["value"] for a in "xyz")
    value = float(text.split("gyroscope_noise_density:")[1].split()[0])
    assert value == pytest.approx(N * DEG, rel=1e-6)
    back = load_profile(yaml)
    assert back.x.N == pytest.approx(N, rel=1e-6) and back.z.gauss_markov_terms == ()


def test_matlab_export_uses_the_flicker_readoff_and_imports_it_as_a_flat_bank(
        record, tmp_path, capsys):
    path = tmp_path / "gyro.m"
    out = run_json(capsys, record, "--rate", "200", "--matlab-out", path)
    text = path.read_text()
    assert "'BiasInstability'" in text and "gyroparams(" in text
    readoff = out["axes"]["x"]["ieee_readoffs"]["B_flicker"]["value"]
    bi = float(text.split("'BiasInstability', [")[1].split()[0])
    assert bi == pytest.approx(readoff * DEG, rel=1e-6)
    back = load_profile(path)
    assert back.x.N == pytest.approx(out["axes"]["x"]["N"]["value"], rel=1e-6)
    # the bank's Allan deviation is flat at 0.664 BiasInstability over 1 .. 1000 s (within
    # the ripple of poles a factor 4 apart, measured below 6 %)
    tau = np.geomspace(1.0, 1000.0, 40)
    adev = np.sqrt(sum(gauss_markov_avar(B, T, tau) for B, T in back.x.gm))
    assert np.all(np.abs(adev / (FLICKER_ADEV_FACTOR * readoff) - 1) < 0.06)
    NoiseGenerator(path, seed=1).generate(10)


def test_flicker_poles_of_zero_are_none():
    assert flicker_poles(0.0) == ()


def test_skip_poles_and_flicker_options(record, capsys):
    out = run_json(capsys, record, "--rate", "200", "--skip", "5min", "--poles", "1")
    assert out["skipped_s"] == 300.0 and out["samples"] == 25 * 60 * 200
    assert all(len(out["axes"][a]["terms"]) == 1 for a in "xyz")
    flick = run_json(capsys, record, "--rate", "200", "--flicker", "--poles", "0")
    assert "flicker_B" in flick["axes"]["x"] and "1/f bank" in flick["axes"]["x"]["fit"]["model"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--poles", "many"], "--poles must be a number"),
        (["--poles", "9"], "--poles must be 0 to 5"),
        (["--skip", "soon"], "--skip: not a duration"),
        (["--skip", "2h"], "skipping 2 h leaves 0 of .* too short"),
        (["--method", "magic"], "unknown fit method 'magic'"),
        (["--curve"], "--curve needs the record's length"),
        (["--curve", "--samples", "100"], r"rec\.npy:2: not a number"),
    ],
)
def test_bad_options_are_one_line_errors(record, capsys, args, message):
    import re

    assert main(["identify", str(record), "--rate", "200", *args]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert re.search(message, err), err


def test_generate_bandwidth_passes_the_noise_through_the_chip_filter(tmp_path, capsys):
    out = tmp_path / "bw.npy"
    assert main(["generate", "--profile", "paper", "--bandwidth", "5", "--duration", "20min",
                 "--seed", "2", "-o", str(out)]) == 0
    capsys.readouterr()  # generate's report, not identify's JSON
    data = np.load(out)
    # BW code 5: ODR 100 Hz, 12 Hz low-pass: the per-sample std of the white part drops
    # from N sqrt(100) = 0.178 to about N sqrt(pi/2 x 12 x 1.1) = 0.081 (noise bandwidth of a
    # 2nd-order Butterworth); std of 120 000 samples is known to < 1 %
    assert 0.07 < data[:, 0].std() < 0.10
    result = run_json(capsys, out, "--rate", "100")
    ax = result["axes"]["x"]
    # the chip's filter comes back from the PSD (order 2 at 12 Hz) and is fitted as part of
    # the white term from the first tau
    assert ax["output_filter"]["order"] == 2
    assert ax["output_filter"]["corner_hz"] == pytest.approx(12.0, rel=0.02)
    assert "output filter is part of the white term" in ax["fit"]["tau_range_reason"]
    # 20 min: N to ~1 %; the filter is fitted, not taken for N
    assert ax["N"]["value"] == pytest.approx(load_profile("paper").x.N, rel=0.03)


def test_the_library_filtered_noise_is_chunk_invariant():
    # the noise is filtered in fixed chunks counted from its start (device.datapath
    # SensorNoise), so how generate() is called changes no bit
    whole = profile_noise("paper", seed=4, bandwidth_code=3).generate(5000)
    gen = profile_noise("paper", seed=4, bandwidth_code=3)
    parts = np.concatenate([gen.generate(k) for k in (1, 999, 3000, 1000)])
    assert gen.rate_hz == 400.0
    assert np.array_equal(parts, whole)
    with pytest.raises(ValueError, match="unknown BW code 8"):
        profile_noise("paper", bandwidth_code=8)


def test_a_curve_in_deg_per_hour_whitespace_separated(tmp_path, capsys):
    taus = 0.01 * 2.0 ** np.arange(14)
    path = tmp_path / "pasted.txt"
    np.savetxt(path, np.column_stack([taus, 0.02 * 3600 / np.sqrt(taus)]), delimiter=" ")
    out = run_json(capsys, path, "--curve", "--rate", "100", "--samples", "1000000",
                   "--curve-units", "deg/h")
    assert out["axes"]["x"]["N"]["value"] == pytest.approx(0.02, rel=1e-3)


@pytest.mark.parametrize(("value", "where"), [(1e-320, "row 10"), (1e300, "row 10")])
def test_a_curve_point_the_fit_cannot_weigh_is_a_one_line_error(tmp_path, capsys, value, where):
    """A deviation whose square underflows to 0 (1e-320, found by tools/fuzz.py --cli, seed
    7710283: the fit's weights became inf and scipy's nnls raised) or overflows is refused
    with the file and the row, before anything is fitted."""
    from bmg160_emu.cli import main

    taus = 0.005 * 2.0 ** np.arange(14)
    adev = 0.01 / np.sqrt(taus)
    adev[9] = value
    path = tmp_path / "adev.csv"
    np.savetxt(path, np.column_stack([taus, adev, adev, adev]), delimiter=",")
    assert main(["identify", str(path), "--curve", "--rate", "200", "--duration", "1h"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and where in err[0]
    assert "Allan deviation must be 1e-30 to 1e+06 deg/s" in err[0]
