"""Boot a guest beside the back ends, run commands in it, collect what they left.

The back ends (virtio-i2c for the chips, virtio-gpio for their INT1/INT2 lines) run in
this process, on a thread: the caller keeps the chips and the bus, so a test can read the
transaction log and install faults on the same ``I2CBus`` the guest's kernel talks to.
The guest runs :mod:`.agent`, which executes the commands dropped into the results folder;
one boot serves many commands (linux-kernel-notes.md: a boot is about 6 s under QEMU TCG,
about 0.3 s under user-mode Linux).
"""

from __future__ import annotations

import os
import shlex
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bmg160_emu.linux.guest.engine import Boot, Engine

AGENT = Path(__file__).resolve().parent / "agent.py"
PACKAGE_ROOT = Path(__file__).resolve().parents[3]  # the folder holding bmg160_emu


class GuestDied(RuntimeError):
    """The guest powered off or crashed while a command was pending."""


@dataclass(frozen=True)
class CommandResult:
    """One command run in the guest."""

    command: str
    returncode: int
    stdout: str
    stderr: str
    seconds: float


class Backend:
    """The chips' vhost-user back ends in this process, served on a thread."""

    def __init__(self, chips: Mapping[int, Any], sockets: Path, gpio: bool = True,
                 clock: Any = None, bus_number: int = 0) -> None:
        from bmg160_emu.bus.i2c import I2CBus
        from bmg160_emu.linux.vhost_user_server import Server
        from bmg160_emu.linux.virtio_gpio import VirtioGPIODevice
        from bmg160_emu.linux.virtio_i2c import VirtioI2CDevice

        self.chips = dict(chips)
        self.bus = I2CBus(bus_number, self.chips)
        self.i2c = VirtioI2CDevice(self.bus)
        self.gpio = (VirtioGPIODevice(self.chips, self.i2c.rate_reads, clock,
                                      self.i2c.guest_took_rate_read) if gpio else None)
        sockets.mkdir(mode=0o700, parents=True, exist_ok=True)
        self.i2c_socket = sockets / "i2c.sock"
        self.gpio_socket = sockets / "gpio.sock" if gpio else None
        self.server = Server()
        self.server.add(os.fspath(self.i2c_socket), self.i2c)
        if self.gpio is not None and self.gpio_socket is not None:
            self.server.add(os.fspath(self.gpio_socket), self.gpio)
            self.server.pollers.append(self.gpio.poll)
            gpio_device = self.gpio
            self.gpio.wake = lambda at_s: self.server.schedule(gpio_device.poll, at_s)
            self.i2c.after_transfer.insert(0, self.gpio.after_transfer)
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._serve, name="bmg160-backend", daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            self.server.run()
        except Exception as exc:  # noqa: BLE001 (kept for the caller; the guest sees a dead device)
            self.error = exc

    def line_of(self, address: int, pin: int = 1) -> int:
        """The virtio-gpio line of a chip's INT1 (pin 1) or INT2: 2i + pin - 1 for the i-th
        chip by address (bmg160-emu vhost-user-i2c's numbering)."""
        return 2 * sorted(self.chips).index(address) + pin - 1

    def close(self) -> None:
        self.server.stop()
        self.thread.join(timeout=10)
        self.server.close()


