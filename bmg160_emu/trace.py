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

from bmg160_emu.register_dump import (
    REGISTER_COUNT,
    decode_register,
    register_label,
    register_name,
)

TRACE_FORMAT_TAG = "bmg160-emu trace"
TRACE_FORMAT_VERSION = 1
RATE_REGISTERS = range(0x02, 0x08)  # RATE_X_LSB..RATE_Z_MSB (spec 4.2)
FIFO_DATA = 0x3F  # the pointer does not advance here (spec 2.4)


class TraceFormatError(ValueError):
    """A trace file that cannot be read; the message names the line."""


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


def _as_bytes(value: Any) -> bytes:
    if value is None:
        return b""
    if isinstance(value, str):
        return bytes.fromhex(value.replace("0x", "").replace(",", " "))
    return bytes(value)


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
    written = _as_bytes(_get(record, "written", "data_out", "write"))
    read = _as_bytes(_get(record, "read", "data_in", "result"))
    if error:
        target = f" {register_label(register)}" if isinstance(register, int) and register < REGISTER_COUNT else ""
        return head + f"{kind}{target} failed: {error}"
    if isinstance(register, int):
        if read:
            return head + describe_read(register, read) + f"  [{kind}]"
        if written:
            return head + describe_write(register, written) + f"  [{kind}]"
        return head + f"set pointer {register_label(register)}  [{kind}]"
    if read:
        return head + f"{kind} -> {read.hex(' ')}"
    return head + f"{kind} {written.hex(' ')}".rstrip()


# --------------------------------------------------------------------------- JSON Lines


@dataclass
class TraceHeader:
    """What replay needs to rebuild the chip: seed, profile, options, starting time."""

    seed: int | None = None
    chip: dict = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"format": TRACE_FORMAT_TAG, "version": TRACE_FORMAT_VERSION, "seed": self.seed, "chip": self.chip}


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
            if header is None:
                if obj.get("format") != TRACE_FORMAT_TAG:
                    raise TraceFormatError(f"{path}:{lineno}: not a {TRACE_FORMAT_TAG} (header line missing)")
                if obj.get("version") != TRACE_FORMAT_VERSION:
                    raise TraceFormatError(f"{path}:{lineno}: unsupported trace version {obj.get('version')!r}")
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


def iter_descriptions(records: Iterable[dict]) -> Iterator[str]:
    for record in records:
        yield describe_transaction(record)
