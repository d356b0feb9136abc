"""Recordings read for replay: a user's flight or lab data (a time column and x, y, z in
deg/s or raw counts), checked line by line before anything plays.

CSV (``#`` comment lines, then a header row naming a time column and x, y, z columns, or no
header and exactly four numeric columns ``t, x, y, z``) and NPZ; the files ``bmg160-emu
record`` writes are read as they are. The registry's kind ``replay`` names the formats
(io/formats.py); session/rate_replay.py plays the data (``docs/replay.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bmg160_emu.io.array_files import npz_array, npz_columns, numeric, open_npz
from bmg160_emu.io.csv_table import read_csv_table
from bmg160_emu.io.errors import loads_json
from bmg160_emu.io.formats import FileFormat, FileReader, format_for, register_format
from bmg160_emu.io.rate_table import RateFileError
from bmg160_emu.io.time_column import (
    check_time_column,
    in_seconds,
    time_column_help,
    time_column_index,
    time_column_scale_s,
)

UNITS = ("dps", "counts")
DEFAULT_MAX_GAP_FACTOR = 3.0  # a step over 3x the median step is a gap, not jitter
MAX_RATE_DPS = 2000.0 * 1.05  # beyond the widest range (spec 5.1) with 5% margin
INT16 = (-32768, 32767)


@dataclass
class ReplayData:
    """Checked samples: times in seconds (n,), rates in deg/s (n, 3)."""

    t_s: np.ndarray
    rate_dps: np.ndarray
    source: str = "<data>"

    def __post_init__(self) -> None:
        # computed once: the replay hook consults it for every output sample
        self.median_step_s = float(np.median(np.diff(self.t_s))) if len(self.t_s) > 1 else math.inf

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])


# --------------------------------------------------------------------------- loading


_UNIT_SUFFIXES = {
    "_dps": "dps", "_deg_s": "dps", "[dps]": "dps", "(dps)": "dps",
    "_counts": "counts", "_raw": "counts", "_lsb": "counts", "[lsb]": "counts", "(lsb)": "counts",
}


def _split_unit(name: str) -> tuple[str, str | None]:
    """'x_dps' -> ('x', 'dps'); 'gx' -> ('gx', None)."""
    for suffix, unit in _UNIT_SUFFIXES.items():
        if name.endswith(suffix):
            return name[: -len(suffix)].strip(), unit
    return name, None


def _pick_columns(header: list[str], unit: str, where: str) -> tuple[int, float, list[int]]:
    """Index of the time column, its seconds per unit (its name says: time_ms, ...), and the
    indices of the x, y, z columns for ``unit``."""
    names = [h.strip().lower() for h in header]
    time_column = time_column_index(names)
    if time_column is None:
        raise RateFileError(f"{where}: no time column (a column named {time_column_help()})")
    axes = []
    for axis in "xyz":
        bases = {axis, f"g{axis}", f"rate_{axis}", f"gyro_{axis}", f"omega_{axis}"}
        candidates = [(i, u) for i, (b, u) in enumerate(map(_split_unit, names)) if b in bases]
        chosen = [i for i, u in candidates if u == unit] or [i for i, u in candidates if u is None]
        if chosen:
            axes.append(chosen[0])
        elif candidates:
            i, found = candidates[0]
            raise RateFileError(
                f"{where}: unit mismatch: column {header[i].strip()!r} holds {found}, "
                f"but unit {unit} was given"
            )
        else:
            raise RateFileError(f"{where}: no {axis} column among {', '.join(header)}")
    return time_column[0], time_column[1], axes


def _check_values(t: np.ndarray, xyz: np.ndarray, unit: str, where: Callable[[int], str],
                  max_gap_factor: float) -> None:
    """Time must increase without gaps; values must fit the unit."""
    if len(t) < 2:
        raise RateFileError(f"{where(0)}: a recording needs at least two samples")
    check_time_column(t, where, max_gap_factor,
                      "fill the gap or raise the allowed gap (max_gap_factor)")
    if unit == "counts":
        frac = np.flatnonzero(np.any(xyz != np.round(xyz), axis=1))
        if frac.size:
            i = int(frac[0])
            raise RateFileError(
                f"{where(i)}: raw counts must be whole numbers, found {xyz[i].tolist()}: "
                "deg/s data? use unit dps"
            )
        out = np.flatnonzero(np.any((xyz < INT16[0]) | (xyz > INT16[1]), axis=1))
        if out.size:
            i = int(out[0])
            raise RateFileError(f"{where(i)}: {xyz[i].tolist()} is outside the 16-bit range of raw counts")
    else:
        out = np.flatnonzero(np.any(np.abs(xyz) > MAX_RATE_DPS, axis=1))
        if out.size:
            i = int(out[0])
            raise RateFileError(
                f"{where(i)}: {xyz[i].tolist()} deg/s is beyond the widest range (+-2000 deg/s): "
                "raw counts? use unit counts"
            )


def _to_dps(xyz: np.ndarray, unit: str, lsb_per_dps: float | None, where: str) -> np.ndarray:
    if unit == "dps":
        return xyz.astype(float)
    if not lsb_per_dps:
        raise RateFileError(
            f"{where}: raw counts need the sensitivity they were recorded with (lsb_per_dps, "
            "or the range: 16.384 LSB/(deg/s) at +-2000 deg/s)"
        )
    return xyz / float(lsb_per_dps)


def load_replay_data(
    path: str | Path,
    unit: str = "dps",
    lsb_per_dps: float | None = None,
    max_gap_factor: float = DEFAULT_MAX_GAP_FACTOR,
) -> ReplayData:
    """Read and check a CSV or NPZ recording; raise :class:`RateFileError` naming the line.

    CSV: ``#`` comment lines, then either a header row naming a time column and x, y, z
    columns, or no header and exactly four numeric columns ``t, x, y, z``. The files written
    by ``bmg160-emu record`` are read as they are: the unit picks their ``*_dps`` or
    ``*_counts`` columns and their sensitivity comes from their settings line.
    """
    if unit not in UNITS:
        raise ValueError(f"unit must be one of {UNITS}, not {unit!r}")
    path = Path(path)
    if not path.exists():
        raise RateFileError(f"{path}: no such file")
    if path.suffix.lower() == ".npy":
        raise RateFileError(f"{path}: a .npy array holds no time column: replay reads a "
                            ".csv or .npz recording (t and x, y, z)")
    fmt = format_for("replay", path, RateFileError, reading=True, what="replay data")
    return fmt.read(path, unit, lsb_per_dps, max_gap_factor)


def _lsb_from_settings(text: str) -> float | None:
    """``lsb_per_dps`` of a recording's JSON settings, or None when they hold none (a file of
    counts then needs --lsb-per-dps; _to_dps says so)."""
    try:
        settings = loads_json(text, RateFileError, "settings")
    except RateFileError:
        return None
    value = settings.get("lsb_per_dps") if isinstance(settings, dict) else None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value)


class CsvReplayData(FileReader):
    """A CSV recording: a header naming the time and x, y, z columns (a unit suffix picks
    ``*_dps`` or ``*_counts``), or four numeric columns t, x, y, z."""

    noun = "recording"
    error = RateFileError

    def read(self, unit: str = "dps", lsb_per_dps: float | None = None,
             max_gap_factor: float = DEFAULT_MAX_GAP_FACTOR) -> ReplayData:
        return _load_csv(self.path, unit, lsb_per_dps, max_gap_factor)


class NpzReplayData(FileReader):
    """An NPZ recording: a time array and rate_dps/gyro_dps (or counts/raw, or x, y, z)."""

    noun = "recording"
    error = RateFileError

    def read(self, unit: str = "dps", lsb_per_dps: float | None = None,
             max_gap_factor: float = DEFAULT_MAX_GAP_FACTOR) -> ReplayData:
        return _load_npz(self.path, unit, lsb_per_dps, max_gap_factor)


def _load_csv(path: Path, unit: str, lsb_per_dps: float | None, max_gap_factor: float) -> ReplayData:
    time_scale_s = [1.0]  # seconds per unit of the time column (a header's name may say)

    def choose(header: list[str] | None, width: int, where: str) -> tuple[int, list[int]]:
        if header is None:
            if width != 4:
                raise RateFileError(
                    f"{where}: {width} columns without a header; expected 4 (t, x, y, z) "
                    "or a header row naming the columns"
                )
            return 0, [1, 2, 3]
        time_index, time_scale_s[0], axes = _pick_columns(header, unit, where)
        return time_index, axes

    table = read_csv_table(path, choose)
    if lsb_per_dps is None:
        for _, text in table.comments:
            if text.startswith("{"):
                lsb_per_dps = _lsb_from_settings(text)
                break
    t, xyz = table.t_s, table.values
    assert t is not None
    t = in_seconds(t, time_scale_s[0])
    finite = np.isfinite(t) & np.isfinite(xyz).all(axis=1)
    if not finite.all():
        row = int(np.argmin(finite))
        raise RateFileError(
            f"{table.where(row)}: empty or non-finite value in {table.line_text(row)!r}"
        )
    _check_values(t, xyz, unit, table.where, max_gap_factor)
    return ReplayData(t, _to_dps(xyz, unit, lsb_per_dps, str(path)), str(path))


def _load_npz(path: Path, unit: str, lsb_per_dps: float | None, max_gap_factor: float) -> ReplayData:
    with open_npz(path) as data:
        keys = set(data.files)
        t_key = next((k for k in sorted(keys) if time_column_scale_s(k) is not None), None)
        if t_key is None:
            raise RateFileError(f"{path}: no time array (an array named {time_column_help()})")
        if "metadata" in keys and lsb_per_dps is None:
            lsb_per_dps = _lsb_from_settings(str(npz_array(data, "metadata", path)))
        wanted = {"dps": ("rate_dps", "gyro_dps"), "counts": ("counts", "raw")}[unit]
        other = {"dps": ("counts", "raw"), "counts": ("rate_dps", "gyro_dps")}[unit]
        key = next((k for k in wanted if k in keys), None)
        if key is None:
            if all(a in keys for a in "xyz"):
                xyz = npz_columns(data, list("xyz"), path)
            elif any(k in keys for k in other):
                found = next(k for k in other if k in keys)
                raise RateFileError(
                    f"{path}: unit mismatch: the file holds {found!r} but unit {unit} was given"
                )
            else:
                raise RateFileError(
                    f"{path}: no rate array ({', '.join(wanted)}, or x, y, z) among {sorted(keys)}"
                )
        else:
            xyz = numeric(npz_array(data, key, path), path, f"key {key}")
        t = in_seconds(numeric(npz_array(data, t_key, path), path, f"key {t_key}").reshape(-1),
                       time_column_scale_s(t_key))
    if xyz.ndim != 2 or xyz.shape[1] != 3:
        raise RateFileError(f"{path}: the rate array must have 3 columns (x, y, z), not shape {xyz.shape}")
    if len(xyz) != len(t):
        raise RateFileError(f"{path}: {len(t)} time stamps but {len(xyz)} rate rows")

    def where(row: int) -> str:
        return f"{path}: row {row}"

    finite = np.isfinite(t) & np.isfinite(xyz).all(axis=1)
    if not finite.all():
        raise RateFileError(f"{where(int(np.argmin(finite)))}: non-finite value")
    _check_values(t, xyz, unit, where, max_gap_factor)
    return ReplayData(t, _to_dps(xyz, unit, lsb_per_dps, str(path)), str(path))


# --------------------------------------------------------------------------- playing


for _suffix in (".csv", ".txt", ".log"):
    register_format(FileFormat("replay", _suffix, CsvReplayData, None,
                               "header naming t and x, y, z, or 4 columns"))
register_format(FileFormat("replay", ".npz", NpzReplayData, None, "a time array and the rates"))
