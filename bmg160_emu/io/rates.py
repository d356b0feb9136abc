"""Rate records: what ``identify`` reads (time and x, y, z in deg/s, or the rates alone),
one reader class per format over a common base, and ``write_rates``, which writes every
one of them so that ``load_rate_record`` reads it back exactly.

The bytes are read by the shared readers (io/csv_table.py, io/array_files.py, io/resd.py,
io/uart_stream.py) into a RateTable; :class:`RateFileReader` then checks what every format
must hold and finds the rate. The registry (io/formats.py) names the formats: kind
``rates`` for identify's records, and ``rate table`` for a scenario's table of t, x, y, z.
"""

from __future__ import annotations

import math
import re
from abc import abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bmg160_emu.io.array_files import (
    first_non_finite,
    npz_array,
    npz_columns,
    numeric,
    open_npz,
    read_npy,
    write_npz,
)
from bmg160_emu.io.csv_table import read_csv_table, write_csv
from bmg160_emu.io.formats import (
    FileFormat,
    FileReader,
    FileWriter,
    check_file,
    format_for,
    register_format,
)
from bmg160_emu.io.rate_table import RateFileError, RateTable
from bmg160_emu.io.rate_units import RECORD_UNITS, rate_unit
from bmg160_emu.io.time_column import (
    check_time_column,
    in_seconds,
    time_column_help,
    time_column_index,
    time_column_scale_s,
)
from bmg160_emu.limits import SAMPLE_RATE_HZ


@dataclass(frozen=True)
class RateRecord:
    """A rate record ready for identification."""

    rate_dps: np.ndarray  # (n, k), k = 1..3
    rate_hz: float
    axis_names: tuple[str, ...]
    source: str
    unit: str = "deg/s"  # the unit the rates were in before they were read as deg/s


RATE_COLUMN_SETS = (("x_dps", "y_dps", "z_dps"), ("x", "y", "z"), ("gx", "gy", "gz"))
GAP_FACTOR = 2.5  # identify: a step this many times the median step is a gap


class RateFileReader(FileReader):
    """A static record read for identification: a subclass reads its format into a
    RateTable (``table``); the base checks what every format must hold (1 to 3 axes, at
    least one sample, finite rates, the sample count a ``generate`` header states) and finds
    the rate from ``rate_hz`` or the time column."""

    noun = "record file"
    error = RateFileError
    takes_columns = False  # --columns applies (CSV with a header row)

    @abstractmethod
    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable: ...

    def read(self, rate_hz: float | None = None, columns: list[str] | None = None,
             record_units: str | None = None) -> RateRecord:
        """The record; ``record_units`` ("deg/s" or "rad/s") is the unit of rates whose file
        states none (io/rate_units.py), refused where it states another."""
        self.check_path()
        if columns and not self.takes_columns:
            raise RateFileError("--columns applies to CSV files with a header row",
                                path=self.path)
        if record_units is not None and record_units not in RECORD_UNITS:
            raise RateFileError(f"record units must be one of {', '.join(RECORD_UNITS)}, "
                                f"not {record_units!r}", path=self.path)
        table = self.table(rate_hz, columns)
        data = table.values
        stated = table.stated_unit
        if record_units is not None and stated is not None and stated != record_units:
            raise RateFileError(f"the file states its rates in {stated}; --record-units "
                                f"{record_units} applies to a record that states none",
                                path=self.path)
        if stated is None and record_units is not None and RECORD_UNITS[record_units] != 1.0:
            data = data * RECORD_UNITS[record_units]
        if data.ndim == 1:
            data = data[:, None]
        if data.ndim != 2 or not 1 <= data.shape[1] <= 3:
            raise RateFileError(
                f"expected one column per axis (1 to 3 axes), got shape {data.shape}",
                path=self.path)
        if data.shape[0] == 0:
            raise RateFileError("the record is empty (no samples)", path=self.path)
        if table.t_s is not None and (table.t_s.ndim != 1 or len(table.t_s) != data.shape[0]):
            raise RateFileError(f"the time column has shape {table.t_s.shape}; the rates have "
                                f"{data.shape[0]} rows", path=self.path)
        _check_sample_count(table, data.shape[0])
        bad = first_non_finite(data)
        if bad is not None:
            raise RateFileError(f"{table.where(bad)}: NaN or infinite rate: "
                                f"{[float(v) for v in np.ravel(data[bad])]}")
        names = table.header or ("x", "y", "z")[: data.shape[1]]
        rate = _resolve_rate(table, rate_hz, data.shape[0])
        return RateRecord(data, rate, tuple(n.removesuffix("_dps") for n in names),
                          str(self.path), stated or record_units or "deg/s")


