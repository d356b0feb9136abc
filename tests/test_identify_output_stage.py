"""identify and the sensor's output stage (issue 23): the filter, the LSB and lines found on a
record and carried by the profile into generate; curves read for what they are (dense,
non-overlapping, in the wrong units); what the fit says about the terms it takes."""

from __future__ import annotations

import json
import math
import re

import numpy as np
import pytest
from scipy import signal

from bmg160_emu.cli import main
from bmg160_emu.noise import NoiseGenerator, ProfileError, load_profile
from bmg160_emu.noise.identify import identify, identify_curve
from bmg160_emu.noise.profile import AxisNoise, OutputStage, Profile
from bmg160_emu.noise.profile_writer import format_profile
from bmg160_emu.noise.sensor_noise import profile_noise

RATE = 100.0
WHITE = AxisNoise(N=0.04, B=0.0, T=0.0, K=2e-4, bias=0.1, gm=((1.2e-2, 5.0), (8e-3, 60.0)))


def sensor(**output) -> Profile:
    return Profile("s", WHITE, WHITE, WHITE, output=OutputStage(**output))


def test_a_quantized_filtered_record_gives_its_filter_and_lsb_to_the_profile(tmp_path):
    record = profile_noise(sensor(order=3, corner_hz=20.0, lsb_dps=0.0625, rate_hz=RATE),
                           seed=1).generate(20 * 60 * 100)
    result = identify(record, RATE)
    stage = result.to_profile().output
    # 20 min: the corner to a fraction of a percent (tests/test_identify_real_sensor.py)
    assert stage.order == 3 and stage.corner_hz == pytest.approx(20.0, rel=0.02)
    assert stage.lsb_dps == pytest.approx(0.0625) and stage.rate_hz == RATE
    for axis in result.axes:  # N of the sensing element, not of the filtered output
        assert axis.N.value == pytest.approx(WHITE.N, rel=0.03)
    path = tmp_path / "p.toml"
    path.write_text(format_profile(result.to_profile("p")), encoding="utf-8")
    back = load_profile(path)
    assert back.output == stage
    again = profile_noise(back, seed=2).generate(1000)  # generate's default: the same stage
    assert np.allclose(again / 0.0625, np.rint(again / 0.0625))
    assert profile_noise(back, seed=2).rate_hz == RATE


def test_an_unquantized_unfiltered_record_has_no_output_stage():
    x = NoiseGenerator("paper", rate_hz=200.0, seed=3).generate(10 * 60 * 200)
    result = identify(x, 200.0)
    assert result.to_profile().output is None
    assert all(a.output_filter is None and a.lsb_dps is None for a in result.axes)


def test_a_line_is_identified_as_a_sinusoidal_term_and_generated():
    axis = AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.0, sine=((0.02, 1.3),))
    x = NoiseGenerator(Profile("line", axis, axis, axis), rate_hz=RATE, seed=4).generate(
        30 * 60 * 100)[:, 0]
    found = identify(x, RATE).axes[0]
    assert len(found.sines) == 1
    amplitude, frequency = found.sines[0]
    # Welch bins of 0.0015 Hz: the centre to a bin; the amplitude from the line's power
    # (A^2 / 2) with the ADEV fit's interval around it
    assert frequency == pytest.approx(1.3, abs=0.003)
    assert amplitude.ci_low <= 0.02 <= amplitude.ci_high
    assert amplitude.value == pytest.approx(0.02, rel=0.1)
    assert found.to_axis_noise().sine[0][1] == frequency
    emulated = NoiseGenerator(Profile("e", *[found.to_axis_noise()] * 3), rate_hz=RATE,
                              seed=5).generate(30 * 60 * 100)[:, 0]
    again = identify(emulated, RATE).axes[0]
    assert again.sines and again.sines[0][1] == pytest.approx(1.3, abs=0.003)


