"""Recordings of what the chip outputs at its output data rate.

A recording holds, per output sample: the chip's sample time, the three rate words as the
driver reads them (raw counts from RATE_X/Y/Z), the same in deg/s with the range's
sensitivity, and the true body rate the chip was fed (from ``chip.truth_hooks``). It is
written as CSV (readable, with the chip settings in ``#`` comment lines) or NPZ (compact),
see ``docs/commands/record.md``; :func:`read_recording` reads both back.
"""

from __future__ import annotations

import io
import json
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

RECORDING_FORMAT_TAG = "bmg160-emu recording"
RECORDING_FORMAT_VERSION = 1
RATE_X_LSB = 0x02  # 6-byte burst 0x02..0x07 gives x, y, z LSB first (spec 4.2)
CSV_COLUMNS = (
    "t_s",
    "x_counts", "y_counts", "z_counts",
    "x_dps", "y_dps", "z_dps",
    "true_x_dps", "true_y_dps", "true_z_dps",
)


class RecordingFormatError(ValueError):
    """A recording file that is not what :func:`write_recording` produces."""


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


# --------------------------------------------------------------------------- recording


def chip_odr_hz(chip) -> float:
    """The chip's current output data rate, from its own attribute or BW (spec 5.3)."""
    for name in ("odr_hz", "output_data_rate_hz"):
        value = getattr(chip, name, None)
        if value is not None:
            return float(value() if callable(value) else value)
    odr_by_code = (2000.0, 2000.0, 1000.0, 400.0, 200.0, 100.0, 200.0, 100.0)  # spec 5.3
    return odr_by_code[chip.peek(0x10) & 0x07]


def chip_lsb_per_dps(chip) -> float:
    """The chip's current sensitivity in LSB per deg/s (spec 5.1; binary or nominal table)."""
    for name in ("sensitivity", "lsb_per_dps"):
        value = getattr(chip, name, None)
        if value is not None:
            return float(value() if callable(value) else value)
    raise AttributeError("the chip exposes no sensitivity (lsb_per_dps)")


def chip_range_dps(chip) -> int:
    """Full scale of the chip's current RANGE code; reserved codes 5..7 act as 2000 (spec 4.8)."""
    full_scale = {0: 2000, 1: 1000, 2: 500, 3: 250, 4: 125}
    return full_scale.get(chip.peek(0x0F) & 0x07, 2000)


def record(
    chip,
    duration_s: float,
    progress: Callable[[int, int], None] | None = None,
) -> Recording:
    """Read every output sample of ``chip`` for ``duration_s`` seconds of chip time.

    After each new sample the 6 rate bytes are read in one burst from RATE_X_LSB, as a
    polling driver would; the clock is advanced to the middle of each output period so every
    step holds exactly one sample whatever the rounding of the sample times.
    """
    if not (duration_s > 0 and math.isfinite(duration_s)):
        raise ValueError(f"duration must be positive, not {duration_s}")
    odr = chip_odr_hz(chip)
    period = 1.0 / odr
    n = round(duration_s * odr)
    if n < 1:
        raise ValueError(f"{duration_s} s is shorter than one output period ({period} s)")
    samples: list[tuple[float, np.ndarray]] = []

    def truth(_chip, t, true_rate) -> None:
        samples.append((float(t), np.array(true_rate, dtype=float, copy=True)))

    t_s = np.empty(n)
    counts = np.empty((n, 3), dtype=np.int64)
    truth_rows = np.empty((n, 3))
    chip.truth_hooks.append(truth)
    try:
        # Find the phase of the sample clock: advance one period at a time until one appears.
        for _ in range(3):
            if samples:
                break
            chip.advance(period)
        if not samples:
            raise RuntimeError("the chip produced no sample in three output periods (suspended?)")
        first_t = samples[-1][0]
        del samples[:-1]
        for k in range(n):
            if k > 0:
                chip.advance(first_t + (k + 0.5) * period - chip.time)
                if len(samples) != 1:
                    raise RuntimeError(
                        f"{len(samples)} samples in one output period at t={chip.time:.6f} s: "
                        "did the output data rate change?"
                    )
            data = chip.read(RATE_X_LSB, 6)
            raw = np.frombuffer(bytes(data), dtype="<i2")
            t_s[k], truth_rows[k] = samples[0]
            counts[k] = raw
            samples.clear()
            if progress is not None:
                progress(k + 1, n)
    finally:
        chip.truth_hooks.remove(truth)
    metadata = {
        "odr_hz": odr,
        "range_dps": chip_range_dps(chip),
        "seed": getattr(chip, "seed", None),
    }
    return Recording(t_s, counts, chip_lsb_per_dps(chip), truth_rows, metadata)


# --------------------------------------------------------------------------- files


