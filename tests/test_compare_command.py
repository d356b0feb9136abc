"""bmg160-emu compare (issue 37): a recording against the spread of a profile's emulated
records. It passes the profile identify writes for the recording and fails a profile that is
wrong (the recording's resonant band dropped), by the figures it names."""

import json

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.noise.profile import AxisNoise, OutputStage, Profile
from bmg160_emu.noise.profile_writer import write_profile

# white noise with a band at 15 Hz holding 0.0036 / (0.0036 + 0.04) = 8 % of the variance,
# and a two-sample average at the output, 20 min at 100 Hz (the stage is the subject here)
TRUTH = AxisNoise(N=0.02, B=0.0, T=0.0, K=0.0, bias=0.1, band=((15.0, 1.0, 0.06),),
                  response=(0.5, 0.25))
SEEDS = "8"  # 8 records: the forward and reverse ADEV figures on 7 octave taus each


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    from bmg160_emu.noise.sensor_noise import profile_noise

    folder = tmp_path_factory.mktemp("compare")
    # the recording: the truth's sensing element with its band, through the average (the
    # response applied by generate's path, the band then drawn by the engine explicitly)
    no_response = Profile("t", *(AxisNoise(**{**TRUTH.__dict__, "response": ()}),) * 3)
    data = profile_noise(no_response, 100.0, seed=77).generate(120_000)
    data = np.vstack([data[:1], (data[1:] + data[:-1]) / 2.0])
    path = folder / "rec.npy"
    np.save(path, data)
    return folder, path


def _compare(capsys, *args):
    code = main(["compare", *map(str, args), "--rate", "100", "--seeds", SEEDS, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_the_identified_profile_passes(recording, capsys):
    folder, path = recording
    profile = folder / "identified.toml"
    assert main(["identify", str(path), "--rate", "100", "--profile-out", str(profile)]) == 0
    capsys.readouterr()
    code, report = _compare(capsys, path, profile)
    for axis in report["axes"].values():
        assert abs(axis["std_ratio"] - 1) < 0.03
        lags = np.abs(np.array(axis["autocorrelation_emulated"][:5])
                      - np.array(axis["autocorrelation_recorded"][:5]))
        assert lags.max() < 0.05
    assert code == 0, report


def test_dropping_the_band_fails(recording, capsys, tmp_path):
    _, path = recording
    wrong = AxisNoise(**{**TRUTH.__dict__, "band": ()})
    profile = tmp_path / "wrong.toml"
    write_profile(Profile("wrong", wrong, wrong, wrong, output=OutputStage(rate_hz=100.0)),
                  profile)
    code, report = _compare(capsys, path, profile)
    assert code == 1 and report["passed"] is False
    for axis in report["axes"].values():  # the band's 8 % of the variance: std 4 % low
        assert axis["checks"]["std"]["passed"] is False and axis["std_ratio"] < 0.97
        assert axis["checks"]["psd"]["passed"] is False


def test_figure_and_bad_input(recording, capsys, tmp_path):
    _, path = recording
    figure = tmp_path / "v.png"
    assert main(["compare", str(path), "paper", "--rate", "100", "--seeds", "2",
                 "--figure", str(figure)]) == 1
    assert figure.stat().st_size > 10_000
    assert main(["compare", str(path), "paper", "--rate", "100", "--figure",
                 str(tmp_path / "v.txt")]) == 2
    assert "--figure must end in .png or .svg" in capsys.readouterr().err
    assert main(["compare", str(tmp_path / "missing.npy"), "paper", "--rate", "100"]) == 2
    assert main(["compare", str(path), "paper", "--rate", "50"]) == 2
    assert "not an output data rate" in capsys.readouterr().err


def test_a_sensor_at_its_own_rate_is_generated_and_compared_there(tmp_path, capsys):
    """A user's sensor at a rate the BMG160 does not offer (a PX4 autopilot's 250 Hz): the
    profile identified from it runs at that rate (its [output] rate_hz), so identify prints a
    verdict and compare draws there; another rate is refused, naming both."""
    from bmg160_emu.noise import NoiseGenerator
    from bmg160_emu.noise.profile import load_profile

    white = AxisNoise(N=0.01, B=0.0, T=0.0, K=0.0, bias=0.0)
    own = Profile("own", white, white, white, output=OutputStage(rate_hz=250.0))
    data = NoiseGenerator(own, rate_hz=250.0, seed=5).generate(60_000)
    path = tmp_path / "px4.npy"
    np.save(path, data)
    profile = tmp_path / "px4.toml"
    assert main(["identify", str(path), "--rate", "250", "--profile-out", str(profile)]) == 0
    capsys.readouterr()
    assert load_profile(str(profile)).output.rate_hz == 250.0
    main(["compare", str(path), str(profile), "--rate", "250", "--seeds", SEEDS, "--json"])
    report = json.loads(capsys.readouterr().out)
    assert report["rate_hz"] == 250.0 and report["samples"] == 60_000
    for axis in report["axes"].values():  # drawn at 250 Hz: the same white noise (the std of
        assert abs(axis["std_ratio"] - 1) < 0.03  # 60,000 samples scatters by 0.3 %)
    with pytest.raises(ValueError, match="it was identified at, 250"):
        NoiseGenerator(str(profile), rate_hz=300.0)
    with pytest.raises(ValueError, match="BMG160 offers"):
        NoiseGenerator(str(profile), rate_hz=250.0, mode="paper")


def test_identify_sizes_its_verdict_by_samples_not_by_the_clock(recording, capsys, tmp_path,
                                                                 monkeypatch):
    # the number of emulated records follows from the record's length alone, so the same
    # record gives the same verdict (and the same JSON) on a fast host and a loaded one
    from bmg160_emu.commands import identify

    _, path = recording
    samples = 120_000
    profile = tmp_path / "p.toml"
    args = ["identify", str(path), "--rate", "100", "--profile-out", str(profile), "--json"]
    monkeypatch.setattr(identify, "VERDICT_SAMPLES", 6 * samples + samples // 2)
    assert main(args) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["verdict"]["seeds"] == 6
    assert "verdict over 6 emulated records" in captured.err
    monkeypatch.setattr(identify, "VERDICT_SAMPLES", 4 * samples)  # under the 5 it needs
    assert main(args) == 0
    captured = capsys.readouterr()
    assert "verdict" not in json.loads(captured.out)
    assert "no verdict: 5 emulated records of 120,000 samples" in captured.err
