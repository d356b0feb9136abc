"""RESD files (Renode Sensor Data): angular rate in the form Renode's sensor models read.

So that Renode users can feed our noise and recordings to a simulated gyroscope (docs/resd.md).
RESD format version 1, the only one Renode's parser accepts (LowLevelRESDParser in
renode-infrastructure; the layout is in Renode's documentation, "Renode Sensor Data Format"):

- file header: ``b"RESD"``, the version byte ``0x01``, three zero bytes;
- then data blocks, all little-endian: block type (u8), sample type (u16), channel id (u16),
  data size (u64: the bytes of the block after this field), and for a constant-frequency
  block (type 2) the time of its first sample and the sample period (u64 each, virtual ns
  from the start of the file), a metadata size (u64; 0, as standard sample types carry no
  metadata) and the samples;
- an angular-rate sample (type 0x0003) is three int32, X, Y, Z, in units of 1e-5 rad/s.

We write constant-frequency blocks only: Renode's parser skips every other block type. The
reader accepts what the writer writes and skips blocks of other sample types, as Renode does.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from bmg160_emu.io.atomic import atomic_open
from bmg160_emu.io.errors import FormatError
from bmg160_emu.io.formats import BlockWriter

if TYPE_CHECKING:
    from typing_extensions import Self

RESD_MAGIC = b"RESD"
RESD_VERSION = 1  # the version Renode's parser supports (SupportedVersion = 0x1)
FILE_HEADER = RESD_MAGIC + bytes([RESD_VERSION, 0, 0, 0])
BLOCK_ARBITRARY_TIMESTAMP = 0x01
BLOCK_CONSTANT_FREQUENCY = 0x02
SAMPLE_ANGULAR_RATE = 0x0003
ANGULAR_RATE_UNIT_RAD_S = 1e-5  # one count of an angular-rate sample (Renode: "tens of urad/s")
DPS_PER_UNIT = math.degrees(ANGULAR_RATE_UNIT_RAD_S)  # 5.73e-4 deg/s per RESD count
NS_PER_S = 1_000_000_000

_BLOCK_HEADER = struct.Struct("<BHHQ")  # block type, sample type, channel id, data size
_CONSTANT_FREQUENCY = struct.Struct("<QQQ")  # start time ns, period ns, metadata size
_SAMPLE = np.dtype("<i4")
_SAMPLE_BYTES = 3 * _SAMPLE.itemsize
_INT32 = np.iinfo(np.int32)
_LAST_NS = 2**63 - 1


class ResdFormatError(FormatError):
    """A RESD file (or the data to write as one) that is not what the format allows."""


def dps_to_units(rate_dps: np.ndarray) -> np.ndarray:
    """deg/s -> int32 RESD angular-rate counts (1e-5 rad/s), rounded to nearest."""
    units = np.rint(np.radians(np.asarray(rate_dps, dtype=float)) / ANGULAR_RATE_UNIT_RAD_S)
    if not np.isfinite(units).all():
        raise ResdFormatError("an angular rate to write is not a finite number")
    if units.size and (units.max() > _INT32.max or units.min() < _INT32.min):
        raise ResdFormatError("an angular rate beyond +-1.23e6 deg/s does not fit RESD's int32")
    return units.astype(_SAMPLE)


def units_to_dps(units: np.ndarray) -> np.ndarray:
    return np.degrees(np.asarray(units, dtype=float) * ANGULAR_RATE_UNIT_RAD_S)


def period_ns_for(rate_hz: float, samples: int) -> int:
    """The whole-nanosecond period RESD stores for ``rate_hz``; refused when rounding it
    would shift the last of ``samples`` samples by half a period or more."""
    if not (rate_hz > 0 and math.isfinite(rate_hz)):
        raise ResdFormatError(f"sample rate must be a positive number of Hz, not {rate_hz!r}")
    exact = NS_PER_S / rate_hz
    period = round(exact)
    if period < 1 or abs(period - exact) * max(samples - 1, 0) >= period / 2:
        raise ResdFormatError(
            f"{rate_hz:g} Hz has no whole-nanosecond period that holds over {samples} samples"
        )
    return period


class ResdWriter:
    """Streams one constant-frequency angular-rate block: the sample count is given first
    (the block header holds the size), then the samples arrive in chunks of (m, 3) deg/s."""

    def __init__(
        self,
        handle: IO[Any],
        *,
        rate_hz: float,
        samples: int,
        start_s: float = 0.0,
        channel: int = 0,
        file_header: bool = True,
    ) -> None:
        if samples < 1:
            raise ResdFormatError("a RESD block needs at least one sample")
        if not 0 <= channel <= 0xFFFF:
            raise ResdFormatError(f"RESD channel id must be 0..65535, not {channel}")
        if not (start_s >= 0 and math.isfinite(start_s)):
            raise ResdFormatError(f"RESD times start at 0: a first sample at {start_s} s")
        self.handle = handle
        self.samples = samples
        self.written = 0
        period = period_ns_for(rate_hz, samples)
        size = _CONSTANT_FREQUENCY.size + samples * _SAMPLE_BYTES
        if file_header:
            handle.write(FILE_HEADER)
        self._channel = channel
        self._block_at = handle.tell() if handle.seekable() else None
        handle.write(
            _BLOCK_HEADER.pack(BLOCK_CONSTANT_FREQUENCY, SAMPLE_ANGULAR_RATE, channel, size)
        )
        handle.write(_CONSTANT_FREQUENCY.pack(round(start_s * NS_PER_S), period, 0))

    def write_dps(self, rate_dps: np.ndarray) -> None:
        block = np.asarray(rate_dps, dtype=float).reshape(-1, 3)
        if self.written + len(block) > self.samples:
            raise ResdFormatError(f"more than the {self.samples} samples announced")
        self.handle.write(dps_to_units(block).tobytes())
        self.written += len(block)

    def end_short(self) -> None:
        """After an interruption: the block's size rewritten for the samples written so far
        and the file cut after them, so the file is a valid, shorter RESD (a stream that
        cannot seek back cannot be made honest: refused)."""
        if self._block_at is None:
            raise ResdFormatError("an interrupted RESD stream that cannot seek back")
        if self.written == 0:
            raise ResdFormatError("interrupted before the first sample: a RESD block needs one")
        size = _CONSTANT_FREQUENCY.size + self.written * _SAMPLE_BYTES
        end = self._block_at + _BLOCK_HEADER.size + size
        self.handle.seek(self._block_at)
        self.handle.write(_BLOCK_HEADER.pack(BLOCK_CONSTANT_FREQUENCY, SAMPLE_ANGULAR_RATE,
                                             self._channel, size))
        self.handle.seek(end)
        self.handle.truncate(end)
        self.samples = self.written

    def close(self) -> None:
        if self.written != self.samples:
            raise ResdFormatError(f"{self.written} samples written, {self.samples} announced")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: object, *rest: object) -> None:
        if exc_type is None:
            self.close()


class ResdRateStream(BlockWriter):
    """A rate stream (generate's output) as one constant-frequency block of channel 0, sample
    k at (k + 1) / rate_hz as in the CSV. RESD has no field for a note: ``end_short`` makes
    the block the samples written, and the note goes beside the file (io.partial)."""

    notes_inside = False

    def __init__(self, handle: IO[bytes], total: int, rate_hz: float,
                 comments: Sequence[str] = ()) -> None:
        super().__init__(handle, total, rate_hz, comments)
        self._writer = ResdWriter(handle, rate_hz=rate_hz, samples=total, start_s=1.0 / rate_hz)

    def write(self, start: int, block: np.ndarray) -> None:
        self._writer.write_dps(block)
        self.samples = self._writer.written

    @staticmethod
    def size_bytes(total: int) -> int:
        return 45 + 12 * total  # exact: RESD v1's file and block headers, 12 bytes a sample

    def end_short(self, note: str) -> None:
        self._writer.end_short()


def write_resd(
    path: str | Path,
    t_s: np.ndarray,
    channels: dict[int, np.ndarray],
) -> None:
    """Write uniformly sampled rates, ``{channel id: (n, 3) deg/s}`` at times ``t_s``, as one
    constant-frequency block per channel (a recording: channel 0 the output, 1 the truth)."""
    t_s = np.asarray(t_s, dtype=float).reshape(-1)
    if len(t_s) < 1:
        raise ResdFormatError("nothing to write: no samples")
    rate_hz = _uniform_rate_hz(t_s)
    with atomic_open(path, "wb") as handle:  # complete or absent (docs/outputs.md)
        handle.write(FILE_HEADER)
        for channel, rate_dps in channels.items():
            rate_dps = np.asarray(rate_dps, dtype=float).reshape(-1, 3)
            if len(rate_dps) != len(t_s):
                raise ResdFormatError(
                    f"channel {channel}: {len(rate_dps)} rows for {len(t_s)} times"
                )
            with ResdWriter(
                handle, rate_hz=rate_hz, samples=len(t_s), start_s=float(t_s[0]),
                channel=channel, file_header=False,
            ) as writer:  # fmt: skip
                writer.write_dps(rate_dps)


def _uniform_rate_hz(t_s: np.ndarray) -> float:
    """The sample rate of evenly spaced times (RESD stores a start and a period, no times)."""
    if len(t_s) < 2:
        return 1.0  # one sample: any period will do
    steps = np.diff(t_s)
    period = (t_s[-1] - t_s[0]) / (len(t_s) - 1)
    if not period > 0 or np.abs(steps - period).max() > 1e-6 * period + 1e-9:
        raise ResdFormatError(
            "RESD holds evenly spaced samples only: the time column is not uniform "
            f"(steps from {steps.min():.9g} to {steps.max():.9g} s)"
        )
    return 1.0 / period


@dataclass(frozen=True)
class ResdBlock:
    """One data block as stored: ``data`` holds the sample bytes after the metadata."""

    offset: int  # byte offset of the block header in the file
    block_type: int
    sample_type: int
    channel: int
    start_ns: int
    period_ns: int
    metadata: bytes
    data: bytes

    def angular_rate_units(self) -> np.ndarray:
        if self.sample_type != SAMPLE_ANGULAR_RATE:
            raise ResdFormatError(f"block at byte {self.offset} is not angular rate")
        return np.frombuffer(self.data, dtype=_SAMPLE).reshape(-1, 3)

    def t_s(self) -> np.ndarray:
        n = len(self.data) // _SAMPLE_BYTES
        return (self.start_ns + self.period_ns * np.arange(n, dtype=np.int64)) / NS_PER_S

    def angular_rate_dps(self) -> np.ndarray:
        return units_to_dps(self.angular_rate_units())


def iter_blocks(path: str | Path) -> Iterator[ResdBlock]:
    """The constant-frequency blocks of a RESD file; errors name the file and the byte."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ResdFormatError(f"{path}: cannot read the file ({exc.strerror})") from None
    if data[:4] != RESD_MAGIC:
        raise ResdFormatError(f"{path}: byte 0: not a RESD file (starts {data[:4]!r})")
    if len(data) < len(FILE_HEADER) or data[4] != RESD_VERSION:
        version = data[4] if len(data) > 4 else None
        raise ResdFormatError(f"{path}: byte 4: RESD version {version}, not {RESD_VERSION}")
    if data[5:8] != b"\0\0\0":
        raise ResdFormatError(f"{path}: byte 5: header padding must be three zero bytes")
    offset = len(FILE_HEADER)
    while offset < len(data):
        if offset + _BLOCK_HEADER.size > len(data):
            raise ResdFormatError(f"{path}: byte {offset}: truncated block header")
        block_type, sample_type, channel, size = _BLOCK_HEADER.unpack_from(data, offset)
        body = offset + _BLOCK_HEADER.size
        end = body + size
        if end > len(data):
            raise ResdFormatError(
                f"{path}: byte {offset}: block of {size} bytes runs past the end of the file"
            )
        if block_type == BLOCK_CONSTANT_FREQUENCY:
            yield _constant_frequency_block(path, data, offset, body, end, sample_type, channel)
        elif block_type != BLOCK_ARBITRARY_TIMESTAMP:
            raise ResdFormatError(f"{path}: byte {offset}: unknown block type {block_type}")
        offset = end  # arbitrary-timestamp blocks are skipped, as Renode skips them


def _constant_frequency_block(
    path: Path, data: bytes, offset: int, body: int, end: int, sample_type: int, channel: int
) -> ResdBlock:
    if body + _CONSTANT_FREQUENCY.size > end:
        raise ResdFormatError(f"{path}: byte {body}: block too short for its start and period")
    start_ns, period_ns, meta_size = _CONSTANT_FREQUENCY.unpack_from(data, body)
    meta_start = body + _CONSTANT_FREQUENCY.size
    samples = meta_start + meta_size
    if samples > end:
        raise ResdFormatError(f"{path}: byte {meta_start - 8}: metadata runs past its block")
    block = ResdBlock(
        offset, BLOCK_CONSTANT_FREQUENCY, sample_type, channel, start_ns, period_ns,
        data[meta_start:samples], data[samples:end],
    )  # fmt: skip
    if sample_type == SAMPLE_ANGULAR_RATE:
        if len(block.data) % _SAMPLE_BYTES:
            raise ResdFormatError(
                f"{path}: byte {samples}: {len(block.data)} bytes of angular rate are not "
                f"whole samples of {_SAMPLE_BYTES} bytes"
            )
        if period_ns == 0 and len(block.data) > _SAMPLE_BYTES:
            raise ResdFormatError(f"{path}: byte {body + 8}: period 0 with several samples")
        last_ns = start_ns + period_ns * max(len(block.data) // _SAMPLE_BYTES - 1, 0)
        if last_ns > _LAST_NS:  # u64 fields: the times must fit numpy's int64 nanoseconds
            raise ResdFormatError(f"{path}: byte {body}: sample times beyond 2**63 ns")
    return block


def read_angular_rate(path: str | Path, channel: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(t_s (n,), rate_dps (n, 3)) of one angular-rate channel, its blocks in file order."""
    times, rates = [], []
    for block in iter_blocks(path):
        if block.sample_type == SAMPLE_ANGULAR_RATE and block.channel == channel:
            times.append(block.t_s())
            rates.append(block.angular_rate_dps())
    if not times:
        raise ResdFormatError(f"{path}: no angular-rate channel {channel}")
    return np.concatenate(times), np.concatenate(rates)


def resd_rate_table(path: str | Path):
    """Channel 0 as the rate reader's table (``identify`` and ``load_rate_record``): times
    from the blocks' start and period, errors as :class:`~bmg160_emu.io.rate_table.RateFileError`."""
    from bmg160_emu.io.rate_table import RateFileError, RateTable

    try:
        t_s, rate_dps = read_angular_rate(path, channel=0)
    except ResdFormatError as exc:
        raise RateFileError(str(exc)) from None
    return RateTable(Path(path), ["x", "y", "z"], t_s, rate_dps)


def write_resd_rates(path: str | Path, t_s: np.ndarray | None, rate_dps: np.ndarray) -> None:
    """``write_rates`` for .resd: evenly spaced times and three axes, as channel 0."""
    from bmg160_emu.io.rate_table import RateFileError

    rate_dps = np.asarray(rate_dps, dtype=float)
    if t_s is None or rate_dps.ndim != 2 or rate_dps.shape[1] != 3:
        raise RateFileError("RESD holds times and three axes: give t_s and (n, 3) rates",
                            path=path)
    try:
        write_resd(path, np.asarray(t_s, dtype=float), {0: rate_dps})
    except ResdFormatError as exc:
        raise RateFileError(exc.detail, path=path) from None
