"""A virtual ``/dev/i2c-N`` for unmodified programs, answered by the emulator through umockdev.

Why: programs that were never written for the emulator (i2c-tools, smbus2, C code calling
``ioctl`` on ``/dev/i2c-N``) should see a BMG160 without root and without a kernel module.
umockdev's preload library redirects their ``open``/``ioctl``/``read``/``write`` on the
device node to a socket; the handler here only moves the client's memory in and out:
:class:`~bmg160_emu.bus.i2c_dev.I2CDevFile` answers each request as the kernel's i2c-dev driver
would (the same emulation ``patch_smbus`` uses), and the transaction itself goes to
:class:`~bmg160_emu.bus.i2c.I2CBus`, so SMBus semantics, errors, hooks and the transaction
log are the ones every other front end has.

Needs umockdev (Debian ``umockdev``, ``gir1.2-umockdev-1.0``) and PyGObject. The children
run with ``LD_PRELOAD=libumockdev-preload.so.0`` and the testbed's ``UMOCKDEV_DIR``.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, os_error
from bmg160_emu.bus.i2c_dev import I2CDevFile, unsigned_long
from bmg160_emu.clock import RealTimeClock

PRELOAD_LIBRARY = "libumockdev-preload.so.0"
I2C_DEV_MAJOR = 89  # Documentation/admin-guide/devices.txt: "89 char I2C bus interface"


class UMockdevUnavailable(RuntimeError):
    """umockdev or PyGObject is missing: the message says which package to install."""


def load_umockdev() -> Any:
    """The ``gi.repository.UMockdev`` module, or :class:`UMockdevUnavailable` saying why not."""
    try:
        import gi
    except ImportError:
        raise UMockdevUnavailable(
            "PyGObject is not importable (pip install 'PyGObject<3.50' after "
            "apt-get install libgirepository1.0-dev libcairo2-dev pkg-config gcc)"
        ) from None
    try:
        gi.require_version("UMockdev", "1.0")
        from gi.repository import UMockdev
    except (ValueError, ImportError):
        raise UMockdevUnavailable(
            "the UMockdev typelib is missing (apt-get install umockdev gir1.2-umockdev-1.0)"
        ) from None
    return UMockdev


def preload_available() -> bool:
    """True if the dynamic loader can find umockdev's preload library."""
    for folder in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
                   "/usr/lib", "/usr/local/lib"):
        if os.path.exists(os.path.join(folder, PRELOAD_LIBRARY)):
            return True
    return False


class RequestClock(RealTimeClock):
    """Real time that stands still while one client request is answered.

    Why: a request (one ioctl, read or write) is one bus transaction, or one combined
    I2C_RDWR transfer, so the chip must catch up once, at the request's start, and the
    transaction log must carry that same instant. With a running clock the log took its
    time after the chip had answered, and a trace replay (which advances virtual time to
    the logged instants) could place a sample or an ODR change on the other side of it.
    """

    def __init__(self, origin_ns: int | None = None) -> None:
        super().__init__()
        if origin_ns is not None:
            self._origin_ns = origin_ns  # continue another RealTimeClock's time base
        self._held_ns: int | None = None

    def now_ns(self) -> int:
        held = self._held_ns
        return super().now_ns() if held is None else held

    @contextlib.contextmanager
    def request(self) -> Iterator[None]:
        """Hold the time at its current value until the block ends (nested: the outer one)."""
        if self._held_ns is not None:
            yield
            return
        self._held_ns = super().now_ns()
        try:
            yield
        finally:
            self._held_ns = None


def hold_time_per_request(buses: Iterable[I2CBus]) -> list[RequestClock]:
    """Give the chips on ``buses`` that run on a plain RealTimeClock a RequestClock with the
    same time base (one per original clock, so chips that shared a clock still do)."""
    converted: dict[int, RequestClock] = {}
    for bus in buses:
        for chip in bus.devices.values():
            clock = getattr(chip, "clock", None)
            if isinstance(clock, RequestClock):
                converted.setdefault(id(clock), clock)
            elif type(clock) is RealTimeClock:
                new = converted.get(id(clock))
                if new is None:
                    new = converted[id(clock)] = RequestClock(clock._origin_ns)
                with chip.lock:
                    chip.clock = new
    return list({id(c): c for c in converted.values()}.values())


