"""The firmware's UART sample stream (docs/firmware.md, "UART stream"), read as rates.

A stream is ``#`` lines (the firmware's banner after reset; ``firmware capture`` adds a first
line naming the ODR it set) and then one line per output sample, ``INDEX X Y Z``: the sample
index (output periods of the data path since power-on, uint32) and the three rates in whole
millidegrees per second (int32). A gap in the index is a lost line or a missed period.

The same bytes come from ``bmg160-emu firmware capture`` and from a board's serial port
(``cat /dev/ttyUSB0 > stream.txt``); only the capture knows the ODR, a board's stream needs
it given. ``identify`` reads either through :func:`bmg160_emu.io.rates.load_rate_record`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bmg160_emu.io.errors import FormatError

MDPS_PER_DPS = 1000.0
BANNER_PREFIX = "# bmg160-emu firmware"  # the firmware's banner and the capture's line
CAPTURE_LINE = "# bmg160-emu firmware capture: simavr odr_hz={odr_hz:g} seconds={seconds:g}"
_ODR = re.compile(r"\bodr_hz=([0-9]+(?:\.[0-9]*)?)\b")
_INTEGER = re.compile(r"-?[0-9]{1,11}\Z")  # as ultoa/ltoa print; the range is checked below
_SAMPLE_LINE = re.compile(rb"^[0-9]+ -?[0-9]+ -?[0-9]+ -?[0-9]+\r?$")
_INDEX_MAX = 2**32 - 1  # INDEX is a uint32 (ultoa in firmware/src/main.c)
_VALUE_MAX = 2**31  # X, Y, Z are int32 mdps (lrintf of float deg/s * 1000)
_BODY = re.compile(rb"(?:[0-9]{1,10} -?[0-9]{1,11} -?[0-9]{1,11} -?[0-9]{1,11}\r?\n)*")
SNIFF_BYTES = 4096
SUFFIXES = (".txt", ".log")  # the rate reader looks into these for a stream


class UartStreamError(FormatError):
    """A stream line that does not follow the documented format."""


@dataclass(frozen=True)
class UartStream:
    index: np.ndarray  # (n,) int64, sample index
    rate_dps: np.ndarray  # (n, 3) float64, deg/s
    banner: str
    odr_hz: float | None = None  # from the capture's line; a board's stream does not say
    line_of: np.ndarray | None = None  # (n,) the file line of each sample, for messages

    @property
    def gaps(self) -> int:
        """Samples missing between the first and the last index."""
        if len(self.index) < 2:
            return 0
        return int(self.index[-1] - self.index[0] + 1 - len(self.index))

    def first_gap(self) -> int | None:
        """The position of the first sample after a gap in the index, or None."""
        jumps = np.flatnonzero(np.diff(self.index) != 1)
        return int(jumps[0]) + 1 if jumps.size else None


def _error(message: str, path: str | Path | None, line: int) -> UartStreamError:
    if path is None:
        return UartStreamError(f"line {line}: {message}")
    return UartStreamError(message, path=path, place=line)


def parse_uart_stream(data: str | bytes, *, allow_partial_last_line: bool = True,
                      path: str | Path | None = None) -> UartStream:
    """Parse the stream; a line cut by the end of a capture is dropped when allowed.

    Errors name the line (and the file, given ``path``)."""
    if isinstance(data, str):
        data = data.encode("utf-8", errors="surrogateescape")
    fast = _parse_whole(data, allow_partial_last_line)
    if fast is not None:
        return fast
    lines = data.split(b"\n")
    if lines and lines[-1] == b"":
        lines.pop()
    elif lines and allow_partial_last_line:
        lines.pop()  # the capture stopped inside this line
    banner = ""
    odr_hz: float | None = None
    indices: list[int] = []
    values: list[tuple[int, int, int]] = []
    numbers: list[int] = []
    for number, raw in enumerate(lines, start=1):
        try:
            line = raw.decode("ascii").rstrip("\r")
        except UnicodeDecodeError as exc:
            raise _error(f"not ASCII text (byte 0x{raw[exc.start]:02X} at column "
                         f"{exc.start + 1})", path, number) from None
        if line.startswith("#"):
            if line.startswith(BANNER_PREFIX + " profile="):
                banner = banner or line
            found = _ODR.search(line)
            if found and odr_hz is None:
                odr_hz = float(found.group(1))
                if not 0 < odr_hz <= 1e6:
                    raise _error(f"odr_hz={found.group(1)} is not a sample rate", path, number)
            continue
        parts = line.split(" ")
        if len(parts) != 4 or not all(parts):
            raise _error(f"expected 'INDEX X Y Z', got {line[:80]!r}", path, number)
        if not all(_INTEGER.match(p) for p in parts):
            raise _error(f"non-integer field in {line[:80]!r}", path, number)
        index, x, y, z = (int(p) for p in parts)
        if not 0 <= index <= _INDEX_MAX:
            raise _error(f"index {index} is not a uint32", path, number)
        if max(abs(x), abs(y), abs(z)) > _VALUE_MAX:
            raise _error(f"a rate beyond the int32 mdps the firmware prints: {line[:80]!r}",
                         path, number)
        if indices and index <= indices[-1]:
            raise _error(f"index {index} does not increase", path, number)
        indices.append(index)
        values.append((x, y, z))
        numbers.append(number)
    rate = np.asarray(values, dtype=float).reshape(-1, 3) / MDPS_PER_DPS
    return UartStream(np.asarray(indices, dtype=np.int64), rate, banner, odr_hz,
                      np.asarray(numbers, dtype=np.int64))


def _header(lines: list[bytes]) -> tuple[str, float | None] | None:
    """Banner and ODR of the ``#`` lines at the top, or None when one is not plain."""
    banner, odr_hz = "", None
    for raw in lines:
        line = raw.decode("ascii", errors="replace").rstrip("\r")
        if "\ufffd" in line:
            return None
        if line.startswith(BANNER_PREFIX + " profile="):
            banner = banner or line
        found = _ODR.search(line)
        if found and odr_hz is None:
            odr_hz = float(found.group(1))
            if not 0 < odr_hz <= 1e6:
                return None
    return banner, odr_hz


