"""Transaction traces: JSON Lines files of every bus transaction (the format only).

Decoding for a person is :mod:`bmg160_emu.session.decode`, replay is :mod:`bmg160_emu.session.trace_replay`.

File layout (``docs/trace-format.md``): the first line is a header object describing the
chip the session ran against (seed, profile, options), every following line is one
transaction as ``Transaction.to_dict()`` gives it. The writer is a sink a front end's
``TransactionLog`` can feed, so whichever front end carried the traffic the file is the same.
"""

from __future__ import annotations

import errno
import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from bmg160_emu.device.config import ChipConfig
from bmg160_emu.io.atomic import AtomicFile
from bmg160_emu.io.errors import FormatError, loads_json, read_text
from bmg160_emu.io.formats import FileFormat, register_format
from bmg160_emu.traffic.kinds import TRUE_RATE_KIND, known_kind
from bmg160_emu.traffic.transaction import Transaction, bytes_from_json

TRACE_FORMAT_TAG = "bmg160-emu trace"
TRACE_FORMAT_VERSION = 1
END_KEY = "end"  # the last line of a complete trace: {"end": TRACE_FORMAT_TAG, "transactions": n}
CUT_SHORT = "no end line: the session was cut short (docs/outputs.md)"


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


# --------------------------------------------------------------------------- JSON Lines


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

    def add_config(self, config: Any) -> None:
        """Describe one device by its config (a ChipConfig, or a StandinConfig whose whole
        declaration is written): every option it sets is carried to replay."""
        self.chips.append(config.to_dict())

    def configs(self) -> list[Any]:
        """The devices the header describes (one default chip when it describes none):
        ChipConfig for the parts, StandinConfig for the stand-ins."""
        from bmg160_emu.device.standin import StandinConfig
        from bmg160_emu.io.standin_file import spec_from_dict

        configs: list[Any] = []
        for i, entry in enumerate(self.chips or [{"settings": {}}]):
            if "standin" in entry:
                spec = spec_from_dict(entry["standin"], f"header chips[{i}].standin")
                configs.append(StandinConfig(spec, int(entry["address"]), entry.get("bus")))
            else:
                configs.append(ChipConfig.from_dict(entry))
        return configs

    def build_chips(self) -> dict[int, Any]:
        """Fresh devices as the header describes them, sharing one VirtualClock at t = 0,
        by address (replay drives every bus of the session on these; two devices at one
        address on two buses cannot be told apart and are refused)."""
        from bmg160_emu.clock import VirtualClock

        clock = VirtualClock()
        chips: dict[int, Any] = {}
        for config in self.configs():
            chip = config.build(self.seed, clock)
            if chip.address in chips:
                raise TraceFormatError(
                    f"the session had two devices at 0x{chip.address:02x} (on two buses): "
                    "replay tells devices apart by address and cannot rebuild it")
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
        self._atomic: AtomicFile | None = None
        self._error: OSError | None = None
        if isinstance(path_or_file, (str, Path)):
            # under a temporary name until closed: a killed session leaves no half line
            # under the target's name; close() (also after ^C) renames the lines written
            self._atomic = AtomicFile(path_or_file, "w", encoding="utf-8")
            self._file: IO[str] = self._atomic.file
            self._owns = True
        else:
            self._file = path_or_file
            self._owns = False
        try:
            self._file.write(json.dumps((header or TraceHeader()).to_dict()) + "\n")
        except BaseException:  # a full disk at the first line: no hidden .part file left
            if self._atomic is not None:
                self._atomic.discard()
            raise
        self.count = 0
        self._closed = False

    def __call__(self, transaction: Any) -> None:
        if self._error is not None:
            return  # the file already failed: the session goes on, close() reports it
        record = transaction if isinstance(transaction, dict) else transaction.to_dict()
        try:
            self._file.write(json.dumps(record, default=_json_default, allow_nan=False) + "\n")
            self._file.flush()
        except OSError as exc:  # a full disk must not fail the driver's bus transaction
            self._error = exc
            return
        self.count += 1

    write = __call__

    def write_all(self, transactions: Iterable[Any]) -> None:
        for transaction in transactions:
            self(transaction)

    def close(self, complete: bool = True) -> None:
        """Finish the file: every transaction written so far, renamed into place (a write
        error, such as a full disk, is raised here). ``complete``: the session ended by itself
        and the end line is written; a session cut short (a signal, an error) has none, so
        every reader can tell (docs/outputs.md)."""
        if complete and self._error is None and not self._closed:
            try:
                end = {END_KEY: TRACE_FORMAT_TAG, "transactions": self.count}
                self._file.write(json.dumps(end) + "\n")
                self._file.flush()
            except OSError as exc:
                self._error = exc
        self._closed = True
        if self._atomic is not None:
            if not complete and self.count == 0 and self._error is None:
                self._atomic.discard()  # a cut session with no transaction: no file at all
                return
            if self._error is not None:
                self._atomic.discard()
                raise self._error
            self._atomic.commit()
        elif self._owns:
            self._file.close()
        if self._error is not None:
            raise self._error

    def __enter__(self):  # returns self (subclasses too)
        return self

    def __exit__(self, kind: object, *exc: object) -> None:
        self.close(complete=kind is None)


