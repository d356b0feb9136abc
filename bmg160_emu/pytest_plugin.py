"""pytest fixtures for testing driver code against the emulated BMG160.

Registered as the ``pytest11`` entry point ``bmg160_emu``, so installing the package is enough:

    def test_driver_reads_chip_id(bmg160_smbus):
        from mydriver import Gyro            # builds smbus2.SMBus(1) itself
        assert Gyro(bus=1).chip_id() == 0x0F

Fixtures (docs/pytest-plugin.md): ``bmg160_chip`` (a fresh chip), ``bmg160_devices`` (every
device on the bus: the chip and the marker's ``devices``), ``bmg160_i2c_bus`` (the emulated
adapter with them on bus 1, an ``I2CBus`` with its transaction log, ``assert_wrote`` and the
marker's faults), ``bmg160_i2c_dev`` (``patch_i2c_dev`` on it: the in-process
/dev/i2c-1 for smbus2, smbus3, Adafruit_PureIO, periphery ...), ``bmg160_smbus``
(``patch_smbus``: the same plus the legacy smbus module; yields the ``I2CBus``),
``bmg160_faults`` (bus, chip and sample faults on that bus from the rigs' FaultSchedule),
``bmg160_machine`` and ``bmg160_circuitpython`` (MicroPython's ``machine``, CircuitPython's
``board``/``busio``/``digitalio`` in ``sys.modules``, wired to the chip), ``bmg160_spidev`` (``patch_spidev`` with the chip at
/dev/spidev0.0; yields the emulated device, an ``SpiDevNode``), ``bmg160_fake_smbus`` and
``bmg160_fake_spidev`` (a ``FakeSMBus`` / ``FakeSpiDev`` already open; ``fake_smbus`` and
``fake_spidev`` are the 0.1 names), ``bmg160_virtual_sleep`` (``time.sleep`` advances the
chip's virtual clock) and ``bmg160_virtual_time`` (so do ``time.monotonic``,
``time.perf_counter`` and ``time.time``).

Chip options come from the ``bmg160`` marker, ``@pytest.mark.bmg160(seed=3, noise=False,
bus=2, part="bmi088_gyro", devices=["bmi088_accel@0x18"], faults=[{"kind": "nack",
"on_transaction": 3}], fault_seed=1)``: ``part`` chooses the chip's part, ``devices`` puts
more parts or register-file stand-ins on its bus (``bmg160_devices``), every other keyword
except ``bus``, ``faults`` and ``fault_seed`` goes to the chip; an unknown one, or a fault or
device that cannot be built, is a usage error naming the test. Markers on the module, the
class and the test merge, the closest winning per key. The ini options ``bmg160_seed``,
``bmg160_profile``, ``bmg160_part`` and ``bmg160_devices`` set the suite's defaults; a marker
overrides them.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

DEFAULT_BUS = 1
DEFAULT_SEED = 7
SPI_NODE = (0, 0)  # /dev/spidev0.0
# marker keys the plugin uses; the others go to the chip
PLUGIN_KEYS = ("bus", "faults", "fault_seed", "part", "devices")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini(
        "bmg160_seed",
        f"noise seed of the bmg160_emu fixtures' chip when the marker gives none "
        f"(default {DEFAULT_SEED})",
        default=None,
    )
    parser.addini(
        "bmg160_profile",
        "noise profile of the bmg160_emu fixtures' chip: a built-in name or a TOML file "
        "(relative to the ini file); the marker's profile= overrides it",
        default=None,
    )
    parser.addini(
        "bmg160_part",
        "part of the bmg160_emu fixtures' chip (bmg160, bmi055_gyro, bmx055_gyro, "
        "bmi088_gyro); the marker's part= overrides it",
        default=None,
    )
    parser.addini(
        "bmg160_devices",
        "more devices on the fixtures' bus, one NAME@ADDRESS a line (a part, or a stand-in: "
        "bmi088_accel, bma2x2_accel, bmm150, a TOML or dump file relative to the ini file); "
        "the marker's devices= overrides it",
        type="linelist",
        default=[],
    )


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "bmg160(**options): options of the emulated BMG160 for the bmg160_emu fixtures "
        "(BMG160 keywords, plus bus=, part=, devices=, faults=, fault_seed=)",
    )
    config.stash[_DEFAULTS] = _ini_defaults(config)


_DEFAULTS = pytest.StashKey[dict[str, Any]]()


def _ini_defaults(config: pytest.Config) -> dict[str, Any]:
    """The suite-wide chip options from the ini file, checked once at start-up."""
    defaults: dict[str, Any] = {"seed": DEFAULT_SEED}
    seed = config.getini("bmg160_seed")
    if seed not in (None, ""):
        text = str(seed).strip()
        if text.lower() == "none":
            defaults["seed"] = None  # a fresh random realisation per test
        else:
            from bmg160_emu.limits import SEED, LimitError

            try:  # the command line's seed range (limits.SEED), or 'none'
                defaults["seed"] = SEED.parse(text)
            except LimitError:
                raise pytest.UsageError(
                    f"{_ini_name(config)}: bmg160_seed must be an integer >= 0 or none, "
                    f"not {text!r}"
                ) from None
    profile = config.getini("bmg160_profile")
    if profile not in (None, ""):
        from bmg160_emu.noise import load_profile
        from bmg160_emu.noise.profile import builtin_profile_names

        name = str(profile).strip()
        if name not in builtin_profile_names():
            base = config.inipath.parent if config.inipath else config.rootpath
            name = str((base / name) if not Path(name).is_absolute() else Path(name))
        try:
            load_profile(name)
        except ValueError as exc:
            raise pytest.UsageError(f"{_ini_name(config)}: bmg160_profile: {exc}") from None
        defaults["profile"] = name
    part = config.getini("bmg160_part")
    if part not in (None, ""):
        defaults["part"] = _checked_part(str(part).strip(), _ini_name(config))
    devices = [line.strip() for line in config.getini("bmg160_devices") if line.strip()]
    if devices:
        base = config.inipath.parent if config.inipath else config.rootpath
        defaults["devices"] = _checked_devices(devices, f"{_ini_name(config)}: bmg160_devices",
                                               base)
    return defaults


def _checked_part(name: Any, where: str) -> str:
    from bmg160_emu.device.parts import PART_NAMES

    __tracebackhide__ = True
    if name not in PART_NAMES:
        raise pytest.UsageError(f"{where}: part must be one of {', '.join(PART_NAMES)}, "
                                f"not {name!r}")
    return str(name)


def _checked_devices(entries: Any, where: str, base: Path) -> list[tuple[str, int, Any]]:
    """``["NAME@ADDRESS", ...]`` as (text, address, what: a part name or a stand-in's
    declaration), each checked: a part at 0x68/0x69, a stand-in at one of its addresses."""
    from bmg160_emu.device.parts import PART_NAMES
    from bmg160_emu.device.spec_choices import VALID_ADDRESSES
    from bmg160_emu.io.errors import FormatError
    from bmg160_emu.io.standin_file import builtin_names, load_standin

    __tracebackhide__ = True
    if isinstance(entries, str) or not isinstance(entries, (list, tuple)):
        raise pytest.UsageError(f"{where}: devices= takes a list of NAME@ADDRESS, such as "
                                "['bmi088_accel@0x18']")
    devices: list[tuple[str, int, Any]] = []
    for text in entries:
        name, at, place = str(text).rpartition("@")
        try:
            address = int(place, 0) if at and name else -1
        except ValueError:
            address = -1
        if not 0x03 <= address <= 0x77:
            raise pytest.UsageError(f"{where}: {text!r}: give NAME@ADDRESS with a 7-bit "
                                    "address, e.g. bmi088_accel@0x18")
        if name in PART_NAMES:
            if address not in VALID_ADDRESSES:
                raise pytest.UsageError(f"{where}: {text!r}: a {name} answers at 0x68 or 0x69")
            devices.append((str(text), address, name))
            continue
        path = name if name in builtin_names() or Path(name).is_absolute() else str(base / name)
        if name not in builtin_names() and not Path(path).exists():
            raise pytest.UsageError(
                f"{where}: {text!r}: unknown device {name!r}: a part ({', '.join(PART_NAMES)}), "
                f"a stand-in ({', '.join(builtin_names())}) or a stand-in TOML or dump file")
        try:
            spec = load_standin(path)
        except FormatError as exc:
            raise pytest.UsageError(f"{where}: {text!r}: {exc}") from None
        if spec.addresses and address not in spec.addresses:
            allowed = ", ".join(f"0x{a:02x}" for a in spec.addresses)
            raise pytest.UsageError(f"{where}: {text!r}: a {spec.name} answers at {allowed} "
                                    "only")
        devices.append((str(text), address, spec))
    return devices


def _ini_name(config: pytest.Config) -> str:
    return str(config.inipath) if config.inipath else "ini file"


def chip_option_names() -> tuple[str, ...]:
    """The keywords ``BMG160`` accepts, hence the marker's options besides ``bus``."""
    from bmg160_emu.device.chip import BMG160

    parameters = inspect.signature(BMG160.__init__).parameters.values()
    return tuple(
        p.name for p in parameters if p.name != "self" and p.kind is not p.VAR_KEYWORD
    )