def _parse_whole(data: bytes, allow_partial_last_line: bool) -> UartStream | None:
    """The common case at C speed (a 24 h stream is 17 M lines): ``#`` lines, then only
    well-formed sample lines in range with a rising index. None sends the stream to the
    line-by-line parser, which names what is wrong and where."""
    start, top = 0, []
    while data.startswith(b"#", start):
        end = data.find(b"\n", start)
        if end < 0:
            return None
        top.append(data[start:end])
        start = end + 1
    body = data[start:]
    if not body.endswith(b"\n"):
        if not allow_partial_last_line:
            return None
        body = body[: body.rfind(b"\n") + 1]  # the capture stopped inside the last line
    header = _header(top)
    if header is None or not _BODY.fullmatch(body):
        return None
    fields = np.fromstring(body, dtype=np.int64, sep=" ") if body else np.zeros(0, np.int64)
    if fields.size % 4:
        return None
    fields = fields.reshape(-1, 4)
    index, values = fields[:, 0], fields[:, 1:]
    if (index.size and (index.max() > _INDEX_MAX or np.abs(values).max() > _VALUE_MAX)) \
            or not (np.diff(index) > 0).all():
        return None
    lines = np.arange(len(top) + 1, len(top) + 1 + len(index), dtype=np.int64)
    return UartStream(index.copy(), values / MDPS_PER_DPS, header[0], header[1], lines)


def read_uart_stream(path: str | Path) -> UartStream:
    """Read a stream file; every failure is a :class:`UartStreamError` naming the file."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise UartStreamError(f"cannot read the file ({exc.strerror})", path=path) from None
    return parse_uart_stream(data, path=path)


def looks_like_uart_stream(path: str | Path) -> bool:
    """Whether a text file is a UART stream: its first line is the firmware's banner or the
    capture's line, or its first line that is not a comment is ``INDEX X Y Z`` (a board's
    stream captured from the serial port after reset)."""
    try:
        with open(path, "rb") as handle:
            head = handle.read(SNIFF_BYTES)
    except OSError:
        return False
    for line in head.split(b"\n"):
        if line.startswith(BANNER_PREFIX.encode()):
            return True
        if line.strip() and not line.startswith(b"#"):
            return bool(_SAMPLE_LINE.match(line))
    return False


def uart_rate_table(path: str | Path, rate_hz: float | None):
    """A stream as the rate reader's table (``identify``): times from the index and the ODR
    (the capture's line, else ``rate_hz``); every sample must be there, as in a time column
    (a gap is refused at its line); errors as :class:`~bmg160_emu.io.rate_table.RateFileError`."""
    import math

    from bmg160_emu.io.rate_table import RateFileError, RateTable

    path = Path(path)
    try:
        stream = read_uart_stream(path)
    except UartStreamError as exc:
        raise RateFileError(str(exc)) from None
    lines = stream.line_of
    if lines is None or len(stream.index) == 0:
        raise RateFileError("the UART stream holds no sample lines", path=path)
    gap = stream.first_gap()
    if gap is not None:
        before, after = int(stream.index[gap - 1]), int(stream.index[gap])
        raise RateFileError(
            f"the sample index jumps from {before} to {after} ({after - before - 1} samples "
            "lost: the UART queue was full or periods were missed); evenly spaced samples are "
            "needed: capture at 400 Hz or less, or split the stream at the gap",
            path=path, place=int(lines[gap]))
    odr = stream.odr_hz if stream.odr_hz is not None else rate_hz
    if odr is None:
        raise RateFileError("the stream does not say its ODR (a board's stream: only "
                            "firmware capture writes it): give the sample rate (--rate HZ)",
                            path=path)
    if not (isinstance(odr, (int, float)) and math.isfinite(odr) and odr > 0):
        raise RateFileError(f"sample rate must be a positive number of Hz, got {odr!r}")
    t_s = (stream.index - stream.index[0]) / float(odr)
    table = RateTable(path, ["x", "y", "z"], t_s, stream.rate_dps)
    table.row_starts, table.row_lines = [0], [lines]  # where(row) names the file line
    return table
