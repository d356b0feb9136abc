"""Trace replay: a recorded session run again on fresh chips, to the first difference.

The chips are built from the trace header; each transaction goes through the same front
end (I2CBus, FakeSpiDev) at its recorded time, and recorded faults are acted again.
``docs/trace-format.md`` gives the method and its limits.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from bmg160_emu.io.trace import (
    TRACE_FORMAT_TAG,
    TraceFormatError,
    TraceHeader,
    parse_true_rate_entry,
)
from bmg160_emu.session.decode import describe_transaction, record_value
from bmg160_emu.traffic.fault_entry import parse_fault_entry
from bmg160_emu.traffic.kinds import FAULT_KIND_PREFIX, TRUE_RATE_KIND
from bmg160_emu.traffic.transaction import Transaction, bytes_from_json, errno_name


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
        from bmg160_emu.bus.i2c import I2CBus, I2CMessage
        from bmg160_emu.bus.spi import FakeSpiDev, chip_select_of, read_dummy_bytes

        self.chips = chips
        self.clock_chip = next(iter(chips.values()))
        self._buses: dict[Any, Any] = {}
        self._spi: dict[Any, Any] = {}
        self._I2CBus = I2CBus
        self._I2CMessage = I2CMessage
        self._FakeSpiDev = FakeSpiDev
        self._read_dummy_bytes = read_dummy_bytes
        self._chip_select_of = chip_select_of
        self._pending_error: str | None = None

    def bus(self, number: Any):
        if number not in self._buses:
            bus = self._I2CBus(number if isinstance(number, int) else 0, devices=self.chips)
            bus.transaction_hooks.append(self._inject_recorded_error)
            self._buses[number] = bus
        return self._buses[number]

    def spi(self, name: Any):
        """The replayed SPI device of a logged name: chip select i is the i-th chip in
        address order (as serve's board); a name without one is the first chip."""
        if name not in self._spi:
            cs = self._chip_select_of(name)
            ordered = [self.chips[a] for a in sorted(self.chips)]
            chip = ordered[cs] if cs is not None and cs < len(ordered) else self.clock_chip
            self._spi[name] = self._FakeSpiDev(chip)
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
            if kind == "spi_read" and reg is not None:  # command byte, dummy bytes, data
                dummy = self._read_dummy_bytes(spi.chip)
                return bytes(spi.xfer2([0x80 | reg] + [0] * (dummy + len(expected)))[1 + dummy:])
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
            if reg is not None and a is not None:  # a register read: write, repeated start, read
                write = self._I2CMessage.write(a, bytes([reg]) + w)
                read = self._I2CMessage.read_message(a, len(expected))
                return bytes(bus.i2c_transfer([write, read])[1].data)
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
    faults that fail a transaction need no entry: it carries its errno and is failed again;
    a corrupted byte is acted again on the transaction after its entry.
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

        from bmg160_emu.faults import SAMPLE_KINDS, FaultError, replay_schedule

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
        from bmg160_emu.faults import CHIP_KINDS, SAMPLE_KINDS

        kind = str(record["kind"])[len(FAULT_KIND_PREFIX):]
        detail, entry = _fault_entry(record)
        if kind in SAMPLE_KINDS:
            return entry is not None and "activation" in entry
        if kind in CHIP_KINDS:
            return entry is not None or _chip_fault_from_text(kind, detail) is not None
        return kind == "corrupt_byte" and entry is not None  # the next transaction's byte

    def act(self, record: dict, line: int) -> None:
        """The replay has reached a fault entry: act a chip fault now, count a sample fault."""
        from bmg160_emu.faults import CHIP_KINDS, inject, replay_bus_fault

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
        elif kind == "corrupt_byte":
            assert entry is not None
            replay_bus_fault(entry, self._chip(record, line), self.replayer.bus(record.get("bus", 0)))
        self.reapplied += 1


def _fault_entry(record: dict) -> tuple[str, dict | None]:
    return parse_fault_entry(bytes_from_json(record_value(record, "written", "data_out", "write")))


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
        _check_replayable(t, line)
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


# The written bytes each kind needs to be repeated (plain `trace` decodes a record without
# them; a replay has to send them).
_WRITTEN_BYTES = {"write_byte_data": 1, "write_word_data": 2, "process_call": 2,
                  "write_block_data": 1, "block_process_call": 1}
_NO_REGISTER = {"read_byte", "write_quick", "read_quick", "i2c_read", "i2c_write", "spi_read",
                "spi_write", "spi_frame", "spi_xfer"}


def _check_replayable(t: Transaction, line: int) -> None:
    """Refuse, naming the line, a record a replay cannot repeat: bytes or a register its
    kind needs are missing, or its time is past the cap on simulated time."""
    from bmg160_emu.durations import MAX_SIMULATED_S, MAX_TEXT

    need = _WRITTEN_BYTES.get(t.kind, 0)
    if len(t.written) < need:
        raise TraceFormatError(f"line {line}: a {t.kind} record needs {need} written byte(s) "
                               f"to be replayed; it has {len(t.written)}")
    if t.register is None and t.kind not in _NO_REGISTER and not t.kind.startswith("spi_"):
        raise TraceFormatError(f"line {line}: a {t.kind} record needs its register to be "
                               "replayed")
    if not 0 <= t.time <= MAX_SIMULATED_S:
        raise TraceFormatError(f"line {line}: time {t.time!r} s is past the cap on simulated "
                               f"time, {MAX_TEXT}")


def _set_true_rate(replayer: _Replayer, record: dict, line: int) -> None:
    """A ``true_rate`` entry: bring the clock to its time, then give its chip the rate."""
    address = record.get("address")
    chip = replayer.chips.get(address) if isinstance(address, int) else None
    if chip is None:
        raise TraceFormatError(f"line {line}: true_rate entry for a chip at {address!r} that "
                               "the header does not describe")
    try:
        rate = parse_true_rate_entry(bytes_from_json(record_value(record, "written", "data_out", "write")))
    except TraceFormatError as exc:
        raise TraceFormatError(f"line {line}: {exc}") from None
    time_s = float(record.get("time", record.get("time_s", 0.0)))
    clock_chip = replayer.clock_chip
    if time_s > clock_chip.time:
        clock_chip.advance(time_s - clock_chip.time)
    chip.set_true_rate(rate)
