"""ChipConfig: the one place where command-line options, trace headers and rigs become chips.

A config holds every keyword option of :class:`~bmg160_emu.device.chip.BMG160` except the
session's own (master seed, clock), plus the start-up state a session gives a chip before
its traffic (a true rate, register writes such as ``--range``). ``to_dict``/``from_dict``
are the chip entries of a trace header, so an option the CLI or a rig sets is carried to
replay or refused there, never dropped (``tests/test_chip_config.py`` checks the fields
against the constructor's signature).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field, fields
from typing import Any

from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.spec_choices import DEFAULT_PART

# Written into every trace header entry, in this order, whatever their value (the header
# layout since format v1); the other options only when they differ from the default.
ALWAYS_WRITTEN = ("address", "profile", "noise", "noise_mode", "sensitivity", "temperature_c")
SESSION_OPTIONS = ("seed", "clock")  # BMG160 options a config leaves to the session
START_STATE = ("true_rate_dps", "setup_writes")  # not constructor options
PLACEMENT = ("part", "bus")  # which part, on which bus: not constructor options either
NOT_SETTINGS = START_STATE + PLACEMENT


@dataclass
class ChipConfig:
    """The options of one chip (BMG160 keyword arguments) and its start-up state."""

    address: int = choice.DEFAULT_ADDRESS
    profile: Any = None  # None: the part's own (parts.part_profile), named on construction
    noise: bool = True
    noise_mode: str = "physical"
    sensitivity: Any = choice.DEFAULT_SENSITIVITY
    temperature_c: Any = 23.0  # deg C, or a function of time (not carried by traces)
    hold_data_int: bool = False
    strict: bool = False
    startup_time_s: float = choice.STARTUP_TIME_NS / 1e9
    true_rate: Any = (0.0, 0.0, 0.0)  # constructor input: 3 deg/s or a function of time
    mounting: Any = None
    scale_factor: Any = None
    misalignment: Any = None
    nvm_image: bytes | None = None
    nvm_remain: int = choice.NVM_DEFAULT_REMAIN
    errors: Any = None  # a SensorErrors or its table (traces carry the table)
    unit: int | None = None  # unit k of the lot given by the seed (device.unit_population)
    acceleration_g: Any = (0.0, 0.0, 0.0)  # g in the chip's frame, or a function of time
    true_rate_dps: tuple[float, ...] | None = None  # x, y, z deg/s, set after construction
    setup_writes: list[tuple[int, bytes]] = field(default_factory=list)  # written at start
    part: str = DEFAULT_PART  # a device.parts.PART_NAMES entry
    bus: int | None = None  # the I2C bus number, None: the command's own bus

    def __post_init__(self) -> None:
        """The part checked and its profile named, once, so a trace carries what the chip
        takes (the parts module is imported here: it imports the chip model)."""
        from bmg160_emu.device.parts import part_profile

        self.profile = part_profile(self.part, self.profile)

    def chip_options(self) -> dict[str, Any]:
        """The BMG160 keyword arguments (defaults left out, so the chip's own apply)."""
        options: dict[str, Any] = {}
        for f in fields(self):
            if f.name in NOT_SETTINGS:
                continue
            value = getattr(self, f.name)
            if f.name in ALWAYS_WRITTEN or not _is_default(f.name, value):
                options[f.name] = value
        return options

    def build(self, seed: int | None = None, clock: Any = None) -> Any:
        """A chip of this part with these options, then its start-up state (true rate,
        register writes)."""
        from bmg160_emu.device.parts import make_chip

        chip = make_chip(self.part, seed=seed, clock=clock, **self.chip_options())
        if self.true_rate_dps is not None:
            chip.set_true_rate(tuple(self.true_rate_dps))
        for register, data in self.setup_writes:
            chip.write(register, bytes(data))
        return chip

    def to_dict(self) -> dict[str, Any]:
        """A trace header's chip entry: ``settings``, then ``true_rate_dps``, ``setup_writes``."""
        settings: dict[str, Any] = {}
        for name, value in self.chip_options().items():
            if callable(value):
                raise ValueError(f"a trace cannot carry {name} as a function; give a number")  # noqa: TRY004
            settings[name] = _json_value(value)
        entry: dict[str, Any] = {"settings": settings}
        if self.true_rate_dps is not None:
            entry["true_rate_dps"] = [float(v) for v in self.true_rate_dps]
        writes = [[int(reg), list(bytes(data))] for reg, data in self.setup_writes]
        if writes:
            entry["setup_writes"] = writes
        if self.part != DEFAULT_PART:
            entry["part"] = self.part
        if self.bus is not None:
            entry["bus"] = int(self.bus)
        return entry

    @classmethod
    def from_dict(cls, entry: dict[str, Any]) -> ChipConfig:
        """The config of a trace header's chip entry (what :meth:`to_dict` writes)."""
        settings = dict(entry.get("settings") or {})
        unknown = set(settings) - set(SETTING_KEYS)
        if unknown:
            raise ValueError(f"chip settings a trace cannot carry: {sorted(unknown)}")
        if isinstance(settings.get("nvm_image"), list):
            settings["nvm_image"] = bytes(settings["nvm_image"])
        rate = entry.get("true_rate_dps")
        writes = [(int(reg), bytes(data)) for reg, data in entry.get("setup_writes", [])]
        part = entry.get("part", DEFAULT_PART)
        bus = entry.get("bus")
        from bmg160_emu.device.parts import PART_NAMES, UnknownPartError

        try:
            return cls(**settings, true_rate_dps=None if rate is None else tuple(rate),
                       setup_writes=writes, part=part, bus=None if bus is None else int(bus))
        except UnknownPartError:
            raise ValueError(f"the trace's chip is a {part!r}, a part this version does not "
                             f"know (known: {', '.join(PART_NAMES)})") from None

    @classmethod
    def from_settings(cls, settings: dict[str, Any] | None = None,
                      true_rate_dps: Iterable[float] | None = None,
                      setup_writes: Iterable[tuple[int, bytes]] = ()) -> ChipConfig:
        """A config from BMG160 keyword arguments, refusing any a trace cannot carry."""
        settings = dict(settings or {})
        unknown = set(settings) - set(SETTING_KEYS)
        if unknown:
            raise ValueError(f"chip settings a trace cannot carry: {sorted(unknown)}")
        config = cls(**settings)
        config.true_rate_dps = None if true_rate_dps is None else tuple(float(v) for v in true_rate_dps)
        config.setup_writes = [(int(r), bytes(d)) for r, d in setup_writes]
        return config


def _json_value(value: Any) -> Any:
    if hasattr(value, "to_dict"):  # SensorErrors
        return value.to_dict()
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if hasattr(value, "tolist"):
        return value.tolist()
    return value


def _is_default(name: str, value: Any) -> bool:
    default = _DEFAULTS[name]
    if value is None or default is None:
        return value is default
    if callable(value):
        return False
    try:
        return bool(value == default) and type(value) is type(default)
    except (TypeError, ValueError):  # an array compared with a number
        return False


_DEFAULTS: dict[str, Any] = {
    f.name: f.default for f in fields(ChipConfig) if f.name not in NOT_SETTINGS
}
# Every option a trace header may carry (the functions of time are refused when written).
SETTING_KEYS: tuple[str, ...] = tuple(_DEFAULTS)