def read_trace(path: str | Path) -> tuple[dict, list[dict]]:
    """Read a trace file: (header, transaction dictionaries), every field checked against the
    schema of docs/trace-format.md, errors naming the line (never another exception).

    ``header["_partial"]`` is None for a complete trace (its end line present, counting the
    transactions before it), else why it is partial; a bare log has no header to say."""
    header: dict | None = None
    records: list[dict] = []
    end: dict | None = None
    text = read_text(path, TraceFormatError)
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        where = f"{path}:{lineno}"
        obj = loads_json(line, TraceFormatError, where)
        if not isinstance(obj, dict):
            raise TraceFormatError(f"{where}: each line must be a JSON object")
        if end is not None:
            raise TraceFormatError(f"{where}: a line after the end line")
        if header is not None and END_KEY in obj and "kind" not in obj:
            end = _check_end(obj, len(records), where)
            continue
        if header is None and "format" not in obj and "kind" in obj:
            header = {}  # a bare log (Transaction.to_dict() lines): decodable, not replayable
        if header is None:
            if obj.get("format") != TRACE_FORMAT_TAG:
                raise TraceFormatError(f"{where}: not a {TRACE_FORMAT_TAG} (header line missing)")
            if obj.get("version") != TRACE_FORMAT_VERSION:
                raise TraceFormatError(f"{where}: unsupported trace version {obj.get('version')!r}")
            _check_header(obj, where)
            header = obj
            continue
        _check_record(obj, where)
        obj["_line"] = lineno
        records.append(obj)
    if header is None:
        raise TraceFormatError(f"{path}: empty trace")
    if "format" in header:
        header["_partial"] = None if end is not None else CUT_SHORT
    return header, records


def _check_end(obj: dict, count: int, where: str) -> dict:
    if obj.get(END_KEY) != TRACE_FORMAT_TAG or obj.get("transactions") != count:
        raise TraceFormatError(f"{where}: the end line says {obj.get('transactions')!r} "
                               f"transactions, the trace holds {count}")
    return obj


_MAX_BYTES = 1 << 16  # far beyond any bus transaction (SMBus blocks: 32, i2c_rdwr: 8192)