def load_rate_record(
    path: str | Path, rate_hz: float | None = None, columns: list[str] | None = None,
    record_units: str | None = None,
) -> RateRecord:
    """Read a static record (deg/s); ``rate_hz`` overrides (and is checked against) a time column.
    ``record_units`` ("rad/s") is the unit of a record that states none (a CSV column's
    name may: ``w_RS_S_x [rad s^-1]``, ``gx_rad_s``, ``x_dps``; io/rate_units.py).

    - CSV: one column per axis, optionally a time column (t, time or timestamp in
      seconds, or with its unit: time_ms, timestamp_us, t_ns, ``timestamp [ns]``); an
      optional header row names the columns; when it has x_dps, y_dps, z_dps (the
      ``record`` and ``generate`` layout) those are the axes.
    - .npy: an (n,) or (n, k) array, k <= 3, no time.
    - .npz: a single array, or rate_dps (n, 3) and t_s, or x, y, z with an optional t, or
      counts with lsb_dps (and axes); a rate_hz number gives the rate without a time array.
    - .resd: Renode sensor data, angular-rate channel 0; .txt or .log holding the firmware's
      UART stream (told from a CSV by its first line): io/resd.py, io/uart_stream.py.
    """
    check_file(path, RateFileReader.noun, RateFileError)  # before the suffix: one message
    fmt = format_for("rates", path, RateFileError, reading=True, what="record file")
    return fmt.read(path, rate_hz, columns, record_units)


_SAMPLES_COMMENT = re.compile(r"\bbmg160-emu generate:.*\bsamples=(\d+)\b")


def _check_sample_count(table: RateTable, n: int) -> None:
    """A ``generate`` CSV says how many samples it holds: a file that holds fewer was cut
    short (copied while written, a full disk, a crash) and is refused, not read as a shorter
    record without a word. An interrupted run rewrites the count, so it passes."""
    for line, text in table.comments:
        found = _SAMPLES_COMMENT.search(text)
        if found and int(found.group(1)) != n:
            raise RateFileError(f"its header says samples={found.group(1)} but it holds {n} "
                                "rows: the file was cut short", path=table.path, place=line)


def _resolve_rate(table: RateTable, rate_hz: float | None, n: int) -> float:
    path, t = table.path, table.t_s
    valid = isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0
    if rate_hz is not None and not valid:
        raise RateFileError(f"sample rate must be a positive number of Hz, got {rate_hz!r}")
    stated = table.rate_hz
    if t is None and stated is not None:
        if rate_hz is not None and abs(stated / rate_hz - 1.0) > 0.01:
            raise RateFileError(f"--rate {rate_hz:g} Hz disagrees with the file's rate_hz "
                                f"({stated:g} Hz)", path=path)
        return float(rate_hz if rate_hz is not None else stated)
    if t is None:
        if rate_hz is None:
            raise RateFileError(f"no time column (a column named {time_column_help()}): "
                                "give the sample rate (--rate HZ) or name the time column so",
                                path=path)
        return float(rate_hz)
    check_time_column(t, table.where, GAP_FACTOR)
    if n < 2:
        if rate_hz is None:
            raise RateFileError("too few samples to read the rate from the time column", path=path)
        return float(rate_hz)
    from_time = (n - 1) / float(t[-1] - t[0])
    bounds = SAMPLE_RATE_HZ
    if rate_hz is None and not bounds.low <= from_time <= bounds.high:
        # a bare "timestamp" is seconds: PX4's CSV export stamps in us under that name
        raise RateFileError(
            f"the time column gives {from_time:.4g} Hz, outside {bounds.low:g} to "
            f"{bounds.high:g} Hz: are its stamps in ms, us or ns? Name the column with its "
            f"unit ({time_column_help()})", path=path)
    if rate_hz is not None:
        if abs(from_time / rate_hz - 1.0) > 0.01:
            raise RateFileError(
                f"--rate {rate_hz:g} Hz disagrees with the time column ({from_time:.6g} Hz)",
                path=path,
            )
        return float(rate_hz)
    return from_time


