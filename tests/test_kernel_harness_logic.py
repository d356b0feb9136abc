"""The guest harness without a kernel (no ``kernel`` marker): the engine registry and its
missing-package lines, QEMU's command line for a Boot, the agent (agent.c, built here) and
its protocol over a stand-in engine that runs it on this host with named pipes for its
channel, the orphan guard, driver load order and binding."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bmg160_emu.linux.guest import agent, drivers
from bmg160_emu.linux.guest.engine import Boot, EngineError, choose, default_engine, engines
from bmg160_emu.linux.guest.harness import Guest, GuestDied
from bmg160_emu.linux.guest.qemu import QemuEngine

needs_gcc = pytest.mark.skipif(bool(agent.missing()), reason="; ".join(agent.missing()))


class Fake:
    def __init__(self, name: str, missing: list[str]) -> None:
        self.name, self._missing = name, missing

    def missing(self) -> list[str]:
        return self._missing


class LocalEngine:
    """Runs the agent on this host as a guest would, its channel two named pipes (``agent
    serve FOLDER fifo fifo``): the harness's protocol, without a kernel."""

    name = "local"

    def missing(self) -> list[str]:
        return []

    def prepare(self, progress) -> None:
        pass

    def start(self, boot: Boot) -> subprocess.Popen[bytes]:
        assert boot.agent is not None
        env = {**os.environ, **boot.environment, "BMG160_RESULTS": str(boot.results)}
        return subprocess.Popen(agent.guarded([str(agent.binary()), "serve", *boot.agent.words]),
                                env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


def test_qemu_is_registered_and_the_first_ready_engine_is_the_default():
    assert "qemu" in engines()
    fakes = {"uml": Fake("uml", ["ptrace is refused"]), "qemu": Fake("qemu", [])}
    assert default_engine(fakes) is fakes["qemu"]
    assert default_engine({"uml": Fake("uml", ["x"])}) is None


def test_unknown_and_unready_engines_are_one_line_errors(monkeypatch):
    with pytest.raises(EngineError, match="unknown engine 'bochs'"):
        choose("bochs")
    monkeypatch.setenv("PATH", "/nonexistent")
    with pytest.raises(EngineError, match=r"qemu-system-x86_64 is missing \(Debian package "
                                          r"qemu-system-x86\)"):
        choose("qemu")


def test_a_host_without_the_tools_is_told_the_debian_packages(monkeypatch):
    monkeypatch.setenv("PATH", "/nonexistent")
    lines = QemuEngine().missing()
    packages = {line.rsplit("(Debian package ", 1)[1].rstrip(")") for line in lines}
    assert {"qemu-system-x86", "busybox-static", "make", "gcc", "patch", "xz-utils",
            "kmod"} <= packages, lines


def test_qemu_command_line_for_a_boot(tmp_path, monkeypatch):
    from bmg160_emu.linux.guest import qemu

    if qemu.find_kernel() is None or qemu.bundled_dir() is None:
        pytest.skip("no prepared QEMU guest in the cache (bmg160-emu kernel prepare)")
    boot = Boot(script=tmp_path / "s.sh", results=tmp_path / "r", i2c_socket=tmp_path / "i",
                gpio_socket=tmp_path / "g", environment={"SEED": "7"},
                modules=("bmg160_i2c", tmp_path / "my.ko"), memory_mb=256)
    command = QemuEngine().command(boot)
    append = command[command.index("-append") + 1].split()
    assert "SEED=7" in append and f"guest_modules=bmg160_i2c,{tmp_path / 'my.ko'}" in append
    assert any(w.startswith("guest_vio=") for w in append)
    assert any("readonly=on" in w for w in command)
    assert "memory-backend-memfd,id=mem,size=256M,share=on" in command
    assert "vhost-user-gpio-pci,chardev=vgpio" in command
    rw = QemuEngine().command(Boot(script=boot.script, results=boot.results,
                                   host_root_readonly=False))
    assert any("readonly=off" in w for w in rw) and "guest_rw=1" in rw[rw.index("-append") + 1]
    with pytest.raises(EngineError, match="neither may hold spaces"):
        QemuEngine().command(Boot(script=boot.script, results=boot.results,
                                  environment={"NAME": "two words"}))


@needs_gcc
def test_guest_runs_commands_through_the_agent_and_reports_a_death(tmp_path):
    guest = Guest(LocalEngine(), tmp_path)
    guest.start(timeout_s=30)
    first = guest.run("echo out; echo err >&2; exit 3")
    assert (first.returncode, first.stdout, first.stderr) == (3, "out\n", "err\n")
    assert guest.run("pwd", cwd=tmp_path).stdout.strip() == str(tmp_path)
    with pytest.raises(AssertionError, match="exited with 1"):
        guest.run("false", check=True)
    with pytest.raises(GuestDied, match="'sleep 5' took over 0.5 s"):
        guest.run("sleep 5", timeout_s=0.5)
    assert not guest.alive
    with pytest.raises(GuestDied):
        guest.run("true")


@needs_gcc
def test_the_agent_reads_writes_and_stops_a_batch_at_a_checked_failure(tmp_path):
    guest = Guest(LocalEngine(), tmp_path)
    guest.start(timeout_s=30)
    try:
        target = guest.agent_dir / "attr"
        replies = guest.call([agent.write(str(target), "0.000266\n"),
                              agent.read(str(target)),
                              agent.glob(str(guest.agent_dir / "at*")),
                              agent.read(str(tmp_path / "absent"), check=True),
                              agent.read(str(target))])
        assert [r.status for r in replies[:3]] == [0, 0, 0]
        assert replies[1].text == "0.000266\n"
        assert replies[2].text.split() == [str(target)]
        assert replies[3].error().startswith("ENOENT")
        assert replies[4].status == agent.SKIPPED  # after the checked failure
        # a wait for a path that never comes ends on its own, in the guest's time
        started = time.monotonic()
        late = guest.call([agent.wait(str(tmp_path / "never"), 0.2)])[0]
        assert late.error().startswith("ETIMEDOUT") and time.monotonic() - started < 10
        assert guest.read(str(target)) == "0.000266\n"
        with pytest.raises(OSError, match="ENOENT"):
            guest.read(str(tmp_path / "absent"))
    finally:
        guest.close(timeout_s=30)
    assert guest.process is not None and guest.process.returncode == 0


def test_the_wire_format_round_trips_and_a_stale_response_is_refused():
    ops = [agent.write("/sys/x", b"\n\x00binary\n"), agent.stop()]
    encoded = agent.encode(7, ops)
    assert encoded.startswith(b"BGQ1 7 2\nwrite 0 2\n6\n/sys/x\n9\n\n\x00binary\n\n")
    response = b"BGR1 7 2\n0 1\n3\na\nb\n22 0\n"
    replies = agent.decode(response, 7)
    assert replies[0] == agent.Reply(0, [b"a\nb"]) and replies[1].status == 22
    with pytest.raises(agent.ProtocolError, match="does not answer request 8"):
        agent.decode(response, 8)
    with pytest.raises(agent.ProtocolError, match="holds 1 of 2 replies"):
        agent.decode(b"BGR1 7 2\n0 0\n", 7)  # the agent stopped at a record it could not read


@needs_gcc
def test_a_guest_that_stops_ends_cleanly(tmp_path):
    guest = Guest(LocalEngine(), tmp_path)
    guest.start(timeout_s=30)
    guest.close(timeout_s=30)
    assert guest.process is not None and guest.process.returncode == 0


@needs_gcc
def test_the_orphan_guard_ends_the_group_with_the_command_and_with_its_parent(tmp_path):
    marker = tmp_path / "alive"
    # a helper the command leaves behind (as UML leaves its helper processes) is ended
    # with it: the console pipe reaches its end at once
    left = subprocess.run(agent.guarded(["sh", "-c", f"(sleep 30; touch {marker}) & exit 3"]),
                          capture_output=True, timeout=20, check=False)
    assert left.returncode == 3
    # the harness that started it dies: the guard ends the command's whole group
    script = ("import subprocess, sys, time; from bmg160_emu.linux.guest import agent; "
              f"subprocess.Popen(agent.guarded(['sh', '-c', 'sleep 30; touch {marker}']));"
              "time.sleep(0.3)")
    subprocess.run([sys.executable, "-c", script], timeout=30, check=True)
    # SIGTERM ignored: SIGKILL follows the guard's grace
    stubborn = subprocess.Popen(agent.guarded(["sh", "-c", "trap '' TERM; sleep 30"]))
    time.sleep(0.3)
    stubborn.send_signal(signal.SIGTERM)
    assert stubborn.wait(timeout=20) == 128 + signal.SIGKILL
    time.sleep(0.5)
    assert not marker.exists()
    assert not subprocess.run(["pgrep", "-f", f"touch {marker}"], capture_output=True,
                              check=False).stdout


def test_modules_load_after_their_dependencies(monkeypatch, tmp_path):
    depends = {"bmg160_i2c": ["bmg160_core", "regmap-i2c"],
               "bmg160_core": ["industrialio", "industrialio-triggered-buffer"]}
    aliases = {"bmg160_i2c": ["i2c:bmi088_gyro", "i2c:bmi055_gyro", "i2c:bmg160"],
               "bmg160_core": []}
    monkeypatch.setattr(drivers, "_modinfo", lambda ko, field: (
        depends if field == "depends" else aliases)[ko.stem])
    kos = [tmp_path / "bmg160_i2c.ko", tmp_path / "bmg160_core.ko"]
    assert drivers.load_order(kos) == ["regmap_i2c", "industrialio",
                                       "industrialio_triggered_buffer", *reversed(kos)]
    assert drivers.driver_name(kos) == "bmg160"  # the table's first entry (listed last)
    assert drivers.driver_name(kos, prefer=["bmi055_gyro"]) == "bmi055_gyro"


def test_binding_with_and_without_the_irq():
    plain = drivers.bind_ops("gyro_chipid", [0x68], bus=3)
    assert [(op.name, op.fields) for op in plain] == [
        ("write", ("/sys/bus/i2c/devices/i2c-3/new_device", "gyro_chipid 0x68\n")),
        ("wait", ("/sys/bus/i2c/devices/3-0068/driver", "5000000000"))]
    board = drivers.bind_ops("bmg160", [0x68, 0x69], 0, [0, 2], Path("/b/bmg160-board.ko"),
                             gpio_base=506, kernel_driver=True)
    assert board[0] == agent.modprobe("i2c:bmg160", check=False)
    assert board[1] == agent.insmod("/b/bmg160-board.ko", "bus=0 gpio_base=506 "
                                    "addr=0x68,0x69 line=0,2 name=bmg160")
    assert [op.name for op in board[2:]] == ["wait", "wait"]
    assert drivers.unbind_ops([0x68], 0, board=True) == [agent.rmmod("bmg160_board")]
    failed = [agent.Reply(0), agent.Reply(0), agent.Reply(110), agent.Reply(agent.SKIPPED)]
    assert drivers.bind_failure(failed, board) == (
        "no driver bound (/sys/bus/i2c/devices/0-0068/driver did not appear)")
    assert drivers.bind_failure([agent.Reply(0)] * 4, board) is None


def test_assert_wrote_lists_the_writes_for_a_wrong_order_as_for_a_missing_one():
    from types import SimpleNamespace

    from bmg160_emu.bus.i2c import I2CBus
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.pytest_kernel import KernelTest

    bus = I2CBus(0, {0x68: BMG160(seed=1)})
    session = SimpleNamespace(guest=None, backend=SimpleNamespace(bus=bus, chips=bus.devices))
    test = KernelTest(session, (0x68,))
    bus.write_byte_data(0x68, 0x0F, 0x02)  # RANGE first, then BW: the wrong order below
    bus.write_byte_data(0x68, 0x10, 0x07)
    test.assert_wrote(RANGE=0x02, before="BW")
    writes = "its writes: 0x0f=0x02, 0x10=0x07"
    with pytest.raises(AssertionError, match=f"never wrote RANGE = 0x03; {writes}"):
        test.assert_wrote(RANGE=0x03)
    with pytest.raises(AssertionError, match=rf"BW = 0x07 was not written before RANGE "
                                             rf"\(written in the wrong order\); {writes}"):
        test.assert_wrote(BW=0x07, before="RANGE")
    with pytest.raises(AssertionError, match=rf"\(it never wrote LPM1\); {writes}"):
        test.assert_wrote(BW=0x07, before="LPM1")
