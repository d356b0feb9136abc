"""A fault on the wire of one transaction: the bytes the host hears, the bytes the device
receives.

Why here: a glitch on SDA changes a bit the receiver samples, in either direction, without
the transaction failing; the chip's primitives and the host's call both stay as they are.
A transaction hook with ``takes_register`` (the fault schedule's) may return a
:class:`WireFault`; the bus then hands the chip wrapped in :class:`WiredChip` to the
transaction, so every read primitive's bytes pass through ``heard`` and every write
primitive's data bytes (after the register byte) through ``sent``, each with its offset in
the transaction, and ``finished`` is called once the transaction is logged or failed, so a
fault that found nothing to change can say so.
"""

from __future__ import annotations

from typing import Any, Protocol


class WireFault(Protocol):
    """What a transaction hook may return to change the bytes on the wire."""

    def heard(self, offset: int, data: bytes) -> bytes:
        """The bytes the host reads: ``data[0]`` is byte ``offset`` of what it reads."""

    def sent(self, offset: int, data: bytes) -> bytes:
        """The data bytes the device receives after the register byte, from ``offset``."""

    def finished(self) -> None:
        """The transaction is over (logged, or failed)."""


class WiredChip:
    """The chip as the host reaches it during one transaction on a faulty wire; every
    attribute but the four primitives is the chip's."""

    def __init__(self, chip: Any, wires: list[WireFault]) -> None:
        self.chip, self.wires = chip, wires
        self.heard_offset = self.sent_offset = 0
        self.done = False

    def __getattr__(self, name: str) -> Any:
        return getattr(self.chip, name)

    def _heard(self, data: bytes) -> bytes:
        offset, self.heard_offset = self.heard_offset, self.heard_offset + len(data)
        for wire in self.wires:
            data = wire.heard(offset, data)
        return data

    def _sent(self, data: bytes) -> bytes:
        offset, self.sent_offset = self.sent_offset, self.sent_offset + len(data)
        for wire in self.wires:
            data = wire.sent(offset, data)
        return data

    def read(self, register: int, count: int) -> bytes:
        return self._heard(self.chip.read(register, count))

    def i2c_read(self, count: int) -> bytes:
        return self._heard(self.chip.i2c_read(count))

    def write(self, register: int, data: bytes) -> None:
        self.chip.write(register, self._sent(bytes(data)))

    def i2c_write(self, data: bytes) -> None:
        data = bytes(data)  # data[0] is the register byte: it reaches the chip as it is
        self.chip.i2c_write(data[:1] + self._sent(data[1:]) if len(data) > 1 else data)

    def finish(self) -> None:
        if not self.done:
            self.done = True
            for wire in self.wires:
                wire.finished()
