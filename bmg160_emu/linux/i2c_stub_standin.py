"""Keep a Linux i2c-stub chip in step with a register-file stand-in (device/standin.py).

Why: a kernel driver of a companion device (the kernel's bmc150-accel for the BMI055/BMX055
accelerometer, bmc150_magn for the BMM150) probes it through i2c-stub as the gyro's driver
does. Plain i2c-stub memory loaded from a dump would take any write; this adapter applies
what the client wrote to the stand-in (write masks, read-only bits, soft reset, the power
gate) and writes back what the stand-in then reads, so the driver sees the declared chip.

The memory model is i2c-stub's (see linux/i2c_stub.py): slot r holds reg[r] | reg[r+1] << 8
so byte, word and block reads agree. A stand-in has no time behaviour: nothing changes
unless the client writes, so a refresh is a poll of the whole low-byte map (8 block reads)
and writes only where the stand-in now differs from the stub.

What i2c-stub cannot express: a write the client makes between the poll and the write-back
of that same register is seen at the next poll (each write-back is re-read first, as the
gyro adapter does); reads have no side effects.
"""

from __future__ import annotations

import errno
import time
from collections.abc import Callable
from typing import Any

from bmg160_emu.bus import kernel_abi as abi

SLOTS = 256  # i2c-stub's slots per chip address (drivers/i2c/i2c-stub.c)
DEFAULT_POLL_HZ = 200.0  # a probe's write-then-read completes well within a driver's delays


class StandinStubAdapter:
    """Mirror a stand-in into i2c-stub's memory for ``address`` on ``/dev/i2c-<bus>``."""

    def __init__(self, device: Any, bus: int, address: int, smbus: Any = None,
                 poll_hz: float = DEFAULT_POLL_HZ) -> None:
        if not poll_hz > 0:
            raise ValueError(f"poll rate must be > 0 Hz, not {poll_hz!r}")
        self.device = device
        self.address = address
        if smbus is None:
            from smbus2 import SMBus

            smbus = SMBus(bus, force=True)  # I2C_SLAVE answers EBUSY while a driver is bound
        self.smbus = smbus
        self.poll_hz = float(poll_hz)
        self.shadow: list[int | None] = [None] * SLOTS  # low byte the adapter left in each slot
        self.high: list[int | None] = [None] * SLOTS
        self.events: list[dict[str, Any]] = []  # each client write, with what it reads after
        self.polls = 0

    def _read_lows(self) -> list[int]:
        out: list[int] = []
        for first in range(0, SLOTS, abi.I2C_SMBUS_BLOCK_MAX):
            out += self.smbus.read_i2c_block_data(self.address, first, abi.I2C_SMBUS_BLOCK_MAX)
        return out

    def preload(self) -> None:
        """The stand-in's whole map in place (words first for the high bytes, then lows)."""
        image = self.device.dump()
        for reg in range(SLOTS):
            high = image[reg + 1] if reg + 1 < SLOTS else 0
            self.smbus.write_word_data(self.address, reg, image[reg] | high << 8)
            self.high[reg] = high
        for first in range(0, SLOTS, abi.I2C_SMBUS_BLOCK_MAX):
            chunk = image[first:first + abi.I2C_SMBUS_BLOCK_MAX]
            self.smbus.write_i2c_block_data(self.address, first, list(chunk))
        self.shadow = list(image)

    def refresh(self) -> None:
        """Apply the client's writes (in register order) and write back what changed."""
        self.polls += 1
        lows = self._read_lows()
        writes = {reg: v for reg, v in enumerate(lows) if self.shadow[reg] != v}
        reset = self.device.spec.soft_reset
        if reset is not None and reset.register in writes and reset.triggered_by(
                writes[reset.register]):
            # one poll cannot tell the order of the writes it sees; a driver resets first
            # and configures after, so the reset is applied first (else it undoes them)
            writes = {reset.register: writes.pop(reset.register), **writes}
        for reg, value in writes.items():
            self.device.write(reg, bytes([value]))
            self.shadow[reg] = value
        if not writes:
            return
        image = self.device.dump()
        self.events.append({"writes": {f"0x{r:02x}": f"0x{v:02x}" for r, v in writes.items()},
                            "differs_after": sum(a != b for a, b in zip(image, lows))})
        for reg in range(SLOTS):
            if self.shadow[reg] != image[reg]:
                if self.smbus.read_byte_data(self.address, reg) != self.shadow[reg]:
                    continue  # the client wrote again meanwhile: next poll
                self.smbus.write_byte_data(self.address, reg, image[reg])
                self.shadow[reg] = image[reg]
        for reg in range(SLOTS):
            high = image[reg + 1] if reg + 1 < SLOTS else 0
            low = self.shadow[reg]
            if self.high[reg] == high or low is None:
                continue
            if self.smbus.read_byte_data(self.address, reg) != low:
                continue
            self.smbus.write_word_data(self.address, reg, low | high << 8)
            self.high[reg] = high

    def run(self, duration_s: float | None = None,
            should_stop: Callable[[], bool] | None = None, preload: bool = True) -> int:
        """Poll at ``poll_hz`` until ``duration_s`` has passed or ``should_stop()``; returns
        the number of polls."""
        if preload:
            self.preload()
        start = time.monotonic()
        period = 1.0 / self.poll_hz
        while not (duration_s is not None and time.monotonic() - start >= duration_s):
            if should_stop is not None and should_stop():
                break
            try:
                self.refresh()
            except OSError as exc:
                if exc.errno not in (errno.ENXIO, errno.EAGAIN, errno.EBUSY):
                    raise
            time.sleep(period)
        return self.polls

    def close(self) -> None:
        close = getattr(self.smbus, "close", None)
        if close is not None:
            close()
