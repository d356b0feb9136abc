"""pytest fixture for testing a kernel driver against the emulated chips in a Linux guest.

Registered as the ``pytest11`` entry point ``bmg160_emu_kernel``. One guest boots per test
session (linux-kernel-notes.md); each test gets the chips reset to their power-on state,
the driver bound to them (``new_device``, or bmg160-board with the INT1 line as IRQ), and at
its end the driver unbound again::

    @pytest.mark.bmg160_kernel(driver="bmg160")
    def test_probe_sets_range(bmg160_kernel):
        assert bmg160_kernel.attr("in_anglvel_scale") == "0.000266"
        bmg160_kernel.assert_wrote(RANGE=0x02, before="BW")

Time: on the uml engine the guest runs in virtual time (the chips' clock is its clock, UML
time travel): a capture of N samples costs N samples of work, nothing depends on the host's
speed, and the same seed gives the same values. ``bmg160_kernel_time = real`` (ini) or
``$BMG160_KERNEL_TIME=real`` runs it against wall time instead (QEMU always does).

Marker keywords: ``driver`` (the I2C device name, default ``bmg160``; None binds nothing),
``module`` (a ``.ko`` or Kbuild folder: the driver under test, loaded once per session and
path), ``irq`` (default True), ``addresses`` (which chips to bind; default the first),
``faults`` (bus faults from :mod:`bmg160_emu.faults`, installed before the bind). The ini
option ``bmg160_kernel_engine`` (or ``$BMG160_KERNEL_ENGINE``) picks the engine; without it
the first ready one. A test whose command kills the guest fails; the next test boots a
fresh one. Without a ready engine the tests are skipped, saying what is missing.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

DEFAULT_ADDRESSES = (0x68, 0x69)  # the chips of every session guest (SDO low, SDO high)
DEFAULT_SEED = 7
TIME_MODES = ("virtual", "real")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini("bmg160_kernel_engine", "guest engine of the bmg160_kernel fixture "
                  "(uml or qemu; default: the first that is ready)", default=None)
    parser.addini("bmg160_kernel_time", "time of the bmg160_kernel fixture's guest: virtual "
                  "(default where the engine can: uml) or real", default=None)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "bmg160_kernel(driver='bmg160', module=None, irq=True, addresses=None, "
        "faults=None): the bmg160_kernel fixture's driver, module, IRQ and bus faults")


class KernelSession:
    """The session's guest, its back ends and chips; booted again after a guest died."""

    def __init__(self, engine_name: str | None, work: Path, time_mode: str | None = None) -> None:
        if time_mode not in (None, *TIME_MODES):
            raise pytest.UsageError(f"bmg160_kernel_time = {time_mode!r}: virtual or real")
        self.engine_name = engine_name
        self.time_mode = time_mode
        self.work = work
        self.guest: Any = None
        self.backend: Any = None
        self.virtual = False  # the guest's clock is the chips' (time travel)
        self.loaded: dict[Path, list[Path]] = {}  # module path -> its .ko files, loaded
        self.boots = 0
        self.boot_s: list[float] = []

    def ensure(self) -> Any:
        """The running guest (a fresh one if there is none or the last one died)."""
        from bmg160_emu.clock import VirtualClock
        from bmg160_emu.linux.guest.engine import EngineError, choose
        from bmg160_emu.linux.guest.harness import Backend, Guest, GuestDied
        from bmg160_emu.linux.guest_pace import GuestPacedClock

        if self.guest is not None and self.guest.alive:
            return self.guest
        self.close()
        try:
            engine = choose(self.engine_name)
        except EngineError as exc:
            pytest.skip(f"no kernel guest here: {exc}")
        can_travel = bool(getattr(engine, "time_travel", False))
        if self.time_mode == "virtual" and not can_travel:
            pytest.skip(f"the {engine.name} engine cannot run in virtual time")
        self.virtual = can_travel and self.time_mode != "real"
        from bmg160_emu.device.chip import BMG160

        clock = VirtualClock() if self.virtual else GuestPacedClock()
        chips = {a: BMG160(seed=DEFAULT_SEED + i, clock=clock, address=a)
                 for i, a in enumerate(DEFAULT_ADDRESSES)}
        self.boots += 1
        folder = self.work / f"boot{self.boots}"
        folder.mkdir(parents=True)
        self.backend = Backend(chips, folder / "s", gpio=True, clock=clock,
                               time_travel=self.virtual)
        self.guest = Guest(engine, folder, self.backend)
        self.loaded = {}
        try:
            self.boot_s.append(self.guest.start())
        except GuestDied as exc:
            self.close()
            pytest.fail(f"the kernel guest did not boot: {exc}")
        return self.guest

    def load(self, path: Path) -> list[Path]:
        """Build (cached) and load a user's module once per boot; its .ko files."""
        from bmg160_emu.linux.guest import agent
        from bmg160_emu.linux.guest.drivers import load_order

        if path in self.loaded:
            return self.loaded[path]
        build = getattr(self.guest.engine, "build_module", None)
        if build is None:
            pytest.skip(f"the {self.guest.engine.name} engine cannot load modules")
        kos = list(build(path, lambda _: None))
        ops = [agent.modprobe(m) if isinstance(m, str) else agent.insmod(m)
               for m in load_order(kos)]
        for op, reply in zip(ops, self.guest.call(ops)):
            if reply.status:
                raise AssertionError(f"{op.name} {op.subject}: {reply.error()}")
        self.loaded[path] = kos
        return kos

    def close(self) -> None:
        if self.guest is not None:
            self.guest.close()
        if self.backend is not None:
            self.backend.close()
        self.guest = self.backend = None


