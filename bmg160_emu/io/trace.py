"""Transaction traces: JSON Lines files of every bus transaction (the format only).

Decoding for a person is :mod:`bmg160_emu.decode`, replay is :mod:`bmg160_emu.replay`.

File layout (``docs/trace-format.md``): the first line is a header object describing the
chip the session ran against (seed, profile, options), every following line is one
transaction as ``Transaction.to_dict()`` gives it. The writer is a sink a front end's
``TransactionLog`` can feed, so whichever front end carried the traffic the file is the same.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from bmg160_emu.bus.transactions import Transaction
from bmg160_emu.device.config import SETTING_KEYS, ChipConfig
from bmg160_emu.io.errors import FileFormat, FormatError, register_format

TRACE_FORMAT_TAG = "bmg160-emu trace"
TRACE_FORMAT_VERSION = 1
FAULT_KIND_PREFIX = "fault:"  # entries bmg160_emu.faults adds at a fault's onset
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


def parse_fault_entry(written: bytes | str) -> tuple[str, dict[str, Any] | None]:
    """(description, parameters or None) of a ``fault:<kind>`` entry's written bytes.

    Entries written before the parameters were added carry only the description (None)."""
    text = written.decode("utf-8", "replace") if isinstance(written, (bytes, bytearray)) else written
    detail, _, rest = text.partition("\n")
    if not rest.strip():
        return detail, None
    try:
        entry = json.loads(rest)
    except json.JSONDecodeError:
        return detail, None
    if not isinstance(entry, dict) or not isinstance(entry.get("fault"), dict):
        return detail, None
    return detail, entry


# --------------------------------------------------------------------------- JSON Lines


# Chip constructor settings a trace header may carry: every ChipConfig option.
CHIP_SETTING_KEYS = SETTING_KEYS


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
        ChipConfig.from_settings(settings)  # refuses an option a trace cannot carry
        entry: dict[str, Any] = {"settings": settings}
        if true_rate_dps is not None:
            entry["true_rate_dps"] = [float(v) for v in true_rate_dps]
        writes = [[int(reg), list(bytes(data))] for reg, data in setup_writes]
        if writes:
            entry["setup_writes"] = writes
        self.chips.append(entry)

    def add_config(self, config: ChipConfig) -> None:
        """Describe one chip by its config: every option it sets is carried to replay."""
        self.chips.append(config.to_dict())

    def configs(self) -> list[ChipConfig]:
        """The chips the header describes (one default chip when it describes none)."""
        return [ChipConfig.from_dict(entry) for entry in self.chips or [{"settings": {}}]]

    def build_chips(self) -> dict[int, Any]:
        """Fresh chips as the header describes them, sharing one VirtualClock at t = 0."""
        from bmg160_emu.clock import VirtualClock

        clock = VirtualClock()
        chips: dict[int, Any] = {}
        for config in self.configs():
            chip = config.build(self.seed, clock)
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