def _check_marker(item: pytest.Item) -> dict[str, Any]:
    """The merged options of ``item``'s bmg160 markers ({} without one): module, class and
    test markers together, the closest winning per key. A UsageError names the test and
    lists the valid keys when one is misspelled."""
    __tracebackhide__ = True
    markers = list(item.iter_markers("bmg160"))  # closest first
    if not markers:
        return {}
    valid = chip_option_names() + PLUGIN_KEYS
    options: dict[str, Any] = {}
    for marker in reversed(markers):
        if marker.args:
            raise pytest.UsageError(f"{item.nodeid}: @pytest.mark.bmg160 takes keyword "
                                    "options only")
        unknown = sorted(set(marker.kwargs) - set(valid))
        if unknown:
            raise pytest.UsageError(
                f"{item.nodeid}: unknown @pytest.mark.bmg160 option"
                f"{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                f"valid: {', '.join(sorted(valid))}"
            )
        options.update(marker.kwargs)
    where = f"{item.nodeid}: @pytest.mark.bmg160"
    if "faults" in options:
        options["faults"] = _marker_faults(item.nodeid, options["faults"])
    if "part" in options:
        options["part"] = _checked_part(options["part"], where)
    if "devices" in options:
        options["devices"] = _checked_devices(options["devices"], where,
                                              Path(str(item.path)).parent)
    return options


