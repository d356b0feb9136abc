"""The corrupt_byte fault on the wire of one transaction, in either direction.

A glitch on SDA inverts one bit the receiver samples; the transaction itself succeeds. On a
transaction that reads (a register read, a process call, a plain read) the host hears the
``byte``-th byte it reads with bit ``bit`` inverted; on a write-only transaction the device
receives the ``byte``-th data byte after the register byte so, and stores it. A transaction
that carries no such byte is left alone, and the fault's event says so: a fault that cannot
act reports it rather than passing silently.
"""

from __future__ import annotations

from collections.abc import Callable

from bmg160_emu.faults.model import Fault
from bmg160_emu.traffic.kinds import READ_KINDS


class CorruptWire:
    """One corrupt_byte fault acting on one transaction (a ``WireFault`` for the bus);
    ``report(wire)`` is called once the transaction is over, with ``acted`` and ``what``
    saying what it did."""

    def __init__(self, fault: Fault, kind: str, report: Callable[[CorruptWire], None]) -> None:
        self.fault, self.report = fault, report
        self.reading = kind in READ_KINDS
        self.carried = 0  # bytes the transaction carried in the fault's direction
        self.acted = False
        self.what = ""

    def _flip(self, offset: int, data: bytes, direction: str) -> bytes:
        self.carried = max(self.carried, offset + len(data))
        place = self.fault.byte - offset
        if self.acted or not 0 <= place < len(data):
            return data
        out = bytearray(data)
        out[place] ^= 1 << self.fault.bit
        self.acted = True
        self.what = (f"{direction} byte {self.fault.byte} 0x{data[place]:02x} -> "
                     f"0x{out[place]:02x}")
        return bytes(out)

    def heard(self, offset: int, data: bytes) -> bytes:
        return self._flip(offset, data, "read") if self.reading else data

    def sent(self, offset: int, data: bytes) -> bytes:
        return data if self.reading else self._flip(offset, data, "written")

    def finished(self) -> None:
        if not self.acted:
            direction = "read" if self.reading else "wrote after its register"
            self.what = (f"not acted: the transaction {direction} {self.carried} byte"
                         f"{'' if self.carried == 1 else 's'}, no byte {self.fault.byte}")
        self.report(self)
