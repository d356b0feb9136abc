"""The recording file: what ``bmg160-emu record`` writes, one row per output sample.

Per sample: the chip's sample time, the three rate words as the driver reads them (raw
counts from RATE_X/Y/Z), the same in deg/s with the range's sensitivity, and the true body
rate the chip was fed. CSV (readable, the chip settings in ``#`` comment lines) or NPZ
(compact), see ``docs/commands/record.md``, with the CSV and array readers every rate file
uses (io/csv_table.py, io/array_files.py); RESD (Renode: channel 0 the output, 1 the truth)
is written only. The formats are the registry's kind ``recording`` (io/formats.py).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bmg160_emu.io.array_files import ARRAY_ERRORS, first_non_finite, npz_array, open_npz, write_npz
from bmg160_emu.io.csv_table import read_csv_table, write_csv
from bmg160_emu.io.errors import loads_json
from bmg160_emu.io.formats import FileFormat, FileReader, FileWriter, format_for, register_format
from bmg160_emu.io.rate_table import RateFileError

RECORDING_FORMAT_TAG = "bmg160-emu recording"
RECORDING_FORMAT_VERSION = 1
CSV_COLUMNS = (
    "t_s",
    "x_counts", "y_counts", "z_counts",
    "x_dps", "y_dps", "z_dps",
    "true_x_dps", "true_y_dps", "true_z_dps",
)

@dataclass
class Recording:
    """Chip output at its ODR. ``t_s`` (n,), ``counts`` (n, 3) int, deg/s arrays (n, 3)."""

    t_s: np.ndarray
    counts: np.ndarray
    lsb_per_dps: float
    true_rate_dps: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.t_s = np.asarray(self.t_s, dtype=float).reshape(-1)
        self.counts = np.asarray(self.counts, dtype=np.int64).reshape(-1, 3)
        if len(self.counts) != len(self.t_s):
            raise ValueError("t_s and counts must have the same number of samples")
        if self.true_rate_dps is not None:
            self.true_rate_dps = np.asarray(self.true_rate_dps, dtype=float).reshape(-1, 3)
            if len(self.true_rate_dps) != len(self.t_s):
                raise ValueError("true_rate_dps must have one row per sample")
        if not (self.lsb_per_dps > 0 and math.isfinite(self.lsb_per_dps)):
            raise ValueError(f"lsb_per_dps must be positive, not {self.lsb_per_dps}")

    @property
    def rate_dps(self) -> np.ndarray:
        """The output in deg/s: counts divided by the range's sensitivity (spec 5.1)."""
        return self.counts / self.lsb_per_dps

    @property
    def odr_hz(self) -> float:
        if "odr_hz" in self.metadata:
            return float(self.metadata["odr_hz"])
        if len(self.t_s) < 2:
            raise ValueError("the output data rate of a recording needs two samples or metadata")
        return float(1.0 / np.median(np.diff(self.t_s)))

    def __len__(self) -> int:
        return len(self.t_s)


def _truth(rec: Recording) -> np.ndarray:
    return rec.true_rate_dps if rec.true_rate_dps is not None else np.full((len(rec), 3), np.nan)


class CsvRecordingWriter(FileWriter):
    """CSV: the format line and the settings (JSON) as ``#`` lines, then CSV_COLUMNS."""

    def write_to(self, path: Path, record: Recording) -> None:
        rec = record
        meta = dict(rec.metadata)
        meta["lsb_per_dps"] = rec.lsb_per_dps
        comments = [f"{RECORDING_FORMAT_TAG} v{RECORDING_FORMAT_VERSION}",
                    json.dumps(meta, sort_keys=True)]
        write_csv(path, comments, CSV_COLUMNS, [rec.t_s, rec.counts, rec.rate_dps, _truth(rec)])


class NpzRecordingWriter(FileWriter):
    """NPZ: t_s, counts (int16), rate_dps, true_rate_dps and the settings as JSON."""

    def write_to(self, path: Path, record: Recording) -> None:
        rec = record
        meta = dict(rec.metadata, lsb_per_dps=rec.lsb_per_dps, format=RECORDING_FORMAT_TAG,
                    version=RECORDING_FORMAT_VERSION)
        write_npz(path, {
            "t_s": rec.t_s, "counts": rec.counts.astype(np.int16), "rate_dps": rec.rate_dps,
            "true_rate_dps": _truth(rec), "metadata": np.array(json.dumps(meta)),
        })