def _marker_faults(nodeid: str, faults: Any) -> list[Any]:
    """The marker's ``faults=``: Fault objects or their dictionaries, checked at collection."""
    from bmg160_emu.faults import Fault, FaultError, fault_from_dict

    __tracebackhide__ = True
    if isinstance(faults, (dict, Fault)) or not isinstance(faults, (list, tuple)):
        raise pytest.UsageError(f"{nodeid}: @pytest.mark.bmg160 faults= takes a list of faults "
                                f"(dictionaries such as {{'kind': 'nack', 'on_transaction': 3}})")
    built = []
    for i, entry in enumerate(faults):
        try:
            built.append(entry if isinstance(entry, Fault) else
                         fault_from_dict(dict(entry), f"fault {i + 1}"))
        except (FaultError, TypeError, ValueError) as exc:
            raise pytest.UsageError(f"{nodeid}: @pytest.mark.bmg160 faults: {exc}") from None
    return built


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Check every bmg160 marker before any test runs, as --strict-markers checks names."""
    for item in items:
        _check_marker(item)


def _options(request: pytest.FixtureRequest) -> dict[str, Any]:
    __tracebackhide__ = True
    options = dict(request.config.stash.get(_DEFAULTS, {"seed": DEFAULT_SEED}))
    options.update(_check_marker(request.node))
    return options


@pytest.fixture
def bmg160_chip(request: pytest.FixtureRequest) -> Any:
    """A fresh chip of the marker's ``part`` (a BMG160 by default; seed 7, or the ini file's
    ``bmg160_seed``, unless the marker says)."""
    from bmg160_emu.device.parts import DEFAULT_PART, make_chip

    __tracebackhide__ = True
    options = _options(request)
    part = options.get("part", DEFAULT_PART)
    for key in PLUGIN_KEYS:
        options.pop(key, None)
    try:
        return make_chip(part, **options)
    except (TypeError, ValueError) as exc:
        raise pytest.UsageError(
            f"{request.node.nodeid}: @pytest.mark.bmg160 options rejected by the {part}: {exc}"
        ) from None


@pytest.fixture
def bmg160_devices(request: pytest.FixtureRequest, bmg160_chip: Any) -> dict[int, Any]:
    """Every device on the plugin's bus, {address: device}: the chip first, then the
    marker's ``devices`` (parts and stand-ins, on the chip's clock, with its seed)."""
    from bmg160_emu.device.parts import make_chip
    from bmg160_emu.device.standin import StandinDevice

    __tracebackhide__ = True
    options = _options(request)
    devices = {bmg160_chip.address: bmg160_chip}
    for text, address, what in options.get("devices", []):
        if address in devices:
            raise pytest.UsageError(f"{request.node.nodeid}: @pytest.mark.bmg160 devices: "
                                    f"{text!r}: 0x{address:02x} is taken")
        if isinstance(what, str):
            devices[address] = make_chip(what, address=address, clock=bmg160_chip.clock,
                                         seed=options.get("seed"))
        else:
            devices[address] = StandinDevice(what, address, bmg160_chip.clock)
    return devices


class BusFaults:
    """What ``bmg160_faults`` yields: faults on the plugin's chip and bus, acted by the same
    seeded :class:`~bmg160_emu.faults.FaultSchedule` the rigs use. ``add(kind, **params)``
    schedules one more (``Fault`` keywords: a trigger ``at_s``/``on_transaction``/
    ``probability``, conditions ``address``/``on_register``, effect parameters); ``events``
    lists every onset; ``schedules`` holds the marker's schedule first."""

    def __init__(self, chip: Any, bus: Any, seed: int | None) -> None:
        self.chip, self.bus, self.seed = chip, bus, seed
        self.schedules: list[Any] = []

    def schedule(self, faults: list[Any], seed: int | None = None) -> Any:
        """Install a schedule of several faults (one random stream per fault, from ``seed``)."""
        from bmg160_emu.faults import ChipOnBus, FaultSchedule

        schedule = FaultSchedule(faults, seed=self.seed if seed is None else seed)
        schedule.install([ChipOnBus(self.chip, self.bus)])
        self.schedules.append(schedule)
        return schedule

    def add(self, kind: str, **params: Any) -> Any:
        """One fault from now on; without a trigger or condition it acts at the chip's
        current time (the next transaction, for a bus fault)."""
        if not {"at_s", "on_transaction", "probability", "address", "on_register"} & set(params):
            params["at_s"] = float(self.chip.time)
        return self.schedule([{"kind": kind, **params}])

    @property
    def events(self) -> list[Any]:
        return [event for schedule in self.schedules for event in schedule.events]

    def remove(self) -> None:
        for schedule in self.schedules:
            schedule.remove()