@pytest.fixture(scope="session")
def bmg160_kernel_session(request: pytest.FixtureRequest,
                          tmp_path_factory: pytest.TempPathFactory) -> Iterator[KernelSession]:
    """The session's guest (booted on first use): ``.guest``, ``.backend``, ``.boot_s``."""
    name = (os.environ.get("BMG160_KERNEL_ENGINE")
            or request.config.getini("bmg160_kernel_engine") or None)
    time_mode = (os.environ.get("BMG160_KERNEL_TIME")
                 or request.config.getini("bmg160_kernel_time") or None)
    session = KernelSession(name, tmp_path_factory.mktemp("kernel-guest"), time_mode)
    yield session
    session.close()


class KernelTest:
    """What one test sees: the guest, the chips and bus it talks to, the bound driver."""

    def __init__(self, session: KernelSession, addresses: tuple[int, ...]) -> None:
        self.session = session
        self.guest = session.guest
        self.bus = session.backend.bus
        self.chips = session.backend.chips
        self.addresses = addresses
        self.chip = self.chips[addresses[0]]
        self.mark = self.bus.log.total  # transactions before the test's own
        self.faults: Any = None

    @property
    def virtual(self) -> bool:
        """The guest runs in virtual time (its clock is the chips')."""
        return self.session.virtual

    def run(self, command: str, timeout_s: float = 120.0, check: bool = True) -> Any:
        """Run a shell command in the guest; its result (``returncode``, ``stdout``,
        ``stderr``); a non-zero status fails the test unless ``check=False``."""
        return self.guest.run(command, timeout_s=timeout_s, check=check)

    def iio(self, address: int | None = None) -> str:
        """The guest's sysfs folder of the IIO device bound to the chip at ``address``."""
        from bmg160_emu.linux.guest import agent

        address = self.addresses[0] if address is None else address
        pattern = f"/sys/bus/i2c/devices/{self.guest.i2c_bus}-{address:04x}/iio:device*"
        found = self.guest.call([agent.glob(pattern)])[0].text.split()
        assert found, f"no IIO device for 0x{address:02x} (is the driver bound?)"
        return found[0]

    def attr(self, name: str, address: int | None = None) -> str:
        """An IIO attribute's text (``in_anglvel_x_raw``, ``buffer/enable``), stripped: read
        by the guest's agent, no program started."""
        return str(self.guest.read(f"{self.iio(address)}/{name}")).strip()

    def set_attr(self, name: str, value: object, address: int | None = None) -> None:
        self.guest.write(f"{self.iio(address)}/{name}", value)

    def at(self, seconds: float, action: Callable[[], None]) -> None:
        """Run ``action`` (on the back end's thread) ``seconds`` after the chips' time now:
        in virtual time at that instant of the guest's clock, whatever the host's speed
        (e.g. a step of the true rate while a guest command runs)."""
        self.session.backend.at(seconds, action)

    def capture(self, seconds: float | None = None, address: int | None = None,
                watermark: int = 1, length: int = 4096,
                samples: int | None = None) -> list[tuple[int, ...]]:
        """Enable every scan element and the buffer with the driver's own trigger
        (monotonic time stamps; the reader wakes every ``watermark`` records), read
        ``samples`` records or for ``seconds`` of the guest's clock (whichever comes
        first), disable it: (x, y, z, timestamp_ns) records (16 bytes each: three s16,
        padding, s64, as the bmg160 driver lays them out). In virtual time N samples cost
        N samples of work, not N output periods of the host's time."""
        return list(self.guest.capture(self.iio(address), seconds, samples, watermark,
                                       length))

    def writes(self, address: int | None = None) -> list[tuple[int, int]]:
        """(register, value) of every byte the driver wrote to the chip since the test began,
        in order (a burst write is one entry per register)."""
        address = self.addresses[0] if address is None else address
        entries = list(self.bus.log.entries)
        new = entries[max(0, len(entries) - (self.bus.log.total - self.mark)):]
        out = []
        for _time, _bus, addr, kind, register, written, _read, error in new:
            if addr == address and error is None and register is not None and written \
                    and "write" in kind:
                out += [(register + i, value) for i, value in enumerate(written)]
        return out

    def assert_wrote(self, before: str | None = None, address: int | None = None,
                     **values: int) -> None:
        """Assert the driver wrote each ``NAME=value`` (register names as the data sheet
        gives them), and, with ``before="NAME"``, each before its first write of NAME."""
        from bmg160_emu.device.registers import address_of

        writes = self.writes(address)
        listed = ", ".join(f"0x{r:02x}=0x{v:02x}" for r, v in writes) or "none"
        for name, value in values.items():
            register = address_of(name)
            hits = [i for i, (r, v) in enumerate(writes) if r == register and v == value]
            assert hits, f"the driver never wrote {name} = 0x{value:02x}; its writes: {listed}"
            if before is not None:
                other = address_of(before)
                later = [i for i, (r, _v) in enumerate(writes) if r == other]
                assert later and hits[0] < later[0], (
                    f"{name} = 0x{value:02x} was not written before {before} "
                    f"({'it never wrote ' + before if not later else 'written in the wrong order'}"
                    f"); its writes: {listed}")


