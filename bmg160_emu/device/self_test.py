"""The built-in self-test (6.8): BIST's ready, fail and rate_ok bits."""

from __future__ import annotations

from bmg160_emu.device import spec_choices as choice
from bmg160_emu.device.registers import field_of

_RATE_OK = field_of("BIST", "rate_ok")
_BIST_FAIL = field_of("BIST", "bist_fail")
_BIST_RDY = field_of("BIST", "bist_rdy")


class SelfTest:
    """The built-in self-test (6.8): ready BIST_TIME_NS after the trigger."""

    def __init__(self) -> None:
        self.start_ns: int | None = None

    def trigger(self, now_ns: int) -> None:
        self.start_ns = now_ns

    def register(self, now_ns: int, rate_ok: bool, inject_failure: bool) -> int:
        """The BIST register's read-only bits; ``inject_failure`` makes a finished test fail."""
        rdy = fail = 0
        if self.start_ns is not None and now_ns - self.start_ns >= choice.BIST_TIME_NS:
            rdy, fail = 1, int(inject_failure)
        return _RATE_OK.insert(_BIST_FAIL.insert(_BIST_RDY.insert(0, rdy), fail), rate_ok)