def _metadata_lines(rec: Recording) -> list[str]:
    meta = dict(rec.metadata)
    meta["lsb_per_dps"] = rec.lsb_per_dps
    return [f"# {RECORDING_FORMAT_TAG} v{RECORDING_FORMAT_VERSION}", "# " + json.dumps(meta, sort_keys=True)]


def write_recording(rec: Recording, path: str | Path) -> None:
    """Write CSV or NPZ, chosen by the file suffix."""
    path = Path(path)
    truth = rec.true_rate_dps if rec.true_rate_dps is not None else np.full((len(rec), 3), np.nan)
    suffix = path.suffix.lower()
    if suffix == ".npz":
        meta = dict(rec.metadata, lsb_per_dps=rec.lsb_per_dps, format=RECORDING_FORMAT_TAG,
                    version=RECORDING_FORMAT_VERSION)
        np.savez_compressed(
            path, t_s=rec.t_s, counts=rec.counts.astype(np.int16), rate_dps=rec.rate_dps,
            true_rate_dps=truth, metadata=np.array(json.dumps(meta)),
        )
    elif suffix == ".csv":
        with open(path, "w", encoding="utf-8", newline="") as handle:
            handle.write("\n".join(_metadata_lines(rec)) + "\n")
            handle.write(",".join(CSV_COLUMNS) + "\n")
            buffer = io.StringIO()
            # repr() of a Python float is the shortest text that reads back to the same float.
            rows = zip(rec.t_s.tolist(), rec.counts.tolist(), rec.rate_dps.tolist(), truth.tolist())
            for t, c, r, w in rows:
                cells = [repr(t), *map(str, c), *map(repr, r), *map(repr, w)]
                buffer.write(",".join(cells) + "\n")
            handle.write(buffer.getvalue().replace("nan", ""))
    else:
        raise ValueError(f"recording file must end in .csv or .npz, not {path.name!r}")


def read_recording(path: str | Path) -> Recording:
    """Read a file written by :func:`write_recording` (CSV or NPZ)."""
    path = Path(path)
    if path.suffix.lower() == ".npz":
        try:
            with np.load(path, allow_pickle=False) as data:
                meta = json.loads(str(data["metadata"]))
                if meta.get("format") != RECORDING_FORMAT_TAG:
                    raise RecordingFormatError(f"{path}: not a {RECORDING_FORMAT_TAG}")
                truth = data["true_rate_dps"]
                meta.pop("format", None)
                meta.pop("version", None)
                lsb = float(meta.pop("lsb_per_dps"))
                return Recording(
                    data["t_s"], data["counts"], lsb,
                    None if np.isnan(truth).all() else truth, meta,
                )
        except (KeyError, ValueError, OSError) as exc:
            if isinstance(exc, RecordingFormatError):
                raise
            raise RecordingFormatError(f"{path}: not a {RECORDING_FORMAT_TAG} NPZ file ({exc})") from None
    with open(path, encoding="utf-8") as handle:
        lines = handle.read().splitlines()
    if len(lines) < 3 or not lines[0].startswith(f"# {RECORDING_FORMAT_TAG}"):
        raise RecordingFormatError(f"{path}:1: not a {RECORDING_FORMAT_TAG} CSV file")
    try:
        meta = json.loads(lines[1][1:])
    except json.JSONDecodeError as exc:
        raise RecordingFormatError(f"{path}:2: bad settings line: {exc.msg}") from None
    if lines[2].split(",") != list(CSV_COLUMNS):
        raise RecordingFormatError(f"{path}:3: expected the columns {','.join(CSV_COLUMNS)}")
    rows = []
    for lineno, line in enumerate(lines[3:], 4):
        cells = line.split(",")
        if len(cells) != len(CSV_COLUMNS):
            raise RecordingFormatError(f"{path}:{lineno}: {len(cells)} columns, expected {len(CSV_COLUMNS)}")
        try:
            rows.append([float(c) if c else math.nan for c in cells])
        except ValueError:
            raise RecordingFormatError(f"{path}:{lineno}: not a number in {line!r}") from None
    table = np.array(rows, dtype=float).reshape(-1, len(CSV_COLUMNS))
    truth = table[:, 7:10]
    lsb = float(meta.pop("lsb_per_dps"))
    return Recording(
        table[:, 0], table[:, 1:4].astype(np.int64), lsb,
        None if np.isnan(truth).all() else truth, meta,
    )


# Output data rate -> the BW code the Linux driver writes for it (LNX bmg160_samp_freq_table;
# spec 5.3). Codes 0, 4 and 5 give the same rates with other filters: use --bandwidth for them.
BW_CODE_BY_ODR_HZ = {100: 0x07, 200: 0x06, 400: 0x03, 1000: 0x02, 2000: 0x01}
