"""What can go wrong with a gyro on a spacecraft bus: the fault kinds and their parameters.

:class:`Fault` is one entry of a schedule (trigger + effect, checked when built); the
engine that acts them is :mod:`bmg160_emu.faults.schedule`. The table of kinds, layers and
effects is in :mod:`bmg160_emu.faults`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bmg160_emu.traffic.kinds import NO_DATA_KINDS

BUS_KINDS = ("nack", "timeout", "stuck_bus", "corrupt_byte")
SAMPLE_KINDS = ("stuck_axis", "bias_step", "spike", "saturation", "lost_samples",
                "temperature_ramp")
CHIP_KINDS = ("seu", "brownout")
FAULT_KINDS = BUS_KINDS + SAMPLE_KINDS + CHIP_KINDS

# One bit per kind in the truth record's ``fault_flags`` column; kinds added later take the
# next bits, so the bits of a saved truth record keep their meaning.
_FLAG_ORDER = ("nack", "timeout", *SAMPLE_KINDS, *CHIP_KINDS, "stuck_bus", "corrupt_byte")
FAULT_FLAGS = {kind: 1 << i for i, kind in enumerate(_FLAG_ORDER)}

SATURATED_DPS = 1.0e6  # far beyond +-2000 deg/s: the chip clips it to +-32767 counts
AXES = {"x": 0, "y": 1, "z": 2}


class FaultError(ValueError):
    """A fault description that cannot be used, with the reason."""


class GyroTarget(Protocol):
    """What a fault needs to know about a gyro (a :class:`~bmg160_emu.adcs.rig.Gyro`)."""

    @property
    def index(self) -> int: ...
    @property
    def chip(self) -> Any: ...
    @property
    def bus(self) -> Any: ...
    @property
    def address(self) -> int: ...


@dataclass
class FaultEvent:
    """The onset of a fault, as it happened: when, where and what."""

    time_s: float
    kind: str
    gyro: int | None
    transaction: int | None
    detail: str

    def to_dict(self) -> dict[str, Any]:
        return {"time_s": self.time_s, "kind": self.kind, "gyro": self.gyro,
                "transaction": self.transaction, "detail": self.detail}


_NUMBER_FIELDS = ("at_s", "probability", "duration_s", "step_dps", "amplitude_dps",
                  "rate_c_per_s", "stall_s")
_COUNT_FIELDS = ("on_transaction", "gyro", "samples", "register", "bit", "max_count", "address",
                 "on_register", "byte")
_OPTIONAL_FIELDS = {"at_s", "probability", "duration_s", "on_transaction", "gyro", "register",
                    "max_count", "address", "on_register"}


@dataclass
class Fault:
    """One scheduled fault: a trigger, an effect and its parameters (see the module table)."""

    kind: str
    at_s: float | None = None
    on_transaction: int | None = None
    probability: float | None = None
    gyro: int | None = None
    duration_s: float | None = None
    axis: int | None = None
    step_dps: float = 0.0
    amplitude_dps: float = 0.0
    samples: int = 1
    register: int | None = None
    bit: int = 0
    rate_c_per_s: float = 0.0
    tc_bias_dps_per_c: np.ndarray = field(default_factory=lambda: np.zeros(3))
    stall_s: float = 0.0
    max_count: int | None = None
    address: int | None = None
    on_register: int | None = None
    byte: int = 0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise FaultError(f"fault kind must be one of {list(FAULT_KINDS)}, not {self.kind!r}")
        self._check_types()
        triggers = [self.at_s is not None, self.on_transaction is not None,
                    self.probability is not None]
        if sum(triggers) > 1:
            raise FaultError(
                f"{self.kind}: give one trigger (at_s, on_transaction or probability), or none "
                "for 'from the start'; on_register and address narrow it to the transactions "
                "naming that register or sent to that address"
            )
        if sum(triggers) == 0:
            # no trigger: from the start (the first sample, or the first transaction that
            # meets its conditions), as bmg160_faults.add(kind) is "from now on"
            self.at_s = 0.0
        if self.address is not None and not 0 <= self.address <= 0x7F:
            raise FaultError(f"{self.kind}: address must be a 7-bit address 0x00..0x7f")
        if self.on_register is not None and not 0 <= self.on_register <= 0xFF:
            raise FaultError(f"{self.kind}: on_register must be a register 0x00..0xff")
        if self.conditional and self.layer == "sample":
            raise FaultError(f"{self.kind}: address and on_register select transactions; a "
                             "sample fault acts on samples (give at_s, on_transaction or "
                             "probability)")
        if self.kind == "corrupt_byte":
            if not 0 <= self.bit <= 7:
                raise FaultError("corrupt_byte: bit must be 0..7")
            if self.byte < 0:
                raise FaultError("corrupt_byte: byte must be >= 0 (its place in the data read)")
        if self.probability is not None and not 0.0 <= self.probability <= 1.0:
            raise FaultError(f"{self.kind}: probability must be within 0..1, not {self.probability}")
        if self.on_transaction is not None and self.on_transaction < 0:
            raise FaultError(f"{self.kind}: on_transaction must be >= 0")
        if self.duration_s is not None and not self.duration_s > 0:
            raise FaultError(f"{self.kind}: duration_s must be positive")
        if isinstance(self.axis, str):
            if self.axis not in AXES:
                raise FaultError(f"{self.kind}: axis must be x, y, z or 0, 1, 2, not {self.axis!r}")
            self.axis = AXES[self.axis]
        if self.axis is not None and self.axis not in (0, 1, 2):
            raise FaultError(f"{self.kind}: axis must be x, y, z or 0, 1, 2, not {self.axis!r}")
        if self.kind in ("stuck_axis", "saturation") and self.axis is None:
            raise FaultError(f"{self.kind}: needs an axis")
        if self.kind in ("spike", "lost_samples") and not (
            isinstance(self.samples, int) and self.samples >= 1
        ):
            raise FaultError(f"{self.kind}: samples must be a whole number >= 1")
        if self.kind == "seu":
            if self.register is None or not 0 <= self.register <= 0x3F:
                raise FaultError("seu: register must be an address 0x00..0x3F")
            if not 0 <= self.bit <= 7:
                raise FaultError("seu: bit must be 0..7")
        try:
            self.tc_bias_dps_per_c = np.broadcast_to(
                np.asarray(self.tc_bias_dps_per_c, dtype=float), (3,)
            ).copy()
        except (TypeError, ValueError):
            raise FaultError(f"{self.kind}: tc_bias_dps_per_c must be one number or 3 (x, y, z) "
                             f"in deg/s per degC, not {self.tc_bias_dps_per_c!r}") from None
        if not np.all(np.isfinite(self.tc_bias_dps_per_c)):
            raise FaultError(f"{self.kind}: tc_bias_dps_per_c must be finite")
        if self.max_count is not None and self.max_count < 1:
            raise FaultError(f"{self.kind}: max_count must be at least 1")
        if self.stall_s < 0:
            raise FaultError(f"{self.kind}: stall_s must not be negative")

    def _check_types(self) -> None:
        """Numbers where numbers are meant, whole numbers where counts are: a quoted TOML
        value would otherwise be kept and fail mid-run (or a fractional count never fire)."""
        for name in _NUMBER_FIELDS:
            value = getattr(self, name)
            if value is None and name in _OPTIONAL_FIELDS:
                continue
            if (isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating))
                    or not math.isfinite(value)):
                raise FaultError(f"{self.kind}: {name} must be a finite number, not {value!r}")
        for name in _COUNT_FIELDS:
            value = getattr(self, name)
            if value is None and name in _OPTIONAL_FIELDS:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
                raise FaultError(f"{self.kind}: {name} must be a whole number, not {value!r}")

    @property
    def conditional(self) -> bool:
        """The fault acts only on transactions to ``address`` or naming ``on_register``."""
        return self.address is not None or self.on_register is not None

    def selects(self, address: int, register: int | None, kind: str) -> bool:
        """Whether a transaction (7-bit address, register it names, I2CBus kind) is one the
        fault may act on: its conditions hold, and a corrupt_byte needs a transaction that
        carries bytes (not a quick command)."""
        if self.address is not None and address != self.address:
            return False
        if self.on_register is not None and register != self.on_register:
            return False
        return self.kind != "corrupt_byte" or kind not in NO_DATA_KINDS

    @property
    def layer(self) -> str:
        if self.kind in BUS_KINDS:
            return "bus"
        return "chip" if self.kind in CHIP_KINDS else "sample"

    def describe(self) -> str:
        where = "" if self.axis is None else f" axis {'xyz'[self.axis]}"
        extra = {
            "bias_step": f" {self.step_dps:+g} deg/s",
            "spike": f" {self.amplitude_dps:+g} deg/s x{self.samples}",
            "lost_samples": f" {self.samples} periods",
            "seu": f" register 0x{self.register or 0:02x} bit {self.bit}",
            "corrupt_byte": f" byte {self.byte} bit {self.bit}",
            "temperature_ramp": f" {self.rate_c_per_s:+g} degC/s",
        }.get(self.kind, "")
        span = "" if self.duration_s is None else f" for {self.duration_s:g} s"
        if self.on_register is not None:
            span += f" on register 0x{self.on_register:02x}"
        if self.address is not None:
            span += f" to 0x{self.address:02x}"
        return f"{self.kind}{where}{extra}{span}"


_FAULT_KEYS = {f for f in Fault.__dataclass_fields__}


# The keys every fault takes (its kind, trigger, conditions, target) and each kind's effect.
COMMON_KEYS = ("kind", "at_s", "on_transaction", "probability", "on_register", "address",
               "gyro", "max_count")
EFFECT_KEYS = {
    "nack": ("duration_s",),
    "timeout": ("stall_s", "duration_s"),
    "stuck_bus": ("stall_s", "duration_s"),
    "corrupt_byte": ("byte", "bit", "duration_s"),
    "stuck_axis": ("axis", "duration_s"),
    "bias_step": ("step_dps", "axis", "duration_s"),
    "spike": ("amplitude_dps", "axis", "samples"),
    "saturation": ("axis", "amplitude_dps", "duration_s"),
    "lost_samples": ("samples",),
    "temperature_ramp": ("rate_c_per_s", "tc_bias_dps_per_c", "duration_s"),
    "seu": ("register", "bit"),
    "brownout": (),
}


def fault_keys(kind: str) -> tuple[str, ...]:
    """The keys a fault of ``kind`` takes: the common ones, then its effect's."""
    return COMMON_KEYS + EFFECT_KEYS.get(kind, ())


