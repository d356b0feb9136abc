"""bmg160-emu watch: the private socket, the snapshots a session serves, the view drawn from
them, and the viewer driven in a real terminal (tmux) against a script run with --watch."""

from __future__ import annotations

import os
import shutil
import stat
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import pytest

from bmg160_emu import cli
from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import address_of
from bmg160_emu.watch.session import (
    WatchError,
    WatchServer,
    live_sockets,
    read_snapshots,
    socket_dir,
)

pytest.importorskip("rich")


@pytest.fixture
def runtime_dir(monkeypatch):
    # A short folder of its own: a Unix socket path holds at most 107 bytes, and pytest's
    # tmp_path can be longer than that with the socket's name added.
    folder = Path(tempfile.mkdtemp(prefix="bmgw", dir="/tmp"))
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(folder))
    yield folder
    shutil.rmtree(folder, ignore_errors=True)


def test_socket_directory_is_private_and_an_open_one_is_refused(runtime_dir):
    folder = socket_dir()
    assert folder == runtime_dir / "bmg160-emu"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    folder.chmod(0o755)
    with pytest.raises(WatchError, match="can be entered by other users .*755"):
        socket_dir()


def test_server_serves_registers_rates_and_traffic_on_a_user_only_socket(runtime_dir):
    chip = BMG160(seed=1, noise=False, true_rate=(10.0, -20.0, 30.0))
    bus = I2CBus(1, {0x68: chip})
    bus.write_byte_data(0x68, address_of("RANGE"), 0x01)  # +-1000 deg/s
    chip.advance(0.01)
    with WatchServer({0x68: chip}, [bus.log], title="test") as server:
        assert stat.S_IMODE(server.path.stat().st_mode) == 0o600
        assert live_sockets() == [server.path]
        snapshot = next(read_snapshots(server.path))
    assert not server.path.exists()  # removed when the session ends
    [view] = snapshot["chips"]
    assert view["name"] == "0x68" and view["registers"][address_of("CHIP_ID")] == 0x0F
    assert view["registers"][address_of("RANGE")] == 0x01
    # noise off: the rates are the true rates to one LSB of the +-1000 deg/s range
    assert view["rate_dps"] == pytest.approx([10.0, -20.0, 30.0], abs=1000 / 32768)
    assert snapshot["transactions"] == 1
    assert "write_byte_data reg 0x0f <- 01" in snapshot["last"][-1]


def test_view_highlights_a_changed_register_and_decodes_it():
    from rich.color import ColorSystem
    from rich.console import Console
    from rich.style import Style

    from bmg160_emu.watch.view import CHANGED, WatchView

    chip = BMG160(seed=1)
    bus = I2CBus(1, {0x68: chip})
    server = WatchServer({0x68: chip}, [bus.log], path=None)
    view = WatchView()
    view.update(server.snapshot(), now=100.0)
    bus.write_byte_data(0x68, address_of("RANGE"), 0x03)
    chip.advance(0.05)  # new samples: the RATE registers change too, but are not "changes"
    view.update(server.snapshot(), now=100.1)
    chip_view = view.chips["0x68"]
    assert list(chip_view.changes) == [address_of("RANGE")]
    console = Console(record=True, width=120, force_terminal=True, color_system="standard")
    console.print(view.render())
    text = console.export_text(clear=False)
    assert "RANGE = 0x03" in text and "±250 °/s" in text
    styled = console.export_text(styles=True)
    changed = Style.parse(CHANGED).render("0F RANGE         03", color_system=ColorSystem.STANDARD)
    assert changed in styled  # the changed register, highlighted
    assert "│ 10 BW            80" in styled  # an unchanged one, plain


def test_a_socket_path_too_long_for_unix_sockets_is_a_clear_error(runtime_dir):
    deep = runtime_dir / ("d" * 100)
    deep.mkdir(mode=0o700)
    with pytest.raises(WatchError, match="too long for a Unix socket .* at most 107"):
        WatchServer({}, path=deep / "x.sock")


def test_watch_without_a_session_says_how_to_start_one(runtime_dir, capsys):
    assert cli.main(["watch"]) == 2
    assert "no live session to watch: start one with --watch" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux not installed (.ci/setup.d/watch.sh)")
