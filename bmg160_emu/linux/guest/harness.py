"""Boot a guest beside the back ends, send its agent requests, collect what they left.

The back ends (virtio-i2c for the chips, virtio-gpio for their INT1/INT2 lines and the
agent's two lines) run in this process, on a thread: the caller keeps the chips and the
bus, so a test can read the transaction log and install faults on the same ``I2CBus`` the
guest's kernel talks to. The guest runs the agent (:mod:`.agent`), which serves batches of
requests; one boot serves many (linux-kernel-notes.md: a boot is about 6 s under QEMU TCG,
a fraction of a second under user-mode Linux).

In virtual time (``Backend(time_travel=True)``, the uml engine) the back end is also the
guest's clock: UML runs under ``time-travel=ext`` with :class:`~bmg160_emu.linux.calendar.
Calendar` as its scheduler, the chips' ``VirtualClock`` is the calendar's time, and the
guest never waits on the host's clock (docs/kernel-engines.md, "Virtual time").
"""

from __future__ import annotations

import os
import select
import signal
import struct
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bmg160_emu.linux.guest import agent
from bmg160_emu.linux.guest.engine import AgentBoot, Boot, Engine

PACKAGE_ROOT = Path(__file__).resolve().parents[3]  # the folder holding bmg160_emu
KILL_GRACE_S = 5.0  # SIGTERM first (UML then kills its own processes), SIGKILL after this
RECORD_BYTES = 16  # an IIO buffer record of the bmg160 driver: three s16, padding, an s64


class GuestDied(RuntimeError):
    """The guest powered off or crashed while a request was pending."""


@dataclass(frozen=True)
class CommandResult:
    """One command run in the guest."""

    command: str
    returncode: int
    stdout: str
    stderr: str
    seconds: float


class Replies:
    """The replies the agent has given, counted on the back end's thread and waited for
    on the caller's (a condition variable: no polling)."""

    def __init__(self) -> None:
        self.count = 0
        self.changed = threading.Condition()

    def add(self) -> None:
        with self.changed:
            self.count += 1
            self.changed.notify_all()

    def wait_for(self, count: int, timeout_s: float, alive: Callable[[], bool]) -> bool:
        """Until ``count`` replies (True), the guest ends or ``timeout_s`` passes (False)."""
        end = time.monotonic() + timeout_s
        with self.changed:
            while self.count < count:
                left = end - time.monotonic()
                if left <= 0 or not alive():
                    return self.count >= count
                self.changed.wait(min(left, 0.5))  # (a guest that dies says so on its console)
        return True


class FifoChannel:
    """The agent's channel as two named pipes (``agent serve FOLDER fifo fifo``): the
    protocol on this host without a kernel, for the harness's own tests."""

    def __init__(self, folder: Path) -> None:
        self.replies = Replies()
        folder.mkdir(parents=True, exist_ok=True)
        for name in ("request.fifo", "reply.fifo"):
            if not (folder / name).exists():
                os.mkfifo(folder / name, 0o600)
        self._request = os.open(folder / "request.fifo", os.O_RDWR)
        self._reply = os.open(folder / "reply.fifo", os.O_RDWR | os.O_NONBLOCK)
        self._closed = False
        threading.Thread(target=self._read, daemon=True).start()

    lines = ("fifo", "fifo")

    def ring(self) -> None:
        os.write(self._request, b"q")

    def _read(self) -> None:
        while not self._closed:
            ready, _, _ = select.select([self._reply], [], [], 0.5)
            if ready and not self._closed:
                for _ in os.read(self._reply, 64):
                    self.replies.add()

    def close(self) -> None:
        self._closed = True