def _marker(request: pytest.FixtureRequest) -> dict[str, Any]:
    marker = request.node.get_closest_marker("bmg160_kernel")
    options = dict(marker.kwargs) if marker else {}
    unknown = set(options) - {"driver", "module", "irq", "addresses", "faults"}
    if unknown:
        raise pytest.UsageError(f"{request.node.nodeid}: @pytest.mark.bmg160_kernel: unknown "
                                f"keyword(s) {', '.join(sorted(unknown))}")
    return options


@pytest.fixture
def bmg160_kernel(request: pytest.FixtureRequest,
                  bmg160_kernel_session: KernelSession) -> Iterator[KernelTest]:
    """The session's guest with the chips reset and the marker's driver bound to them."""
    from bmg160_emu.device.registers import address_of
    from bmg160_emu.linux.guest.drivers import bind_failure, bind_ops, driver_name, unbind_ops

    options = _marker(request)
    session = bmg160_kernel_session
    guest = session.ensure()
    addresses = tuple(options.get("addresses") or DEFAULT_ADDRESSES[:1])
    for chip in session.backend.chips.values():  # soft reset: each test starts at power-on
        chip.write(address_of("BGW_SOFTRESET"), b"\xb6")  # (spec 4.2)
    name = options.get("driver", "bmg160")
    if options.get("module") is not None:
        kos = session.load(Path(options["module"]))
        name = options.get("driver") or driver_name(kos, prefer=["bmg160"])
    test = KernelTest(session, addresses)
    if options.get("faults"):
        from bmg160_emu.faults import ChipOnBus, FaultSchedule

        test.faults = FaultSchedule(options["faults"], seed=0)
        test.faults.install([ChipOnBus(test.chip, test.bus)])
    board = getattr(guest.engine, "board_module", lambda: None)()
    irq = options.get("irq", True) and board is not None
    if name:
        lines = [session.backend.line_of(a) for a in addresses] if irq else None
        ops = bind_ops(name, addresses, guest.i2c_bus, lines, board if irq else None,
                       int(guest.facts.get("gpio_base") or 0),
                       kernel_driver=options.get("module") is None)
        failure = bind_failure(guest.call(ops, timeout_s=60), ops)
        if failure:
            dmesg = guest.run("dmesg | tail -n 8", check=False).stdout
            raise AssertionError(f"binding {name}: {failure}; dmesg:\n{dmesg}")
    yield test
    if test.faults is not None:
        test.faults.remove()
    if name and guest.alive:
        guest.call(unbind_ops(addresses, guest.i2c_bus, board=irq))


def kernel_tools_missing() -> list[str]:
    """Host programs the guest borrows (it runs the host's own): one line each."""
    return [f"{tool} is missing (Debian package {package})"
            for tool, package in (("i2cget", "i2c-tools"), ("modprobe", "kmod"))
            if shutil.which(tool) is None]