def _integer(value: Any, low: int, high: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and low <= value <= high


def _check_bytes(value: Any, key: str, where: str) -> None:
    if value is None:
        return
    if isinstance(value, str):
        try:
            data = bytes_from_json(value)
        except ValueError:
            raise TraceFormatError(f"{where}: {key!r} is not hex bytes: {value[:40]!r}") from None
        if len(data) > _MAX_BYTES:
            raise TraceFormatError(f"{where}: {key!r} holds more than {_MAX_BYTES} bytes")
        return
    if not isinstance(value, list) or len(value) > _MAX_BYTES \
            or not all(_integer(v, 0, 255) for v in value):
        raise TraceFormatError(f"{where}: {key!r} must be a list of bytes 0..255 or hex text")


def _check_record(obj: dict, where: str) -> None:
    kind = obj.get("kind")
    if not isinstance(kind, str) or not known_kind(kind):
        raise TraceFormatError(f"{where}: unknown transaction kind {str(kind)[:40]!r}")
    t = obj.get("time", obj.get("time_s"))
    if not isinstance(t, (int, float)) or isinstance(t, bool) or not 0 <= t < 1e12:
        raise TraceFormatError(f"{where}: transaction without a finite 'time' >= 0 in seconds")
    bus = obj.get("bus", 0)
    if not (_integer(bus, 0, 2**31 - 1) or (isinstance(bus, str) and len(bus) <= 64)):
        raise TraceFormatError(f"{where}: 'bus' must be a bus number or an SPI device name")
    address = obj.get("address")
    if address is not None and not _integer(address, 0, 0x3FF):
        raise TraceFormatError(f"{where}: 'address' must be null or an I2C address 0..0x3FF")
    register = obj.get("register")
    if register is not None and not _integer(register, 0, 0xFF):
        raise TraceFormatError(f"{where}: 'register' must be null or 0..255")
    for key in ("written", "read"):
        _check_bytes(obj.get(key), key, where)
    error = obj.get("error")
    if error is not None and (not isinstance(error, str) or error not in _ERRNO_NAMES):
        raise TraceFormatError(f"{where}: 'error' must be null or an errno name (EREMOTEIO)")


_ERRNO_NAMES = frozenset(errno.errorcode.values())


def _check_header(obj: dict, where: str) -> None:
    seed = obj.get("seed")
    if seed is not None and not _integer(seed, 0, 2**64 - 1):
        raise TraceFormatError(f"{where}: header 'seed' must be null or an integer >= 0")
    chips = obj.get("chips", [])
    if not isinstance(chips, list):
        raise TraceFormatError(f"{where}: header 'chips' must be a list")
    for i, chip in enumerate(chips):
        if not isinstance(chip, dict):
            raise TraceFormatError(f"{where}: header chips[{i}] must be an object")
        if not isinstance(chip.get("settings", {}), dict):
            raise TraceFormatError(f"{where}: header chips[{i}].settings must be an object")
        if "part" in chip and not isinstance(chip["part"], str):
            raise TraceFormatError(f"{where}: header chips[{i}].part must be a part name")
        if "bus" in chip and not _integer(chip["bus"], 0, 2**31 - 1):
            raise TraceFormatError(f"{where}: header chips[{i}].bus must be a bus number")
        if "standin" in chip:
            if not isinstance(chip["standin"], dict) or not _integer(chip.get("address"), 0, 0x7F):
                raise TraceFormatError(f"{where}: header chips[{i}] is a stand-in: it needs its "
                                       "declaration (an object) and an 'address' 0..0x7F")
            from bmg160_emu.io.standin_file import spec_from_dict

            try:
                spec_from_dict(chip["standin"], f"{where}: header chips[{i}].standin")
            except FormatError as exc:
                raise TraceFormatError(str(exc)) from None
        rate = chip.get("true_rate_dps")
        if rate is not None and not (isinstance(rate, list) and len(rate) == 3 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) for v in rate)):
            raise TraceFormatError(f"{where}: header chips[{i}].true_rate_dps must be 3 numbers")
        writes = chip.get("setup_writes", [])
        if not isinstance(writes, list) or not all(
                isinstance(w, list) and len(w) == 2 and _integer(w[0], 0, 0xFF) for w in writes):
            raise TraceFormatError(
                f"{where}: header chips[{i}].setup_writes must be [register, [bytes]] pairs")
        for w in writes:
            _check_bytes(w[1], f"chips[{i}].setup_writes", where)


register_format(FileFormat("trace", ".jsonl", read_trace, TraceWriter,
                           "JSON Lines: a header object, then one transaction per line"))