class Backend:
    """The chips' vhost-user back ends in this process, served on a thread; with
    ``time_travel``, the calendar of a UML guest's ``time-travel=ext`` too."""

    def __init__(self, chips: Mapping[int, Any], sockets: Path, gpio: bool = True,
                 clock: Any = None, bus_number: int = 0, time_travel: bool = False) -> None:
        from bmg160_emu.bus.i2c import I2CBus
        from bmg160_emu.linux.agent_lines import AgentLines
        from bmg160_emu.linux.vhost_user_server import Server
        from bmg160_emu.linux.virtio_gpio import VirtioGPIODevice
        from bmg160_emu.linux.virtio_i2c import VirtioI2CDevice

        self.chips = dict(chips)
        self.bus = I2CBus(bus_number, self.chips)
        self.i2c = VirtioI2CDevice(self.bus)
        self.agent_lines = AgentLines() if gpio else None
        self.replies = Replies()
        self.gpio = (VirtioGPIODevice(self.chips, self.i2c.rate_reads, clock,
                                      self.i2c.guest_took_rate_read, agent=self.agent_lines)
                     if gpio else None)
        sockets.mkdir(mode=0o700, parents=True, exist_ok=True)
        self.i2c_socket = sockets / "i2c.sock"
        self.gpio_socket = sockets / "gpio.sock" if gpio else None
        self.server = Server()
        self.calendar: Any = None
        self.calendar_socket: Path | None = None
        if time_travel:
            from bmg160_emu.linux.calendar import Calendar

            self.calendar_socket = sockets / "time.sock"
            self.calendar = Calendar(self.server, os.fspath(self.calendar_socket), clock)
            calendar = self.calendar
            self.server.before_reply = lambda: calendar.tighten(self._settle_calls)
            for device in (self.i2c, self.gpio):
                if device is not None:
                    device.inband = True  # completions as events of the calendar
                    device.wait_readable = self.calendar.wait_readable
        self.server.add(os.fspath(self.i2c_socket), self.i2c)
        if self.gpio is not None and self.gpio_socket is not None:
            self.server.add(os.fspath(self.gpio_socket), self.gpio)
            gpio_device = self.gpio
            if self.calendar is not None:
                self.calendar.sources.append(gpio_device)
            else:
                self.server.pollers.append(self.gpio.poll)
                self.gpio.wake = lambda at_s: self.server.schedule(gpio_device.poll, at_s)
            self.gpio.pins_may_have_changed = self.i2c.pins_may_have_changed
            self.i2c.after_transfer.insert(0, self.gpio.after_transfer)
        if self.agent_lines is not None:
            self.agent_lines.on_reply = self._replied
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._serve, name="bmg160-backend", daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        try:
            self.server.run()
        except Exception as exc:  # noqa: BLE001 (kept for the caller; the guest sees a dead device)
            self.error = exc
            self.replies.add()  # wake a waiting caller: it finds the guest gone or the error

    def _settle_calls(self) -> None:
        for device in (self.i2c, self.gpio):
            if device is not None:
                device.settle_calls()

    def _replied(self) -> None:
        if self.calendar is not None:
            self.calendar.hold()  # between requests the guest's time stands still
        self.replies.add()

    @property
    def lines(self) -> tuple[str, str]:
        """The agent's request and reply lines (virtio-gpio offsets, after the chips')."""
        if self.gpio is None:
            raise RuntimeError("the agent's channel needs the virtio-gpio back end")
        first = len(self.gpio.lines)
        return str(first), str(first + 1)

    def ring(self) -> None:
        """Pulse the agent's request line (from any thread): at once in real time; in
        virtual time at the calendar's next turn for the host."""
        assert self.gpio is not None
        if self.calendar is not None:
            self.calendar.release(self.gpio.pulse_agent_request)
        else:
            self.server.call_soon(self.gpio.pulse_agent_request)

    def at(self, delay_s: float, action: Callable[[], None]) -> None:
        """Run ``action`` on the back end's thread ``delay_s`` after the chips' time now:
        in virtual time a calendar event (the guest sees it at that instant whatever the
        host's speed); in real time after that many wall seconds."""
        if self.calendar is not None:
            self.calendar.at(delay_s, action)
        else:
            def once(_now: float) -> None:
                action()

            self.server.call_soon(lambda: self.server.schedule(once, time.monotonic() + delay_s))

    def line_of(self, address: int, pin: int = 1) -> int:
        """The virtio-gpio line of a chip's INT1 (pin 1) or INT2: 2i + pin - 1 for the i-th
        chip by address (bmg160-emu vhost-user-i2c's numbering)."""
        return 2 * sorted(self.chips).index(address) + pin - 1

    def close(self) -> None:
        self.server.stop()
        self.thread.join(timeout=10)
        if self.calendar is not None:
            self.calendar.close()
        self.server.close()


