"""The guest harness without a kernel (no ``kernel`` marker): the engine registry and its
missing-package lines, QEMU's command line for a Boot, the agent protocol and Guest.run over
a stand-in engine that runs the boot script on this host, driver load order and binding."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bmg160_emu.linux.guest import drivers
from bmg160_emu.linux.guest.engine import Boot, EngineError, choose, default_engine, engines
from bmg160_emu.linux.guest.harness import Guest, GuestDied
from bmg160_emu.linux.guest.qemu import QemuEngine


class Fake:
    def __init__(self, name: str, missing: list[str]) -> None:
        self.name, self._missing = name, missing

    def missing(self) -> list[str]:
        return self._missing


class LocalEngine:
    """Runs the boot script on this host as the guest would (the agent included): the
    harness's protocol, without a kernel."""

    name = "local"

    def missing(self) -> list[str]:
        return []

    def prepare(self, progress) -> None:
        pass

    def start(self, boot: Boot) -> subprocess.Popen[bytes]:
        env = {**os.environ, **boot.environment, "BMG160_RESULTS": str(boot.results)}
        return subprocess.Popen(["/bin/sh", str(boot.script)], env=env,
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT)


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


def test_guest_runs_commands_through_the_agent_and_reports_a_death(tmp_path):
    guest = Guest(LocalEngine(), tmp_path)
    guest.start(timeout_s=30)
    first = guest.run("echo out; echo err >&2; exit 3")
    assert (first.returncode, first.stdout, first.stderr) == (3, "out\n", "err\n")
    assert guest.run("pwd", cwd=tmp_path).stdout.strip() == str(tmp_path)
    with pytest.raises(AssertionError, match="exited with 1"):
        guest.run("false", check=True)
    with pytest.raises(GuestDied, match="took over"):
        guest.run("sleep 5", timeout_s=0.5)
    assert not guest.alive
    with pytest.raises(GuestDied):
        guest.run("true")


def test_a_guest_that_stops_ends_cleanly(tmp_path):
    guest = Guest(LocalEngine(), tmp_path)
    guest.start(timeout_s=30)
    guest.close(timeout_s=30)
    assert guest.process is not None and guest.process.returncode == 0


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
    plain = drivers.bind_command("gyro_chipid", [0x68])
    assert "echo gyro_chipid 0x68 > /sys/bus/i2c/devices/i2c-$GUEST_I2C_BUS/new_device" in plain
    assert "$GUEST_I2C_BUS-0068/driver" in plain and "modprobe" not in plain
    board = drivers.bind_command("bmg160", [0x68, 0x69], [0, 2], Path("/b/bmg160-board.ko"),
                                 kernel_driver=True)
    assert "addr=0x68,0x69 line=0,2 name=bmg160" in board
    assert board.startswith("modprobe -q") and "i2c:bmg160" in board
    assert drivers.unbind_command([0x68], board=True) == "rmmod bmg160_board\n"


def test_the_agent_runs_as_a_script(tmp_path):
    folder = tmp_path / "agent"
    folder.mkdir()
    agent = subprocess.Popen([sys.executable, str(Path(drivers.__file__).parent / "agent.py"),
                              str(folder)])
    (folder / "1.tmp").write_text("echo hi\n")
    (folder / "1.tmp").rename(folder / "1.sh")
    for _ in range(500):
        if (folder / "1.rc").exists():
            break
        time.sleep(0.01)
    (folder / "stop").write_text("")
    assert agent.wait(timeout=10) == 0
    assert (folder / "1.out").read_text() == "hi\n" and (folder / "1.rc").read_text() == "0\n"
    assert (folder / "ready").exists()