def test_a_filter_that_is_no_butterworth_keeps_n_right():
    # a decimating chain (3rd-order Bessel at 30 Hz at 400 Hz, then 4-sample averages): no
    # Butterworth follows its first taus; its measured response does (issue 37), so every tau
    # is fitted through it and N stays within the round trip's 3 % (fitting the closest
    # Butterworth from the first tau gave N 19 % low)
    x = NoiseGenerator(Profile("t", WHITE, WHITE, WHITE), rate_hz=400.0, seed=3).generate(
        40 * 60 * 400)[:, 0]
    b, a = signal.bessel(3, 30 / 200)
    y = signal.lfilter(b, a, x)
    y = y[: y.size // 4 * 4].reshape(-1, 4).mean(axis=1)
    axis = identify(y, RATE).axes[0]
    assert axis.N.value == pytest.approx(WHITE.N, rel=0.03)
    assert axis.chi2_reduced < 3.0
    assert axis.stage is not None and axis.stage.carries_response, axis.notes
    assert axis.output_filter is None  # the measured response is carried for generate
    assert axis.to_axis_noise().response == axis.stage.response.cosine
    model = np.sqrt(axis.fit.model_avar(axis.allan.taus[:4]))
    assert np.all(np.abs(model / axis.allan.adev[:4] - 1) < 0.05)


def test_a_shallow_start_of_a_curve_is_fitted_with_a_filter_not_a_poor_chi_square():
    # a curve (no samples) whose first octave is about 0.2 shallower than -1/2 (a 2nd-order
    # filter at 44 Hz at 100 Hz, and the poles): the filter from the curve's start, and a
    # reduced chi-square about 1
    x = profile_noise(sensor(order=2, corner_hz=44.0, rate_hz=RATE), seed=6).generate(
        2 * 3600 * 100)[:, 0]
    curve = identify(x, RATE).axes[0].allan
    slope = math.log(curve.adev[1] / curve.adev[0]) / math.log(2)
    assert -0.35 < slope < -0.25
    axis = identify_curve(curve.taus, curve.adev, RATE, x.size)
    assert axis.output_filter is not None
    assert axis.chi2_reduced < 3.0
    assert axis.N.value == pytest.approx(WHITE.N, rel=0.03)


def allan_variance_ros_table(x: np.ndarray) -> np.ndarray:
    """allan_variance_ros's output for a gyro record in deg/s: periods 0.1 .. 999.9 s,
    non-overlapping cluster means (its AllanVarianceComputor.cpp), 7 columns."""
    csum = np.concatenate(([0.0], np.cumsum(x)))
    rows = []
    for period in range(1, 10000):
        m = round(period * 0.1 * RATE)
        means = np.diff(csum[::m]) / m
        adev = math.sqrt(np.mean(np.diff(means) ** 2) / 2.0)
        rows.append([period * 0.1, 0.0, 0.0, 0.0, adev, adev, adev])
    return np.array(rows)


@pytest.fixture(scope="module")
def ros_curve(tmp_path_factory):
    x = NoiseGenerator(Profile("t", WHITE, WHITE, WHITE), rate_hz=RATE, seed=7).generate(
        40 * 60 * 100)[:, 0]
    path = tmp_path_factory.mktemp("ros") / "allan_variance.csv"
    np.savetxt(path, allan_variance_ros_table(x), delimiter=",")
    return path, x.size


def test_a_dense_non_overlapping_curve_is_thinned_and_labelled(ros_curve, tmp_path, capsys):
    path, n = ros_curve
    out = tmp_path / "adev.csv"
    assert main(["identify", str(path), "--curve", "--rate", "100", "--samples", str(n),
                 "--adev-out", str(out), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    x = result["axes"]["x"]
    # 9,999 taus 0.1 s apart hold the information of about 14 a factor 2 apart
    assert x["fit"]["points"] <= 14
    assert any("9,999 taus thinned to 14" in note for note in x["notes"])
    assert any("non-overlapping Allan deviation curve" in note for note in x["notes"])
    assert out.read_text().startswith("# non-overlapping Allan deviation in deg/s")
    # 40 min of N = 0.04: from 0.1 s up, N to a few per cent
    assert x["N"]["value"] == pytest.approx(WHITE.N, rel=0.05)
    assert x["fit"]["chi2_reduced"] < 3.0


def test_a_curve_read_in_the_wrong_units_is_warned_about(ros_curve, capsys):
    path, n = ros_curve
    assert main(["identify", str(path), "--curve", "--rate", "100", "--samples", str(n)]) == 0
    assert "implausible" not in capsys.readouterr().err
    # the deg/s curve read as rad/s: N 57 times too high
    assert main(["identify", str(path), "--curve", "--rate", "100", "--samples", str(n),
                 "--curve-units", "rad/s"]) == 0
    captured = capsys.readouterr()
    assert re.search(r"implausible N = 2\.\d+ deg/s", captured.err)
    assert "--curve-units" in captured.err
    assert "note: implausible N" in captured.out


def test_poles_never_gives_terms_of_size_zero_and_every_count_is_listed():
    x = NoiseGenerator("paper", rate_hz=200.0, seed=3).generate(20 * 60 * 200)[:, 0]
    axis = identify(x, 200.0, poles=4).axes[0]
    assert axis.terms and all(t.B.value > 0 for t in axis.terms)
    assert any("came out of size 0 and are left out" in note for note in axis.notes)
    rows = axis.fit.selection["candidates"]
    assert [r["terms"] for r in rows] == sorted(r["terms"] for r in rows) and len(rows) >= 4
    assert [r["terms"] for r in rows if r["chosen"]] == [4]
    result = identify(x, 200.0, poles=1)
    fixed = result.axes[0]
    line = next(t for t in result.summary().splitlines() if "scored by AICc" in t)
    scored = [r["terms"] for r in fixed.fit.selection["candidates"]]
    assert len(scored) >= 2  # before, --poles scored and listed its own count only
    for count in scored:  # every count scored is listed, the one taken marked
        assert (f" {count}*:" if count == 1 else f" {count}:") in line, line


def test_a_term_taken_by_a_thin_aicc_margin_is_said():
    # the case: 30 min of the paper profile, a 0.03 s term taken by 0.1 AICc
    x = NoiseGenerator("paper", rate_hz=200.0, seed=1).generate(30 * 60 * 200)[:, 1]
    axis = identify(x, 200.0).axes[0]
    short = [t for t in axis.terms if t.T.value < 1.0]
    assert short, "the seed no longer gives the short term of the issue"
    note = next(n for n in axis.notes if "AICc over" in n)
    assert "no evidence" in note and "B's interval reaches 0" in note
    lo, hi = axis.fit.T_search_range_s  # T of a term that may be absent: the whole range
    assert (short[0].T.ci_low, short[0].T.ci_high) == (lo, hi)


@pytest.mark.parametrize(("table", "message"), [
    ({"bw_code": 9}, "bw_code must be 0..7"),
    ({"order": 2}, "needs both order and corner_hz"),
    ({"bw_code": 4, "order": 2, "corner_hz": 23.0}, "not both"),
    ({"order": 0, "corner_hz": 10.0}, "order must be 1..8"),
    ({"order": 2, "corner_hz": -1.0}, "must not be negative"),
    ({"lsb_dps": 0.0}, "lsb_dps must be positive"),
    ({"gain": 2}, "unknown field"),
])
def test_a_bad_output_table_is_named(table, message):
    data = {"x": WHITE.__dict__ | {"gm": list(WHITE.gm)}, "output": table}
    data = {"name": "bad", "output": table,
            **{a: {"N": 0.01, "B": 0.0, "T": 0.0, "K": 0.0, "bias": 0.0} for a in "xyz"}}
    with pytest.raises(ProfileError, match=message):
        load_profile(data)


def test_a_bad_sine_term_is_named():
    axis = {"N": 0.01, "B": 0.0, "T": 0.0, "K": 0.0, "bias": 0.0, "sine": [{"A": 0.1}]}
    with pytest.raises(ProfileError, match=r"\[x\] sine\[0\]: needs exactly A"):
        load_profile({"x": axis, "y": axis, "z": axis})


def test_the_filter_is_said_once_per_axis():
    # issue 23: the filter sentence was printed twice per axis (reason and note)
    record = profile_noise(sensor(order=2, corner_hz=32.0, rate_hz=RATE), seed=8).generate(
        10 * 60 * 100)
    text = identify(record, RATE).summary()
    for block in text.split("\n\naxis ")[1:]:
        assert block.count("Butterworth") == 1, block
        assert "below the white-noise line" not in block


def test_odd_records_raise_clear_errors_and_no_numpy_warnings(recwarn):
    # issue 24: numpy RuntimeWarnings leaked to stderr from allan.py and datapath.py
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.noise.allan import octave_oadev, overlapping_adev
    from bmg160_emu.noise.identify import IdentificationError

    for bad in (np.zeros(0), np.r_[np.ones(100), np.nan], np.r_[np.ones(100), np.inf]):
        with pytest.raises(ValueError, match="needs"):
            octave_oadev(bad, 100.0)
    huge = np.random.default_rng(1).standard_normal(4000)
    assert np.allclose(overlapping_adev(huge * 1e300, 100.0).ci_high / 1e300,
                       overlapping_adev(huge, 100.0).ci_high, rtol=1e-12)
    with pytest.raises(IdentificationError, match="beyond"):
        identify(huge * 1e300, 100.0)
    chip = BMG160(seed=1)
    with pytest.raises(ValueError, match="within"):
        chip.set_true_rate((1e308, 0.0, 0.0))
    chip.set_true_rate((1e9, -1e9, 0.0))  # the largest taken: saturated counts
    chip.advance(0.01)
    assert chip.read(0x02, 4) == b"\xff\x7f\x00\x80"
    with pytest.raises(ValueError, match="within"):
        BMG160(seed=1, scale_factor=(1e300, 0.0, 0.0))
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
