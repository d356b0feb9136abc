"""CSV tables of numbers: the one reader and writer of the CSV files of every rate kind
(identify's records, recordings, replay data, a scenario's rate table).

``#`` lines and blank lines are skipped; the first other line is a header when any of its
cells is not a number (or, in the EuRoC layout, the ``#`` line right above the first row,
when it names a time column); the caller chooses the columns (``ColumnChoice``). Errors name the
file and the line.

Memory: a CSV file is parsed in chunks of about 1 MiB of text straight into arrays sized
from a count of its lines, so reading costs the result arrays plus one chunk
(``tools/bench_rate_read.py`` measures it).
"""

from __future__ import annotations

import csv
import io
import math
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from bmg160_emu.io.rate_table import ColumnChoice, RateFileError, RateTable
from bmg160_emu.io.time_column import time_column_scale_s

CHUNK_BYTES = 1 << 20  # text parsed per np.loadtxt call: bounds the reader's working memory


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
        first_is_data = header is None
        width = len(cells)
        if header is None and comments and comments[-1][0] == lineno - 1:
            header = _commented_header(comments[-1][1], width)
        t_index, use = choose(header, width, f"{path}:{lineno}")
        usecols = ([t_index] if t_index is not None else []) + list(use)
        t = np.empty(bound) if t_index is not None else None
        values = np.empty((bound, len(use)))
        table = RateTable(path, header, t, values, comments)
        n = 0
        pending = [first] if first_is_data else []
        next_line = lineno if first_is_data else lineno + 1
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


def _commented_header(text: str, width: int) -> list[str] | None:
    """The header of a file whose header line is a comment: the EuRoC MAV and TUM-VI
    datasets' ``#timestamp [ns],w_RS_S_x [rad s^-1],...`` right above the first row. Taken
    only when it has a cell for each column and names a time column, so that a comment
    with commas above headerless rows is still a comment."""
    try:
        cells = [c.strip() for c in next(csv.reader([text]))]
    except (csv.Error, StopIteration):
        return None
    if len(cells) != width or not any(time_column_scale_s(c) is not None for c in cells):
        return None
    return cells


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


CSV_ROWS = 65_536  # rows formatted at a time by write_csv (a few MB of text)


def write_csv(path: str | Path, comments: Sequence[str], names: Sequence[str],
              blocks: Sequence[np.ndarray]) -> None:
    """Write ``#`` comment lines, a header and the columns of ``blocks`` side by side.

    Integer arrays are written with ``str``, floats with ``repr`` (the shortest text that
    reads back to the same float), NaN as an empty cell. ``CSV_ROWS`` rows at a time: the
    whole table as Python numbers and one string took about 770 bytes a row, 77 GB for the
    1e8 samples ``record`` may hold (issue 35).
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