def fault_from_dict(entry: dict[str, Any], where: str = "fault") -> Fault:
    """Build a fault from its TOML table (``[[fault]]`` in a scenario file); a key it does
    not take is refused with the keys it does."""
    kind = entry.get("kind")
    if kind not in FAULT_KINDS:
        raise FaultError(f"{where}: fault kind must be one of {list(FAULT_KINDS)}, not {kind!r}")
    valid = fault_keys(kind)
    unknown = sorted(set(entry) - _FAULT_KEYS)
    if unknown:
        raise FaultError(f"{where}: unknown key{'s' if len(unknown) > 1 else ''} "
                         f"{', '.join(unknown)}; a {kind} fault takes {', '.join(valid)}")
    foreign = sorted(set(entry) - set(valid))
    if foreign:
        hint = (" (to select transactions naming a register, give on_register)"
                if "register" in foreign else "")
        raise FaultError(f"{where}: a {kind} fault takes no {', '.join(foreign)}{hint}; it "
                         f"takes {', '.join(valid)}")
    try:
        return Fault(**entry)
    except FaultError as exc:
        raise FaultError(f"{where}: {exc}") from None
    except TypeError as exc:
        raise FaultError(f"{where}: {exc}") from None


# Effect parameters of a Fault; a log entry replaces its trigger by the onset it records.
_EFFECT_KEYS = ("duration_s", "axis", "step_dps", "amplitude_dps", "samples", "register", "bit",
                "rate_c_per_s", "tc_bias_dps_per_c", "byte")


def effect_parameters(fault: Fault) -> dict[str, Any]:
    """The fault's kind and the effect parameters that differ from their defaults (no
    trigger): what a ``fault:<kind>`` log entry carries for a replay."""
    params: dict[str, Any] = {"kind": fault.kind}
    defaults = Fault.__dataclass_fields__
    for key in _EFFECT_KEYS:
        value = getattr(fault, key)
        if key == "tc_bias_dps_per_c":
            if np.any(value):
                params[key] = [float(v) for v in value]
        elif value != defaults[key].default:
            params[key] = value
    return params


def describe_flags(flags: int) -> list[str]:
    """Fault kinds named by a ``fault_flags`` value."""
    return [kind for kind, bit in FAULT_FLAGS.items() if flags & bit]