@pytest.fixture
def bmg160_i2c_bus(request: pytest.FixtureRequest, bmg160_chip: Any,
                   bmg160_devices: dict[int, Any]) -> Iterator[Any]:
    """The emulated I2C adapter /dev/i2c-N (N = the marker's ``bus``, 1 by default) with the
    chip and the marker's ``devices`` at their addresses, an ``I2CBus`` (``.log``,
    ``.devices``, ``.transaction_hooks``, ``.assert_wrote``); the marker's ``faults=`` act on
    it. Nothing is patched: the stack fixtures build on it."""
    from bmg160_emu.bus.i2c import I2CBus

    options = _options(request)
    bus = I2CBus(options.get("bus", DEFAULT_BUS), bmg160_devices)
    faults = BusFaults(bmg160_chip, bus, options.get("fault_seed", 0))
    if options.get("faults"):
        faults.schedule(options["faults"])
    request.node.stash[_FAULTS] = faults
    yield bus
    faults.remove()


_FAULTS = pytest.StashKey[BusFaults]()


@pytest.fixture
def bmg160_faults(request: pytest.FixtureRequest, bmg160_i2c_bus: Any) -> BusFaults:
    """Faults on the plugin's chip and bus (the marker's first): ``bmg160_faults.add("nack",
    on_transaction=3)``, ``bmg160_faults.events``."""
    return request.node.stash[_FAULTS]


@pytest.fixture
def bmg160_i2c_dev(bmg160_i2c_bus: Any) -> Iterator[Any]:
    """``patch_i2c_dev`` on the plugin's bus: opening /dev/i2c-N from any pure-Python stack
    (smbus2, smbus3, Adafruit_PureIO and Blinka, periphery, os/fcntl code) reaches the chip;
    yields the ``I2CBus``."""
    from bmg160_emu.bus.i2c_dev_node import patch_i2c_dev

    with patch_i2c_dev({bmg160_i2c_bus.number: bmg160_i2c_bus}):
        yield bmg160_i2c_bus


@pytest.fixture
def bmg160_smbus(bmg160_i2c_bus: Any) -> Iterator[Any]:
    """``patch_smbus`` with the chip on the I2C bus (1 by default): ``bmg160_i2c_dev`` plus
    the legacy smbus module; yields the emulated adapter /dev/i2c-N, an ``I2CBus``."""
    from bmg160_emu.bus.patching import patch_smbus

    with patch_smbus({bmg160_i2c_bus.number: bmg160_i2c_bus}):
        yield bmg160_i2c_bus


