"""One simulator's board: its chips on their own clock, and its requests served on them.

Why one board per connection: each simulator has its own time (a native_sim process starts
at 0), so two simulators sharing chips would pull one clock two ways. A board is built
fresh for every client from the same options and seed: the same firmware sees the same
counts, alone or beside another client.

A request's time stamp moves the board's clock (simulated mode); every reply carries the
levels of the chips' interrupt lines and the earliest time one may change by itself
(``BMG160.next_pin_change_ns``), so the simulator sets a timer instead of polling.
Transfers go through the same :class:`~bmg160_emu.bus.i2c.I2CBus` and
:class:`~bmg160_emu.bus.spi.FakeSpiDev` as every other front end: NACK for an absent
address, fault hooks, the transaction log and its trace sinks.
"""

from __future__ import annotations

import errno
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass, field
from typing import Any

from bmg160_emu.bus.i2c import I2C_SMBUS_BLOCK_MAX, I2CBus, I2CMessage
from bmg160_emu.bus.spi import FakeSpiDev
from bmg160_emu.clock import NS_PER_S, VirtualClock
from bmg160_emu.device.contract import InterruptPins, RateSensor
from bmg160_emu.device.registers import address_of
from bmg160_emu.durations import MAX_SIMULATED_S
from bmg160_emu.serve import protocol as p
from bmg160_emu.traffic.transaction import TransactionLog, errno_name

MAX_TIME_NS = int(MAX_SIMULATED_S * NS_PER_S)  # the one cap on simulated time (durations)
CHIP_ID = address_of("CHIP_ID")


@dataclass
class Board:
    """What a session serves: ``chips`` {I2C address: device} on ``clock`` (every device
    shares it), ``spi`` {chip select: device}, and the bus number the log records."""

    chips: dict[int, Any]
    clock: Any
    spi: dict[int, Any] = field(default_factory=dict)
    bus_number: int = 0


@dataclass
class SessionStats:
    """What one session served, for ``--stats``."""

    requests: dict[str, int] = field(default_factory=dict)
    failed: int = 0  # requests answered with a status other than 0
    i2c_messages: int = 0
    spi_bytes: int = 0
    busy_s: float = 0.0  # time spent serving requests (host time)
    edges: list[int] = field(default_factory=list)  # level changes each line showed
    protocol_error: str | None = None

    def as_dict(self) -> dict[str, Any]:
        total = sum(self.requests.values())
        return {"requests": dict(self.requests), "failed": self.failed,
                "i2c_messages": self.i2c_messages, "spi_bytes": self.spi_bytes,
                "busy_s": round(self.busy_s, 6),
                "us_per_request": round(self.busy_s / total * 1e6, 2) if total else 0.0,
                "edges": list(self.edges), "protocol_error": self.protocol_error}