class NpyRates(RateFileReader):
    """An .npy (n,) or (n, k) array of rates, no time (the rate must be given)."""

    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable:
        return RateTable(self.path, None, None, read_npy(self.path))


def _npz_scalar(archive: Any, key: str, path: Path) -> float | None:
    """A positive finite number stored as a 0-d (or one-element) array, or None when absent."""
    if key not in archive.files:
        return None
    value = numeric(npz_array(archive, key, path), path, f"key {key}").reshape(-1)
    if value.size != 1 or not math.isfinite(float(value[0])) or float(value[0]) <= 0:
        raise RateFileError(f"key {key} must be one positive number, got {value[:4].tolist()}",
                            path=path)
    return float(value[0])


def _npz_axis_names(archive: Any, width: int, path: Path) -> list[str] | None:
    """The ``axes`` array's names when it holds one string per column."""
    if "axes" not in archive.files:
        return None
    names = npz_array(archive, "axes", path).reshape(-1)
    if names.dtype.kind not in "US" or names.size != width:
        return None
    return [str(n.decode() if isinstance(n, bytes) else n) for n in names]


class NpzRates(RateFileReader):
    """An .npz archive: rate_dps (and t_s), or x, y, z (and a time key), or integer
    ``counts`` with their step ``lsb_dps`` (a sensor's raw output, as recorded: rates are
    counts x lsb_dps), or one array; a ``rate_hz`` number gives the rate when there is no
    time array."""

    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable:
        with open_npz(self.path) as archive:
            table = self._table(archive)
            table.rate_hz = _npz_scalar(archive, "rate_hz", self.path)
        return table

    def _table(self, archive: Any) -> RateTable:
        path = self.path
        keys = list(archive.files)
        t_key = next((k for k in keys if time_column_scale_s(k) is not None), None)
        t = None
        if t_key is not None:
            t = numeric(npz_array(archive, t_key, path), path, f"key {t_key}")
            t = in_seconds(t, time_column_scale_s(t_key))
        if "rate_dps" in keys:
            return RateTable(path, None, t, numeric(npz_array(archive, "rate_dps", path), path),
                             stated_unit="deg/s")
        if "counts" in keys:
            lsb = _npz_scalar(archive, "lsb_dps", path)
            if lsb is None:
                raise RateFileError("counts without lsb_dps (deg/s per count): store the "
                                    "step, or the rates as rate_dps", path=path)
            counts = numeric(npz_array(archive, "counts", path), path, "key counts")
            with np.errstate(over="ignore"):  # an inf is refused by row below
                values = counts * lsb
            width = values.shape[1] if values.ndim == 2 else 1
            return RateTable(path, _npz_axis_names(archive, width, path), t, values,
                             stated_unit="deg/s")
        for names in RATE_COLUMN_SETS:
            present = [k for k in names if k in keys]
            if present:
                return RateTable(path, present, t, npz_columns(archive, present, path),
                                 stated_unit="deg/s" if present[0].endswith("_dps") else None)
        others = [k for k in keys if time_column_scale_s(k) is None]
        numbers = [k for k in others if k not in ("rate_hz", "lsb_dps")
                   and npz_array(archive, k, path).dtype.kind in "fiu"]
        if len(numbers) == 1:
            return RateTable(path, None, t, numeric(npz_array(archive, numbers[0], path), path))
        raise RateFileError(
            f"cannot tell which arrays hold the rates (found {sorted(keys)}); "
            "store one array, or rate_dps, or x, y, z", path=path,
        )