def test_viewer_in_a_real_terminal_shows_a_script_session(tmp_path, runtime_dir):
    # A script in real time long enough to watch: a RANGE change every 0.25 s.
    lines = ["read CHIP_ID == 0x0F", "write BGW_SOFTRESET 0xB6", "advance 30ms"]
    for i in range(60):
        lines += [f"write RANGE 0x0{i % 5}", "advance 250ms", "burst RATE_X_LSB 6"]
    script = tmp_path / "watched.script"
    script.write_text("\n".join(lines) + "\n")
    env = dict(os.environ, XDG_RUNTIME_DIR=str(runtime_dir), PYTHONUNBUFFERED="1")
    env.pop("TMUX", None)  # inside tmux, --watch would open a pane in the developer's window
    session = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "script", str(script), "--realtime", "--watch",
         "--seed", "3", "--quiet"],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=env,
    )  # fmt: skip
    name = f"bmg160-watch-test-{uuid.uuid4().hex[:8]}"
    try:
        announce = session.stderr.readline()  # printed once the socket listens
        assert "watch this session with: bmg160-emu watch --socket " in announce, announce
        socket_path = announce.rsplit(" ", 1)[1].strip()
        viewer = (f"{sys.executable} -m bmg160_emu watch --socket {socket_path}; "
                  "echo viewer-exit-status=$?; sleep 30")
        subprocess.run(
            ["tmux", "new-session", "-d", "-s", name, "-x", "120", "-y", "50", viewer],
            check=True, env=env,
        )  # fmt: skip
        screen = ""
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            time.sleep(0.5)
            screen = subprocess.run(
                ["tmux", "capture-pane", "-p", "-t", name], capture_output=True, text=True,
                check=True,
            ).stdout  # fmt: skip
            if "changed since reset" in screen and "RANGE = 0x0" in screen:
                break
        assert "BMG160 0x68" in screen, screen
        assert "00 CHIP_ID       0F" in screen, screen
        assert "tx/s" in screen and "last transactions" in screen, screen
        assert "write_byte_data reg 0x0f" in screen, screen
        assert "RANGE = 0x0" in screen, screen  # a change, decoded
        assert any(ch in screen for ch in "▁▂▃▄▅▆▇█"), screen  # the rate sparklines
        assert "INT1" in screen and "FIFO" in screen, screen
        assert "q quits the view" in screen, screen
        # q leaves the view: the viewer process exits with 0, the session goes on
        subprocess.run(["tmux", "send-keys", "-t", name, "q"], check=True)
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and "viewer-exit-status=" not in screen:
            time.sleep(0.2)
            screen = subprocess.run(
                ["tmux", "capture-pane", "-p", "-t", name], capture_output=True, text=True,
                check=True,
            ).stdout  # fmt: skip
        assert "viewer-exit-status=0" in screen, screen
        assert "left the view; the session goes on" in screen, screen
        assert session.poll() is None  # the watched script is still running
    finally:
        subprocess.run(["tmux", "kill-session", "-t", name], check=False, capture_output=True)
        session.kill()
        session.wait(timeout=10)


def _pty_keys():
    import pty

    main, secondary = pty.openpty()
    return os.fdopen(main, "wb", buffering=0), os.fdopen(secondary, "r")


def test_q_on_the_terminal_leaves_the_view_and_the_session_goes_on(runtime_dir):
    import io
    import threading

    from rich.console import Console

    from bmg160_emu.watch.view import run_viewer

    chip = BMG160(seed=1)
    press, keys = _pty_keys()
    out = io.StringIO()
    with press, keys, WatchServer({0x68: chip}, [], title="q test") as server:
        done = threading.Event()
        status = []
        viewer = threading.Thread(target=lambda: (status.append(run_viewer(
            server.path, Console(file=out, width=120), keys=keys)), done.set()), daemon=True)
        viewer.start()
        time.sleep(0.5)  # the view has drawn a snapshot or two
        assert not done.is_set()  # it would go on while the session does
        press.write(b"x")  # any other key does nothing
        time.sleep(0.3)
        assert not done.is_set()
        press.write(b"q")
        assert done.wait(5.0), "q did not end the viewer"
        assert server.path.exists()  # the session is untouched
    assert status == [0]
    text = out.getvalue()
    assert "BMG160 0x68" in text and "left the view; the session goes on" in text


def test_the_view_ends_when_the_session_does(runtime_dir):
    import io

    from rich.console import Console

    from bmg160_emu.watch.view import run_viewer

    server = WatchServer({0x68: BMG160(seed=1)}, [], title="short").start()
    import threading

    threading.Timer(0.5, server.stop).start()
    out = io.StringIO()
    assert run_viewer(server.path, Console(file=out, width=120), keys=io.StringIO()) == 0
    assert f"the session behind {server.path} ended" in out.getvalue()


