"""A minimal register file implementing the chip primitives of docs/architecture.md.

Bus front-end tests use it where the behaviour under test is the bus's own (framing, errors,
argument handling), so that they do not depend on the chip model's physics.
"""

from __future__ import annotations

import threading

FIFO_DATA = 0x3F


class RegisterFileChip:
    """64 plain registers with the chip's pointer rules (spec 2.4) and nothing else."""

    def __init__(self, content: bytes | None = None) -> None:
        self.regs = bytearray(content or bytes(range(0x40)))
        self.pointer = 0
        self.lock = threading.RLock()
        self.time = 0.0
        self.reads: list[tuple[int, int]] = []
        self.writes: list[tuple[int, bytes]] = []

    def _next(self, reg: int) -> int:
        return reg if reg >= FIFO_DATA else reg + 1

    def read(self, reg: int, n: int) -> bytes:
        with self.lock:
            self.reads.append((reg, n))
            out = bytearray()
            for _ in range(n):
                out.append(self.regs[reg] if reg < 0x40 else 0)
                reg = self._next(reg)
            self.pointer = reg
            return bytes(out)

    def write(self, reg: int, data: bytes) -> None:
        with self.lock:
            self.writes.append((reg, bytes(data)))
            for value in data:
                if reg < 0x40:
                    self.regs[reg] = value
                reg = self._next(reg)
            self.pointer = reg

    def i2c_write(self, data: bytes) -> None:
        if not data:
            return
        with self.lock:
            self.pointer = data[0]
            if len(data) > 1:
                self.write(data[0], data[1:])

    def i2c_read(self, n: int) -> bytes:
        return self.read(self.pointer, n)

    def peek(self, reg: int) -> int:
        return self.regs[reg] if reg < 0x40 else 0

    def dump(self) -> bytes:
        return bytes(self.regs)

    def advance(self, seconds: float) -> None:
        self.time += seconds
