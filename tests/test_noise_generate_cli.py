"""`bmg160-emu generate`: streams seeded noise to .npy / .csv, clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from bmg160_emu.cli import main
from bmg160_emu.commands import generate as generate_command
from bmg160_emu.commands.generate import parse_duration
from bmg160_emu.noise import NoiseGenerator


@pytest.mark.parametrize(
    ("text", "seconds"),
    [("10s", 10), ("5min", 300), ("2h", 7200), ("1d", 86400), ("250ms", 0.25), ("1.5", 1.5)],
)
def test_durations(text, seconds):
    assert parse_duration(text) == pytest.approx(seconds)


def test_npy_output_is_the_generator_stream_written_in_chunks(tmp_path, monkeypatch):
    monkeypatch.setattr(generate_command, "CHUNK_SAMPLES", 1000)  # force many chunks
    out = tmp_path / "noise.npy"
    assert (
        main(["generate", "--rate", "400", "--duration", "10s", "--seed", "1", "-o", str(out)]) == 0
    )
    data = np.load(out)
    assert data.shape == (4000, 3)
    assert np.array_equal(data, NoiseGenerator("paper", rate_hz=400.0, seed=1).generate(4000))


def test_csv_output_has_time_and_reads_back(tmp_path):
    out = tmp_path / "noise.csv"
    args = ["generate", "--profile", "datasheet", "--rate", "100", "--duration", "2s"]
    assert main(args + ["--seed", "2", "--noise-mode", "physical", "-o", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert lines[0].startswith("# bmg160-emu generate: profile=datasheet mode=physical")
    assert lines[1] == "t_s,x_dps,y_dps,z_dps"
    table = np.loadtxt(out, delimiter=",", skiprows=2)
    np.testing.assert_allclose(table[:, 0], np.arange(1, 201) / 100.0)
    expected = NoiseGenerator("datasheet", rate_hz=100.0, seed=2).generate(200)
    np.testing.assert_allclose(table[:, 1:], expected, rtol=1e-9, atol=1e-12)  # %.10g text


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--duration", "soon"], "not a duration"),
        (["--duration", "0s"], "must be positive"),
        (["--duration", "1s", "--rate", "250"], "unsupported output data rate 250"),
        (["--duration", "1s", "--profile", "nope"], "unknown noise profile 'nope'"),
        (["--duration", "1s", "--profile", "datasheet", "--noise-mode", "paper"], "paper mode needs"),
        (["--duration", "1ms"], "shorter than one sample period"),
    ],
)
def test_bad_arguments_are_one_line_errors(tmp_path, capsys, extra, message):
    status = main(["generate", *extra, "-o", str(tmp_path / "n.npy")])
    err = capsys.readouterr().err
    assert status == 2
    assert len(err.strip().splitlines()) == 1
    assert "Traceback" not in err
    import re

    assert re.search(message, err)


def test_unknown_output_suffix_is_an_error(tmp_path, capsys):
    assert main(["generate", "--duration", "1s", "-o", str(tmp_path / "n.txt")]) == 2
    assert "must end in .npy, .csv or .resd" in capsys.readouterr().err


def test_progress_only_on_a_terminal_unless_asked_for(tmp_path, capsys):
    # the terminal line itself is tested in virtual time (tests/test_progress.py)
    out = str(tmp_path / "n.npy")
    assert main(["generate", "--duration", "10s", "--seed", "1", "-o", out]) == 0
    assert "sample" not in capsys.readouterr().err
    assert main(["generate", "--duration", "10s", "--seed", "1", "-o", out, "--progress"]) == 0
    assert "bmg160-emu generate: 2,000/2,000 samples (100 %)" in capsys.readouterr().err


def test_the_old_spelling_of_noise_mode_still_works_and_says_the_new_one(tmp_path, capsys):
    # generate said --mode where eight other commands say --noise-mode (issue 35); the old
    # spelling stays for one release, hidden from the help
    old, new = tmp_path / "old.npy", tmp_path / "new.npy"
    args = ["generate", "--duration", "2s", "--seed", "5", "--profile", "paper"]
    assert main(args + ["--mode", "paper", "-o", str(old)]) == 0
    assert "--mode is now spelled --noise-mode" in capsys.readouterr().err
    assert main(args + ["--noise-mode", "paper", "-o", str(new)]) == 0
    assert old.read_bytes() == new.read_bytes()
    from bmg160_emu.cli import build_parser

    with pytest.raises(SystemExit):
        build_parser().parse_args(["generate", "--help"])
    assert "--mode " not in capsys.readouterr().out


def test_without_seed_a_random_seed_is_named_and_repeats_the_record(tmp_path, capsys):
    first, again = tmp_path / "a.csv", tmp_path / "b.csv"
    assert main(["generate", "--duration", "1s", "-o", str(first)]) == 0
    header = first.read_text().splitlines()[0]
    seed = int(header.split("seed=")[1].split()[0])
    assert f"seed {seed}" in capsys.readouterr().err
    assert main(["generate", "--duration", "1s", "--seed", str(seed), "-o", str(again)]) == 0
    assert again.read_text() == first.read_text()


def test_negative_seed_is_named_in_the_error(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:  # a usage error now: the seed's range is limits.SEED
        main(["generate", "--duration", "1s", "--seed=-1", "-o", str(tmp_path / "n.npy")])
    assert exc.value.code == 2
    assert "argument --seed: seed must be an integer from 0" in capsys.readouterr().err


def test_generate_reports_what_it_wrote(tmp_path, capsys):
    out = tmp_path / "n.npy"
    assert main(["generate", "--rate", "400", "--duration", "2s", "--seed", "4", "-o",
                 str(out)]) == 0
    report = capsys.readouterr().out.strip()
    samples = np.load(out).shape[0]
    assert report == (f"wrote {out}: {samples:,} samples x 3 axes, deg/s, at 400 Hz (2 s); "
                      "profile paper, physical mode, seed 4")
    assert samples == 800