def _umockdev_missing() -> str | None:
    try:
        from bmg160_emu.linux.umockdev import UMockdevUnavailable, load_umockdev, preload_available

        load_umockdev()
    except UMockdevUnavailable as exc:
        return str(exc)
    return None if preload_available() else "umockdev's preload library is missing"


PROGRAM = """\
import time
import smbus2
bus = smbus2.SMBus(1)
bus.write_byte_data(0x68, 0x0F, 0x02)
for _ in range(100):
    bus.read_byte_data(0x68, 0x00)
    time.sleep(0.05)
"""


@pytest.mark.umockdev
def test_run_watch_serves_an_unmodified_programs_session(runtime_dir):
    missing = _umockdev_missing()
    if missing:
        pytest.skip(f"umockdev route unavailable: {missing}")
    env = dict(os.environ, XDG_RUNTIME_DIR=str(runtime_dir), PYTHONUNBUFFERED="1")
    env.pop("TMUX", None)  # inside tmux, --watch would open a pane in the developer's window
    session = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "run", "--watch", "--seed", "1",  # no seed line
         "--", sys.executable, "-c", PROGRAM],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=env,
    )  # fmt: skip
    try:
        announce = session.stderr.readline()
        assert "watch this session with: bmg160-emu watch --socket " in announce, announce
        path = Path(announce.rsplit(" ", 1)[1].strip())
        assert stat.S_IMODE(path.stat().st_mode) == 0o600
        deadline = time.monotonic() + 60
        for snapshot in read_snapshots(path, timeout_s=10):
            if snapshot["transactions"] >= 10 or time.monotonic() > deadline:
                break
        [chip] = snapshot["chips"]
        assert snapshot["title"].startswith("run ") and snapshot["transactions"] >= 10
        assert chip["registers"][address_of("RANGE")] == 0x02  # the program's write
        assert "read_byte_data reg 0x00 -> 0f" in snapshot["last"][-1]
    finally:
        session.kill()
        session.wait(timeout=10)


def test_a_64_column_pane_shows_registers_rates_and_changes_stacked():
    # tmux splits a pane beside the session: 64 columns used to show every value as "..."
    from rich.console import Console

    from bmg160_emu.watch.view import WatchView

    chip = BMG160(seed=1, noise=False, true_rate=(10.0, -20.0, 30.0))
    bus = I2CBus(1, {0x68: chip})
    server = WatchServer({0x68: chip}, [bus.log], path=None)
    view = WatchView()
    bus.write_byte_data(0x68, address_of("RANGE"), 0x01)
    chip.advance(0.05)
    view.update(server.snapshot(), now=100.0)
    console = Console(record=True, width=64, force_terminal=True)
    console.print(view.render(console.width))
    lines = console.export_text().splitlines()
    assert max(len(line) for line in lines) <= 64
    text = "\n".join(lines)
    assert "0F RANGE         01" in text and "3E FIFO_CONFIG_1 00" in text  # both columns
    import re

    rates = [float(v) for v in re.findall(r"^│ [xyz] +([-+][\d.]+) °/s", text, re.MULTILINE)]
    # noise off: the true rates to one LSB of the +-1000 deg/s range
    assert rates == pytest.approx([10.0, -20.0, 30.0], abs=1000 / 32768)
    assert re.search(r"FIFO +\d+/100", text)
    assert "RANGE = 0x01: fixed=0 range=1 (±1000 °/s)" in text
    # the side column is under the registers, not squeezed beside them
    assert text.index("°/s") > text.index("1E FIFO_WM_EN")


def test_the_shipped_watch_example_runs_long_enough_to_attach_to(runtime_dir):
    example = Path(__file__).resolve().parent.parent / "examples" / "watch_session.py"
    env = {k: v for k, v in os.environ.items() if k != "TMUX"}  # no pane opened by the test
    session = subprocess.Popen([sys.executable, str(example), "--seconds", "6"], env=env,
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        line = session.stderr.readline()
        assert "watch this session with: bmg160-emu watch --socket" in line
        path = Path(line.split("--socket", 1)[1].strip())
        time.sleep(2.0)  # attached late, as a person opening a second terminal would be
        seen = []
        for snapshot in read_snapshots(path):
            [chip] = snapshot["chips"]
            seen.append((chip["time_s"], chip["registers"][address_of("RANGE")]))
            if len(seen) == 15:
                break
        assert seen[0][0] >= 2.0 and seen[-1][0] > seen[0][0]  # still live, in real time
        assert {range_code for _, range_code in seen} <= {0x02, 0x03}
    finally:
        session.terminate()
        session.wait(timeout=30)
