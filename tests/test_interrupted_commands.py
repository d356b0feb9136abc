"""SIGINT and SIGTERM stop a command within a second with a message and the documented exit
status (130, 143), and leave no partial output file (bmg160_emu.io.atomic)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest


def _start(args, tmp_path):
    # SIGINT at its default in the child, also when pytest runs as a background job
    from _fuzz_signals import sigint_not_ignored

    with sigint_not_ignored():
        return subprocess.Popen([sys.executable, "-m", "bmg160_emu", *args],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize(("number", "status", "name"),
                         [(signal.SIGTERM, 143, "SIGTERM"), (signal.SIGINT, 130, "SIGINT")])
def test_a_long_monte_carlo_stops_on_a_signal_and_keeps_its_finished_runs(
        tmp_path, number, status, name):
    scenario = tmp_path / "s.toml"
    scenario.write_text('duration_s = 2.0\n[[motion]]\nkind = "constant"\nrate_dps = [0, 1, 0]\n'
                        '[readout]\ngrid_s = 0.5\n')
    session = _start(["montecarlo", str(scenario), "--runs", "100000", "--scheduler", "sync",
                      "--output", str(tmp_path / "curves.json"), "--progress"], tmp_path)
    # wait until the progress line shows a finished run (each takes 0.05-2 s here; off a
    # terminal --progress writes a line when the first run is done)
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = session.stderr.readline()
        if "/100,000 runs" in line or not line:
            break
    session.send_signal(number)
    sent = time.monotonic()
    _, err = session.communicate(timeout=30)
    assert time.monotonic() - sent < 10  # stops after the run under way (<= 2 s loaded)
    assert session.returncode == status
    assert f"interrupted by {name} after" in err and "curves.json" in err
    import json

    data = json.loads((tmp_path / "curves.json").read_text())
    assert data["interrupted"] is True and 0 < len(data["seeds"]) < 100000
    assert [p.name for p in tmp_path.iterdir() if ".part" in p.name] == []


@pytest.mark.parametrize("suffix", [".npy", ".csv", ".resd"])
def test_an_interrupted_generate_leaves_an_honest_shorter_record(tmp_path, monkeypatch, suffix,
                                                                 capsys):
    # ^C after two chunks: the file holds exactly the samples written, and says so (the .npy
    # shape; the CSV header's samples= and a last comment; the RESD block's size rewritten);
    # it loads as a shorter record
    import numpy as np

    from bmg160_emu.cli import main
    from bmg160_emu.commands import generate
    from bmg160_emu.io.rates import load_rate_record

    real_chunks = generate._chunks

    def two_then_stop(gen, total, bar):
        for i, item in enumerate(real_chunks(gen, total, bar)):
            if i == 2:
                raise KeyboardInterrupt
            yield item

    monkeypatch.setattr(generate, "_chunks", two_then_stop)
    out = tmp_path / f"noise{suffix}"
    assert main(["generate", "--duration", "1h", "--seed", "3", "-o", str(out)]) == 130
    err = capsys.readouterr().err
    written = 2 * generate.CHUNK_SAMPLES
    assert f"interrupted by SIGINT after {written:,} of 720,000 samples" in err
    record = load_rate_record(out, rate_hz=200.0 if suffix == ".npy" else None)
    assert record.rate_dps.shape == (written, 3)
    if suffix == ".csv":
        text = out.read_text()
        assert f"samples={written}" in text.splitlines()[0].split()
        assert text.rstrip().endswith(f"# interrupted after {written} of 720000 samples")
    elif suffix == ".npy":
        assert np.load(out).shape == (written, 3)
    else:  # 45-byte header (docs/resd.md), then 12 bytes a sample: nothing after the last
        assert out.stat().st_size == 45 + 12 * written
    # the same samples as an uninterrupted run
    monkeypatch.setattr(generate, "_chunks", real_chunks)
    full = tmp_path / f"full{suffix}"
    assert main(["generate", "--duration", "1h", "--seed", "3", "-o", str(full)]) == 0
    whole = load_rate_record(full, rate_hz=200.0 if suffix == ".npy" else None).rate_dps
    assert np.array_equal(whole[:written], record.rate_dps)
    assert [p.name for p in tmp_path.iterdir() if ".part" in p.name] == []


def test_generate_stopped_by_sigterm_within_a_second(tmp_path):
    out = tmp_path / "day.npy"
    session = _start(["generate", "--duration", "1d", "--seed", "1", "-o", str(out)], tmp_path)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".day.npy.*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.0)  # some samples in
    session.send_signal(signal.SIGTERM)
    sent = time.monotonic()
    _, err = session.communicate(timeout=30)
    assert time.monotonic() - sent < 5  # a chunk is ~0.1 s: it stops at once (5 s for load)
    assert session.returncode == 143 and "interrupted by SIGTERM after" in err
    import numpy as np

    data = np.load(out)
    assert 0 < data.shape[0] < 17_280_000 and data.shape[1] == 3


@pytest.mark.parametrize("suffix", [".csv", ".npz"])
def test_an_interrupted_record_keeps_the_samples_so_far(tmp_path, monkeypatch, suffix, capsys):
    # record used to leave no file at all: every sample lost
    from bmg160_emu.cli import main
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.io.recording import read_recording

    reads = {"n": 0}
    real_read = BMG160.read

    def read_then_stop(self, reg, n=1):
        reads["n"] += 1
        if reads["n"] == 1001:
            raise KeyboardInterrupt
        return real_read(self, reg, n)

    monkeypatch.setattr(BMG160, "read", read_then_stop)
    out = tmp_path / f"rec{suffix}"
    assert main(["record", "--duration", "60s", "--rate", "200", "--seed", "4",
                 "-o", str(out)]) == 130
    assert "interrupted by SIGINT after 1,000 of 12,000 samples" in capsys.readouterr().err
    rec = read_recording(out)
    assert len(rec) == 1000 and rec.metadata["interrupted"] is True
    assert rec.metadata["samples_planned"] == 12000
    assert [p.name for p in tmp_path.iterdir() if ".part" in p.name] == []
