"""Register scripts run: scripted register sessions and driver regression checks.

:func:`~bmg160_emu.session.script_language.parse_script` checks the whole script first
(script_language.py); :class:`ScriptRunner` then plays it against a chip through the chip's
bus primitives (an I2C or SPI register port) and stops at the first failed expectation with
the line number and the decoded difference.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bmg160_emu import durations
from bmg160_emu.device.fields import describe_value_difference, register_label
from bmg160_emu.device.registers import REGISTER_COUNT
from bmg160_emu.io.dump import RegisterDump, format_dump
from bmg160_emu.session.script_language import (
    FAULT_TRIGGERS,
    ScriptFailure,
    Statement,
    parse_script,
)

ADVANCE_STEP_NS = 60 * 10**9  # a reported advance goes a simulated minute at a time


class I2CRegisterPort:
    """Register access through an I2C front end, as an smbus2 driver does it: one register
    with ``read_byte_data``/``write_byte_data``, bursts with the I2C block kinds (a write
    of the register address then a read for bursts over 32 bytes). Every access is a
    transaction in the bus log, so a script session can be traced."""

    def __init__(self, bus, address: int):
        self.bus = bus
        self.address = address

    def write(self, register: int, data: bytes) -> None:
        if len(data) == 1:
            self.bus.write_byte_data(self.address, register, data[0])
        else:
            self.bus.write_i2c_block_data(self.address, register, data)

    def read(self, register: int, count: int) -> bytes:
        from bmg160_emu.bus.i2c import I2C_SMBUS_BLOCK_MAX, I2CMessage

        if count == 1:
            return bytes([self.bus.read_byte_data(self.address, register)])
        if count <= I2C_SMBUS_BLOCK_MAX:
            return bytes(self.bus.read_i2c_block_data(self.address, register, count))
        messages = [I2CMessage.write(self.address, [register]), I2CMessage.read_message(self.address, count)]
        return bytes(self.bus.i2c_transfer(messages)[1].data)


class SpiRegisterPort:
    """Register access through the SPI front end (spec 2.2), as an spidev driver does it:
    a read is one frame, the command byte ``0x80 | reg`` then one byte per register
    (auto-increment); a write is one frame of the address, its data byte, then an
    (address, data) pair per further register. Every frame is in the device's log, so a
    script session over SPI can be traced too."""

    def __init__(self, spi):
        self.spi = spi

    @property
    def log(self):
        return self.spi.log

    @property
    def bus_name(self) -> str:
        return self.spi.name

    def write(self, register: int, data: bytes) -> None:
        frame: list[int] = []
        for offset, value in enumerate(data):
            frame += [(register + offset) & 0x7F, value]
        self.spi.xfer2(frame)

    def read(self, register: int, count: int) -> bytes:
        return bytes(self.spi.xfer2([0x80 | register] + [0] * count)[1:])


class ScriptRunner:
    """Plays parsed statements against a chip.

    Register accesses go through ``port`` (an object with ``write(reg, data)`` and
    ``read(reg, n)``); by default an :class:`I2CRegisterPort` on a fresh ``I2CBus``
    (``runner.bus``) with the chip at its address. Time, true rate and dumps use the
    chip's own primitives (docs/architecture.md). ``log`` receives one readable line per
    statement.
    """

    def __init__(
        self,
        chip,
        log: Callable[[str], None] = print,
        source: str = "<script>",
        port=None,
        bus=None,
        progress: Any = None,
    ):
        self.chip = chip
        self.log = log
        self.progress = progress  # a bmg160_emu.progress.Progress: the time left of an advance
        self.source = source
        self.bus = bus
        if port is None:
            if bus is None:
                from bmg160_emu.bus.i2c import I2CBus

                bus = self.bus = I2CBus(1, {chip.address: chip})
            port = I2CRegisterPort(bus, chip.address)
        self.port = port
        self.faults: list = []

    def _advance(self, seconds: float) -> None:
        """``advance``: at once, or (with a progress report, and longer than ADVANCE_STEP_S)
        in steps of whole nanoseconds, so that ``advance 720h`` at 2000 Hz (about 12 min of
        work) shows the time it has left (issue 35). The steps add up to the same
        nanoseconds and the chip makes the same samples: it is chunk invariant."""
        total_ns = round(seconds * 1e9)
        if self.progress is None or total_ns <= ADVANCE_STEP_NS:
            self.chip.advance(seconds)
            return
        text = durations.exact_duration_text(seconds)
        with self.progress.stage(-(-total_ns // ADVANCE_STEP_NS), "simulated minutes",
                                 f"advance {text}") as update:
            done = 0
            while done < total_ns:
                step = min(ADVANCE_STEP_NS, total_ns - done)
                self.chip.advance(step / 1e9)
                done += step
                update(-(-done // ADVANCE_STEP_NS))

    def run(self, statements: list[Statement]) -> None:
        for statement in statements:
            self.execute(statement)

    def _say(self, statement: Statement, message: str) -> None:
        self.log(f"{statement.line:4d}  t={self.chip.time:.6f}s  {message}")

    def execute(self, s: Statement) -> None:
        try:
            self._execute(s)
        except OSError as exc:  # a bus error the script did not expect (e.g. an injected NACK)
            from bmg160_emu.traffic.transaction import errno_name

            name = errno_name(exc.errno) if exc.errno else str(exc)
            raise ScriptFailure(
                self.source, s.line, f"bus error during {s.command}: {name} ({exc.strerror})"
            ) from None

    def _execute(self, s: Statement) -> None:
        chip = self.chip
        if s.command == "write":
            self.port.write(s.register, bytes(s.values))
            from bmg160_emu.session.decode import describe_write

            self._say(s, describe_write(s.register, bytes(s.values)))
        elif s.command in ("read", "burst"):
            data = self.port.read(s.register, s.count)
            from bmg160_emu.session.decode import describe_read

            self._say(s, describe_read(s.register, data))
            if s.values:
                self._check_read(s, data)
        elif s.command == "poll":
            self._poll(s)
        elif s.command == "advance":
            self._advance(s.seconds)
            self._say(s, f"advance {durations.exact_duration_text(s.seconds)}")
        elif s.command == "rate":
            chip.set_true_rate(s.rate_dps)
            self._log_true_rate(s.rate_dps)
            x, y, z = s.rate_dps
            self._say(s, f"true rate x={x:g} y={y:g} z={z:g} deg/s")
        elif s.command == "fault":
            self._inject(s)
        elif s.command == "chip":
            self._select(s)
        elif s.command == "dump":
            self._say(s, f"dump ({s.dump_format})")
            text = format_dump(RegisterDump.from_chip(chip), s.dump_format)
            for out in text.rstrip("\n").split("\n"):
                self.log("      " + out)

    def _log_true_rate(self, rate_dps) -> None:
        """Put a ``true_rate`` entry in the log the accesses go to, so a trace replays it."""
        from bmg160_emu.io.trace import true_rate_entry

        bus: int | str
        if isinstance(self.port, SpiRegisterPort):
            log, bus = self.port.log, self.port.bus_name
        else:
            log, bus = getattr(self.bus, "log", None), getattr(self.bus, "number", 0)
        if log is not None and getattr(log, "enabled", True):
            log.append(true_rate_entry(self.chip.time, bus, self.chip.address, rate_dps))

    def _select(self, s: Statement) -> None:
        """``chip ADDRESS``: later statements address the chip at ADDRESS on the same bus."""
        devices = getattr(self.bus, "devices", {})
        if s.register not in devices or not isinstance(self.port, I2CRegisterPort):
            raise ScriptFailure(self.source, s.line, f"no chip at 0x{s.register:02x} on this bus")
        self.chip = devices[s.register]
        self.port = I2CRegisterPort(self.bus, s.register)
        self._say(s, f"chip 0x{s.register:02x}")

    def _inject(self, s: Statement) -> None:
        from types import SimpleNamespace

        from bmg160_emu.faults import Fault, FaultSchedule

        params = dict(s.fault)
        if not any(k in params for k in FAULT_TRIGGERS):
            params["at_s"] = self.chip.time
        fault = Fault(**params)
        if self.bus is None and fault.layer == "bus":
            raise ScriptFailure(self.source, s.line, "bus faults need the script to run on a bus")
        target = SimpleNamespace(index=0, chip=self.chip, bus=self.bus, address=self.chip.address)
        schedule = FaultSchedule([fault], seed=getattr(self.chip, "seed", None) or 0)
        schedule.install([target])
        self.faults.append(schedule)
        self._say(s, f"fault {fault.describe()}")

    def _check_read(self, s: Statement, data: bytes) -> None:
        for offset, (got, want) in enumerate(zip(data, s.values)):
            if got & s.mask != want & s.mask:
                reg = min(s.register + offset, REGISTER_COUNT - 1)
                masked = "" if s.mask == 0xFF else f" (mask 0x{s.mask:02x})"
                detail = describe_value_difference(reg, want & s.mask, got & s.mask, s.mask)
                raise ScriptFailure(
                    self.source,
                    s.line,
                    f"{register_label(reg)}: expected 0x{want & s.mask:02x}, read "
                    f"0x{got & s.mask:02x}{masked}{': ' + detail if detail else ''}",
                )

    def _poll(self, s: Statement) -> None:
        """Read every ``interval`` of simulated time until the bit has the value, or fail
        once the timeout has passed."""
        chip = self.chip
        start = chip.time
        reads = 0
        while True:
            value = self.port.read(s.register, 1)[0]
            reads += 1
            if (value >> s.bit) & 1 == s.expected_bit:
                self._say(
                    s,
                    f"poll {register_label(s.register)} bit {s.bit} == {s.expected_bit}: after "
                    f"{durations.exact_duration_text(chip.time - start)} ({_reads(reads)}, last 0x{value:02x})",
                )
                return
            if chip.time - start + s.interval_s > s.seconds + 1e-12:
                raise ScriptFailure(
                    self.source,
                    s.line,
                    f"{register_label(s.register)} bit {s.bit} still {1 - s.expected_bit} after "
                    f"{durations.exact_duration_text(s.seconds)} ({_reads(reads)}, last 0x{value:02x})",
                )
            chip.advance(s.interval_s)


def _reads(count: int) -> str:
    return "1 read" if count == 1 else f"{count} reads"


def run_script(
    text: str, chip, log: Callable[[str], None] = print, source: str = "<script>", bus=None,
    progress: Any = None,
) -> ScriptRunner:
    """Parse then run; raises ScriptSyntaxError before anything runs, ScriptFailure on a miss.
    ``progress`` (a bmg160_emu.progress.Progress) reports a long ``advance``."""
    statements = parse_script(text, source)
    runner = ScriptRunner(chip, log, source, bus=bus, progress=progress)
    runner.run(statements)
    return runner
