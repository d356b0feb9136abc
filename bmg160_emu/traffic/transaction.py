"""What every front end records: one :class:`Transaction` per bus transaction.

A :class:`TransactionLog` is what a test asserts on (``log.filter(kind="write_byte_data")``)
and what a person prints (``print(log)``). Traces are JSON Lines of ``Transaction.to_dict()``;
a log forwards each new transaction to its ``sinks`` (for example a trace writer).
"""

from __future__ import annotations

import errno as _errno
import operator
import sys
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.traffic.kinds import is_annotation, register_writes

Sink = Callable[["Transaction"], None]


def errno_name(code: int) -> str:
    """'EREMOTEIO' for 121: the name a kernel person recognises, stable across libcs."""
    return _errno.errorcode.get(code, str(code))


def bytes_from_json(value: Any) -> bytes:
    """Bytes as a trace stores them: a list of ints, or hex text ("02 03", "0x02,0x03"); None is b""."""
    if value is None:
        return b""
    if isinstance(value, str):
        return bytes.fromhex(value.replace("0x", " ").replace(",", " "))
    return bytes(value)


class Transaction:
    """One bus transaction as the host saw it.

    ``time`` is the chip's time in seconds, ``bus`` the bus number (I2C) or name (``"spi0.0"``),
    ``address`` the 7-bit I2C address (``None`` on SPI), ``kind`` the transaction kind in
    smbus2's words (``read_i2c_block_data``, ``i2c_write``, ``spi_read`` ...), ``register``
    the register the transaction starts at when it names one, ``written``/``read`` the data
    bytes after the register, and ``error`` the errno name when it failed (``"EREMOTEIO"``).
    """

    __slots__ = ("address", "bus", "error", "kind", "read", "register", "time", "written")

    def __init__(
        self,
        time: float,
        bus: int | str,
        address: int | None,
        kind: str,
        register: int | None = None,
        written: bytes = b"",
        read: bytes = b"",
        error: str | None = None,
    ) -> None:
        self.time = time
        self.bus = bus
        self.address = address
        self.kind = kind
        self.register = register
        self.written = written
        self.read = read
        self.error = error

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Transaction):
            return NotImplemented
        return all(getattr(self, name) == getattr(other, name) for name in self.__slots__)

    def __repr__(self) -> str:
        fields = ", ".join(f"{name}={getattr(self, name)!r}" for name in self.__slots__)
        return f"Transaction({fields})"

    def __str__(self) -> str:
        where = f"{self.bus}" + (f" 0x{self.address:02x}" if self.address is not None else "")
        reg = f" reg 0x{self.register:02x}" if self.register is not None else ""
        text = f"{self.time:12.6f}s  {where:<9} {self.kind}{reg}"
        if is_annotation(self.kind):
            # not bus traffic: an event the session noted (a fault, a true-rate change) whose
            # written bytes are a description line (and machine-readable lines after it)
            lines = self.written.decode("utf-8", "replace").splitlines()
            return f"{text}: {lines[0]}" if lines else text
        if self.written:
            text += f" <- {self.written.hex(' ')}"
        if self.read:
            text += f" -> {self.read.hex(' ')}"
        if self.error:
            text += f"  FAILED {self.error}"
        return text

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: bytes become lists of ints."""
        return {
            "time": self.time,
            "bus": self.bus,
            "address": self.address,
            "kind": self.kind,
            "register": self.register,
            "written": list(self.written),
            "read": list(self.read),
            "error": self.error,
        }

    @classmethod
    def from_dict(cls, record: dict[str, Any]) -> Transaction:
        """Inverse of :meth:`to_dict`; bytes may also be hex strings ("02 03")."""
        try:
            return cls(
                time=float(record["time"]),
                bus=record.get("bus", 0),
                address=record.get("address"),
                kind=str(record["kind"]),
                register=record.get("register"),
                written=bytes_from_json(record.get("written")),
                read=bytes_from_json(record.get("read")),
                error=record.get("error"),
            )
        except KeyError as exc:
            raise ValueError(f"transaction record without {exc.args[0]!r}: {record!r}") from None


class TransactionLog:
    """The transactions of one bus, oldest first.

    ``maxlen`` bounds memory for long sessions (oldest entries drop out; ``total`` keeps
    counting). ``enabled = False`` stops recording. ``sinks`` are called with each new
    :class:`Transaction` (e.g. a trace writer). Entries are handed out as
    :class:`Transaction` objects (``entries``: as tuples in ``Transaction`` field order).

    The store is one flat list, ``fields``: each entry's eight fields in ``Transaction``
    order and a ninth, the time in integer ns when a fast path gives that instead (its
    ``time`` field is None then; the seconds are ``time_ns / NS_PER_S``, as the chip's
    ``time`` computes them, when the entry is read), one entry after another. Extending a
    list by a tuple frees the tuple at once, so an entry leaves nothing for the garbage
    collector to scan (a kept tuple per entry cost a polling read about 100 ns of
    collections), and keeping the clock's own ``ns`` object allocates nothing (a new float
    per entry cost about 100 ns more; tools/bench_fake_smbus.py). A front end's fast path
    records an entry with ``log.fields += (...)`` when there is no sink and calls
    :meth:`trim` every so often (it does nothing until ``len(log.fields)`` is over
    ``log.limit``). Dropped entries go in bulk
    (the list holds up to twice ``maxlen`` entries before a trim): a few ns per entry.
    """

    WIDTH = 9  # fields per entry: Transaction.__slots__ in order, then time_ns

    def __init__(self, maxlen: int | None = 100_000, sinks: Iterable[Sink] = ()) -> None:
        if maxlen is not None and maxlen < 0:
            raise ValueError(f"maxlen must be >= 0 or None, not {maxlen!r}")
        self.maxlen = maxlen
        self.fields: list[Any] = []
        # the fields' length at which a trim is due: 2 x maxlen entries (never, unbounded)
        self.limit = 2 * self.WIDTH * maxlen if maxlen is not None else sys.maxsize
        self.sinks: list[Sink] = list(sinks)
        self.enabled = True
        self._dropped = 0  # entries trimmed or cleared out: total counts them

    @property
    def total(self) -> int:
        """Every transaction recorded since the log was made, dropped and cleared ones too."""
        return self._dropped + len(self.fields) // self.WIDTH

    def record(
        self,
        time: float,
        bus: int | str,
        address: int | None,
        kind: str,
        register: int | None = None,
        written: bytes = b"",
        read: bytes = b"",
        error: str | None = None,
    ) -> None:
        """Append one transaction given by its fields."""
        self.add((time, bus, address, kind, register, written, read, error))

    def add(self, entry: tuple) -> None:
        """Append one transaction given as the tuple of its eight fields in ``Transaction``
        order (one argument to bind, no Transaction built unless a sink wants one)."""
        if len(entry) != 8:
            raise ValueError(f"a transaction has 8 fields, not {len(entry)}: {entry!r}")
        fields = self.fields
        fields += (*entry, None)
        if len(fields) > self.limit:
            self.trim()
        if self.sinks:
            transaction = Transaction(*entry)
            for sink in self.sinks:
                sink(transaction)

    def trim(self) -> None:
        """Drop the entries beyond the newest ``maxlen`` once ``fields`` is over ``limit``
        (a front end's fast path may call this as often as it likes: it looks first)."""
        fields = self.fields
        if self.maxlen is None or len(fields) <= self.limit:
            return
        excess = len(fields) - self.WIDTH * self.maxlen  # (a whole number of entries: each
        if excess > 0:  # entry goes in by one list extend, atomic under the GIL)
            del fields[:excess]
            self._dropped += excess // self.WIDTH

    def append(self, transaction: Transaction) -> None:
        t = transaction
        self.record(t.time, t.bus, t.address, t.kind, t.register, t.written, t.read, t.error)

    def clear(self) -> None:
        fields = self.fields
        self._dropped += len(fields) // self.WIDTH
        del fields[:]

    def _window(self) -> list[Any]:
        """A snapshot of the fields of the newest ``maxlen`` entries."""
        fields = self.fields[:]
        if self.maxlen is not None and len(fields) > self.WIDTH * self.maxlen:
            del fields[: len(fields) - self.WIDTH * self.maxlen]
        return fields

    @property
    def entries(self) -> list[tuple]:
        """The entries, oldest first, as tuples in ``Transaction`` field order (a snapshot)."""
        return [
            (time_ns / NS_PER_S if time is None else time, *rest)
            for time, *rest, time_ns in zip(*[iter(self._window())] * self.WIDTH)
        ]

    def __len__(self) -> int:
        n = len(self.fields) // self.WIDTH
        return n if self.maxlen is None else min(n, self.maxlen)

    def __iter__(self) -> Iterator[Transaction]:
        return (Transaction(*entry) for entry in self.entries)

    def __getitem__(self, index: int) -> Transaction:
        fields = self.fields[:]
        n = len(fields) // self.WIDTH
        shown = n if self.maxlen is None else min(n, self.maxlen)
        i = operator.index(index)
        if i < 0:
            i += shown
        if not 0 <= i < shown:
            raise IndexError("transaction log index out of range")
        start = (n - shown + i) * self.WIDTH
        time, *rest, time_ns = fields[start : start + self.WIDTH]
        return Transaction(time_ns / NS_PER_S if time is None else time, *rest)

    def __bool__(self) -> bool:
        return len(self) > 0

    def filter(
        self,
        *,
        kind: str | None = None,
        address: int | None = None,
        register: int | None = None,
        failed: bool | None = None,
    ) -> list[Transaction]:
        """The transactions matching every given criterion."""
        return [
            t
            for t in self
            if (kind is None or t.kind == kind)
            and (address is None or t.address == address)
            and (register is None or t.register == register)
            and (failed is None or (t.error is not None) == failed)
        ]

    def kinds(self) -> list[str]:
        return self._window()[3 :: self.WIDTH]

    def register_writes(self, address: int | None = None) -> list[tuple[int, int]]:
        """``(register, value)`` of every byte written into a device's registers (of the
        device at ``address``, or any), oldest first, one pair per register of a burst:
        the same for a driver whichever stack it uses (smbus2's ``write_byte_data``,
        Blinka's or MicroPython's ``i2c_write``)."""
        return register_writes(self.entries, address)

    def to_dicts(self) -> list[dict[str, Any]]:
        return [t.to_dict() for t in self]

    def __str__(self) -> str:
        if not self:
            return "(no transactions)"
        return "\n".join(str(t) for t in self)

    def __repr__(self) -> str:
        return f"<TransactionLog {len(self)} of {self.total} transactions>"
