"""Rate files: time and x, y, z rates in CSV, NPZ or NPY; the one reader and writer.

Three kinds of tool read such files (``identify`` a static record, ``replay`` a flight
recording, ``record``'s own output read back); each one chooses its columns and checks its
values, but the bytes are read here, once, with one error type (:class:`RateFileError`)
whose message names the file and the line, key or row.

Memory: a CSV file is parsed in chunks of about 1 MiB of text straight into arrays sized
from a count of its lines, and NPZ arrays are copied one key at a time into the result, so
reading costs the result arrays plus one chunk (about 1.33x the rate array for a file with
a time column and three axes; ``tools/bench_rate_read.py`` measures it).
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import tokenize
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bmg160_emu.io.array_header import check_declared_size
from bmg160_emu.io.errors import FileFormat, format_for, register_format
from bmg160_emu.io.rate_table import ColumnChoice, RateFileError, RateTable

# what numpy and zipfile raise on a damaged file: np.load's header parser (tokenize), a zip
# member with an unknown compression method, a cut or corrupt archive
ARRAY_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error,
                tokenize.TokenError, SyntaxError, NotImplementedError)
CHUNK_BYTES = 1 << 20  # text parsed per np.loadtxt call: bounds the reader's working memory
CHUNK_ROWS = 1 << 20  # rows of a time column checked at a time
MEDIAN_STEPS = 1 << 21  # steps the median step is taken from (evenly spread over the record)
TIME_COLUMN_NAMES = ("t", "t_s", "time", "time_s", "timestamp")


def is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _line_count_bound(path: Path) -> int:
    """Line ends + 1: at least the number of data rows, found without holding the file.
    Line ends as the text reader counts them (universal newlines): LF, CRLF and a lone CR;
    a CRLF split between two blocks counts twice, which keeps this a bound."""
    count = 1
    with open(path, "rb") as handle:
        while block := handle.read(1 << 20):
            count += block.count(b"\n") + block.count(b"\r") - block.count(b"\r\n")
    return count


_EMPTY_CELL = re.compile(r"(?m)(?:^|(?<=,))[ \t]*(?=,|$)")


def read_csv_table(path: str | Path, choose: ColumnChoice) -> RateTable:
    """Read the columns ``choose`` picks from a CSV rate file.

    ``#`` lines and blank lines are skipped; the first other line is a header when any of
    its cells is not a number. Every row must have as many cells as the first; an empty
    cell reads as NaN (the caller decides whether that is allowed).
    """
    path = Path(path)
    try:
        bound = _line_count_bound(path)
        handle = open(path, encoding="utf-8", errors="replace")  # noqa: SIM115 (closed below)
    except OSError as exc:
        raise RateFileError(f"cannot read the file ({exc.strerror})", path=path) from None
    comments: list[tuple[int, str]] = []
    with handle:
        lineno = 0
        first: str | None = None
        while line := handle.readline():
            lineno += 1
            stripped = line.strip()
            if not stripped:
                continue
            if stripped.startswith("#"):
                comments.append((lineno, stripped[1:].strip()))
                continue
            first = line
            break
        if first is None:
            raise RateFileError("the CSV file has no data rows", path=path)
        try:
            cells = [c.strip() for c in next(csv.reader([first]))]
        except csv.Error as exc:  # a field over csv's 131,072-character limit, a stray quote
            raise RateFileError(f"not a CSV row: {exc}", path=path, place=lineno) from None
        header = None if all(is_number(c) for c in cells) else cells
        width = len(cells)
        t_index, use = choose(header, width, f"{path}:{lineno}")
        usecols = ([t_index] if t_index is not None else []) + list(use)
        t = np.empty(bound) if t_index is not None else None
        values = np.empty((bound, len(use)))
        table = RateTable(path, header, t, values, comments)
        n = 0
        pending = [] if header is not None else [first]
        next_line = lineno + 1 if header is not None else lineno
        while True:
            lines = pending + handle.readlines(CHUNK_BYTES)
            pending = []
            if not lines:
                break
            n = _parse_chunk(table, lines, next_line, n, width, usecols, t_index is not None)
            next_line += len(lines)
    if n == 0:
        raise RateFileError("the CSV file has no data rows", path=path)
    table.values = values[:n]
    table.t_s = None if t is None else t[:n]
    return table


def _parse_chunk(table: RateTable, lines: list[str], first_line: int, row: int, width: int,
                 usecols: list[int], has_time: bool) -> int:
    """Parse ``lines`` (file lines from ``first_line``) into the table from ``row``; new row count."""
    text = "".join(lines)
    numbers: int | np.ndarray = first_line
    if "#" in text or "\n\n" in text or not lines[0].strip() or not lines[-1].strip():
        lines, numbers = _data_lines(lines, first_line)
        text = "".join(lines)
    if not lines:
        return row
    block = _load_block(table.path, lines, text, numbers, width, usecols)
    if block is None or block.shape[0] != len(lines):
        # a line of spaces only: filter the chunk line by line, then parse it again
        lines, numbers = _data_lines(lines, numbers)
        if not lines:
            return row
        block = _load_block(table.path, lines, "".join(lines), numbers, width, usecols)
        assert block is not None
    m = len(lines)
    if has_time:
        assert table.t_s is not None
        table.t_s[row:row + m] = block[:, 0]
        table.values[row:row + m] = block[:, 1:]
    else:
        table.values[row:row + m] = block
    table.row_starts.append(row)
    table.row_lines.append(numbers)
    return row + m


def _data_lines(lines: list[str], numbers: int | np.ndarray) -> tuple[list[str], np.ndarray]:
    """The lines that hold data (comments after ``#`` removed, blank lines dropped), and
    their line numbers."""
    if isinstance(numbers, int):
        numbers = np.arange(numbers, numbers + len(lines))
    kept, kept_numbers = [], []
    for number, line in zip(numbers.tolist(), lines):
        if "#" in line:
            line = line.split("#", 1)[0].rstrip() + "\n"
        if line.strip():
            kept.append(line)
            kept_numbers.append(number)
    return kept, np.array(kept_numbers, dtype=np.int64)


def _load_block(path: Path, lines: list[str], text: str, numbers: int | np.ndarray, width: int,
                usecols: list[int]) -> np.ndarray | None:
    """The chosen columns of ``lines`` as floats (empty cells NaN), errors naming the line;
    None when the lines hold a line of spaces only (the caller filters them first)."""
    if text.count(",") != len(lines) * (width - 1):
        if any(not line.strip() for line in lines):
            return None
        _find_bad_line(path, lines, numbers, width, usecols)
    source: list[str] = lines
    if ",," in text or ",\n" in text or "\n," in text or text[:1] == "," or text.rstrip("\n")[-1:] == ",":
        source = _EMPTY_CELL.sub("nan", text.removesuffix("\n")).split("\n")
    try:
        return np.loadtxt(source, delimiter=",", usecols=usecols, ndmin=2, dtype=float,
                          comments=None)
    except ValueError as exc:
        if any(not line.strip() for line in lines):
            return None
        _find_bad_line(path, lines, numbers, width, usecols)
        first = numbers if isinstance(numbers, int) else int(numbers[0])
        raise RateFileError(f"unreadable CSV data ({exc})", path=path, place=first) from None


def _find_bad_line(path: Path, lines: list[str], numbers: int | np.ndarray, width: int,
                   usecols: list[int]) -> None:
    """Raise the error of the first row in ``lines`` with the wrong width or a non-number."""
    for k, line in enumerate(lines):
        lineno = numbers + k if isinstance(numbers, int) else int(numbers[k])
        cells = line.rstrip("\n").split(",")
        if len(cells) != width:
            raise RateFileError(f"{len(cells)} columns, expected {width}", path=path, place=lineno)
        for i in usecols:
            cell = cells[i].strip()
            if cell and not is_number(cell):
                raise RateFileError(f"not a number: {cell!r}", path=path, place=lineno)


# --------------------------------------------------------------------------- arrays


def open_npz(path: str | Path):
    """The archive of an NPZ file (arrays read lazily), owning the file it opens here; closed
    here when unreadable (np.load left a truncated zip's file open, issue 35)."""
    from numpy.lib.npyio import NpzFile

    handle = open(path, "rb")  # noqa: SIM115 - owned by the archive from here on
    try:
        magic = handle.read(6)
        handle.seek(0)
        if magic.startswith(b"\x93NUMPY"):
            raise RateFileError("not an NPZ archive (a .npy array)", path=path)
        return NpzFile(handle, own_fid=True, allow_pickle=False)
    except BaseException as exc:
        handle.close()
        if isinstance(exc, ARRAY_ERRORS) and not isinstance(exc, RateFileError):
            raise RateFileError(f"not a readable NPZ archive ({exc})", path=path) from None
        raise


def npz_array(archive, key: str, path: str | Path) -> np.ndarray:
    """One array of the archive; a damaged member, or one whose header declares more data
    than the member holds, is an error naming the key."""
    try:
        name = key if key in archive.zip.namelist() else f"{key}.npy"
        with archive.zip.open(name) as member:
            check_declared_size(member, archive.zip.getinfo(name).file_size, path,
                                RateFileError, f"key {key}")
    except RateFileError:
        raise
    except (AttributeError, *ARRAY_ERRORS):
        pass  # a damaged member: numpy's own error below names it
    try:
        return archive[key]
    except ARRAY_ERRORS as exc:
        raise RateFileError(f"unreadable array ({exc})", path=path, place=f"key {key}") from None


def npz_columns(archive, keys: Sequence[str], path: str | Path) -> np.ndarray:
    """Stack 1-D arrays ``keys`` into one (n, k) float64 array, one key in memory at a time."""
    out: np.ndarray | None = None
    for j, key in enumerate(keys):
        column = numeric(npz_array(archive, key, path), path, f"key {key}").reshape(-1)
        if out is None:
            out = np.empty((len(column), len(keys)))
        elif len(column) != len(out):
            raise RateFileError(f"{len(column)} values, {keys[0]!r} has {len(out)}",
                                path=path, place=f"key {key}")
        out[:, j] = column
    assert out is not None
    return out


def numeric(data: np.ndarray, path: str | Path, place: str | None = None) -> np.ndarray:
    """``data`` as float64 (no copy when it already is); refuse anything but numbers."""
    if data.dtype.kind not in "fiu":
        raise RateFileError(f"the record must hold numbers, not {data.dtype}", path=path,
                            place=place)
    return np.asarray(data, dtype=float)


def first_non_finite(data: np.ndarray, chunk: int = 1 << 20) -> int | None:
    """The first row holding NaN or an infinity, or None; in chunks, so checking a 24 h
    record costs a few MB, not a copy."""
    if data.size == 0:
        return None
    rows = data.reshape(data.shape[0], -1)
    for start in range(0, rows.shape[0], chunk):
        ok = np.isfinite(rows[start : start + chunk]).all(axis=1)
        if not ok.all():
            return start + int(np.argmin(ok))
    return None


def read_npy(path: str | Path) -> np.ndarray:
    try:
        with open(path, "rb") as handle:
            if handle.read(6) == b"\x93NUMPY":
                handle.seek(0)
                check_declared_size(handle, os.fstat(handle.fileno()).st_size, path, RateFileError)
        data = np.load(path, allow_pickle=False)
    except RateFileError:
        raise
    except ARRAY_ERRORS as exc:
        raise RateFileError(f"not a readable .npy array ({exc})", path=path) from None
    if not isinstance(data, np.ndarray):
        data.close()
        raise RateFileError("not a .npy array (an NPZ archive: name it .npz)", path=path)
    return numeric(data, path)


# --------------------------------------------------------------------------- time column


def check_time_column(t: np.ndarray, where: Callable[[int], str], gap_factor: float,
                      gap_hint: str = "split the record at the gap") -> float:
    """Refuse a time column that is not finite, not increasing or has a gap; its median step.

    A step over ``gap_factor`` median steps is a gap (missing samples), not jitter: Allan
    deviation, PSD and resampling all need evenly spaced samples.
    """
    n = len(t)
    for start in range(0, n, CHUNK_ROWS):  # in chunks: no (n,) temporaries beside t
        part = t[start:start + CHUNK_ROWS + 1]
        bad = np.flatnonzero(~np.isfinite(part))
        if bad.size:
            raise RateFileError(f"{where(start + int(bad[0]))}: the time column has NaN or "
                                "infinite values")
        back = np.flatnonzero(~(np.diff(part) > 0))
        if back.size:
            i = start + int(back[0]) + 1
            raise RateFileError(
                f"{where(i)}: time {float(t[i])!r} s is not after {float(t[i - 1])!r} s "
                f"(the time column is not strictly increasing at sample {i})"
            )
    if n < 2:
        return math.inf
    typical = median_step(t)
    for start in range(0, n - 1, CHUNK_ROWS):
        steps = np.diff(t[start:start + CHUNK_ROWS + 1])
        wide = np.flatnonzero(steps > gap_factor * typical)
        if wide.size:
            i = start + int(wide[0])
            step = float(steps[wide[0]])
            raise RateFileError(
                f"{where(i + 1)}: gap of {step:.6g} s after sample {i} ({step / typical:.1f} "
                f"sample periods of {typical:.6g} s): evenly spaced samples are needed; {gap_hint}"
            )
    return typical


def median_step(t: np.ndarray) -> float:
    """The median time step; of evenly spread steps when there are over MEDIAN_STEPS.

    Exact up to MEDIAN_STEPS + 1 samples (2.9 h at 200 Hz); beyond, the median of every
    k-th step, which is within a small fraction of the jitter of the exact one (a sample
    median of 2**21 values has a standard error of 1.25 sd / 1450) and needs no (n,) copy.
    """
    n_steps = len(t) - 1
    if n_steps <= MEDIAN_STEPS:
        return float(np.median(np.diff(t)))
    k = -(-n_steps // MEDIAN_STEPS)
    return float(np.median(t[k::k][: n_steps // k] - t[0:-1:k][: n_steps // k]))


# --------------------------------------------------------------------------- writing


CSV_ROWS = 65_536  # rows formatted at a time by write_csv (a few MB of text)


def write_csv(path: str | Path, comments: Sequence[str], names: Sequence[str],
              blocks: Sequence[np.ndarray]) -> None:
    """Write ``#`` comment lines, a header and the columns of ``blocks`` side by side.

    Integer arrays are written with ``str``, floats with ``repr`` (the shortest text that
    reads back to the same float), NaN as an empty cell; CSV_ROWS rows at a time (all at
    once took 770 bytes a row: 77 GB for the 1e8 samples record may hold, issue 35).
    """
    columns = [b.reshape(len(b), -1) for b in blocks]
    formats = [str if c.dtype.kind in "iu" else _float_cell for c in columns]
    rows = len(columns[0]) if columns else 0
    with open(path, "w", encoding="utf-8", newline="") as handle:
        handle.write("".join(f"# {c}\n" for c in comments))
        handle.write(",".join(names) + "\n")
        for start in range(0, rows, CSV_ROWS):
            buffer = io.StringIO()
            for cells in zip(*(c[start:start + CSV_ROWS].tolist() for c in columns)):
                buffer.write(",".join(f(v) for f, group in zip(formats, cells) for v in group)
                             + "\n")
            handle.write(buffer.getvalue())


def _float_cell(value: float) -> str:
    return "" if math.isnan(value) else repr(value)


def write_npz(path: str | Path, arrays: dict[str, np.ndarray]) -> None:
    """Write the named arrays, compressed."""
    np.savez_compressed(path, **arrays)  # type: ignore[arg-type]


# --------------------------------------------------------------------------- generic files


@dataclass(frozen=True)
class RateRecord:
    """A rate record ready for identification."""

    rate_dps: np.ndarray  # (n, k), k = 1..3
    rate_hz: float
    axis_names: tuple[str, ...]
    source: str


RATE_COLUMN_SETS = (("x_dps", "y_dps", "z_dps"), ("x", "y", "z"), ("gx", "gy", "gz"))
GAP_FACTOR = 2.5  # identify: a step this many times the median step is a gap


def load_rate_record(
    path: str | Path, rate_hz: float | None = None, columns: list[str] | None = None
) -> RateRecord:
    """Read a static record (deg/s); ``rate_hz`` overrides (and is checked against) a time column.

    - CSV: one column per axis, optionally a time column (t, t_s, time, time_s or
      timestamp); an optional header row names the columns; when it has x_dps, y_dps,
      z_dps (the ``record`` and ``generate`` layout) those are the axes.
    - .npy: an (n,) or (n, k) array, k <= 3, no time.
    - .npz: a single array, or rate_dps (n, 3) and t_s, or x, y, z with an optional t.
    - .resd: Renode sensor data, angular-rate channel 0; .txt or .log holding the firmware's
      UART stream (told from a CSV by its first line): io/resd.py, io/uart_stream.py.
    """
    path = Path(path)
    if path.is_dir():
        raise RateFileError(f"{path}: is a directory, not a record file")
    if not path.is_file():
        raise RateFileError(f"no such record file: {path}")
    suffix = path.suffix.lower()
    from bmg160_emu.io import uart_stream

    stream = suffix in uart_stream.SUFFIXES and uart_stream.looks_like_uart_stream(path)
    if columns and (suffix not in (".csv", ".txt") or stream):
        raise RateFileError("--columns applies to CSV files with a header row", path=path)
    if suffix not in _READERS:
        raise RateFileError("record file must end in .csv, .npy, .npz, .resd or .txt (a UART "
                            f"stream), not {path.name!r}")
    table = uart_stream.uart_rate_table(path, rate_hz) if stream else _READERS[suffix](path, columns)
    data = table.values
    if data.ndim == 1:
        data = data[:, None]
    if data.ndim != 2 or not 1 <= data.shape[1] <= 3:
        raise RateFileError(
            f"expected one column per axis (1 to 3 axes), got shape {data.shape}", path=path
        )
    if data.shape[0] == 0:
        raise RateFileError("the record is empty (no samples)", path=path)
    if table.t_s is not None and (table.t_s.ndim != 1 or len(table.t_s) != data.shape[0]):
        raise RateFileError(f"the time column has shape {table.t_s.shape}; the rates have "
                            f"{data.shape[0]} rows", path=path)
    _check_sample_count(table, data.shape[0])
    bad = first_non_finite(data)
    if bad is not None:
        raise RateFileError(f"{table.where(bad)}: NaN or infinite rate: "
                            f"{[float(v) for v in np.ravel(data[bad])]}")
    names = table.header or ("x", "y", "z")[: data.shape[1]]
    rate = _resolve_rate(table, rate_hz, data.shape[0])
    return RateRecord(data, rate, tuple(n.removesuffix("_dps") for n in names), str(path))


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
    if t is None:
        if rate_hz is None:
            raise RateFileError("no time column: give the sample rate (--rate HZ)", path=path)
        return float(rate_hz)
    check_time_column(t, table.where, GAP_FACTOR)
    if n < 2:
        if rate_hz is None:
            raise RateFileError("too few samples to read the rate from the time column", path=path)
        return float(rate_hz)
    from_time = (n - 1) / float(t[-1] - t[0])
    if rate_hz is not None:
        if abs(from_time / rate_hz - 1.0) > 0.01:
            raise RateFileError(
                f"--rate {rate_hz:g} Hz disagrees with the time column ({from_time:.6g} Hz)",
                path=path,
            )
        return float(rate_hz)
    return from_time


def _read_record_npy(path: Path, columns: list[str] | None) -> RateTable:
    return RateTable(path, None, None, read_npy(path))


def _read_record_npz(path: Path, columns: list[str] | None) -> RateTable:
    with open_npz(path) as archive:
        keys = list(archive.files)
        t_key = next((k for k in TIME_COLUMN_NAMES if k in keys), None)
        t = numeric(npz_array(archive, t_key, path), path, f"key {t_key}") if t_key else None
        if "rate_dps" in keys:
            return RateTable(path, None, t, numeric(npz_array(archive, "rate_dps", path), path))
        for names in RATE_COLUMN_SETS:
            present = [k for k in names if k in keys]
            if present:
                return RateTable(path, present, t, npz_columns(archive, present, path))
        others = [k for k in keys if k not in TIME_COLUMN_NAMES]
        numbers = [k for k in others if npz_array(archive, k, path).dtype.kind in "fiu"]
        if len(numbers) == 1:
            return RateTable(path, None, t, numeric(npz_array(archive, numbers[0], path), path))
    raise RateFileError(
        f"cannot tell which arrays hold the rates (found {sorted(keys)}); "
        "store one array, or rate_dps, or x, y, z", path=path,
    )


def _read_record_csv(path: Path, columns: list[str] | None) -> RateTable:
    chosen: list[str] = []

    def choose(header: list[str] | None, width: int, where: str) -> tuple[int | None, list[int]]:
        if header is None:
            if columns:
                raise RateFileError(f"{where}: --columns needs a header row naming the columns")
            return None, list(range(width))
        names = [c.lower() for c in header]
        time_index = next((names.index(n) for n in TIME_COLUMN_NAMES if n in names), None)
        if columns:
            wanted = [c.lower() for c in columns]
            missing = [c for c in wanted if c not in names]
            if missing:
                raise RateFileError(f"{where}: no column(s) {missing[:8]}; the header has "
                                    f"{names[:12]}{' ...' if len(names) > 12 else ''}")
            rate_names = wanted
        else:
            rate_names = next(
                ([n for n in s if n in names] for s in RATE_COLUMN_SETS if s[0] in names),
                [n for i, n in enumerate(names) if i != time_index],
            )
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
    return table


def _read_record_resd(path: Path, columns: list[str] | None) -> RateTable:
    from bmg160_emu.io.resd import resd_rate_table
    return resd_rate_table(path)


_READERS = {".csv": _read_record_csv, ".txt": _read_record_csv, ".log": _read_record_csv,
            ".npy": _read_record_npy, ".npz": _read_record_npz, ".resd": _read_record_resd}


def write_rates(path: str | Path, t_s: np.ndarray | None, rate_dps: np.ndarray,
                comments: Sequence[str] = ()) -> None:
    """Write a rate record that :func:`load_rate_record` reads back exactly.

    CSV: ``#`` comments, header ``t_s,x_dps,...``; NPZ: ``t_s`` and ``rate_dps``; NPY: the
    (n, k) array alone (no time: the reader is given the rate); RESD: io/resd.py, channel 0.
    """
    rate_dps = np.asarray(rate_dps, dtype=float)
    rate_dps = rate_dps.reshape(len(rate_dps), -1)
    names = ("x_dps", "y_dps", "z_dps")[: rate_dps.shape[1]]
    fmt = format_for("rates", path, RateFileError)
    if fmt.suffix == ".resd":
        from bmg160_emu.io.resd import write_resd_rates

        write_resd_rates(path, t_s, rate_dps)
    elif fmt.suffix == ".npy":
        np.save(path, rate_dps)
    elif fmt.suffix == ".npz":
        arrays = {"rate_dps": rate_dps}
        if t_s is not None:
            arrays["t_s"] = np.asarray(t_s, dtype=float)
        write_npz(path, arrays)
    else:
        blocks = ([np.asarray(t_s, dtype=float)] if t_s is not None else []) + [rate_dps]
        write_csv(path, comments, (["t_s"] if t_s is not None else []) + list(names), blocks)


def _register() -> None:
    for suffix, description in ((".csv", "header row, optional time column"),
                                (".npz", "rate_dps (n, k) and t_s, or x, y, z and t"),
                                (".npy", "(n, k) array, no time"), (".resd", "Renode, channel 0")):
        register_format(FileFormat("rates", suffix, load_rate_record, write_rates, description))


_register()

