"""Snapshots of the BMG160's 64 registers in three text formats, each read back.

A dump is what a driver author compares: the ``i2cdump`` format is byte for byte what
Debian's ``i2cdump -y -r 0x00-0x3f BUS ADDR b`` prints (so Debian's ``i2c-stub-from-dump``
loads it into the kernel's i2c-stub), ``table`` decodes every field by name from the
register table in :mod:`bmg160_emu.device.registers`, and ``json`` is for programs. Every format
parses back into a :class:`RegisterDump`.
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bmg160_emu.device import registers, spec_choices
from bmg160_emu.device.fields import (
    decode_register,
    describe_register,
    register_name,
)
from bmg160_emu.device.registers import REGISTER_COUNT
from bmg160_emu.io.errors import FormatError, loads_json, read_text

DUMP_FORMATS = ("i2cdump", "table", "json")
JSON_FORMAT_TAG = "bmg160-emu register dump"
JSON_FORMAT_VERSION = 1

# The column header i2cdump prints in byte mode (i2c-tools tools/i2cdump.c).
I2CDUMP_HEADER = "     0  1  2  3  4  5  6  7  8  9  a  b  c  d  e  f    0123456789abcdef"
# First line of a table dump, and the title of each chip's block when several are dumped.
DUMP_TITLE = "# bmg160-emu register dump"


class DumpFormatError(FormatError):
    """A dump that cannot be read; the message names the line."""


@dataclass(frozen=True)
class RegisterDump:
    """The content of registers 0x00..0x3F at one moment, with where and when it was taken."""

    values: bytes
    address: int | None = None
    time_s: float | None = None
    metadata: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if len(self.values) != REGISTER_COUNT:
            raise ValueError(f"a register dump holds {REGISTER_COUNT} bytes, not {len(self.values)}")
        object.__setattr__(self, "values", bytes(self.values))

    def __getitem__(self, register: int) -> int:
        return self.values[register]

    @classmethod
    def from_chip(cls, chip) -> RegisterDump:
        """Snapshot a chip without read side effects (``chip.dump()``)."""
        with chip.lock:
            values = bytes(chip.dump())
            time_s = float(chip.time)
        return cls(values, address=getattr(chip, "address", None), time_s=time_s)


# --------------------------------------------------------------------------- i2cdump


def _i2cdump_char(value: int) -> str:
    # i2cdump prints '.' for 0x00 and 0xff, '?' for other non-printables.
    if value in (0x00, 0xFF):
        return "."
    if value < 32 or value >= 127:
        return "?"
    return chr(value)


def format_i2cdump(values: Sequence[int | None], first: int = 0x00, last: int | None = None) -> str:
    """Render bytes exactly as ``i2cdump -y -r FIRST-LAST BUS ADDR b`` prints them.

    ``values[i]`` is register ``i``; registers outside ``first..last`` are blanked the way
    i2cdump blanks them, and ``None`` entries print as ``XX`` (a failed read).
    """
    cells: list[int | None] = list(values)
    if last is None:
        last = len(cells) - 1
    if not 0 <= first <= last <= 0xFF or last >= len(cells):
        raise ValueError(f"invalid register range 0x{first:02x}-0x{last:02x}")
    lines = [I2CDUMP_HEADER]
    for row in range(first // 16 * 16, last // 16 * 16 + 16, 16):
        hex_part = []
        ascii_part = []
        for reg in range(row, row + 16):
            cell = cells[reg] if first <= reg <= last else -1
            if cell == -1:
                hex_part.append("   ")
                ascii_part.append(" ")
            elif cell is None:
                hex_part.append("XX ")
                ascii_part.append("X")
            else:
                hex_part.append(f"{cell:02x} ")
                ascii_part.append(_i2cdump_char(cell))
        lines.append(f"{row:02x}: " + "".join(hex_part) + "   " + "".join(ascii_part))
    return "\n".join(lines) + "\n"


_I2CDUMP_ROW = re.compile(r"^([0-9a-fA-F]{2}): ((?:(?:[0-9a-fA-F]{2}|XX| {2}) ){16})")


def i2cdump_cells(text: str, source: str = "<dump>") -> dict[int, int | None]:
    """Every cell of an i2cdump byte-mode listing, 0x00..0xFF: register -> value, or None
    for a cell printed ``XX`` (a failed read); blank cells are left out."""
    found: dict[int, int | None] = {}
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip() or line.startswith(I2CDUMP_HEADER.rstrip()[:10]):
            continue
        if line.startswith(DUMP_TITLE):  # the block title of a several-chip dump
            continue
        match = _I2CDUMP_ROW.match(line)
        if not match:
            raise DumpFormatError(f"{source}:{lineno}: not an i2cdump byte-mode row: {line!r}")
        row = int(match.group(1), 16)
        if row % 16:
            raise DumpFormatError(f"{source}:{lineno}: row offset 0x{row:02x} is not a multiple of 0x10")
        cells = [match.group(2)[i : i + 2] for i in range(0, 48, 3)]
        for i, cell in enumerate(cells):
            reg = row + i
            if cell == "  ":
                continue
            if reg in found:
                raise DumpFormatError(f"{source}:{lineno}: register 0x{reg:02x} appears twice")
            found[reg] = None if cell == "XX" else int(cell, 16)
    return found


def parse_i2cdump(text: str, source: str = "<dump>") -> bytes:
    """Read an i2cdump byte-mode listing back into 64 register values.

    Rows above 0x30 (a full 256-register dump) are accepted and ignored; every register
    0x00..0x3F must be present and readable.
    """
    found = i2cdump_cells(text, source)
    unreadable = [reg for reg in range(REGISTER_COUNT) if reg in found and found[reg] is None]
    if unreadable:
        line = _line_of_row(text, unreadable[0] // 16 * 16)
        raise DumpFormatError(f"{source}:{line}: register 0x{unreadable[0]:02x} was unreadable (XX)")
    missing = [reg for reg in range(REGISTER_COUNT) if reg not in found]
    if missing:
        raise DumpFormatError(
            f"{source}: registers missing from the dump: "
            + ", ".join(f"0x{reg:02x}" for reg in missing[:8])
            + (" ..." if len(missing) > 8 else "")
        )
    return bytes(found[reg] or 0 for reg in range(REGISTER_COUNT))


def _line_of_row(text: str, row: int) -> int:
    for lineno, line in enumerate(text.splitlines(), 1):
        if line[:3].lower() == f"{row:02x}:":
            return lineno
    return 0


# --------------------------------------------------------------------------- json


def format_json(dump: RegisterDump) -> str:
    """The dump for programs: every register with its name, value and decoded fields."""
    registers = []
    for reg, value in enumerate(dump.values):
        entry: dict[str, Any] = {
            "register": f"0x{reg:02x}", "name": register_name(reg), "value": f"0x{value:02x}"
        }
        entry["fields"] = {f.name: f.raw for f in decode_register(reg, value)}
        registers.append(entry)
    document = {
        "format": JSON_FORMAT_TAG,
        "version": JSON_FORMAT_VERSION,
        "address": None if dump.address is None else f"0x{dump.address:02x}",
        "time_s": dump.time_s,
        "registers": registers,
    }
    return json.dumps(document, indent=1) + "\n"


def _int_field(value, where: str) -> int:
    if isinstance(value, bool):
        raise DumpFormatError(f"{where}: expected a number, got {value!r}")
    if isinstance(value, int):
        return value
    if isinstance(value, str):
        try:
            return int(value, 0)
        except ValueError:
            pass
    raise DumpFormatError(f"{where}: expected a number, got {value!r}")


def parse_json(text: str, source: str = "<dump>") -> RegisterDump:
    """Read the ``json`` format back; only register numbers and values are used."""
    document = loads_json(text, DumpFormatError, source, lines=True)
    if not isinstance(document, dict) or document.get("format") != JSON_FORMAT_TAG:
        raise DumpFormatError(f"{source}: not a {JSON_FORMAT_TAG} (missing \"format\" tag)")
    if document.get("version") != JSON_FORMAT_VERSION:
        raise DumpFormatError(f"{source}: unsupported dump version {document.get('version')!r}")
    entries = document.get("registers")
    if not isinstance(entries, list):
        raise DumpFormatError(f"{source}: \"registers\" must be a list")
    found: dict[int, int] = {}
    for i, entry in enumerate(entries):
        where = f"{source}: registers[{i}]"
        if not isinstance(entry, dict) or "register" not in entry or "value" not in entry:
            raise DumpFormatError(f"{where}: needs \"register\" and \"value\"")
        reg = _int_field(entry["register"], where)
        value = _int_field(entry["value"], where)
        if not 0 <= reg < REGISTER_COUNT or not 0 <= value <= 0xFF or reg in found:
            raise DumpFormatError(f"{where}: register {reg:#04x} = {value:#x} is out of range or repeated")
        found[reg] = value
    if len(found) != REGISTER_COUNT:
        missing = sorted(set(range(REGISTER_COUNT)) - set(found))
        raise DumpFormatError(f"{source}: registers missing: " + ", ".join(f"0x{r:02x}" for r in missing[:8]))
    address = document.get("address")
    return RegisterDump(
        bytes(found[r] for r in range(REGISTER_COUNT)),
        address=None if address is None else _int_field(address, f"{source}: address"),
        time_s=document.get("time_s"),
    )


# --------------------------------------------------------------------------- table

_TABLE_ROW = re.compile(r"^0x([0-9a-fA-F]{2})\s+(\S+)\s+0x([0-9a-fA-F]{2})(?:\s|$)")


def format_table(dump: RegisterDump, sensitivity: str | None = None) -> str:
    """One line per register: address, name, value and every field decoded by name."""
    sensitivity = sensitivity or dump.metadata.get("sensitivity") or spec_choices.DEFAULT_SENSITIVITY
    where = [] if dump.address is None else [f"address=0x{dump.address:02x}"]
    when = [] if dump.time_s is None else [f"t={dump.time_s:.9f} s"]
    lines = ["  ".join([DUMP_TITLE, *where, *when, f"sensitivity={sensitivity}"])]
    width = max(len(r.name) for r in registers.REGISTERS)
    for reg, value in enumerate(dump.values):
        lines.append(
            f"0x{reg:02X} {register_name(reg):<{width}} 0x{value:02X}  "
            + describe_register(reg, value, sensitivity)
        )
    return "\n".join(lines) + "\n"


def parse_table(text: str, source: str = "<dump>") -> RegisterDump:
    """Read the ``table`` format back (address, name and value of each line)."""
    found: dict[int, int] = {}
    address = time_s = None
    for lineno, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        if line.startswith("#"):
            m = re.search(r"address=0x([0-9a-fA-F]{2})", line)
            address = int(m.group(1), 16) if m else address
            m = re.search(r"t=([0-9.eE+-]+) s", line)
            time_s = float(m.group(1)) if m else time_s
            continue
        m = _TABLE_ROW.match(line)
        if not m:
            raise DumpFormatError(f"{source}:{lineno}: not a register table line: {line!r}")
        reg, name, value = int(m.group(1), 16), m.group(2), int(m.group(3), 16)
        if reg >= REGISTER_COUNT:
            raise DumpFormatError(f"{source}:{lineno}: register 0x{reg:02X} is outside the map")
        if name != register_name(reg):
            raise DumpFormatError(
                f"{source}:{lineno}: register 0x{reg:02X} is {register_name(reg)}, not {name}"
            )
        if reg in found:
            raise DumpFormatError(f"{source}:{lineno}: register 0x{reg:02X} appears twice")
        found[reg] = value
    missing = [r for r in range(REGISTER_COUNT) if r not in found]
    if missing:
        raise DumpFormatError(
            f"{source}: registers missing from the dump: " + ", ".join(f"0x{r:02X}" for r in missing[:8])
        )
    return RegisterDump(bytes(found[r] for r in range(REGISTER_COUNT)), address, time_s)


# --------------------------------------------------------------------------- any format


def format_dump(dump: RegisterDump, fmt: str = "table") -> str:
    """Render in one of :data:`DUMP_FORMATS`."""
    if fmt == "i2cdump":
        return format_i2cdump(dump.values)
    if fmt == "table":
        return format_table(dump)
    if fmt == "json":
        return format_json(dump)
    raise ValueError(f"unknown dump format {fmt!r} (one of {', '.join(DUMP_FORMATS)})")


def detect_format(text: str) -> str:
    """Which of the three formats a text is, from its first meaningful line."""
    lines = text.splitlines()
    for line in lines:
        stripped = line.strip()
        if not stripped:
            continue
        if line.startswith(DUMP_TITLE) and any(
            other.strip() and not other.startswith("#") for other in lines
        ):
            continue  # a title: the lines after it tell the format
        if stripped.startswith("{"):
            return "json"
        if line.rstrip() == I2CDUMP_HEADER or _I2CDUMP_ROW.match(line):
            return "i2cdump"
        return "table"
    raise DumpFormatError("empty dump")


def parse_dump(text: str, source: str = "<dump>") -> RegisterDump:
    """Read a dump in any of the three formats (detected from the text)."""
    if _block_count(text) > 1:
        dumps = parse_dumps(text, source)
        where = ", ".join("?" if d.address is None else f"0x{d.address:02x}" for d in dumps)
        raise DumpFormatError(
            f"{source}: holds the dumps of {len(dumps)} chips ({where}); "
            "take one chip's dump (bmg160-emu dump --chip ADDRESS)"
        )
    try:
        fmt = detect_format(text)
    except DumpFormatError:
        raise DumpFormatError(f"{source}: empty dump") from None
    if fmt == "json":
        return parse_json(text, source)
    if fmt == "i2cdump":
        return RegisterDump(parse_i2cdump(text, source))
    return parse_table(text, source)


# --------------------------------------------------------------------------- several chips


def format_dumps(dumps: Sequence[RegisterDump], fmt: str = "table") -> str:
    """Several chips' dumps in one text; one dump gives exactly :func:`format_dump`.

    i2cdump and table: one block per chip, blocks separated by an empty line, each opened by
    a title line naming its address (the table's own first line is that title), so every
    i2cdump block is byte for byte what i2cdump prints for that address. json: a list of
    the single-chip documents.
    """
    if not dumps:
        raise ValueError("no dump to format")
    if len(dumps) == 1:
        return format_dump(dumps[0], fmt)
    if fmt == "json":
        return json.dumps([json.loads(format_json(d)) for d in dumps], indent=1) + "\n"
    blocks = []
    for dump in dumps:
        title = ""
        if fmt == "i2cdump":
            where = "" if dump.address is None else f"  address=0x{dump.address:02x}"
            when = "" if dump.time_s is None else f"  t={dump.time_s:.9f} s"
            title = f"{DUMP_TITLE}{where}{when}\n"
        blocks.append(title + format_dump(dump, fmt))
    return "\n".join(blocks)


def _block_count(text: str) -> int:
    if text.lstrip().startswith("["):
        try:
            document = loads_json(text, DumpFormatError, "<dump>", lines=True)
        except DumpFormatError:
            return 1
        return len(document) if isinstance(document, list) else 1
    return max(1, sum(1 for line in text.splitlines() if line.startswith(DUMP_TITLE)))


def read_dumps(path: str | Path) -> list[RegisterDump]:
    """The dumps in a file (any format); a file that is not UTF-8 text is a DumpFormatError
    at its line (OSError for a missing file passes through)."""
    return parse_dumps(read_text(path, DumpFormatError), str(path))


def parse_dumps(text: str, source: str = "<dump>") -> list[RegisterDump]:
    """Read one or several chips' dumps (:func:`format_dumps`), in any of the formats.

    Errors name the line in the whole text."""
    if text.lstrip().startswith("["):
        documents = loads_json(text, DumpFormatError, source, lines=True)
        if not isinstance(documents, list) or not documents:
            raise DumpFormatError(f"{source}: a list of dumps must hold at least one")
        return [parse_json(json.dumps(doc), f"{source}[{i}]") for i, doc in enumerate(documents)]
    lines = text.splitlines()
    starts = [i for i, line in enumerate(lines) if line.startswith(DUMP_TITLE)]
    if len(starts) <= 1:
        return [parse_dump(text, source)]
    if any(line.strip() for line in lines[: starts[0]]):
        raise DumpFormatError(f"{source}:1: text before the first dump's title line")
    dumps = []
    for start, end in zip(starts, [*starts[1:], len(lines)]):
        # blank lines in front keep the line numbers of errors those of the whole text
        block = "\n" * start + "\n".join(lines[start:end]) + "\n"
        dump = parse_dump(block, source)
        if dump.address is None or dump.time_s is None:  # i2cdump blocks: from the title
            title = lines[start]
            address = re.search(r"address=0x([0-9a-fA-F]{2})", title)
            time_s = re.search(r"t=([0-9.eE+-]+) s", title)
            dump = RegisterDump(
                dump.values,
                int(address.group(1), 16) if address else dump.address,
                float(time_s.group(1)) if time_s else dump.time_s,
            )
        dumps.append(dump)
    return dumps
