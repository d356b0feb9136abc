"""Loading a static rate record (deg/s) for identification: CSV, .npy or .npz.

- CSV: one column per axis, optionally a time column; ``#`` lines are comments; an optional
  header row names the columns. A time column is one named t, t_s, time, time_s or
  timestamp. When the header has x_dps, y_dps, z_dps (the ``bmg160-emu record`` and
  ``generate`` layout) those are the axes; otherwise every other column is one.
- .npy: an (n,) or (n, k) array, k <= 3, no time.
- .npz: a single array, or the arrays rate_dps (n, 3) and t_s (``bmg160-emu record``), or
  x, y, z with an optional t.

The sample rate is given, or read from the time column ((n - 1) / (t_last - t_first));
when both are present they must agree within 1 %.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

TIME_COLUMN_NAMES = ("t", "t_s", "time", "time_s", "timestamp")
RATE_COLUMN_SETS = (("x_dps", "y_dps", "z_dps"), ("x", "y", "z"), ("gx", "gy", "gz"))


class RecordError(ValueError):
    """A record file that cannot be used: unreadable, wrong shape, bad time column, no rate."""


@dataclass(frozen=True)
class RateRecord:
    """A rate record ready for identification."""

    rate_dps: np.ndarray  # (n, k), k = 1..3
    rate_hz: float
    axis_names: tuple[str, ...]
    source: str


def load_rate_record(
    path: str | Path, rate_hz: float | None = None, columns: list[str] | None = None
) -> RateRecord:
    """Read a record file; rate_hz overrides (and is checked against) a time column."""
    path = Path(path)
    if not path.is_file():
        raise RecordError(f"no such record file: {path}")
    suffix = path.suffix.lower()
    if columns and suffix not in (".csv", ".txt"):
        raise RecordError(f"{path}: --columns applies to CSV files with a header row")
    if suffix == ".csv" or suffix == ".txt":
        data, t, names = _read_csv(path, columns)
    elif suffix == ".npy":
        data, t, names = _read_npy(path), None, None
    elif suffix == ".npz":
        data, t, names = _read_npz(path)
    else:
        raise RecordError(f"record file must end in .csv, .npy or .npz, not {path.name!r}")
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or not 1 <= data.shape[1] <= 3:
        raise RecordError(
            f"{path}: expected one column per axis (1 to 3 axes), got shape {data.shape}"
        )
    if names is None:
        names = ("x", "y", "z")[: data.shape[1]]
    rate = _resolve_rate(path, t, rate_hz, data.shape[0])
    return RateRecord(data, rate, tuple(_axis_label(n) for n in names), str(path))


# A step this many times the median step is a gap (samples missing), not timestamp jitter.
GAP_FACTOR = 2.5


def _axis_label(name: str) -> str:
    return name.removesuffix("_dps")


def _resolve_rate(path: Path, t: np.ndarray | None, rate_hz: float | None, n: int) -> float:
    valid = isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0
    if rate_hz is not None and not valid:
        raise RecordError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
    if t is None:
        if rate_hz is None:
            raise RecordError(f"{path}: no time column: give the sample rate (--rate HZ)")
        return float(rate_hz)
    if not np.all(np.isfinite(t)):
        raise RecordError(f"{path}: the time column has NaN or infinite values")
    steps = np.diff(t)
    if steps.size and not np.all(steps > 0):
        i = int(np.argmax(steps <= 0))
        raise RecordError(
            f"{path}: the time column is not strictly increasing "
            f"(sample {i + 1}: {float(t[i + 1])!r} after {float(t[i])!r})"
        )
    if n < 2:
        if rate_hz is None:
            raise RecordError(f"{path}: too few samples to read the rate from the time column")
        return float(rate_hz)
    typical = float(np.median(steps))
    wide = np.flatnonzero(steps > GAP_FACTOR * typical)
    if wide.size:
        i = int(wide[0])
        raise RecordError(
            f"{path}: the time column has a gap of {float(steps[i]):g} s after sample {i} "
            f"({float(steps[i]) / typical:.1f} sample periods of {typical:g} s): Allan deviation "
            "and PSD need evenly spaced samples; split the record at the gap"
        )
    from_time = (n - 1) / float(t[-1] - t[0])
    if rate_hz is not None:
        if abs(from_time / rate_hz - 1.0) > 0.01:
            raise RecordError(
                f"{path}: --rate {rate_hz:g} Hz disagrees with the time column ({from_time:.6g} Hz)"
            )
        return float(rate_hz)
    return from_time


def _read_npy(path: Path) -> np.ndarray:
    try:
        data = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as exc:
        raise RecordError(f"{path}: not a readable .npy array ({exc})") from None
    return _numeric(data, path)


def _numeric(data: np.ndarray, path: Path) -> np.ndarray:
    if data.dtype.kind not in "fiu":
        raise RecordError(f"{path}: the record must hold numbers, not {data.dtype}")
    return np.asarray(data, dtype=float)


def _read_npz(path: Path) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...] | None]:
    try:
        with np.load(path, allow_pickle=False) as archive:
            arrays = {k: archive[k] for k in archive.files}
    except (ValueError, OSError) as exc:
        raise RecordError(f"{path}: not a readable .npz archive ({exc})") from None
    t = next((arrays[k] for k in TIME_COLUMN_NAMES if k in arrays), None)
    t = _numeric(t, path) if t is not None else None
    if "rate_dps" in arrays:
        return _numeric(arrays["rate_dps"], path), t, None
    for names in RATE_COLUMN_SETS:
        present = [k for k in names if k in arrays]
        if present:
            return np.column_stack([_numeric(arrays[k], path) for k in present]), t, tuple(present)
    numeric = [k for k, v in arrays.items() if v.dtype.kind in "fiu" and k not in TIME_COLUMN_NAMES]
    if len(numeric) == 1:
        return _numeric(arrays[numeric[0]], path), t, None
    raise RecordError(
        f"{path}: cannot tell which arrays hold the rates (found {sorted(arrays)}); "
        "store one array, or rate_dps, or x, y, z"
    )


def _read_csv(
    path: Path, columns: list[str] | None
) -> tuple[np.ndarray, np.ndarray | None, tuple[str, ...] | None]:
    header: list[str] | None = None
    skip = 0
    with open(path, encoding="utf-8", errors="replace") as handle:
        for line in handle:
            stripped = line.strip()
            if not stripped or stripped.startswith("#"):
                skip += 1
                continue
            cells = [c.strip() for c in stripped.split(",")]
            if not all(_is_number(c) for c in cells):
                header = [c.lower() for c in cells]
                skip += 1
            break
        else:
            raise RecordError(f"{path}: the CSV file has no data rows")
    if header is None:
        if columns:
            raise RecordError(f"{path}: --columns needs a header row naming the columns")
        use = None
        time_index = None
    else:
        time_index = next((header.index(n) for n in TIME_COLUMN_NAMES if n in header), None)
        if columns:
            wanted = [c.lower() for c in columns]
            missing = [c for c in wanted if c not in header]
            if missing:
                raise RecordError(f"{path}: no column(s) {missing}; the header has {header}")
            rate_names = wanted
        else:
            rate_names = next(
                ([n for n in s if n in header] for s in RATE_COLUMN_SETS if s[0] in header),
                [n for i, n in enumerate(header) if i != time_index],
            )
        use = [header.index(n) for n in rate_names]
        if len(use) > 3:
            raise RecordError(
                f"{path}: {len(use)} rate columns ({', '.join(rate_names)}); "
                "choose up to three with --columns"
            )
    usecols = None if use is None else ([time_index] if time_index is not None else []) + use
    try:
        table = np.loadtxt(
            path, delimiter=",", comments="#", skiprows=skip, usecols=usecols, ndmin=2
        )
    except ValueError as exc:
        raise RecordError(f"{path}: unreadable CSV data ({exc})") from None
    if table.shape[0] == 0:
        raise RecordError(f"{path}: the CSV file has no data rows")
    if header is None:
        return table, None, None
    if time_index is not None:
        return table[:, 1:], table[:, 0], tuple(rate_names)
    return table, None, tuple(rate_names)


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
