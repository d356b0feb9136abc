"""The serve protocol, version 1: the messages a simulator and ``bmg160-emu serve`` exchange.

Why a protocol of our own: a simulator (Zephyr's native_sim, Renode, a test bench in any
language) has its own notion of time and its own bus model; it needs the chips' answers to
whole I2C and SPI transfers at the simulated time it names, and to know when an interrupt
line will next change so that it need not poll. The layout is fixed-size little-endian
fields a C client reads with one struct each (docs/serve-protocol.md has the tables; the
Zephyr module's host half, zephyr/src/bmg160_emu_link.c, is a client of it).

Every message is a 20-byte header, then ``length`` payload bytes::

    u32 length   payload bytes that follow (at most MAX_PAYLOAD)
    u16 type     HELLO, I2C, SPI, SYNC, SET_RATE, BYE; a reply is type | REPLY
    u16 flags    0 in version 1
    u32 seq      chosen by the client, echoed by the reply (0 in pushed events)
    u64 time_ns  request: the simulator's time; reply and event: the chips' time

I2C messages carry the Linux ``struct i2c_msg`` flags (i2c_rdwr): RD, TEN and NOSTART (the
message continues the previous one with no (repeated) start: Zephyr's ``i2c_burst_write``
sends the register and the data as two such write messages, one write on the wire).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

VERSION = 1

HEADER = struct.Struct("<IHHIQ")  # length, type, flags, seq, time_ns
MAX_PAYLOAD = 1 << 20  # bytes; larger is a protocol error (a client out of step)
NO_TIME = (1 << 64) - 1  # "never": next_change_ns when no line can change by itself

# request types; a reply is type | REPLY
HELLO = 0x01
I2C = 0x02
SPI = 0x03
SYNC = 0x04
SET_RATE = 0x05
BYE = 0x06
REPLY = 0x80
EVENT = 0xC0  # pushed by the server (real-time sessions): the line levels changed
ERROR = 0xFF  # the server's last message before it closes a connection it cannot follow

REQUEST_NAMES = {HELLO: "HELLO", I2C: "I2C", SPI: "SPI", SYNC: "SYNC",
                 SET_RATE: "SET_RATE", BYE: "BYE"}

# time modes (HELLO reply)
MODE_SIMULATED = 0  # the chips' clock follows the requests' time stamps
MODE_REALTIME = 1  # the chips run on wall time; stamps are recorded, not followed

# I2C message flags: the Linux values (include/uapi/linux/i2c.h)
I2C_M_RD = 0x0001
I2C_M_TEN = 0x0010
I2C_M_NOSTART = 0x4000
I2C_M_STOP = 0x8000  # a stop after this message (for the record: this chip behaves the same)
I2C_FLAGS_KNOWN = I2C_M_RD | I2C_M_TEN | I2C_M_NOSTART | I2C_M_STOP
I2C_MAX_MESSAGES = 42  # I2C_RDWR_IOCTL_MAX_MSGS (Linux i2c-dev)
I2C_MAX_MESSAGE_LEN = 8192  # i2c-dev's limit per message

# SPI mode bits: the Linux spi_device mode bits, then ours
SPI_CPHA = 0x01
SPI_CPOL = 0x02
SPI_CS_HIGH = 0x04
SPI_LSB_FIRST = 0x08
SPI_3WIRE = 0x10
SPI_LOOP = 0x20
SPI_KEEP_CS = 0x0100  # chip select stays low after this transfer: the frame goes on
SPI_NO_TX = 0x0200  # nothing sent (MOSI undriven, zeros); no tx bytes in the message
SPI_MODES_KNOWN = (SPI_CPHA | SPI_CPOL | SPI_CS_HIGH | SPI_LSB_FIRST | SPI_3WIRE | SPI_LOOP
                   | SPI_KEEP_CS | SPI_NO_TX)
SPI_MAX_LEN = 4096  # bytes in one transfer (spidev's default bufsiz)

HELLO_REQUEST = struct.Struct("<HH")  # version, reserved; then the client's name (UTF-8)
HELLO_REPLY = struct.Struct("<HHHHQQ")  # version, mode, chips, reserved, levels, next_change_ns
CHIP_RECORD = struct.Struct("<BBBBBB")  # i2c bus, i2c address, spi cs, pins, chip id, name length
I2C_REQUEST = struct.Struct("<BBH")  # bus, message count, reserved
I2C_MESSAGE = struct.Struct("<HHHH")  # address, flags, length, reserved
SPI_REQUEST = struct.Struct("<BBBBHHI")  # bus, cs, bits per word, reserved, mode, reserved, length
SET_RATE_REQUEST = struct.Struct("<B7xddd")  # chip index, x, y, z in deg/s
RESULT = struct.Struct("<iIQQ")  # status (0 or -errno), detail, levels, next_change_ns
NONE_8 = 0xFF  # "none" in a one-byte address or chip-select field


class ProtocolError(Exception):
    """A message the server cannot follow (wrong size, unknown type, out of step): the
    connection ends with an ERROR message carrying this one line."""


@dataclass(frozen=True)
class Header:
    length: int
    type: int
    flags: int
    seq: int
    time_ns: int


def pack(mtype: int, seq: int, time_ns: int, payload: bytes = b"") -> bytes:
    """One message: the header, then the payload."""
    return HEADER.pack(len(payload), mtype, 0, seq, time_ns) + payload


def unpack_header(data: bytes | bytearray | memoryview) -> Header:
    """The header at the start of ``data`` (HEADER.size bytes), checked."""
    length, mtype, flags, seq, time_ns = HEADER.unpack_from(data)
    if length > MAX_PAYLOAD:
        raise ProtocolError(f"message of {length} bytes (at most {MAX_PAYLOAD}): "
                            "not a bmg160-emu serve client, or out of step")
    if flags:
        raise ProtocolError(f"header flags 0x{flags:04x}: version {VERSION} has none")
    return Header(length, mtype, flags, seq, time_ns)


def result(status: int, detail: int, levels: int, next_change_ns: int | None) -> bytes:
    """The fixed start of every reply to a timed request (and of an EVENT)."""
    return RESULT.pack(status, detail, levels, NO_TIME if next_change_ns is None
                       else next_change_ns)


@dataclass(frozen=True)
class ChipRecord:
    """One chip as the HELLO reply lists it; its lines are bits 2i (INT1) and 2i+1 (INT2)
    of every ``levels`` field, i its place in the list."""

    name: str
    chip_id: int
    i2c_address: int | None
    spi_cs: int | None
    pins: int
    i2c_bus: int = 0

    def pack(self) -> bytes:
        name = self.name.encode()[:255]
        return CHIP_RECORD.pack(
            self.i2c_bus, NONE_8 if self.i2c_address is None else self.i2c_address,
            NONE_8 if self.spi_cs is None else self.spi_cs, self.pins, self.chip_id,
            len(name)) + name

    @classmethod
    def unpack_from(cls, data: bytes, offset: int) -> tuple[ChipRecord, int]:
        bus, address, cs, pins, chip_id, size = CHIP_RECORD.unpack_from(data, offset)
        offset += CHIP_RECORD.size
        name = bytes(data[offset:offset + size]).decode("utf-8", "replace")
        return (cls(name, chip_id, None if address == NONE_8 else address,
                    None if cs == NONE_8 else cs, pins, bus), offset + size)