class CsvRates(RateFileReader):
    """A CSV file: one column per axis, an optional header row and time column."""

    takes_columns = True

    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable:
        path = self.path
        chosen: list[str] = []
        time_scale_s = [1.0]  # seconds per unit of the time column (its name says)

        def choose(header: list[str] | None, width: int, where: str) -> tuple[int | None, list[int]]:
            if header is None:
                if columns:
                    raise RateFileError(f"{where}: --columns needs a header row naming the columns")
                return None, list(range(width))
            names = [c.lower() for c in header]
            found = time_column_index(names)
            time_index = None if found is None else found[0]
            if found is not None:
                time_scale_s[0] = found[1]
            if columns:
                wanted = [c.lower() for c in columns]
                twice = sorted({c for c in wanted if wanted.count(c) > 1})
                if twice:
                    raise RateFileError(f"{where}: --columns names {twice[0]!r} more than once")
                missing = [c for c in wanted if c not in names]
                if missing:
                    raise RateFileError(f"{where}: no column(s) {missing[:8]}; the header has "
                                        f"{names[:12]}{' ...' if len(names) > 12 else ''}")
                rate_names = wanted
            else:  # a known set, else the columns whose names carry a rate unit, else all
                others = [n for i, n in enumerate(names) if i != time_index]
                labelled = [n for n in others if rate_unit(n) is not None]
                rate_names = next(
                    ([n for n in s if n in names] for s in RATE_COLUMN_SETS if s[0] in names),
                    labelled if 1 <= len(labelled) <= 3 else others,
                )
            for name in rate_names:  # names.index would read the first of them each time
                if not name:
                    raise RateFileError(f"{where}: column {names.index(name) + 1} of the header "
                                        "has no name; name each axis")
                if names.count(name) > 1:
                    raise RateFileError(f"{where}: column {name!r} appears {names.count(name)} "
                                        "times in the header; name each axis once")
            if len(rate_names) > 3:
                shown = ", ".join(rate_names[:8]) + (", ..." if len(rate_names) > 8 else "")
                raise RateFileError(
                    f"{where}: {len(rate_names)} rate columns ({shown!r}); "
                    "choose up to three with --columns"
                )
            chosen.extend(rate_names)
            return time_index, [names.index(n) for n in rate_names]

        table = read_csv_table(path, choose)
        if table.header is not None:
            table.header = chosen
            units = [rate_unit(n) for n in chosen]
            if any(units):  # deg/s by the column's own unit; the name without it
                stated = {u[1] for u in units if u is not None}
                table.stated_unit = stated.pop() if len(stated) == 1 else "mixed units"
                for i, unit in enumerate(units):
                    if unit is not None:
                        if unit[2] != 1.0:
                            table.values[:, i] *= unit[2]
                        table.header[i] = unit[0]
        if table.t_s is not None:
            table.t_s = in_seconds(table.t_s, time_scale_s[0])
        return table


class TextRates(CsvRates):
    """A .txt or .log file: the firmware's UART stream when its first lines say so (the ODR
    from the capture's line, else ``rate_hz``), else a CSV file."""

    def read(self, rate_hz: float | None = None, columns: list[str] | None = None,
             record_units: str | None = None) -> RateRecord:
        from bmg160_emu.io.uart_stream import looks_like_uart_stream

        self.check_path()
        self.takes_columns = not looks_like_uart_stream(self.path)
        return super().read(rate_hz, columns, record_units)

    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable:
        if self.takes_columns:
            return super().table(rate_hz, columns)
        from bmg160_emu.io.uart_stream import uart_rate_table

        table = uart_rate_table(self.path, rate_hz)
        table.stated_unit = "deg/s"  # the firmware's lines are in deg/s
        return table


class ResdRates(RateFileReader):
    """A Renode sensor data file: angular-rate channel 0 (io/resd.py)."""

    def table(self, rate_hz: float | None, columns: list[str] | None) -> RateTable:
        from bmg160_emu.io.resd import resd_rate_table

        table = resd_rate_table(self.path)
        table.stated_unit = "deg/s"  # converted from the format's 1e-5 rad/s
        return table