class Session:
    """One connected simulator: HELLO first, then timed requests, each answered in turn."""

    def __init__(self, number: int, board: Board, *, realtime: bool = False) -> None:
        self.number = number
        self.board = board
        self.realtime = realtime
        self.log = TransactionLog()
        self.bus = I2CBus(board.bus_number, board.chips, log=self.log)
        self.spi: dict[int, FakeSpiDev] = {}
        for cs, chip in board.spi.items():
            dev = FakeSpiDev(chip)
            dev.name = f"spi{board.bus_number}.{cs}"
            dev.log = self.log
            self.spi[cs] = dev
        # chips in the HELLO list order: I2C devices by address, then SPI-only ones
        self.chips: list[Any] = list(dict.fromkeys(
            [board.chips[a] for a in sorted(board.chips)]
            + [board.spi[c] for c in sorted(board.spi)]))
        # (bit of ``levels``, chip, pin): INT1 of chip i is bit 2i, INT2 bit 2i + 1
        self.pins = [(2 * i + pin - 1, chip, pin) for i, chip in enumerate(self.chips)
                     if isinstance(chip, InterruptPins) for pin in (1, 2)]
        self.stats = SessionStats(edges=[0] * 2 * len(self.chips))
        self.greeted = False
        self.client_name = ""
        self.last_stamp_ns = 0
        self.last_levels: int | None = None
        self.closing = False  # BYE answered: the connection ends after the reply

    # ---------------------------------------------------------------- lines

    def levels(self) -> int:
        """The electrical level of every line: bit 2i INT1, 2i+1 INT2 of chip i."""
        value = 0
        for bit, chip, pin in self.pins:
            if chip.int_pin_level(pin):
                value |= 1 << bit
        if self.last_levels is not None and value != self.last_levels:
            changed = value ^ self.last_levels
            for bit, _, _ in self.pins:
                if changed >> bit & 1:
                    self.stats.edges[bit] += 1
        self.last_levels = value
        return value

    def next_change_ns(self) -> int | None:
        """The earliest time a line may change by itself (None: only a transfer can)."""
        due = [t for chip in self.chips
               if (t := getattr(chip, "next_pin_change_ns", _never)()) is not None]
        return min(due, default=None)

    def now_ns(self) -> int:
        return int(self.board.clock.now_ns())

    def result(self, status: int, detail: int = 0) -> bytes:
        if status:
            self.stats.failed += 1
        return p.result(status, detail, self.levels(), self.next_change_ns())

    # ---------------------------------------------------------------- requests

    def hello(self, payload: bytes) -> bytes:
        """The HELLO reply: version, time mode, the chips and their lines."""
        if len(payload) < p.HELLO_REQUEST.size:
            raise p.ProtocolError(f"HELLO of {len(payload)} bytes: expected at least "
                                  f"{p.HELLO_REQUEST.size}")
        version, _ = p.HELLO_REQUEST.unpack_from(payload)
        if version != p.VERSION:
            raise p.ProtocolError(f"protocol version {version}: this server speaks "
                                  f"version {p.VERSION}")
        self.client_name = payload[p.HELLO_REQUEST.size:][:64].decode("utf-8", "replace")
        self.greeted = True
        records = []
        for chip in self.chips:
            address = next((a for a, c in self.board.chips.items() if c is chip), None)
            cs = next((s for s, c in self.board.spi.items() if c is chip), None)
            records.append(p.ChipRecord(
                _chip_name(chip), _chip_id(chip), address, cs,
                2 if isinstance(chip, InterruptPins) else 0, self.board.bus_number).pack())
        head = p.HELLO_REPLY.pack(p.VERSION, p.MODE_REALTIME if self.realtime
                                  else p.MODE_SIMULATED, len(self.chips), 0,
                                  self.levels(), _or_never(self.next_change_ns()))
        return head + b"".join(records)

    def serve(self, mtype: int, time_ns: int, payload: bytes) -> bytes:
        """The reply payload to one timed request (after HELLO)."""
        started = time.perf_counter()
        name = p.REQUEST_NAMES.get(mtype)
        if name is None or mtype == p.HELLO:
            raise p.ProtocolError(f"unknown message type 0x{mtype:02x}" if name is None
                                  else "a second HELLO")
        self.stats.requests[name] = self.stats.requests.get(name, 0) + 1
        try:
            if not self.realtime:
                status = self._follow(time_ns)
                if status:
                    return self.result(status)
            if mtype == p.I2C:
                return self._i2c(payload)
            if mtype == p.SPI:
                return self._spi(payload)
            if mtype == p.SET_RATE:
                return self._set_rate(payload)
            if mtype == p.BYE:
                self.closing = True
            if payload:
                raise p.ProtocolError(f"{name} with {len(payload)} payload bytes: it has none")
            return self.result(0)
        finally:
            self.stats.busy_s += time.perf_counter() - started

    def _follow(self, time_ns: int) -> int:
        """Move the board's clock to the request's stamp; -EINVAL for one that goes back
        or past the cap on simulated time (the request is then not served)."""
        if time_ns < self.last_stamp_ns or time_ns > MAX_TIME_NS:
            return -errno.EINVAL
        self.last_stamp_ns = time_ns
        clock = self.board.clock
        if isinstance(clock, VirtualClock):
            step = time_ns - clock.now_ns()
            if step > 0:
                clock.advance_ns(step)
        return 0

    def _i2c(self, payload: bytes) -> bytes:
        if len(payload) < p.I2C_REQUEST.size:
            raise p.ProtocolError(f"I2C request of {len(payload)} bytes: shorter than its "
                                  "header")
        _bus, count, _ = p.I2C_REQUEST.unpack_from(payload)
        offset = p.I2C_REQUEST.size
        table_end = offset + count * p.I2C_MESSAGE.size
        if len(payload) < table_end:
            raise p.ProtocolError(f"I2C request of {count} messages in {len(payload)} bytes: "
                                  "its message table is cut short")
        entries = [p.I2C_MESSAGE.unpack_from(payload, offset + i * p.I2C_MESSAGE.size)[:3]
                   for i in range(count)]
        written = sum(n for _, flags, n in entries if not flags & p.I2C_M_RD)
        if len(payload) != table_end + written:
            raise p.ProtocolError(f"I2C request: {len(payload) - table_end} data bytes for "
                                  f"write messages of {written}")
        if not 1 <= count <= p.I2C_MAX_MESSAGES or any(
                flags & ~p.I2C_FLAGS_KNOWN or n > p.I2C_MAX_MESSAGE_LEN or address > 0x3FF
                or (i == 0 and flags & p.I2C_M_NOSTART)
                or (flags & p.I2C_M_NOSTART and (flags ^ entries[i - 1][1]) & p.I2C_M_RD)
                for i, (address, flags, n) in enumerate(entries)):
            return self.result(-errno.EINVAL)
        # the wire's messages: NOSTART continues the previous one (i2c_burst_write)
        wire: list[tuple[I2CMessage, int]] = []  # (message, protocol messages it holds)
        data = memoryview(payload)[table_end:]
        for address, flags, n in entries:
            if flags & p.I2C_M_RD:
                chunk = b""
            else:
                chunk, data = bytes(data[:n]), data[n:]
            if flags & p.I2C_M_NOSTART:
                last, held = wire[-1]
                if last.read:
                    last.length += n
                else:
                    last.data += chunk
                    last.length = len(last.data)
                wire[-1] = (last, held + 1)
            elif flags & p.I2C_M_TEN:
                wire.append((I2CMessage(0x80 | address & 0x7F, False), 1))  # nobody: a NACK
            elif flags & p.I2C_M_RD:
                wire.append((I2CMessage.read_message(address, n), 1))
            else:
                wire.append((I2CMessage.write(address, chunk), 1))
        self.stats.i2c_messages += count
        status, done = self._transfer([m for m, _ in wire])
        reads = b"".join(m.data for m, _ in wire[:done] if m.read)
        held = sum(k for _, k in wire[:done])
        return self.result(status, held) + reads

    def _transfer(self, messages: Sequence[I2CMessage]) -> tuple[int, int]:
        """Run the wire's messages in one transfer: (status, messages completed)."""
        bus = self.bus
        if (len(messages) == 2 and not bus.transaction_hooks
                and not (w := messages[0]).read and len(w.data) == 1
                and (r := messages[1]).read and r.address == w.address
                and 0 < r.length <= I2C_SMBUS_BLOCK_MAX and w.address in bus.devices):
            # a register read: the SMBus I2C block read on the wire (and in the log, as
            # from i2c-dev and virtio-i2c)
            r.data = bus.read_i2c_block_data(w.address, w.data[0], r.length)
            return 0, 2
        chips = {id(c): c for m in messages if (c := bus.devices.get(m.address)) is not None}
        done = 0
        with ExitStack() as stack:  # no other transfer between this one's messages
            for key in sorted(chips):
                stack.enter_context(chips[key].lock)
            for message in messages:
                if message.address > 0x7F:  # a 10-bit address: no such device here
                    self.log.record(self.board.clock.now_ns() / NS_PER_S, bus.number,
                                    message.address & 0x7F, "i2c_read" if message.read
                                    else "i2c_write", error=errno_name(bus.nack_errno))
                    return -bus.nack_errno, done
                try:
                    bus.i2c_transfer([message])
                except OSError as exc:
                    return -(exc.errno or errno.EIO), done
                done += 1
        return 0, done

    def _spi(self, payload: bytes) -> bytes:
        if len(payload) < p.SPI_REQUEST.size:
            raise p.ProtocolError(f"SPI request of {len(payload)} bytes: shorter than its "
                                  "header")
        _bus, cs, bits, _, mode, _, length = p.SPI_REQUEST.unpack_from(payload)
        tx = bytes(payload[p.SPI_REQUEST.size:])
        if len(tx) != (0 if mode & p.SPI_NO_TX else length):
            raise p.ProtocolError(f"SPI request of {length} bytes carries {len(tx)} tx bytes")
        dev = self.spi.get(cs)
        if (dev is None or mode & ~p.SPI_MODES_KNOWN or length > p.SPI_MAX_LEN
                or bits not in (0, 8) or (length == 0 and mode & p.SPI_KEEP_CS)):
            return self.result(-errno.ENODEV if dev is None else -errno.EINVAL)
        self.stats.spi_bytes += length
        dev.mode = mode & (p.SPI_CPHA | p.SPI_CPOL)
        dev.cshigh = bool(mode & p.SPI_CS_HIGH)
        dev.lsbfirst = bool(mode & p.SPI_LSB_FIRST)
        dev.threewire = bool(mode & p.SPI_3WIRE)
        dev.loop = bool(mode & p.SPI_LOOP)
        # chip select held (spidev's NO_CS) during the transfer, so a frame held low by the
        # last one goes on; released after it unless KEEP_CS: then the frame ends
        dev.no_cs = True
        try:
            if length == 0:
                rx = b""
            elif mode & p.SPI_NO_TX:
                rx = bytes(dev.readbytes(length))
            elif dev.threewire:
                dev.writebytes(list(tx))
                rx = bytes(length)
            else:
                rx = bytes(dev.xfer2(list(tx)))
        except OSError as exc:
            dev.no_cs = False
            return self.result(-(exc.errno or errno.EIO)) + bytes(length)
        if not mode & p.SPI_KEEP_CS:
            dev.no_cs = False
        return self.result(0, length) + rx

    def _set_rate(self, payload: bytes) -> bytes:
        if len(payload) != p.SET_RATE_REQUEST.size:
            raise p.ProtocolError(f"SET_RATE of {len(payload)} bytes: expected "
                                  f"{p.SET_RATE_REQUEST.size}")
        index, x, y, z = p.SET_RATE_REQUEST.unpack(payload)
        if index >= len(self.chips) or not isinstance(self.chips[index], RateSensor):
            return self.result(-errno.ENODEV)
        from bmg160_emu import limits
        from bmg160_emu.io.trace import true_rate_entry

        try:
            rate = [float(limits.RATE_DPS.check(v, "true rate")) for v in (x, y, z)]
        except ValueError:
            return self.result(-errno.EINVAL)
        chip = self.chips[index]
        chip.set_true_rate(tuple(rate))
        address = getattr(chip, "address", None)
        self.log.append(true_rate_entry(chip.time, self.board.bus_number, address or 0, rate))
        return self.result(0)


def _never() -> None:
    return None


def _or_never(value: int | None) -> int:
    return p.NO_TIME if value is None else value


def _chip_id(chip: Any) -> int:
    """The content of the chip's ID register (a stand-in declares where its is)."""
    spec = getattr(chip, "spec", None)
    return int(chip.peek(spec.chip_id_register if spec is not None else CHIP_ID))


def _chip_name(chip: Any) -> str:
    spec = getattr(chip, "spec", None)
    if spec is not None:
        return str(spec.name)
    part = getattr(chip, "part", None)
    return str(getattr(part, "name", part or "bmg160"))


BoardFactory = Callable[[int], Board]
