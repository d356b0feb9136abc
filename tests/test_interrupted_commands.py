"""SIGINT and SIGTERM stop a command within a second with a message and the documented exit
status (130, 143), and leave no partial output file (bmg160_emu.io.atomic)."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest


def _start(args, tmp_path):
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
    # wait until the progress bar shows a finished run (each takes 0.05-2 s here)
    seen = ""
    deadline = time.monotonic() + 60
    while "/100000" not in seen.replace(" 0/100000", "") and time.monotonic() < deadline:
        seen += session.stderr.read(1)
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