class Guest:
    """One booted guest running the agent, with the back ends beside it."""

    def __init__(self, engine: Engine, work: Path, backend: Backend | None = None,
                 modules: Sequence[str | Path] = (), environment: Mapping[str, str] = {},
                 memory_mb: int = 512, cpus: int = 1, host_root_readonly: bool = True,
                 results: Path | None = None) -> None:
        self.engine = engine
        self.work = work
        self.backend = backend
        self.results = (work / "results" if results is None else results).resolve()
        self.agent_dir = self.results / ".agent"
        self.console_path = work / "console.txt"
        self.count = 0
        self.process: subprocess.Popen[bytes] | None = None
        self._console: list[bytes] = []
        script = work / "boot.sh"
        script.write_text(
            "cd /\n"
            f"exec \"$BMG160_PY\" -I -S {shlex.quote(str(AGENT))} \"$BMG160_RESULTS/.agent\"\n")
        self.boot = Boot(
            script=script, results=self.results,
            i2c_socket=backend.i2c_socket if backend else None,
            gpio_socket=backend.gpio_socket if backend else None,
            host_root_readonly=host_root_readonly,
            environment={"BMG160_PY": sys.executable, "PYTHONPATH": str(PACKAGE_ROOT),
                         **environment},
            modules=tuple(modules), memory_mb=memory_mb, cpus=cpus)

    def start(self, timeout_s: float = 300.0) -> float:
        """Boot and wait for the agent; the seconds it took."""
        started = time.monotonic()
        self.agent_dir.mkdir(parents=True, exist_ok=True)
        self.process = self.engine.start(self.boot)
        reader = threading.Thread(target=self._read_console, daemon=True)
        reader.start()
        while not (self.agent_dir / "ready").exists():
            if self.process.poll() is not None:
                raise GuestDied(f"the guest ended before its agent started:\n{self.console()}")
            if time.monotonic() - started > timeout_s:
                self.kill()
                raise GuestDied(f"no agent after {timeout_s:g} s:\n{self.console()}")
            time.sleep(0.01)
        return time.monotonic() - started

    def _read_console(self) -> None:
        assert self.process is not None and self.process.stdout is not None
        for line in iter(self.process.stdout.readline, b""):
            self._console.append(line)

    def console(self) -> str:
        return b"".join(self._console).decode("utf-8", "replace").replace("\r\n", "\n")

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    def run(self, command: str, timeout_s: float = 120.0, cwd: Path | None = None,
            check: bool = False) -> CommandResult:
        """Run ``command`` with /bin/sh in the guest (in ``cwd``, the host's current folder
        unless given) and wait for its end."""
        if not self.alive:
            raise GuestDied("the guest is not running")
        self.count += 1
        stem = self.agent_dir / str(self.count)
        folder = Path.cwd() if cwd is None else cwd
        partial = stem.with_suffix(".tmp")
        partial.write_text(f"cd {shlex.quote(str(folder))} 2>/dev/null || cd /\n{command}\n")
        partial.rename(stem.with_suffix(".sh"))
        started = time.monotonic()
        rc_path = stem.with_suffix(".rc")
        while not rc_path.exists():
            if not self.alive:
                raise GuestDied(f"the guest died running {command!r}:\n{self.console()[-4000:]}")
            if time.monotonic() - started > timeout_s:
                self.kill()
                raise GuestDied(f"{command!r} took over {timeout_s:g} s; the guest was killed")
            # short commands answer within milliseconds; a long one need not be polled
            # often (each poll takes the GIL the back-end thread serves the guest with)
            time.sleep(min(0.02, 0.001 + (time.monotonic() - started) / 20))
        result = CommandResult(
            command, int(rc_path.read_text() or "-1"),
            stem.with_suffix(".out").read_text(errors="replace"),
            stem.with_suffix(".err").read_text(errors="replace"),
            time.monotonic() - started)
        if check and result.returncode:
            raise AssertionError(f"{command!r} exited with {result.returncode}:\n"
                                 f"{result.stdout}{result.stderr}")
        return result

    def kill(self) -> None:
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
            self.process.wait()

    def close(self, timeout_s: float = 30.0) -> str:
        """Stop the agent (the guest powers off), kill it if it does not; the console."""
        if self.alive:
            (self.agent_dir / "stop").write_text("stop\n")
            assert self.process is not None
            try:
                self.process.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                self.kill()
        console = self.console()
        self.console_path.write_text(console)
        return console


def temporary_work() -> Path:
    """A private folder for one guest's sockets, script and results (short paths: a
    UNIX socket's path has at most 107 bytes). Not under /dev: a guest mounts its own
    /dev over the host's."""
    return Path(tempfile.mkdtemp(prefix="bmg160-guest-"))


@dataclass(frozen=True)
class ScriptRun:
    """A guest booted for one script: its exit status (None if it never said), console."""

    returncode: int | None
    console: str
    timed_out: bool


def run_script(engine: Engine, boot: Boot, timeout_s: float = 300.0,
               console_log: Path | None = None) -> ScriptRun:
    """Boot, run ``boot.script`` to its end, always end the guest; no agent."""
    process = engine.start(boot)
    timed_out = False
    try:
        output, _ = process.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        timed_out = True
        process.kill()
        output, _ = process.communicate()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    console = output.decode("utf-8", "replace").replace("\r\n", "\n")
    if console_log is not None:
        console_log.write_text(console)
    status = boot.results / "exit-status"
    returncode = int(status.read_text()) if status.exists() else None
    return ScriptRun(returncode, console, timed_out)