class _ClientMemory:
    """A block of the client's memory as umockdev hands it over (``UMockdev.IoctlData``);
    pointers in it are followed through umockdev's ``resolve``."""

    __slots__ = ("data", "pointees")

    def __init__(self, data: Any) -> None:
        self.data = data
        self.pointees: dict[int, _ClientMemory] = {}

    def read(self) -> bytes:
        return bytes(self.data.retrieve())

    def write(self, payload: bytes) -> None:
        self.data.update(0, list(payload))

    def follow(self, offset: int, size: int) -> _ClientMemory:
        known = self.pointees.get(offset)
        if known is not None:
            return known
        target = self.data.resolve(offset, size)
        if target is None:
            raise os_error(errno.EFAULT)
        self.pointees[offset] = _ClientMemory(target)
        return self.pointees[offset]


class _ClientArgument:
    """The ioctl argument: an unsigned long the client passed, maybe a pointer."""

    __slots__ = ("cell",)

    def __init__(self, arg: Any) -> None:
        self.cell = _ClientMemory(arg)

    @property
    def value(self) -> int:
        return unsigned_long(self.cell.read())

    def memory(self, size: int) -> _ClientMemory:
        return self.cell.follow(0, size)


def _handler_class(UMockdev: Any) -> type:
    """Build the IoctlBase subclass (its base exists only once gi has loaded UMockdev)."""

    class I2CDevHandler(UMockdev.IoctlBase):
        """Moves bytes between umockdev's clients and one :class:`I2CDevFile` per open file."""

        def __init__(self, bus: I2CBus, clocks: Sequence[RequestClock] = ()) -> None:
            super().__init__()
            self.bus = bus
            self.clocks = list(clocks)
            self._files: dict[int, I2CDevFile] = {}
            self.errors: list[str] = []

        def _file(self, client: Any) -> I2CDevFile:
            return self._files.setdefault(hash(client), I2CDevFile(self.bus))

        def _answer(self, client: Any, call: Callable[[], int]) -> bool:
            try:
                with contextlib.ExitStack() as held:
                    for clock in self.clocks:  # the request happens at one instant
                        held.enter_context(clock.request())
                    result = call()
            except OSError as exc:
                client.complete(-1, exc.errno or errno.EIO)
            except Exception as exc:  # noqa: BLE001 - never leave a client hanging on a bug
                self.errors.append(repr(exc))
                client.complete(-1, errno.EIO)
            else:
                client.complete(result, 0)
            return True

        def do_client_connected(self, client: Any) -> None:
            self._files[hash(client)] = I2CDevFile(self.bus)  # a new open()

        def do_handle_ioctl(self, client: Any) -> bool:
            file = self._file(client)
            request, arg = client.get_request(), _ClientArgument(client.get_arg())
            return self._answer(client, lambda: file.ioctl(request, arg))

        def do_handle_read(self, client: Any) -> bool:
            file, arg = self._file(client), client.get_arg()

            def read() -> int:
                data = file.read(len(arg.retrieve()))
                if data:
                    arg.update(0, list(data))
                return len(data)

            return self._answer(client, read)

        def do_handle_write(self, client: Any) -> bool:
            file, arg = self._file(client), client.get_arg()
            return self._answer(client, lambda: file.write(bytes(arg.retrieve())))

    return I2CDevHandler


OWNER_FILE = "bmg160-emu.pid"  # in a testbed folder: the pid of the session that made it
PR_SET_PDEATHSIG = 1  # linux/prctl.h


def die_with_parent(parent_pid: int) -> Callable[[], None]:
    """A ``preexec_fn`` that makes the child receive SIGKILL when its parent dies
    (prctl(PR_SET_PDEATHSIG), Linux), and exit at once if the parent is already gone."""

    def preexec() -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != parent_pid:  # died between fork and prctl
            os._exit(1)

    return preexec


def remove_stale_testbeds(tmp_dir: str | None = None) -> list[str]:
    """Remove umockdev testbed folders left by sessions of ours that were killed (their
    owner pid no longer runs); folders of other programs are left alone."""
    removed = []
    for folder in Path(tmp_dir or tempfile.gettempdir()).glob("umockdev.*"):
        try:
            pid = int((folder / OWNER_FILE).read_text().strip())
        except (OSError, ValueError):
            continue
        if pid == os.getpid() or Path(f"/proc/{pid}").exists():
            continue
        shutil.rmtree(folder, ignore_errors=True)
        removed.append(str(folder))
    return removed


