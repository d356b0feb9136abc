"""``bmg160-emu serve`` as a command: one trace per client that replays, a client cut off in
the middle of a message ends in one line and loses no transfer, errors are one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bmg160_emu.device.registers import address_of
from bmg160_emu.serve import protocol as p
from bmg160_emu.serve.client import ServeClient

CHIP_ID, RATE_X_LSB, BW = address_of("CHIP_ID"), address_of("RATE_X_LSB"), address_of("BW")
MS = 1_000_000


def start(tmp_path: Path, *options: str) -> tuple[subprocess.Popen, str]:
    folder = tmp_path / "sock"
    folder.mkdir(mode=0o700)
    path = str(folder / "s.sock")
    ready = tmp_path / "ready"
    proc = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "serve", "--socket", path, "--ready-file",
         str(ready), "--duration", "60", *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not ready.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"serve did not start: {proc.communicate()[1]}")
        time.sleep(0.05)
    return proc, path


def stop(proc: subprocess.Popen) -> tuple[str, int]:
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    return err, proc.returncode


def test_a_client_cut_off_inside_a_message_loses_no_transfer(tmp_path):
    trace = tmp_path / "zephyr.jsonl"
    stats = tmp_path / "stats.json"
    proc, path = start(tmp_path, "--seed", "3", "--bandwidth", "5", "--true-rate", "1", "2",
                       "3", "--trace", str(trace), "--stats", str(stats))
    first = ServeClient(path, "first")
    first.greet()
    for k in range(3):
        assert first.write_read(0x68, RATE_X_LSB, 6, (50 + 10 * k) * MS).status == 0
    first.sock.sendall(p.pack(p.I2C, 99, 90 * MS, b"\x00" * 8)[:10])  # half a header
    first.close()
    second = ServeClient(path, "second")
    second.greet()
    assert second.write_read(0x68, CHIP_ID, 1, MS).data == b"\x0f"
    assert second.bye(2 * MS).status == 0
    err, code = stop(proc)
    assert code == 0
    lines = err.splitlines()
    assert lines[0] == ("bmg160-emu serve: client 1 (first): disconnected inside a message "
                        "(10 of its 20 bytes); the transfers before it stand; connection closed")
    assert lines[1:] == ["bmg160-emu serve: 2 client(s), 5 requests"]
    kept = trace.read_text().splitlines()
    assert len(kept) == 1 + 3 + 1 and json.loads(kept[-1])["transactions"] == 3
    second_trace = tmp_path / "zephyr.2.jsonl"
    assert json.loads(second_trace.read_text().splitlines()[-1])["transactions"] == 1
    report = json.loads(stats.read_text())
    assert [s["client"] for s in report["sessions"]] == ["first", "second"]
    assert report["sessions"][0]["requests"] == {"I2C": 3}
    # the served session replays, byte for byte, on fresh chips from the trace's header
    replay = subprocess.run([sys.executable, "-m", "bmg160_emu", "trace", str(trace),
                             "--replay"], capture_output=True, text=True, timeout=120,
                            check=False)
    assert replay.returncode == 0, replay.stderr
    assert "no divergence: 3 transactions replayed" in replay.stdout


def test_a_socket_in_a_folder_open_to_others_is_one_line(tmp_path):
    folder = tmp_path / "open"
    folder.mkdir()
    os.chmod(folder, 0o777)
    done = subprocess.run([sys.executable, "-m", "bmg160_emu", "serve", "--socket",
                           str(folder / "s.sock"), "--duration", "1"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode != 0
    assert done.stderr.count("\n") == 1 and "is open to other users" in done.stderr


def test_a_device_on_another_bus_is_one_line(tmp_path):
    folder = tmp_path / "sock"
    folder.mkdir(mode=0o700)
    done = subprocess.run([sys.executable, "-m", "bmg160_emu", "serve", "--socket",
                           str(folder / "s.sock"), "--device", "bmg160@0x69:1"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode != 0
    assert done.stderr.count("\n") == 1 and "one I2C bus" in done.stderr
