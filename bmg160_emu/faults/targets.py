"""What a fault acts on, outside a rig, and the few chip calls faults make.

A rig's gyros are its own targets (:class:`~bmg160_emu.faults.model.GyroTarget`); outside a
rig a fault acts on :class:`ChipOnBus` (the pytest plugin's chip on its bus) or on
:class:`LoneChip` (a chip with no bus: sample and chip faults only). The chip calls are in
one place so that a device without one of them (a stand-in, the simulated firmware) is
refused with a sentence, not an AttributeError in the middle of a run.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class ChipOnBus:
    """One chip on one I2C bus as a fault target, outside any rig (the pytest plugin's
    chip on its bus): bus faults act on that bus, the others on the chip."""

    chip: Any
    bus: Any
    address: int = -1  # the chip's own address unless given
    index: int = 0

    def __post_init__(self) -> None:
        if self.address < 0:
            self.address = int(getattr(self.chip, "address", 0x68))


@dataclass
class LoneChip:
    """A chip outside any rig, as a fault target (no bus: bus faults need one)."""

    chip: Any
    index: int = 0
    bus: Any = None

    @property
    def address(self) -> int:
        return int(getattr(self.chip, "address", 0x68))


def clock_time(chip: Any) -> float:
    """The time of the chip's clock, in s (ahead of ``chip.time`` until the chip catches up)."""
    clock = getattr(chip, "clock", None)
    if clock is not None and hasattr(clock, "now"):
        return float(clock.now())
    return float(chip.time)


def stall(chip: Any, seconds: float) -> None:
    """A timed-out transfer takes the adapter's timeout: virtual time moves on by that much."""
    clock = getattr(chip, "clock", None)
    if clock is not None and hasattr(clock, "advance"):
        clock.advance(seconds)


def poke(chip: Any, register: int, value: int) -> None:
    """Change register content as radiation would: no bus, no access rules (the chip's
    ``poke`` primitive, device/contract.py). A device without it cannot take an upset."""
    poke_register = getattr(chip, "poke", None)
    if poke_register is None:
        raise TypeError(f"{type(chip).__name__} has no poke(register, value): a register "
                        f"upset needs it (docs/architecture.md, the chip's primitives)")
    poke_register(register, value)


def base_temperature(gyro: Any) -> float:
    """The die temperature a rig's gyro starts from, deg C (23 outside a rig)."""
    spec = getattr(gyro, "spec", None)
    return float(getattr(spec, "temperature_c", 23.0))


def set_temperature(chip: Any, celsius: float) -> None:
    if hasattr(chip, "set_temperature"):
        chip.set_temperature(celsius)
    else:
        chip.temperature_c = celsius
