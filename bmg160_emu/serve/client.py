"""A client of ``bmg160-emu serve``: a Python simulator, test or bench speaks the protocol.

Why: a test bench written in Python (or a co-simulation with its own dynamics) drives the
chips the way the Zephyr module's host half does, at the times it names, and sees the
errors and line levels a simulator sees. ``tests/test_serve_protocol.py`` uses it for every
message shape Zephyr's I2C and SPI APIs produce.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from bmg160_emu.serve import protocol as p

if TYPE_CHECKING:
    from typing_extensions import Self


class ServeError(Exception):
    """The server ended the connection (its ERROR line), or the connection broke."""


@dataclass(frozen=True)
class Result:
    """One reply: ``status`` 0 or -errno, ``detail`` (I2C: protocol messages completed;
    SPI: bytes), the line ``levels``, ``next_change_ns`` (None: no change due), the chips'
    ``time_ns`` and the ``data`` read (I2C: the read messages' bytes in order; SPI: rx)."""

    status: int
    detail: int
    levels: int
    next_change_ns: int | None
    time_ns: int
    data: bytes = b""


@dataclass(frozen=True)
class Hello:
    version: int
    realtime: bool
    chips: tuple[p.ChipRecord, ...]
    levels: int
    next_change_ns: int | None


@dataclass
class ServeClient:
    """A connection to the server at ``address`` (a UNIX socket path or (host, port))."""

    address: str | tuple[str, int]
    name: str = "python"
    timeout_s: float = 30.0
    events: list[Result] = field(default_factory=list)  # pushed EVENTs, oldest first

    def __post_init__(self) -> None:
        family = socket.AF_UNIX if isinstance(self.address, str) else socket.AF_INET
        self.sock = socket.socket(family, socket.SOCK_STREAM)
        self.sock.settimeout(self.timeout_s)
        self.sock.connect(self.address)
        self.seq = 0
        self.hello: Hello | None = None

    # ---------------------------------------------------------------- framing

    def send(self, mtype: int, time_ns: int, payload: bytes = b"") -> int:
        self.seq += 1
        self.sock.sendall(p.pack(mtype, self.seq, time_ns, payload))
        return self.seq

    def _exactly(self, size: int) -> bytes:
        data = bytearray()
        while len(data) < size:
            chunk = self.sock.recv(size - len(data))
            if not chunk:
                raise ServeError("the server closed the connection")
            data += chunk
        return bytes(data)

    def receive(self) -> tuple[p.Header, bytes]:
        """The next message from the server (an ERROR raises ServeError with its line)."""
        header = p.unpack_header(self._exactly(p.HEADER.size))
        payload = self._exactly(header.length)
        if header.type == p.ERROR:
            raise ServeError(payload[8:].decode("utf-8", "replace"))
        return header, payload

    def reply(self, seq: int, mtype: int) -> tuple[p.Header, bytes]:
        """The reply to request ``seq``; EVENTs that come first are kept in ``events``."""
        while True:
            header, payload = self.receive()
            if header.type == p.EVENT:
                self.events.append(_result(header, payload))
                continue
            if header.seq != seq or header.type != mtype | p.REPLY:
                raise ServeError(f"reply {header.type:#x} to request {header.seq}, expected "
                                 f"{mtype | p.REPLY:#x} to {seq}")
            return header, payload

    def request(self, mtype: int, time_ns: int, payload: bytes = b"") -> Result:
        header, data = self.reply(self.send(mtype, time_ns, payload), mtype)
        return _result(header, data)

    # ---------------------------------------------------------------- requests

    def greet(self) -> Hello:
        _, data = self.reply(self.send(p.HELLO, 0, p.HELLO_REQUEST.pack(
            p.VERSION, 0) + self.name.encode()), p.HELLO)
        version, mode, count, _, levels, next_ns = p.HELLO_REPLY.unpack_from(data)
        offset = p.HELLO_REPLY.size
        chips = []
        for _ in range(count):
            record, offset = p.ChipRecord.unpack_from(data, offset)
            chips.append(record)
        self.hello = Hello(version, mode == p.MODE_REALTIME, tuple(chips), levels,
                           None if next_ns == p.NO_TIME else next_ns)
        return self.hello

    def i2c(self, messages: Sequence[tuple[int, int, bytes | int]], time_ns: int) -> Result:
        """One I2C transfer: (address, flags, data for a write or length for a read)."""
        table = bytearray(p.I2C_REQUEST.pack(0, len(messages), 0))
        data = bytearray()
        for address, flags, body in messages:
            if flags & p.I2C_M_RD:
                table += p.I2C_MESSAGE.pack(address, flags, int(body), 0)  # type: ignore[arg-type]
            else:
                chunk = bytes(body)  # type: ignore[arg-type]
                table += p.I2C_MESSAGE.pack(address, flags, len(chunk), 0)
                data += chunk
        return self.request(p.I2C, time_ns, bytes(table + data))

    def write_read(self, address: int, register: int, count: int, time_ns: int) -> Result:
        """Zephyr's i2c_write_read / i2c_burst_read: [register], restart, read count."""
        return self.i2c([(address, 0, bytes([register])), (address, p.I2C_M_RD, count)],
                        time_ns)

    def burst_write(self, address: int, register: int, data: bytes, time_ns: int) -> Result:
        """Zephyr's i2c_burst_write: [register], then the data with no restart."""
        return self.i2c([(address, 0, bytes([register])),
                         (address, p.I2C_M_NOSTART, bytes(data))], time_ns)

    def spi(self, cs: int, tx: bytes | None, time_ns: int, *, length: int | None = None,
            mode: int = 0, keep_cs: bool = False) -> Result:
        """One SPI transfer on chip select ``cs``: ``tx`` (None: nothing driven, ``length``
        bytes clocked); ``keep_cs`` holds chip select low for the next transfer."""
        size = len(tx) if tx is not None else int(length or 0)
        mode |= (p.SPI_KEEP_CS if keep_cs else 0) | (p.SPI_NO_TX if tx is None else 0)
        payload = p.SPI_REQUEST.pack(0, cs, 8, 0, mode, 0, size) + (tx or b"")
        return self.request(p.SPI, time_ns, payload)

    def sync(self, time_ns: int) -> Result:
        return self.request(p.SYNC, time_ns)

    def set_rate(self, chip: int, rate_dps: Sequence[float], time_ns: int) -> Result:
        x, y, z = (float(v) for v in rate_dps)
        return self.request(p.SET_RATE, time_ns, p.SET_RATE_REQUEST.pack(chip, x, y, z))

    def bye(self, time_ns: int) -> Result:
        return self.request(p.BYE, time_ns)

    def wait_event(self, timeout_s: float) -> Result | None:
        """The next line change a real-time server pushes (None: none within timeout_s)."""
        if self.events:
            return self.events.pop(0)
        self.sock.settimeout(timeout_s)
        try:
            header, payload = self.receive()
        except TimeoutError:
            return None
        finally:
            self.sock.settimeout(self.timeout_s)
        if header.type != p.EVENT:
            raise ServeError(f"message {header.type:#x} while waiting for an EVENT")
        return _result(header, payload)

    def close(self) -> None:
        self.sock.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _result(header: p.Header, data: bytes) -> Result:
    status, detail, levels, next_ns = p.RESULT.unpack_from(data)
    return Result(status, detail, levels, None if next_ns == p.NO_TIME else next_ns,
                  header.time_ns, data[p.RESULT.size:])
