"""The BMG160 family: each part is the BMG160 model plus its differences, declared as data.

This module is the one factory for parts other than the bare BMG160 (issue 13). Today it
knows only ``bmg160``; the BMI055, BMX055 and BMI088 gyroscopes are added as tables of their
differences on top of the BMG160 register table, never as copies of the model.
"""

from __future__ import annotations

from typing import Any

from bmg160_emu.device.chip import BMG160

DEFAULT_PART = "bmg160"
PART_NAMES: tuple[str, ...] = ("bmg160",)


def make_chip(part: str = DEFAULT_PART, /, **options: Any) -> BMG160:
    """A chip of the named part with the BMG160 keyword ``options``."""
    if part not in PART_NAMES:
        raise ValueError(f"unknown part {part!r}: choose from {', '.join(PART_NAMES)}")
    return BMG160(**options)