class RatesWriter(FileWriter):
    """A rate record written so that ``load_rate_record`` reads it back exactly:
    ``write(t_s or None, rate_dps (n,) or (n, k), comments=...)``, complete or not at all."""

    def write_to(self, path: Path, t_s: np.ndarray | None, rate_dps: np.ndarray,
                 comments: Sequence[str] = ()) -> None:
        rate_dps = np.asarray(rate_dps, dtype=float)
        rate_dps = rate_dps.reshape(len(rate_dps), -1)
        suffix = self.path.suffix.lower()
        names = ("x_dps", "y_dps", "z_dps")[: rate_dps.shape[1]]
        if suffix == ".resd":
            from bmg160_emu.io.resd import write_resd_rates

            write_resd_rates(path, t_s, rate_dps)
        elif suffix == ".npy":
            np.save(path, rate_dps)
        elif suffix == ".npz":
            arrays = {"rate_dps": rate_dps}
            if t_s is not None:
                arrays["t_s"] = np.asarray(t_s, dtype=float)
            write_npz(path, arrays)
        else:
            blocks = ([np.asarray(t_s, dtype=float)] if t_s is not None else []) + [rate_dps]
            write_csv(path, comments, (["t_s"] if t_s is not None else []) + list(names), blocks)


def write_rates(path: str | Path, t_s: np.ndarray | None, rate_dps: np.ndarray,
                comments: Sequence[str] = ()) -> None:
    """Write a rate record that :func:`load_rate_record` reads back exactly, complete or
    not at all. CSV: ``#`` comments, header ``t_s,x_dps,...``; NPZ: ``t_s`` and
    ``rate_dps``; NPY: the (n, k) array alone (no time: the reader is given the rate);
    RESD: io/resd.py, channel 0."""
    fmt = format_for("rates", path, RateFileError, writing=True)
    fmt.write(path, t_s, rate_dps, comments=comments)


# --------------------------------------------------------------------------- rate tables


class RateTableFile(FileReader):
    """A scenario's table of true rates: rows of t_s, x, y, z (a header row and ``#``
    lines allowed in a CSV; an (n, 4) array in an .npy); ``read()`` gives the (n, 4) array."""

    noun = "rate table file"
    error = RateFileError

    def read(self) -> np.ndarray:
        self.check_path()
        where = None  # a CSV row's file and line (an .npy's row is its index)
        if self.path.suffix.lower() == ".npy":
            data = read_npy(self.path)
        else:
            def choose(header: list[str] | None, width: int, where: str
                       ) -> tuple[int | None, list[int]]:
                if width != 4:
                    raise RateFileError(f"{where}: {width} columns; a rate table has 4: "
                                        "t_s, x, y, z")
                return None, [0, 1, 2, 3]

            table = read_csv_table(self.path, choose)
            data, where = table.values, table.where
        if data.ndim != 2 or data.shape[1] != 4:
            raise RateFileError(f"a rate table holds rows of 4 numbers (t_s, x, y, z), not "
                                f"shape {data.shape}", path=self.path)
        bad = first_non_finite(data)
        if bad is not None:  # named by line (issue 35: a nan used to fail later, unnamed)
            if where is not None:
                raise RateFileError(f"{where(bad)}: empty or non-finite value")
            raise RateFileError(f"row {bad}: empty or non-finite value", path=self.path)
        return data


def _register() -> None:
    for suffix, reader, writer, description in (
            (".csv", CsvRates, RatesWriter, "header row, optional time column"),
            (".npy", NpyRates, RatesWriter, "(n, k) array, no time"),
            (".npz", NpzRates, RatesWriter, "rate_dps (n, k) and t_s, or x, y, z and t"),
            (".resd", ResdRates, RatesWriter, "Renode, angular rate channel 0"),
            (".txt", TextRates, None, "the firmware's UART stream, or CSV"),
            (".log", TextRates, None, "the firmware's UART stream, or CSV")):
        register_format(FileFormat("rates", suffix, reader, writer, description))
    for suffix, description in ((".csv", "t_s, x, y, z columns"), (".npy", "(n, 4) array")):
        register_format(FileFormat("rate table", suffix, RateTableFile, None, description))


_register()
