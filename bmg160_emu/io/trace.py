"""Transaction traces: JSON Lines files of every bus transaction, decoded for a person,
and replayed against a fresh chip to reproduce a driver's session.

File layout (``docs/trace-format.md``): the first line is a header object describing the
chip the session ran against (seed, profile, options), every following line is one
transaction as ``Transaction.to_dict()`` gives it. The writer is a sink a front end's
``TransactionLog`` can feed, so whichever front end carried the traffic the file is the same.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from bmg160_emu.bus.transactions import Transaction, bytes_from_json, errno_name
from bmg160_emu.io.dump import (
    REGISTER_COUNT,
    decode_register,
    register_label,
    register_name,
)
from bmg160_emu.io.errors import FileFormat, FormatError, register_format

TRACE_FORMAT_TAG = "bmg160-emu trace"
TRACE_FORMAT_VERSION = 1
RATE_REGISTERS = range(0x02, 0x08)  # RATE_X_LSB..RATE_Z_MSB (spec 4.2)
FIFO_DATA = 0x3F  # the pointer does not advance here (spec 2.4)
FAULT_KIND_PREFIX = "fault:"  # entries bmg160_emu.adcs.faults adds at a fault's onset
TRUE_RATE_KIND = "true_rate"  # the session changed a chip's true rate (a script's `rate`)


class TraceFormatError(FormatError):
    """A trace file that cannot be read; the message names the line."""


# --------------------------------------------------------------------------- true-rate entries


def true_rate_entry(time_s: float, bus: int | str, address: int,
                    rate_dps: Iterable[float]) -> Transaction:
    """A log entry saying the chip's true rate became ``rate_dps`` (deg/s) at ``time_s``.

    Not bus traffic: replay needs it to give the fresh chip the same input. ``written`` is
    UTF-8 text like a fault entry's: a description, then ``{"true_rate_dps": [x, y, z]}``.
    """
    x, y, z = (float(v) for v in rate_dps)
    text = f"true rate x={x:g} y={y:g} z={z:g} deg/s\n" + json.dumps({"true_rate_dps": [x, y, z]})
    return Transaction(time_s, bus, address, TRUE_RATE_KIND, written=text.encode())


def parse_true_rate_entry(written: bytes | str) -> tuple[float, float, float]:
    """The rate (deg/s) a ``true_rate`` entry carries; TraceFormatError if it has none."""
    text = written.decode("utf-8", "replace") if isinstance(written, (bytes, bytearray)) else written
    try:
        values = json.loads(text.partition("\n")[2])["true_rate_dps"]
        x, y, z = (float(v) for v in values)
    except (ValueError, KeyError, TypeError):
        raise TraceFormatError("a true_rate entry without its 'true_rate_dps' [x, y, z]") from None
    if not all(math.isfinite(v) for v in (x, y, z)):
        raise TraceFormatError("a true_rate entry with a rate that is not finite")
    return x, y, z


# --------------------------------------------------------------------------- reading text


def _register_span(register: int, count: int) -> str:
    if count <= 1:
        return f"0x{register:02X}"
    last = register + count - 1
    if register < FIFO_DATA <= last:  # the pointer stops at FIFO_DATA (spec 2.4)
        last = FIFO_DATA
    if register >= FIFO_DATA:
        return f"0x{register:02X} x{count}"
    return f"0x{register:02X}..0x{min(last, 0xFF):02X}"


def _field_text(register: int, value: int) -> str:
    parts = [f.text for f in decode_register(register, value) if f.text]
    return f" ({'; '.join(parts)})" if parts else ""


def _rate_words(register: int, data: bytes) -> str | None:
    """'x=-12 y=3 z=40' when a burst covers whole rate words (LSB first, spec 4.2)."""
    if register not in (0x02, 0x04, 0x06) or len(data) < 2:
        return None
    words = []
    axes = {0x02: "x", 0x04: "y", 0x06: "z"}
    reg = register
    for i in range(0, len(data) - 1, 2):
        if reg not in axes:
            break
        value = data[i] | data[i + 1] << 8
        words.append(f"{axes[reg]}={value - 0x10000 if value & 0x8000 else value}")
        reg += 2
    rest = data[2 * len(words) :]
    text = " ".join(words)
    if rest:
        text += " then " + " ".join(f"0x{b:02x}" for b in rest)
    return text


def describe_write(register: int, data: bytes) -> str:
    """'write 0x0F RANGE <- 0x02 (+-500 deg/s)': one register, or each byte of a burst."""
    if len(data) == 1:
        return f"write {register_label(register)} <- 0x{data[0]:02x}{_field_text(register, data[0])}"
    parts = []
    for offset, value in enumerate(data):
        reg = register + offset
        if reg >= REGISTER_COUNT:
            parts.append(f"0x{reg:02X} <- 0x{value:02x} (outside the map, ignored)")
        else:
            parts.append(f"{register_label(reg)} <- 0x{value:02x}{_field_text(reg, value)}")
    return f"burst write {_register_span(register, len(data))}: " + ", ".join(parts)


def describe_read(register: int, data: bytes) -> str:
    """'burst read 0x02..0x07 -> x=-12 y=3 z=40' or 'read 0x00 CHIP_ID -> 0x0f (...)'."""
    if len(data) == 1:
        value = data[0]
        if register >= REGISTER_COUNT:
            return f"read 0x{register:02X} (outside the map) -> 0x{value:02x}"
        return f"read {register_label(register)} -> 0x{value:02x}{_field_text(register, value)}"
    span = _register_span(register, len(data))
    words = _rate_words(register, data)
    if words is not None:
        return f"burst read {span} -> {words}"
    if register == FIFO_DATA:
        return f"burst read {span} (FIFO_DATA) -> {len(data)} bytes: {data[:12].hex(' ')}" + (
            " ..." if len(data) > 12 else ""
        )
    parts = []
    for offset, value in enumerate(data):
        reg = min(register + offset, FIFO_DATA) if register < FIFO_DATA else register
        parts.append(f"{register_name(reg) if reg < REGISTER_COUNT else hex(reg)}=0x{value:02x}")
    return f"burst read {span} -> " + " ".join(parts)


def _get(record: dict, *names: str, default: Any = None) -> Any:
    for name in names:
        if name in record and record[name] is not None:
            return record[name]
    return default


def describe_transaction(record: dict) -> str:
    """One line for a person from a transaction dictionary (``Transaction.to_dict()``)."""
    time_s = _get(record, "time", "time_s", default=float("nan"))
    bus = _get(record, "bus", default="?")
    address = _get(record, "address")
    where = f"{bus}" + (f" 0x{address:02x}" if isinstance(address, int) else "")
    head = f"{time_s:12.6f}s  {where:<10} "
    kind = str(_get(record, "kind", default="?"))
    register = _get(record, "register")
    error = _get(record, "error")
    written = bytes_from_json(_get(record, "written", "data_out", "write"))
    read = bytes_from_json(_get(record, "read", "data_in", "result"))
    if kind.startswith(FAULT_KIND_PREFIX):  # an injected fault's onset, not bus traffic
        from bmg160_emu.adcs.faults import parse_fault_entry

        detail, _ = parse_fault_entry(written)
        return head + f"FAULT injected: {detail or kind[len(FAULT_KIND_PREFIX):]}  [{kind}]"
    if kind == TRUE_RATE_KIND:  # the session changed the chip's input, not bus traffic
        return head + f"{written.decode('utf-8', 'replace').partition(chr(10))[0]}  [{kind}]"
    if kind == "spi_xfer" and written and not error:  # a raw frame, command byte first
        return head + _describe_spi_frame(written, read) + f"  [{kind}]"
    if kind == "spi_write" and isinstance(register, int) and len(written) > 1 and not error:
        # one register, then (address, data) pairs in the same frame (spec 2.2)
        return head + _describe_spi_frame(bytes([register & 0x7F]) + written, b"") + f"  [{kind}]"
    if error:
        target = f" {register_label(register)}" if isinstance(register, int) and register < REGISTER_COUNT else ""
        return head + f"{kind}{target} failed: {error}"
    if isinstance(register, int):
        if read and written:  # process calls: write from register on, then read on from there
            after = min(register + len(written), FIFO_DATA) if register < FIFO_DATA else register
            return (head + describe_write(register, written) + "; then "
                    + describe_read(after, read) + f"  [{kind}]")
        if read:
            return head + describe_read(register, read) + f"  [{kind}]"
        if written:
            return head + describe_write(register, written) + f"  [{kind}]"
        return head + f"set pointer {register_label(register)}  [{kind}]"
    if read:
        return head + f"{kind} -> {read.hex(' ')}"
    return head + f"{kind} {written.hex(' ')}".rstrip()


def _describe_spi_frame(mosi: bytes, miso: bytes) -> str:
    """An SPI frame (spec 2.2): command byte, then read data, or write data and pairs."""
    command, register = mosi[0], mosi[0] & 0x7F
    if command & 0x80:
        return "SPI " + describe_read(register, miso[1:]) if len(mosi) > 1 else "SPI read command only"
    if len(mosi) < 2:
        return f"SPI write command 0x{register:02X} without data"
    parts = [describe_write(register, mosi[1:2])]
    rest = mosi[2:]
    for i in range(0, len(rest) - 1, 2):  # further (address, data) pairs in the same frame
        parts.append(describe_write(rest[i] & 0x7F, rest[i + 1 : i + 2]))
    return "SPI " + "; ".join(parts)


# --------------------------------------------------------------------------- JSON Lines


# Chip constructor settings a trace header may carry (JSON-able; see BMG160.__init__).
CHIP_SETTING_KEYS = (
    "address", "profile", "noise", "noise_mode", "sensitivity", "temperature_c", "hold_data_int",
)


@dataclass
class TraceHeader:
    """What replay needs to rebuild the chips: master seed and, per chip, its constructor
    settings, true rate and the register writes made before the trace began."""

    seed: int | None = None
    chips: list[dict] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {
            "format": TRACE_FORMAT_TAG,
            "version": TRACE_FORMAT_VERSION,
            "seed": self.seed,
            "chips": self.chips,
        }

    @classmethod
    def from_dict(cls, document: dict) -> TraceHeader:
        return cls(document.get("seed"), list(document.get("chips") or []))

    def add_chip(
        self,
        settings: dict | None = None,
        true_rate_dps: Iterable[float] | None = None,
        setup_writes: Iterable[tuple[int, bytes]] = (),
    ) -> None:
        """Describe one chip: ``settings`` are BMG160 keyword arguments (JSON-able ones)."""
        settings = dict(settings or {})
        unknown = set(settings) - set(CHIP_SETTING_KEYS)
        if unknown:
            raise ValueError(f"chip settings a trace cannot carry: {sorted(unknown)}")
        entry: dict[str, Any] = {"settings": settings}
        if true_rate_dps is not None:
            entry["true_rate_dps"] = [float(v) for v in true_rate_dps]
        writes = [[int(reg), list(bytes(data))] for reg, data in setup_writes]
        if writes:
            entry["setup_writes"] = writes
        self.chips.append(entry)

    def build_chips(self) -> dict[int, Any]:
        """Fresh chips as the header describes them, sharing one VirtualClock at t = 0."""
        from bmg160_emu.clock import VirtualClock
        from bmg160_emu.device.chip import BMG160

        clock = VirtualClock()
        chips: dict[int, Any] = {}
        for entry in self.chips or [{"settings": {}}]:
            settings = dict(entry.get("settings", {}))
            chip = BMG160(self.seed, clock=clock, **settings)
            if entry.get("true_rate_dps") is not None:
                chip.set_true_rate(tuple(entry["true_rate_dps"]))
            for reg, data in entry.get("setup_writes", []):
                chip.write(reg, bytes(data))
            chips[chip.address] = chip
        return chips


def _json_default(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray)):
        return list(value)
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"cannot write {type(value).__name__} to a trace")


class TraceWriter:
    """A sink for transactions: ``writer(transaction)`` appends one JSON line.

    Give it to a front end's ``TransactionLog`` as a sink, or feed it a finished log with
    :meth:`write_all`. Lines are flushed so a crashed driver session still leaves its trace.
    """

    def __init__(self, path_or_file: str | Path | IO[str], header: TraceHeader | None = None):
        if isinstance(path_or_file, (str, Path)):
            self._file: IO[str] = open(path_or_file, "w", encoding="utf-8")  # noqa: SIM115
            self._owns = True
        else:
            self._file = path_or_file
            self._owns = False
        self._file.write(json.dumps((header or TraceHeader()).to_dict()) + "\n")
        self.count = 0

    def __call__(self, transaction: Any) -> None:
        record = transaction if isinstance(transaction, dict) else transaction.to_dict()
        self._file.write(json.dumps(record, default=_json_default, allow_nan=False) + "\n")
        self._file.flush()
        self.count += 1

    write = __call__

    def write_all(self, transactions: Iterable[Any]) -> None:
        for transaction in transactions:
            self(transaction)

    def close(self) -> None:
        if self._owns:
            self._file.close()

    def __enter__(self):  # returns self (subclasses too)
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_trace(path: str | Path) -> tuple[dict, list[dict]]:
    """Read a trace file: (header, transaction dictionaries), with line-numbered errors."""
    header: dict | None = None
    records: list[dict] = []
    with open(path, encoding="utf-8") as handle:
        for lineno, line in enumerate(handle, 1):
            if not line.strip():
                continue
            try:
                obj = json.loads(line)
            except json.JSONDecodeError as exc:
                raise TraceFormatError(f"{path}:{lineno}:{exc.colno}: invalid JSON: {exc.msg}") from None
            if not isinstance(obj, dict):
                raise TraceFormatError(f"{path}:{lineno}: each line must be a JSON object")
            if header is None and "format" not in obj and "kind" in obj:
                header = {}  # a bare log (Transaction.to_dict() lines): decodable, not replayable
            if header is None:
                if obj.get("format") != TRACE_FORMAT_TAG:
                    raise TraceFormatError(f"{path}:{lineno}: not a {TRACE_FORMAT_TAG} (header line missing)")
                if obj.get("version") != TRACE_FORMAT_VERSION:
                    raise TraceFormatError(f"{path}:{lineno}: unsupported trace version {obj.get('version')!r}")
                if not isinstance(obj.get("chips", []), list):
                    raise TraceFormatError(f"{path}:{lineno}: header 'chips' must be a list")
                header = obj
                continue
            for key in ("kind",):
                if key not in obj:
                    raise TraceFormatError(f"{path}:{lineno}: transaction without {key!r}")
            t = obj.get("time", obj.get("time_s"))
            if not isinstance(t, (int, float)) or isinstance(t, bool) or not math.isfinite(t):
                raise TraceFormatError(f"{path}:{lineno}: transaction without a finite 'time'")
            obj["_line"] = lineno
            records.append(obj)
    if header is None:
        raise TraceFormatError(f"{path}: empty trace")
    return header, records


register_format(FileFormat("trace", ".jsonl", read_trace, TraceWriter,
                           "JSON Lines: a header object, then one transaction per line"))


def iter_descriptions(records: Iterable[dict]) -> Iterator[str]:
    for record in records:
        yield describe_transaction(record)


# --------------------------------------------------------------------------- replay


@dataclass
class Divergence:
    """The first transaction whose replay differs from the trace."""

    line: int
    time_s: float
    expected: str
    actual: str

    def __str__(self) -> str:
        return (
            f"line {self.line} (t={self.time_s:.6f} s): the trace has\n    {self.expected}\n"
            f"  the replay gives\n    {self.actual}"
        )


@dataclass
class ReplayResult:
    """``transactions`` replayed (fault entries not counted); the injected faults the trace
    carried: ``faults_reapplied`` were acted again on the replay chips, ``faults_skipped``
    (their lines, described) could not be, so a divergence after them is expected."""

    transactions: int
    divergence: Divergence | None
    faults_reapplied: int = 0
    faults_skipped: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return self.divergence is None


def _errno_code(name: str) -> int:
    import errno

    code = getattr(errno, name, None)
    if isinstance(code, int):
        return code
    try:
        return int(name)
    except ValueError:
        return errno.EIO


class _Replayer:
    """Runs recorded transactions through the same front ends on fresh chips."""

    def __init__(self, chips: dict[int, Any]):
        from bmg160_emu.bus.i2c import I2CBus
        from bmg160_emu.bus.spi import FakeSpiDev

        self.chips = chips
        self.clock_chip = next(iter(chips.values()))
        self._buses: dict[Any, Any] = {}
        self._spi: dict[Any, Any] = {}
        self._I2CBus = I2CBus
        self._FakeSpiDev = FakeSpiDev
        self._pending_error: str | None = None

    def bus(self, number: Any):
        if number not in self._buses:
            bus = self._I2CBus(number if isinstance(number, int) else 0, devices=self.chips)
            bus.transaction_hooks.append(self._inject_recorded_error)
            self._buses[number] = bus
        return self._buses[number]

    def spi(self, name: Any):
        if name not in self._spi:
            self._spi[name] = self._FakeSpiDev(self.clock_chip)
        return self._spi[name]

    def _inject_recorded_error(self, bus, index, address, kind) -> None:
        # A failed transaction came from outside the chip (a NACK, a timeout, a fault hook):
        # fail the replayed one the same way so the chip sees the same traffic.
        if self._pending_error is not None:
            name, self._pending_error = self._pending_error, None
            raise OSError(_errno_code(name), name)

    def run(self, t: Transaction) -> tuple[bytes, str | None]:
        """Replay one transaction; (bytes read, errno name or None)."""
        now = self.clock_chip.time
        if t.time > now:
            self.clock_chip.advance(t.time - now)
        self._pending_error = t.error if t.address is not None else None
        try:
            return self._dispatch(t), None
        except OSError as exc:
            return b"", errno_name(exc.errno or 0)
        finally:
            self._pending_error = None

    def _dispatch(self, t: Transaction) -> bytes:
        kind, reg, w, expected = t.kind, t.register, t.written, t.read
        if kind.startswith("spi_"):
            spi = self.spi(t.bus)
            if kind == "spi_read" and reg is not None:  # command byte, then the data bytes
                return bytes(spi.xfer2([0x80 | reg] + [0] * len(expected))[1:])
            if kind == "spi_write" and reg is not None:
                spi.xfer2([reg & 0x7F, *w])
                return b""
            if kind == "spi_frame":  # the chip took no part in it: nothing to repeat
                return expected
            return bytes(spi.xfer2(list(w)))  # a raw frame (spi_xfer), command byte first
        bus, a = self.bus(t.bus), t.address
        if kind == "read_byte_data":
            return bytes([bus.read_byte_data(a, reg)])
        if kind == "write_byte_data":
            bus.write_byte_data(a, reg, w[0])
            return b""
        if kind == "read_word_data":
            return bus.read_word_data(a, reg).to_bytes(2, "little")
        if kind == "write_word_data":
            bus.write_word_data(a, reg, int.from_bytes(w[:2], "little"))
            return b""
        if kind == "read_i2c_block_data":
            return bytes(bus.read_i2c_block_data(a, reg, len(expected)))
        if kind == "write_i2c_block_data":
            bus.write_i2c_block_data(a, reg, w)
            return b""
        if kind == "read_byte":
            return bytes([bus.read_byte(a)])
        if kind == "write_byte":
            bus.write_byte(a, reg)
            return b""
        if kind in ("write_quick", "read_quick"):
            bus.write_quick(a, kind == "read_quick")
            return b""
        if kind == "process_call":
            return bus.process_call(a, reg, int.from_bytes(w[:2], "little")).to_bytes(2, "little")
        if kind == "read_block_data":
            data = bus.read_block_data(a, reg)
            return bytes([len(data)]) + data
        if kind == "write_block_data":
            bus.write_block_data(a, reg, w[1:])
            return b""
        if kind == "block_process_call":
            data = bus.block_process_call(a, reg, w[1:])
            return bytes([len(data)]) + data
        if kind == "i2c_write":
            bus.i2c_write(a, (bytes([reg]) if reg is not None else b"") + w)
            return b""
        if kind == "i2c_read":
            return bytes(bus.i2c_read(a, len(expected)))
        raise TraceFormatError(f"cannot replay a transaction of kind {kind!r}")


def _outcome_text(t: Transaction, read: bytes, error: str | None) -> str:
    record = t.to_dict()
    record.update(read=list(read), error=error)
    return describe_transaction(record).strip()


class _FaultReplayer:
    """Acts a trace's ``fault:<kind>`` entries again on the replay chips.

    Sample faults (stuck axis, bias step ...) are installed on the chips before the replay
    starts, each from its entry's parameters with its recorded activation start as ``at_s``,
    so they touch exactly the samples they touched in the session (and a stuck axis holds
    the same previous sample). Chip faults (SEU, brown-out) act when the replay reaches
    their entry, just before the transaction that triggered them, as in the session. Bus
    faults need no entry: the failed transaction carries its errno and is failed again.
    """

    def __init__(self, replayer: _Replayer):
        self.replayer = replayer
        self.reapplied = 0
        self.skipped: list[str] = []

    def _chip(self, record: dict, line: int) -> Any:
        address = record.get("address")
        chip = self.replayer.chips.get(address) if isinstance(address, int) else None
        if chip is None:
            where = f"0x{address:02x}" if isinstance(address, int) else repr(address)
            raise TraceFormatError(f"line {line}: fault entry for a chip at {where} that the "
                                   "header does not describe")
        return chip

    def prepare(self, records: list[dict]) -> None:
        """List the entries that cannot be acted again, install the sample faults."""
        from types import SimpleNamespace

        from bmg160_emu.adcs.faults import SAMPLE_KINDS, FaultError, replay_schedule

        per_chip: dict[int, dict[str, Any]] = {}  # id(chip) -> chip, entries, base temperature
        for record in records:
            if not str(record.get("kind", "")).startswith(FAULT_KIND_PREFIX):
                continue
            if not self._replayable(record):
                detail = _fault_entry(record)[0]
                self.skipped.append(f"line {record.get('_line', '?')}: {detail or record['kind']}")
                continue
            if record["kind"][len(FAULT_KIND_PREFIX):] not in SAMPLE_KINDS:
                continue
            entry = _fault_entry(record)[1]
            assert entry is not None
            chip = self._chip(record, int(record.get("_line", 0)))
            group = per_chip.setdefault(id(chip), {"chip": chip, "entries": [], "base": 23.0})
            group["entries"].append(entry)
            if entry.get("base_temperature_c") is not None:
                group["base"] = float(entry["base_temperature_c"])
        for group in per_chip.values():
            chip = group["chip"]
            target = SimpleNamespace(
                index=0, chip=chip, address=chip.address, bus=None,
                spec=SimpleNamespace(temperature_c=group["base"]),
            )
            try:
                replay_schedule(group["entries"], target)
            except (FaultError, TypeError, ValueError) as exc:
                raise TraceFormatError(f"a fault entry cannot be replayed: {exc}") from None

    @staticmethod
    def _replayable(record: dict) -> bool:
        from bmg160_emu.adcs.faults import CHIP_KINDS, SAMPLE_KINDS

        kind = str(record["kind"])[len(FAULT_KIND_PREFIX):]
        detail, entry = _fault_entry(record)
        if kind in SAMPLE_KINDS:
            return entry is not None and "activation" in entry
        if kind in CHIP_KINDS:
            return entry is not None or _chip_fault_from_text(kind, detail) is not None
        return False

    def act(self, record: dict, line: int) -> None:
        """The replay has reached a fault entry: act a chip fault now, count a sample fault."""
        from bmg160_emu.adcs.faults import CHIP_KINDS, inject

        if not self._replayable(record):
            return  # listed by prepare()
        kind = str(record["kind"])[len(FAULT_KIND_PREFIX):]
        detail, entry = _fault_entry(record)
        if kind in CHIP_KINDS:
            params = dict(entry["fault"]) if entry is not None else _chip_fault_from_text(kind, detail)
            assert params is not None
            chip = self._chip(record, line)
            clock_chip = self.replayer.clock_chip
            time_s = float(record.get("time", record.get("time_s", 0.0)))
            if time_s > clock_chip.time:
                clock_chip.advance(time_s - clock_chip.time)
            params.pop("at_s", None)
            params.pop("kind", None)
            inject(chip, kind, **params)
        self.reapplied += 1


def _fault_entry(record: dict) -> tuple[str, dict | None]:
    from bmg160_emu.adcs.faults import parse_fault_entry

    return parse_fault_entry(bytes_from_json(_get(record, "written", "data_out", "write")))


def _chip_fault_from_text(kind: str, detail: str) -> dict | None:
    """Parameters of a chip fault from its description alone (entries without parameters)."""
    import re

    if kind == "brownout":
        return {}
    match = re.search(r"register 0x([0-9a-fA-F]{2}) bit ([0-7])", detail)
    if kind == "seu" and match:
        return {"register": int(match.group(1), 16), "bit": int(match.group(2))}
    return None


def replay_trace(header: dict | TraceHeader, records: Iterable[dict]) -> ReplayResult:
    """Replay a trace against fresh chips; report the first transaction that differs.

    The chips are built from the header (same master seed, same settings, same set-up
    writes, virtual clock from 0); before each transaction the clock is advanced to the
    recorded time, so every sample is the same as in the original session. Injected faults
    recorded in the trace (``fault:<kind>`` entries, failed transactions) are acted again
    (see :class:`_FaultReplayer`); those that cannot be are listed in ``faults_skipped``.
    """
    if isinstance(header, dict):
        if header.get("format") != TRACE_FORMAT_TAG:
            raise TraceFormatError(
                "the trace has no header line: replay needs the seed and chip settings "
                "(write traces with TraceWriter)"
            )
        header = TraceHeader.from_dict(header)
    records = list(records)
    replayer = _Replayer(header.build_chips())
    faults = _FaultReplayer(replayer)
    faults.prepare(records)
    count = 0

    def result(divergence: Divergence | None) -> ReplayResult:
        return ReplayResult(count, divergence, faults.reapplied, faults.skipped)

    for record in records:
        line = int(record.get("_line", count + 2))
        if str(record.get("kind", "")).startswith(FAULT_KIND_PREFIX):
            faults.act(record, line)
            continue
        if record.get("kind") == TRUE_RATE_KIND:
            _set_true_rate(replayer, record, line)
            continue
        t = Transaction.from_dict(record)
        if t.time < replayer.clock_chip.time - 1e-12:
            return result(Divergence(
                line, t.time, f"a transaction at t={t.time:.9f} s",
                f"the clock is already at {replayer.clock_chip.time:.9f} s (time went backwards)",
            ))
        read, error = replayer.run(t)
        count += 1
        if read != t.read or error != t.error:
            return result(Divergence(
                line, t.time, _outcome_text(t, t.read, t.error), _outcome_text(t, read, error)
            ))
    return result(None)


def _set_true_rate(replayer: _Replayer, record: dict, line: int) -> None:
    """A ``true_rate`` entry: bring the clock to its time, then give its chip the rate."""
    address = record.get("address")
    chip = replayer.chips.get(address) if isinstance(address, int) else None
    if chip is None:
        raise TraceFormatError(f"line {line}: true_rate entry for a chip at {address!r} that "
                               "the header does not describe")
    try:
        rate = parse_true_rate_entry(bytes_from_json(_get(record, "written", "data_out", "write")))
    except TraceFormatError as exc:
        raise TraceFormatError(f"line {line}: {exc}") from None
    time_s = float(record.get("time", record.get("time_s", 0.0)))
    clock_chip = replayer.clock_chip
    if time_s > clock_chip.time:
        clock_chip.advance(time_s - clock_chip.time)
    chip.set_true_rate(rate)


def header_from_chip_args(args: Any) -> TraceHeader:
    """The trace header for chips built by ``chips_from_args`` from the same options."""
    from bmg160_emu.commands._chip_options import RANGE_CODE_BY_DPS

    header = TraceHeader(getattr(args, "seed", None))
    for address in list(dict.fromkeys(getattr(args, "addresses", None) or [0x68])):
        writes = []
        if getattr(args, "range_dps", None) is not None:
            writes.append((0x0F, bytes([RANGE_CODE_BY_DPS[args.range_dps]])))
        if getattr(args, "bandwidth", None) is not None:
            writes.append((0x10, bytes([args.bandwidth])))
        header.add_chip(
            {
                "address": address,
                "profile": getattr(args, "profile", "paper"),
                "noise": not getattr(args, "no_noise", False),
                "noise_mode": getattr(args, "noise_mode", "physical"),
                "sensitivity": getattr(args, "sensitivity", "binary"),
                "temperature_c": getattr(args, "temperature", 23.0),
            },
            getattr(args, "true_rate", None),
            writes,
        )
    return header