class ResdRecordingWriter(FileWriter):
    """RESD (Renode Sensor Data, docs/resd.md): channel 0 the output in deg/s, channel 1 the
    truth when there is one. RESD has no field for an interrupted recording: that is said
    beside the file (io.partial's sidecar), and an earlier run's mark goes with a whole one."""

    def write(self, record: Recording, **options: object) -> None:
        from bmg160_emu.io.partial import clear_sidecar, write_sidecar

        rec = record
        interrupted = rec.metadata.get("interrupted")
        if interrupted:  # before the file: a file never appears cut without its mark
            write_sidecar(self.path, f"interrupted after {len(rec)} of "
                          f"{rec.metadata.get('samples_planned')} samples")
        super().write(rec)
        if not interrupted:
            clear_sidecar(self.path)

    def write_to(self, path: Path, record: Recording) -> None:
        from bmg160_emu.io.resd import ResdFormatError, write_resd

        channels = {0: record.rate_dps}
        if record.true_rate_dps is not None:
            channels[1] = record.true_rate_dps
        try:
            write_resd(path, record.t_s, channels)
        except ResdFormatError as exc:
            raise RateFileError(exc.detail, path=self.path) from None


class CsvRecordingReader(FileReader):
    """A CSV recording: the format line, the settings line, then CSV_COLUMNS."""

    noun = "recording file"
    error = RateFileError

    def read(self) -> Recording:
        path = self.path
        with open(path, encoding="utf-8", errors="replace") as handle:
            head = [handle.readline() for _ in range(2)]
        if not head[0].startswith(f"# {RECORDING_FORMAT_TAG}"):
            raise RateFileError(f"not a {RECORDING_FORMAT_TAG} CSV file", path=path, place=1)
        meta = loads_json(head[1][1:], RateFileError, f"{path}:2")
        if not isinstance(meta, dict):
            raise RateFileError("the settings line must be a JSON object", path=path, place=2)

        def choose(header: list[str] | None, width: int, where: str) -> tuple[int, list[int]]:
            if header != list(CSV_COLUMNS) or not where.endswith(":3"):
                raise RateFileError(f"{path}:3: expected the columns {','.join(CSV_COLUMNS)}")
            return 0, list(range(1, len(CSV_COLUMNS)))

        lsb = _lsb_per_dps(meta, path, 2)
        table = read_csv_table(path, choose)
        assert table.t_s is not None
        truth = table.values[:, 6:9]
        counts = table.values[:, 0:3]
        bad = first_non_finite(counts)
        if bad is None:
            bad = first_non_finite(table.values[:, 3:6])
        if bad is not None:
            raise RateFileError(f"{table.where(bad)}: counts and deg/s must be finite numbers")
        if np.any(np.abs(counts) > 32768) or np.any(counts != np.round(counts)):
            row = int(np.argmax(np.any((np.abs(counts) > 32768) | (counts != np.round(counts)), axis=1)))
            raise RateFileError(f"{table.where(row)}: counts must be 16-bit integers")
        return Recording(
            table.t_s, counts.astype(np.int64), lsb,
            None if np.isnan(truth).all() else truth, meta,
        )


class NpzRecordingReader(FileReader):
    """An NPZ recording: its arrays and the settings, tagged with the format."""

    noun = "recording file"
    error = RateFileError

    def read(self) -> Recording:
        path = self.path
        try:
            with open_npz(path) as data:
                meta = loads_json(str(npz_array(data, "metadata", path)), RateFileError,
                                  f"{path}: key metadata")
                if not isinstance(meta, dict) or meta.get("format") != RECORDING_FORMAT_TAG:
                    raise RateFileError(f"not a {RECORDING_FORMAT_TAG}", path=path)
                truth = npz_array(data, "true_rate_dps", path)
                meta.pop("format", None)
                meta.pop("version", None)
                lsb = _lsb_per_dps(meta, path, "key metadata")
                return Recording(
                    npz_array(data, "t_s", path), npz_array(data, "counts", path), lsb,
                    None if np.isnan(truth).all() else truth, meta,
                )
        except ARRAY_ERRORS as exc:
            if isinstance(exc, RateFileError):
                raise
            raise RateFileError(f"not a {RECORDING_FORMAT_TAG} NPZ file ({exc})", path=path) from None


def write_recording(rec: Recording, path: str | Path) -> None:
    """Write CSV, NPZ or RESD, chosen by the file suffix; complete or not at all."""
    format_for("recording", path, RateFileError, writing=True).write(path, rec)


def read_recording(path: str | Path) -> Recording:
    """Read a file written by :func:`write_recording` (CSV or NPZ)."""
    return format_for("recording", path, RateFileError, reading=True).read(path)


def _lsb_per_dps(meta: dict, path: Path, place: int | str | None) -> float:
    value = meta.pop("lsb_per_dps", None)
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not (0 < value < 1e6 and math.isfinite(value)):
        raise RateFileError(f"settings need lsb_per_dps, a positive number (LSB per deg/s), "
                            f"not {value!r}", path=path, place=place)
    return float(value)


for _suffix, _reader, _writer, _description in (
        (".csv", CsvRecordingReader, CsvRecordingWriter, "settings in # lines, CSV_COLUMNS"),
        (".npz", NpzRecordingReader, NpzRecordingWriter, "arrays and the settings as JSON"),
        (".resd", None, ResdRecordingWriter, "Renode: channel 0 the output, 1 the truth")):
    register_format(FileFormat("recording", _suffix, _reader, _writer, _description))