class Guest:
    """One booted guest serving agent requests, with the back ends beside it."""

    def __init__(self, engine: Engine, work: Path, backend: Backend | None = None,
                 modules: Sequence[str | Path] = (), environment: Mapping[str, str] = {},
                 memory_mb: int = 512, cpus: int = 1, host_root_readonly: bool = True,
                 results: Path | None = None) -> None:
        self.engine = engine
        self.work = work
        self.backend = backend
        self.results = (work / "results" if results is None else results).resolve()
        self.agent_dir = self.results / ".agent"
        self.agent_dir.mkdir(parents=True, exist_ok=True)
        self.console_path = work / "console.txt"
        self.seq = 0
        self.count = 0  # commands run
        self.process: subprocess.Popen[bytes] | None = None
        self.facts: dict[str, str] = {}  # what the agent said when ready (bus, gpio_base)
        self._console: list[bytes] = []
        self._fifo: FifoChannel | None = None
        if backend is not None:  # the agent's channel: two lines of its virtio-gpio device
            self.replies = backend.replies
            self._ring = backend.ring
            lines = backend.lines
        else:  # no back end: named pipes, for an engine that runs the agent on this host
            self._fifo = FifoChannel(self.agent_dir)
            self.replies = self._fifo.replies
            self._ring = self._fifo.ring
            lines = FifoChannel.lines
        self.boot = Boot(
            results=self.results,
            agent=AgentBoot(self.agent_dir, *lines),
            i2c_socket=backend.i2c_socket if backend else None,
            gpio_socket=backend.gpio_socket if backend else None,
            time_travel=backend.calendar_socket if backend else None,
            host_root_readonly=host_root_readonly,
            environment={"BMG160_PY": sys.executable, "PYTHONPATH": str(PACKAGE_ROOT),
                         **environment},
            modules=tuple(modules), memory_mb=memory_mb, cpus=cpus)

    def start(self, timeout_s: float = 300.0) -> float:
        """Boot and wait for the agent; the seconds it took."""
        started = time.monotonic()
        self.process = self.engine.start(self.boot)
        threading.Thread(target=self._read_console, daemon=True).start()
        if not self.replies.wait_for(1, timeout_s, lambda: self.alive):
            if self.alive:
                self.kill()
                raise GuestDied(f"no agent after {timeout_s:g} s:\n{self.console()}")
            raise GuestDied(f"the guest ended before its agent started:\n{self.console()}")
        self.seq = 1
        ready = (self.agent_dir / "ready").read_text()
        self.facts = dict(line.split("=", 1) for line in ready.splitlines() if "=" in line)
        return time.monotonic() - started

    def _read_console(self) -> None:
        assert self.process is not None and self.process.stdout is not None
        for line in iter(self.process.stdout.readline, b""):
            self._console.append(line)
        with self.replies.changed:  # the guest has ended: wake whoever waits for it
            self.replies.changed.notify_all()

    def console(self) -> str:
        return b"".join(self._console).decode("utf-8", "replace").replace("\r\n", "\n")

    @property
    def alive(self) -> bool:
        return self.process is not None and self.process.poll() is None

    @property
    def i2c_bus(self) -> int:
        """The guest's number of the virtio-i2c adapter (GUEST_I2C_BUS)."""
        return int(self.facts.get("bus") or -1)

    def call(self, ops: Sequence[agent.Op], timeout_s: float = 120.0) -> list[agent.Reply]:
        """Send a batch of requests and wait for the agent's replies, in order."""
        if not self.alive:
            raise GuestDied("the guest is not running")
        self.seq += 1
        partial = self.agent_dir / "request.tmp"
        partial.write_bytes(agent.encode(self.seq, ops))
        partial.rename(self.agent_dir / "request")
        self._ring()
        if not self.replies.wait_for(self.seq, timeout_s, lambda: self.alive):
            names = ", ".join(op.name for op in ops)
            if self.alive:
                state = ""
                if self.backend is not None and self.backend.calendar is not None:
                    state = f" ({self.backend.calendar.describe()})"
                self.kill()
                raise GuestDied(f"{names} took over {timeout_s:g} s; the guest was killed"
                                f"{state}")
            raise GuestDied(f"the guest died serving {names}:\n{self.console()[-4000:]}")
        if self.backend is not None and self.backend.error is not None:
            raise GuestDied(f"the back end failed: {self.backend.error!r}")
        return agent.decode((self.agent_dir / "response").read_bytes(), self.seq)

    def run(self, command: str, timeout_s: float = 120.0, cwd: Path | None = None,
            check: bool = False) -> CommandResult:
        """Run ``command`` with /bin/sh in the guest (in ``cwd``, the host's current folder
        unless given) and wait for its end."""
        self.count += 1
        out = self.agent_dir / f"{self.count}.out"
        err = self.agent_dir / f"{self.count}.err"
        started = time.monotonic()
        try:
            reply = self.call([agent.run(str(Path.cwd() if cwd is None else cwd), command,
                                         out, err)], timeout_s)[0]
        except GuestDied as exc:
            raise GuestDied(str(exc).replace("run took", f"{command!r} took")
                            .replace("serving run", f"running {command!r}")) from None
        if reply.status:
            raise GuestDied(f"the agent could not run {command!r}: {reply.error()}")
        result = CommandResult(command, int(reply.text), _text(out), _text(err),
                               time.monotonic() - started)
        if check and result.returncode:
            raise AssertionError(f"{command!r} exited with {result.returncode}:\n"
                                 f"{result.stdout}{result.stderr}")
        return result

    def read(self, path: str) -> str:
        """A file of the guest (a sysfs attribute), read by the agent itself."""
        reply = self.call([agent.read(path)])[0]
        if reply.status:
            raise OSError(reply.status, f"{path}: {reply.error()}")
        return reply.text

    def write(self, path: str, value: object) -> None:
        """Write ``value`` to a file of the guest in one write (what sysfs wants)."""
        reply = self.call([agent.write(path, f"{value}\n")])[0]
        if reply.status:
            raise OSError(reply.status, f"{path}: {reply.error()}")

    def capture(self, device: str, seconds: float | None = None, samples: int | None = None,
                watermark: int = 1, length: int = 4096) -> list[tuple[int, int, int, int]]:
        """The triggered buffer of the IIO ``device`` (its sysfs folder) with the driver's
        own trigger: every scan element and the buffer enabled (monotonic time stamps, the
        reader woken every ``watermark`` records), ``samples`` records or ``seconds`` of the
        guest's clock read (whichever comes first) by the agent, the buffer disabled:
        (x, y, z, timestamp_ns) records, 16 bytes each as the bmg160 driver lays them out
        (three s16, padding, s64)."""
        if seconds is None and samples is None:
            raise ValueError("capture needs seconds or samples")
        number = device.rsplit("iio:device", 1)[1]
        found = self.call([agent.glob(f"{device}/scan_elements/*_en"),
                           agent.glob("/sys/bus/iio/devices/trigger*/name")])
        elements, names = (r.text.split() for r in found)
        triggers = [r.text.strip() for r in self.call([agent.read(n) for n in names])]
        own = [t for t in triggers if t.endswith(f"-dev{number}")]
        out = self.agent_dir / f"capture-{self.seq + 1}.bin"
        ops = [agent.write(f"{device}/current_timestamp_clock", "monotonic\n", check=True),
               *(agent.write(e, "1\n", check=True) for e in elements),
               *([agent.write(f"{device}/trigger/current_trigger", own[0], check=True)]
                 if own else []),
               agent.write(f"{device}/buffer/length", f"{length}\n", check=True),
               agent.write(f"{device}/buffer/watermark", f"{watermark}\n", check=True),
               agent.write(f"{device}/buffer/enable", "1\n", check=True),
               agent.capture(f"/dev/iio:device{number}", out, samples or 0, RECORD_BYTES,
                             seconds if seconds is not None else 0.0),
               agent.write(f"{device}/buffer/enable", "0\n")]
        # the wall time allowed: the guest's time in real time, a fraction of it in virtual
        wall_s = 60.0 + (seconds or 0.0) + (samples or 0) * 0.01
        failed = [f"{op.name} {op.subject}: {r.error()}"
                  for op, r in zip(ops, self.call(ops, timeout_s=wall_s)) if r.status]
        if failed:
            raise OSError("; ".join(failed))
        data = out.read_bytes()
        return [struct.unpack_from("<hhhxxq", data, i)
                for i in range(0, len(data) - RECORD_BYTES + 1, RECORD_BYTES)]

    def kill(self) -> None:
        """End the guest: SIGTERM first (UML ends its own processes), SIGKILL if it stays."""
        if self.process is not None and self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
            try:
                self.process.wait(timeout=KILL_GRACE_S)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()

    def close(self, timeout_s: float = 30.0) -> str:
        """Stop the agent (the guest powers off), kill it if it does not; the console."""
        if self.alive:
            try:
                self.call([agent.stop()], timeout_s=timeout_s)
                if self.backend is not None and self.backend.calendar is not None:
                    self.backend.calendar.run_free()  # its power-off may wait for a timer
                assert self.process is not None
                self.process.wait(timeout=timeout_s)
            except (GuestDied, subprocess.TimeoutExpired, agent.ProtocolError, OSError):
                self.kill()
        if self._fifo is not None:
            self._fifo.close()
        console = self.console()
        self.console_path.write_text(console)
        return console


def _text(path: Path) -> str:
    try:
        return path.read_text(errors="replace")
    except FileNotFoundError:
        return ""


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
        process.send_signal(signal.SIGTERM)
        try:
            output, _ = process.communicate(timeout=KILL_GRACE_S)
        except subprocess.TimeoutExpired:
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
