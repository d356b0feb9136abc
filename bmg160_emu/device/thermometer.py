"""The temperature sensor (5.2): the TEMP register, one conversion per rate sample, frozen
while the chip does not sample."""

from __future__ import annotations

import math
from collections.abc import Callable

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.registers import field_of

_TEMP = field_of("TEMP", "temp")


class Thermometer:
    """The TEMP register (5.2): one conversion per rate sample, frozen while not sampling."""

    def __init__(self, temperature_c: float | Callable[[float], float]) -> None:
        self.temperature_c = temperature_c
        self.frozen: tuple[int, int] | None = None  # (raw, last sample ns) when stopped

    @staticmethod
    def check(temperature_c: float | Callable[[float], float]) -> None:
        if not callable(temperature_c) and not math.isfinite(float(temperature_c)):
            raise ValueError("temperature must be finite")

    def raw(self, have_sample: bool, last_sample_ns: int) -> int:
        """The register byte: the conversion of the last sample, 0 before the first."""
        if not have_sample:
            return 0
        frozen = self.frozen
        if frozen is not None and last_sample_ns <= frozen[1]:
            return frozen[0]
        temp = self.temperature_c
        if callable(temp):
            temp = float(temp(last_sample_ns / NS_PER_S))
        raw = round((temp - choice.TEMP_ZERO_C) / choice.TEMP_LSB_K)
        return _TEMP.insert(0, max(-128, min(127, raw)))  # two's complement byte

    def freeze(self, have_sample: bool, last_sample_ns: int) -> None:
        self.frozen = (self.raw(have_sample, last_sample_ns), last_sample_ns)
