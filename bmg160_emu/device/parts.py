"""The BMG160 family: each part is the BMG160 model plus its differences, declared as data.

This module is the one factory for the family (issue 13): ``make_chip("bmi088_gyro")`` is a
``BMG160`` whose register table, reset values, write masks and register hooks are those of
the named part (``part_spec``), with the part's data-sheet noise profile unless ``profile``
is given. ``BMG160(...)`` stays the bare BMG160. docs/parts.md lists every difference and
its source.
"""

from __future__ import annotations

from types import MappingProxyType
from typing import Any

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.part_bmi088_gyro import BMI088_GYRO
from bmg160_emu.device.part_spec import BMG160_PART, Part, derive
from bmg160_emu.device.spec_choices import DEFAULT_PART

# The BMI055 and BMX055 gyroscopes are the BMG160 die (chip ID 0x0F, the same register map:
# PX4's BMI055 gyroscope header, the Linux bmg160 driver's ID table; docs/parts.md). What
# differs is the package: the gyroscope's two interrupt outputs are the module's INT3 and
# INT4 (INT1/INT2 belong to the accelerometer), and the data sheet's typical noise.
BMI055_GYRO = derive("bmi055_gyro", "BMI055 gyroscope", pins=("INT3", "INT4"),
                     noise_profile="bmi055_datasheet")
BMX055_GYRO = derive("bmx055_gyro", "BMX055 gyroscope", pins=("INT3", "INT4"),
                     noise_profile="bmx055_datasheet")

PARTS: MappingProxyType[str, Part] = MappingProxyType({
    p.name: p for p in (BMG160_PART, BMI055_GYRO, BMX055_GYRO, BMI088_GYRO)})
PART_NAMES: tuple[str, ...] = tuple(PARTS)


class UnknownPartError(ValueError):
    """A part name that is none of ``PART_NAMES``."""


def part_table(name: str) -> Part:
    """The part table of ``name`` (one of ``PART_NAMES``): where every way to a chip (options,
    a trace header, a rig, ``make_chip``) checks the name."""
    try:
        return PARTS[name]
    except (KeyError, TypeError):
        raise UnknownPartError(f"unknown part {name!r}: choose from {', '.join(PART_NAMES)}") \
            from None


def part_profile(part: str, profile: Any = None) -> Any:
    """The noise profile a chip of ``part`` takes: ``profile`` when one is given, else the
    part's data-sheet profile (``paper`` for the BMG160, issue 7)."""
    return part_table(part).noise_profile if profile is None else profile


def _chip_class(p: Part) -> type[BMG160]:
    """A BMG160 whose only difference is the part table it resets to (no second model)."""
    if p is BMG160_PART:
        return BMG160
    title = "".join(word.capitalize() for word in p.name.split("_"))
    return type(title, (BMG160,), {"part": p, "__doc__": f"The {p.title} (bmg160_emu.device.parts).",
                                   "__module__": __name__})


_CLASSES = {name: _chip_class(p) for name, p in PARTS.items()}
# the classes by the names their chips print (isinstance checks, introspection)
Bmi055Gyro, Bmx055Gyro, Bmi088Gyro = (_CLASSES[n] for n in ("bmi055_gyro", "bmx055_gyro", "bmi088_gyro"))


def make_chip(part: str = DEFAULT_PART, /, **options: Any) -> BMG160:
    """A chip of the named part with the BMG160 keyword ``options``; without ``profile``
    the part's data-sheet noise profile (``part_profile``)."""
    options["profile"] = part_profile(part, options.get("profile"))
    return _CLASSES[part](**options)
