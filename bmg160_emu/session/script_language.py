"""The register-script language: its statements, and the parser that checks a whole script
before anything runs, reporting every mistake with its line and column.

A script is a list of line-oriented statements (``docs/script-format.md``); script.py's
:class:`~bmg160_emu.session.script.ScriptRunner` plays the parsed statements against a chip.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bmg160_emu import durations
from bmg160_emu.device.fields import (
    resolve_register_name,
)
from bmg160_emu.device.registers import REGISTER_COUNT
from bmg160_emu.io.dump import DUMP_FORMATS
from bmg160_emu.limits import RATE_DPS, LimitError

DEFAULT_POLL_INTERVAL_S = 1e-3  # one read per millisecond of simulated time
MAX_POLL_READS = 10_000_000  # reads of one poll: about 100 s at ~10 us a read
CAP_TEXT = f"past the cap of {durations.MAX_TEXT}"
MAX_BURST = 256  # no bus transfer in scope is longer (FIFO drains of 100 frames x 6 bytes use several)

COMMANDS = ("write", "read", "burst", "poll", "advance", "rate", "fault", "dump", "chip")


class ScriptSyntaxError(ValueError):
    """Mistakes found before running; ``errors`` lists (line, column, message)."""

    def __init__(self, source: str, errors: list[tuple[int, int, str]]):
        self.source = source
        self.errors = errors
        # one ``source:line:column: message`` a mistake, as a compiler lists them
        self.lines = [f"{source}:{line}:{col}: {msg}" for line, col, msg in errors]
        super().__init__("\n".join(self.lines))


class ScriptFailure(AssertionError):
    """A failed expectation while running; carries the line number."""

    def __init__(self, source: str, line: int, message: str):
        self.source = source
        self.line = line
        super().__init__(f"{source}:{line}: {message}")


@dataclass(frozen=True)
class Token:
    text: str
    column: int  # 1-based


@dataclass(frozen=True)
class Statement:
    """One parsed statement; ``args`` holds already-resolved numbers."""

    line: int
    command: str
    text: str
    register: int = 0
    values: tuple[int, ...] = ()
    count: int = 1
    mask: int = 0xFF
    bit: int = 0
    expected_bit: int = 1
    seconds: float = 0.0
    interval_s: float = DEFAULT_POLL_INTERVAL_S
    rate_dps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fault: tuple[tuple[str, Any], ...] = ()  # (kind, kind), then (key, value) pairs
    dump_format: str = "table"

    @property
    def has_expectation(self) -> bool:
        return bool(self.values) and self.command in ("read", "burst")


class _LineError(Exception):
    def __init__(self, column: int, message: str):
        self.column = column
        self.message = message


_TOKEN = re.compile(r"\S+")


def _tokenize(line: str) -> list[Token]:
    code = line.split("#", 1)[0]
    return [Token(m.group(0), m.start() + 1) for m in _TOKEN.finditer(code)]


def parse_number(token: Token, maximum: int = 0xFF, what: str = "value") -> int:
    """An integer literal (decimal, 0x hex, 0b binary) or a register name from the table."""
    text = token.text
    if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", text) and not re.fullmatch(r"0[xXbB].*", text):
        reg = resolve_register_name(text)
        if reg is None:
            raise _LineError(token.column, f"unknown register name {text!r}")
        value = reg
    else:
        try:
            value = int(text, 0)
        except ValueError:
            raise _LineError(token.column, f"bad number {text!r} for the {what}") from None
    if not 0 <= value <= maximum:
        raise _LineError(token.column, f"{what} {text} is outside 0..{maximum:#x}")
    return value


def parse_register(token: Token) -> int:
    return parse_number(token, REGISTER_COUNT - 1, "register")


def parse_duration(token: Token) -> float:
    """A duration token in seconds; zero is allowed (``advance 0s`` is a no-op)."""
    # Durations carry a unit: simulated time is exact, and "10" alone is ambiguous.
    try:
        return durations.parse_duration(token.text, unit_required=True, allow_zero=True)
    except ValueError as exc:
        raise _LineError(token.column, str(exc)) from None


def _parse_float(token: Token) -> float:
    try:
        return float(RATE_DPS.parse(token.text))
    except LimitError as exc:
        raise _LineError(token.column, str(exc)) from None


class _Cursor:
    """Walks the tokens of one statement, reporting where an argument is missing."""

    def __init__(self, tokens: list[Token], end_column: int):
        self.tokens = tokens
        self.index = 1
        self.end_column = end_column

    def peek(self) -> Token | None:
        return self.tokens[self.index] if self.index < len(self.tokens) else None

    def take(self, what: str) -> Token:
        token = self.peek()
        if token is None:
            raise _LineError(self.end_column, f"missing {what}")
        self.index += 1
        return token

    def accept(self, word: str) -> Token | None:
        token = self.peek()
        if token is not None and token.text == word:
            self.index += 1
            return token
        return None

    def done(self) -> None:
        token = self.peek()
        if token is not None:
            raise _LineError(token.column, f"unexpected {token.text!r}")


def _parse_statement(
    tokens: list[Token], line: int, text: str, fault_available: bool
) -> Statement:
    command = tokens[0].text.lower()
    cur = _Cursor(tokens, len(text.split("#", 1)[0].rstrip()) + 1)
    if command == "write":
        reg = parse_register(cur.take("register"))
        written = [parse_number(cur.take("value to write"))]
        while cur.peek() is not None:
            written.append(parse_number(cur.take("value")))
        return Statement(line, command, text, register=reg, values=tuple(written))
    if command in ("read", "burst"):
        reg = parse_register(cur.take("register"))
        count = 1
        if command == "burst":
            count = parse_number(cur.take("byte count"), MAX_BURST, "byte count")
            if count == 0:
                raise _LineError(tokens[2].column, "a burst reads at least one byte")
        values: list[int] = []
        mask = 0xFF
        if cur.accept("=="):
            for _ in range(count):
                values.append(parse_number(cur.take(f"expected value ({count} needed)")))
        if cur.accept("mask"):
            mask = parse_number(cur.take("mask"))
            if not values:
                raise _LineError(tokens[-1].column, "a mask needs an expected value ('== V')")
        cur.done()
        return Statement(line, command, text, register=reg, count=count, values=tuple(values), mask=mask)
    if command == "poll":
        reg = parse_register(cur.take("register"))
        if not cur.accept("bit"):
            raise _LineError(cur.take("'bit'").column, "expected 'bit N' after the register")
        bit = parse_number(cur.take("bit number"), 7, "bit number")
        expected = 1
        if cur.accept("=="):
            expected = parse_number(cur.take("bit value"), 1, "bit value")
        if not cur.accept("timeout"):
            raise _LineError(cur.take("'timeout DURATION'").column, "expected 'timeout DURATION'")
        timeout = parse_duration(cur.take("timeout duration"))
        interval = DEFAULT_POLL_INTERVAL_S
        if cur.accept("every"):
            token = cur.take("poll interval")
            interval = parse_duration(token)
            if interval <= 0:
                raise _LineError(token.column, "the poll interval must be positive")
        if timeout / interval > MAX_POLL_READS:  # a poll that would read for hours
            raise _LineError(1, f"poll reads up to {timeout / interval:.3g} times; at most "
                             f"{MAX_POLL_READS:,}: a longer 'every' or a shorter timeout")
        cur.done()
        return Statement(
            line, command, text, register=reg, bit=bit, expected_bit=expected,
            seconds=timeout, interval_s=interval,
        )
    if command == "advance":
        seconds = parse_duration(cur.take("duration"))
        cur.done()
        return Statement(line, command, text, seconds=seconds)
    if command == "rate":
        rate = tuple(_parse_float(cur.take(f"{axis} rate in deg/s")) for axis in "xyz")
        cur.done()
        return Statement(line, command, text, rate_dps=rate)  # type: ignore[arg-type]
    if command == "fault":
        name = cur.take("fault kind")
        if not fault_available:
            raise _LineError(name.column, "fault injection is not available in this version")
        return Statement(line, command, text, fault=_parse_fault(name, cur))
    if command == "chip":
        token = cur.take("I2C address")
        try:
            address = int(token.text, 0)
        except ValueError:
            raise _LineError(token.column, f"bad I2C address {token.text!r}") from None
        if not 0 <= address <= 0x7F:
            raise _LineError(token.column, f"I2C address {token.text} is outside 0x00..0x7f")
        cur.done()
        return Statement(line, command, text, register=address)
    if command == "dump":
        fmt = "table"
        given = cur.peek()
        if given is not None:
            fmt = cur.take("format").text
            if fmt not in DUMP_FORMATS:
                raise _LineError(given.column, f"dump format must be one of {', '.join(DUMP_FORMATS)}")
        cur.done()
        return Statement(line, command, text, dump_format=fmt)
    raise _LineError(tokens[0].column, f"unknown command {tokens[0].text!r} (one of {', '.join(COMMANDS)})")


def read_script(path: str | Path) -> str:
    """A script file's text; bytes that are not UTF-8 are a ScriptSyntaxError at their line
    and column (OSError for a missing file passes through)."""
    from bmg160_emu.io.errors import FormatError, read_text

    try:
        return read_text(path, FormatError)
    except FormatError as exc:
        where, line, column, message = str(exc).rsplit(":", 3)
        raise ScriptSyntaxError(where, [(int(line), int(column), message.strip())]) from None


def parse_script(
    text: str, source: str = "<script>", fault_available: bool | None = None
) -> list[Statement]:
    """Parse a whole script; raise :class:`ScriptSyntaxError` listing every mistake."""
    if fault_available is None:
        fault_available = fault_injection_available()
    statements: list[Statement] = []
    errors: list[tuple[int, int, str]] = []
    total_s = 0.0  # advances and poll timeouts: the longest the script can simulate
    for number, line in enumerate(text.splitlines(), 1):
        tokens = _tokenize(line)
        if not tokens:
            continue
        try:
            statements.append(_parse_statement(tokens, number, line.strip(), fault_available))
        except _LineError as exc:
            errors.append((number, exc.column, exc.message))
            continue
        before, total_s = total_s, total_s + (statements[-1].seconds or 0.0)  # poll: timeout
        if total_s > durations.MAX_SIMULATED_S >= before:  # said once, where it is passed
            errors.append((number, 1, f"simulated time reaches {total_s:g} s: {CAP_TEXT}"))
    if errors:
        raise ScriptSyntaxError(source, errors)
    return statements


def fault_injection_available() -> bool:
    """Fault statements need the fault-injection module (bmg160_emu.faults)."""
    import importlib.util

    try:
        return importlib.util.find_spec("bmg160_emu.faults") is not None
    except ModuleNotFoundError:
        return False


FAULT_TRIGGERS = ("at_s", "on_transaction", "probability")


def _fault_value(key: str, token: Token, text: str) -> Any:
    if key == "register":
        return parse_register(Token(text, token.column + len(key) + 1))
    if key == "axis" and text in ("x", "y", "z"):
        return text
    try:
        return int(text, 0)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        raise _LineError(token.column + len(key) + 1, f"bad value {text!r} for {key}") from None
    if not math.isfinite(value):
        raise _LineError(token.column + len(key) + 1, f"{key} must be finite")
    return value


def _parse_fault(kind: Token, cur: _Cursor) -> tuple[tuple[str, Any], ...]:
    """``fault KIND key=value ...``: a bmg160_emu.faults.Fault, checked now.

    Without a trigger key the fault starts at the statement's time (``at_s`` is filled in
    when it runs)."""
    from bmg160_emu.faults import FAULT_KINDS, Fault, FaultError

    if kind.text not in FAULT_KINDS:
        raise _LineError(kind.column, f"unknown fault kind {kind.text!r} (one of {', '.join(FAULT_KINDS)})")
    pairs: list[tuple[str, Any]] = [("kind", kind.text)]
    fields = set(Fault.__dataclass_fields__) - {"kind", "gyro"}
    while cur.peek() is not None:
        token = cur.take("key=value")
        key, sep, text = token.text.partition("=")
        if not sep or not text:
            raise _LineError(token.column, f"expected key=value, not {token.text!r}")
        if key not in fields:
            raise _LineError(token.column, f"unknown fault parameter {key!r} (one of {', '.join(sorted(fields))})")
        pairs.append((key, _fault_value(key, token, text)))
    trial: dict[str, Any] = dict(pairs)
    if not any(k in trial for k in FAULT_TRIGGERS):
        trial["at_s"] = 0.0
    try:
        Fault(**trial)
    except (FaultError, TypeError) as exc:
        raise _LineError(kind.column, str(exc)) from None
    return tuple(pairs)