@pytest.fixture
def bmg160_machine(bmg160_i2c_bus: Any) -> Iterator[Any]:
    """MicroPython's ``machine`` in ``sys.modules`` for the test: ``machine.I2C(N)`` (N the
    plugin's bus number) and every ``SoftI2C`` reach the chip; yields the module."""
    from bmg160_emu.bus.machine import micropython_machine

    number = bmg160_i2c_bus.number
    where = (f"the chip is on I2C({number}); to reach it as I2C({{id}}), mark the test "
             f"@pytest.mark.bmg160(bus={{id}})")
    with micropython_machine({number: bmg160_i2c_bus}, where=where) as machine:
        yield machine


@pytest.fixture
def bmg160_circuitpython(bmg160_i2c_bus: Any) -> Iterator[Any]:
    """CircuitPython's ``board``, ``busio`` and ``digitalio`` in ``sys.modules`` for the
    test, the chip on ``board.SCL``/``board.SDA``; yields the ``board`` module."""
    from bmg160_emu.bus.board import circuitpython_board

    with circuitpython_board(bmg160_i2c_bus) as board:
        yield board


class SpiDevNode:
    """The emulated /dev/spidevB.D that ``bmg160_spidev`` yields, as ``bmg160_smbus`` yields
    the emulated /dev/i2c-N: ``.chip``, ``.bus``, ``.device``, ``.path``, and ``open()`` for a
    ``FakeSpiDev`` on it. Each ``SpiDev`` keeps its own transaction ``.log``."""

    def __init__(self, chip: Any, bus: int, device: int) -> None:
        self.chip = chip
        self.bus = bus
        self.device = device

    @property
    def path(self) -> str:
        return f"/dev/spidev{self.bus}.{self.device}"

    def open(self) -> Any:
        """A ``FakeSpiDev`` open on this node, as ``spidev.SpiDev(bus, device)`` gives."""
        from bmg160_emu.bus.spi import FakeSpiDev

        return FakeSpiDev(self.bus, self.device)

    def __repr__(self) -> str:
        return f"SpiDevNode({self.path}, {self.chip!r})"


@pytest.fixture
def bmg160_spidev(bmg160_chip: Any) -> Iterator[SpiDevNode]:
    """``patch_spidev`` with the chip at /dev/spidev0.0; yields that ``SpiDevNode``."""
    from bmg160_emu.bus.patching import patch_spidev

    with patch_spidev({SPI_NODE: bmg160_chip}):
        yield SpiDevNode(bmg160_chip, *SPI_NODE)


@pytest.fixture
def bmg160_fake_smbus(bmg160_smbus: Any) -> Iterator[Any]:
    """A ``FakeSMBus`` open on the patched bus."""
    from bmg160_emu.bus.smbus import FakeSMBus

    with FakeSMBus(bmg160_smbus.number) as bus:
        yield bus


@pytest.fixture
def bmg160_fake_spidev(bmg160_chip: Any) -> Iterator[Any]:
    """A ``FakeSpiDev`` open on the chip."""
    from bmg160_emu.bus.spi import FakeSpiDev

    with FakeSpiDev(bmg160_chip) as spi:
        yield spi


@pytest.fixture
def fake_smbus(bmg160_fake_smbus: Any) -> Any:
    """The 0.1 name of ``bmg160_fake_smbus``."""
    return bmg160_fake_smbus


@pytest.fixture
def fake_spidev(bmg160_fake_spidev: Any) -> Any:
    """The 0.1 name of ``bmg160_fake_spidev``."""
    return bmg160_fake_spidev


@pytest.fixture
def bmg160_virtual_sleep(bmg160_chip: Any) -> Iterator[Any]:
    """``time.sleep(s)`` advances the chip's virtual clock by s; yields the clock."""
    from bmg160_emu.clock import virtual_sleep

    with virtual_sleep(bmg160_chip) as clock:
        yield clock


@pytest.fixture
def bmg160_virtual_time(bmg160_chip: Any) -> Iterator[Any]:
    """As ``bmg160_virtual_sleep``, and ``time.monotonic``, ``time.perf_counter``,
    ``time.time`` (and their ``_ns`` forms) follow the virtual clock, so a driver's timeout
    loop times out in virtual time; yields the clock."""
    from bmg160_emu.clock import virtual_sleep

    with virtual_sleep(bmg160_chip, patch_clocks=True) as clock:
        yield clock
