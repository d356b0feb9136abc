"""The transaction kinds every front end logs, and what each one does on the wire.

Kinds are smbus2's method names for the SMBus transfers (``read_byte_data``,
``read_i2c_block_data`` ...), ``i2c_read``/``i2c_write`` for the messages of a plain I2C
transfer (``I2C_RDWR``, ``read()``/``write()`` on /dev/i2c-N, MicroPython's and
CircuitPython's buses), ``spi_*`` for SPI frames, and two annotations that are no bus
traffic (a fault's onset, a true-rate change).

``KIND_FUNCS`` gives the adapter functionality bit (``I2C_FUNC_*``, <linux/i2c.h>) each I2C
kind needs: an adapter without it answers EOPNOTSUPP. The bits are written here, with the
kinds, because the kinds are what they describe; ``bmg160_emu.bus.kernel_abi`` combines
them into the masks an adapter reports.

Why "register writes": the same driver step is a ``write_byte_data`` through smbus2 and an
``i2c_write`` through Blinka or MicroPython; :func:`register_writes` of either is the same
``(register, value)`` pairs, so a test can ask what the driver wrote whatever its stack.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

# I2C_FUNCS bits (<linux/i2c.h>)
I2C_FUNC_I2C = 0x00000001
I2C_FUNC_10BIT_ADDR = 0x00000002
I2C_FUNC_PROTOCOL_MANGLING = 0x00000004
I2C_FUNC_SMBUS_PEC = 0x00000008
I2C_FUNC_NOSTART = 0x00000010
I2C_FUNC_SMBUS_BLOCK_PROC_CALL = 0x00008000
I2C_FUNC_SMBUS_QUICK = 0x00010000
I2C_FUNC_SMBUS_READ_BYTE = 0x00020000
I2C_FUNC_SMBUS_WRITE_BYTE = 0x00040000
I2C_FUNC_SMBUS_READ_BYTE_DATA = 0x00080000
I2C_FUNC_SMBUS_WRITE_BYTE_DATA = 0x00100000
I2C_FUNC_SMBUS_READ_WORD_DATA = 0x00200000
I2C_FUNC_SMBUS_WRITE_WORD_DATA = 0x00400000
I2C_FUNC_SMBUS_PROC_CALL = 0x00800000
I2C_FUNC_SMBUS_READ_BLOCK_DATA = 0x01000000
I2C_FUNC_SMBUS_WRITE_BLOCK_DATA = 0x02000000
I2C_FUNC_SMBUS_READ_I2C_BLOCK = 0x04000000
I2C_FUNC_SMBUS_WRITE_I2C_BLOCK = 0x08000000

# transaction kind -> the functionality bit it needs
KIND_FUNCS = {
    "write_quick": I2C_FUNC_SMBUS_QUICK,
    "read_quick": I2C_FUNC_SMBUS_QUICK,
    "read_byte": I2C_FUNC_SMBUS_READ_BYTE,
    "write_byte": I2C_FUNC_SMBUS_WRITE_BYTE,
    "read_byte_data": I2C_FUNC_SMBUS_READ_BYTE_DATA,
    "write_byte_data": I2C_FUNC_SMBUS_WRITE_BYTE_DATA,
    "read_word_data": I2C_FUNC_SMBUS_READ_WORD_DATA,
    "write_word_data": I2C_FUNC_SMBUS_WRITE_WORD_DATA,
    "process_call": I2C_FUNC_SMBUS_PROC_CALL,
    "read_block_data": I2C_FUNC_SMBUS_READ_BLOCK_DATA,
    "write_block_data": I2C_FUNC_SMBUS_WRITE_BLOCK_DATA,
    "block_process_call": I2C_FUNC_SMBUS_BLOCK_PROC_CALL,
    "read_i2c_block_data": I2C_FUNC_SMBUS_READ_I2C_BLOCK,
    "write_i2c_block_data": I2C_FUNC_SMBUS_WRITE_I2C_BLOCK,
    "i2c_read": I2C_FUNC_I2C,
    "i2c_write": I2C_FUNC_I2C,
}
I2C_KINDS = frozenset(KIND_FUNCS)
SPI_KINDS = frozenset({"spi_read", "spi_write", "spi_frame"})

# Kinds that carry data from the device to the host: a corrupted byte can only be heard here.
READ_KINDS = frozenset(("read_byte", "read_byte_data", "read_word_data", "process_call",
                        "read_block_data", "block_process_call", "read_i2c_block_data",
                        "i2c_read"))

# Kinds that carry no byte at all: the address alone.
NO_DATA_KINDS = frozenset(("write_quick", "read_quick"))

# Kinds whose written bytes, after the register, are register data (auto-increment).
# (write_byte and a 1-byte i2c_write only move the register pointer; a block write's
# first byte is its count, which this chip stores as data too: spec 2.1.)
REGISTER_WRITE_KINDS = frozenset(("write_byte_data", "write_word_data", "write_block_data",
                                  "write_i2c_block_data", "i2c_write", "spi_write",
                                  "process_call", "block_process_call"))

# Log entries that note an event of the session rather than bus traffic.
TRUE_RATE_KIND = "true_rate"  # the session changed a chip's true rate (a script's `rate`)
FAULT_KIND_PREFIX = "fault:"  # bmg160_emu.faults adds one at a fault's onset
ANNOTATION_KINDS = frozenset({TRUE_RATE_KIND})


def is_annotation(kind: str) -> bool:
    """A log entry that is no bus traffic: a fault's onset or a true-rate change."""
    return kind in ANNOTATION_KINDS or kind.startswith(FAULT_KIND_PREFIX)


def known_kind(kind: str) -> bool:
    """Whether a front end of this package logs ``kind`` (what a trace may hold)."""
    return kind in I2C_KINDS or kind in SPI_KINDS or is_annotation(kind)


def register_writes(entries: Iterable[Sequence[Any]],
                    address: int | None = None) -> list[tuple[int, int]]:
    """``(register, value)`` of every byte written into the device's registers, in order,
    from log entries in ``Transaction`` field order (a burst write is one pair per
    register): the same for one driver step whichever stack carried it. Failed
    transactions wrote nothing."""
    out: list[tuple[int, int]] = []
    for _time, _bus, addr, kind, register, written, _read, error in entries:
        if (error is None and register is not None and written
                and kind in REGISTER_WRITE_KINDS and (address is None or addr == address)):
            out += [(register + i, value) for i, value in enumerate(written)]
    return out