class VirtualI2CDevices:
    """A umockdev testbed holding one ``/dev/i2c-N`` per :class:`I2CBus`.

    Use as a context manager; :meth:`environment` gives what a child process needs, and
    :meth:`run` starts one and waits for it. Requests are answered on umockdev's worker
    thread while the caller waits. Chips on a RealTimeClock get a :class:`RequestClock`
    (same time base) so each request happens at one instant, as its log entry says.
    """

    def __init__(self, buses: Iterable[I2CBus]) -> None:
        self.buses = list(buses)
        numbers = [b.number for b in self.buses]
        if len(set(numbers)) != len(numbers):
            raise ValueError(f"two buses share a number: {numbers}")
        self._umockdev = load_umockdev()
        if not preload_available():
            raise UMockdevUnavailable(
                f"{PRELOAD_LIBRARY} is missing (apt-get install libumockdev0 umockdev)"
            )
        self.testbed: Any = None
        self.handlers: list[Any] = []

    def __enter__(self) -> VirtualI2CDevices:  # noqa: PYI034 - Python 3.10 has no Self
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def open(self) -> None:
        UMockdev = self._umockdev
        remove_stale_testbeds()
        self.testbed = UMockdev.Testbed.new()
        # Marks the folder as ours: a session killed with SIGKILL cannot remove it, so the
        # next one does (remove_stale_testbeds).
        Path(self.testbed.get_root_dir(), OWNER_FILE).write_text(f"{os.getpid()}\n")
        handler_class = _handler_class(UMockdev)
        clocks = hold_time_per_request(self.buses)
        for bus in self.buses:
            n = bus.number
            description = (
                f"P: /devices/virtual/i2c-dev/i2c-{n}\n"
                f"N: i2c-{n}\n"
                "E: SUBSYSTEM=i2c-dev\n"
                f"E: DEVNAME=/dev/i2c-{n}\n"
                f"E: MAJOR={I2C_DEV_MAJOR}\nE: MINOR={n}\n"
                f"A: dev={I2C_DEV_MAJOR}:{n}\n"
                f"A: name=bmg160-emu virtual adapter {n}\n"
            )
            if not self.testbed.add_from_string(description):
                raise RuntimeError(f"umockdev refused the description of /dev/i2c-{n}")
            handler = handler_class(bus, clocks)
            if not self.testbed.attach_ioctl(f"/dev/i2c-{n}", handler):
                raise RuntimeError(f"umockdev could not attach a handler to /dev/i2c-{n}")
            self.handlers.append(handler)

    def close(self) -> None:
        if self.testbed is not None:
            for bus in self.buses:
                self.testbed.detach_ioctl(f"/dev/i2c-{bus.number}")
            self.testbed = None
            self.handlers = []

    @property
    def root_dir(self) -> str:
        return self.testbed.get_root_dir()

    def environment(self, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """Environment for a child: the preload library first, the testbed's directory."""
        env = dict(os.environ if base is None else base)
        preload = env.get("LD_PRELOAD", "")
        env["LD_PRELOAD"] = PRELOAD_LIBRARY + (":" + preload if preload else "")
        env["UMOCKDEV_DIR"] = self.root_dir
        return env

    def popen(self, command: Sequence[str], **kwargs: Any) -> subprocess.Popen:
        """Start a program under the testbed; it is killed if this process dies first (its
        ioctls would have nobody to answer them)."""
        kwargs.setdefault("env", self.environment())
        kwargs.setdefault("preexec_fn", die_with_parent(os.getpid()))
        return subprocess.Popen(list(command), **kwargs)

    def run(self, command: Sequence[str], **kwargs: Any) -> subprocess.CompletedProcess:
        """``subprocess.run`` with the testbed's environment."""
        kwargs.setdefault("env", self.environment())
        return subprocess.run(list(command), check=False, **kwargs)

    def handler_errors(self) -> list[str]:
        """Unexpected exceptions the handlers turned into EIO (empty when all went well)."""
        return [e for h in self.handlers for e in h.errors]
