"""Register and transaction text for people: what a log line, a trace print or a dump
difference says about the bytes.

Register fields are decoded by :mod:`bmg160_emu.device.fields` (the table dump format uses
the same text); this module adds reads, writes, bursts, SPI frames and whole transactions.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

from bmg160_emu.bus.spi import chip_select_of
from bmg160_emu.device import registers
from bmg160_emu.device.fields import (
    decode_register,
    describe_value_difference,
    register_label,
    register_name,
)
from bmg160_emu.device.registers import REGISTER_COUNT, REGISTERS, Register
from bmg160_emu.device.spec_choices import REGISTER_ADDRESS_MASK
from bmg160_emu.io.dump import RegisterDump
from bmg160_emu.traffic.fault_entry import parse_fault_entry
from bmg160_emu.traffic.kinds import FAULT_KIND_PREFIX, TRUE_RATE_KIND
from bmg160_emu.traffic.transaction import bytes_from_json

FIFO_DATA = registers.address_of("FIFO_DATA")  # the pointer does not advance here (spec 2.4)

__all__ = [
    "RegisterDifference", "describe_read", "describe_transaction", "describe_write",
    "diff_dumps", "format_diff", "record_value",
]


def _register_span(register: int, count: int) -> str:
    if count <= 1:
        return f"0x{register:02X}"
    last = register + count - 1
    if register < FIFO_DATA <= last:  # the pointer stops at FIFO_DATA (spec 2.4)
        last = FIFO_DATA
    if register >= FIFO_DATA:
        return f"0x{register:02X} x{count}"
    return f"0x{register:02X}..0x{min(last, 0xFF):02X}"


Table = Sequence[Register]  # a register table: the BMG160's, or a part's (device.part_spec)


def _field_text(register: int, value: int, table: Table = REGISTERS) -> str:
    if not 0 <= register < len(table):  # outside the map: no fields, a write is lost (2.4)
        return " (outside the map, ignored)"
    parts = [f.text for f in decode_register(register, value, table=table) if f.text]
    return f" ({'; '.join(parts)})" if parts else ""


def _rate_words(register: int, data: bytes) -> str | None:
    """'x=-12 y=3 z=40' when a burst covers whole rate words (LSB first, spec 4.2)."""
    if register not in (0x02, 0x04, 0x06) or len(data) < 2:
        return None
    words = []
    axes = {0x02: "x", 0x04: "y", 0x06: "z"}
    reg = register
    for i in range(0, len(data) - 1, 2):
        if reg not in axes:
            break
        value = data[i] | data[i + 1] << 8
        words.append(f"{axes[reg]}={value - 0x10000 if value & 0x8000 else value}")
        reg += 2
    rest = data[2 * len(words) :]
    text = " ".join(words)
    if rest:
        text += " then " + " ".join(f"0x{b:02x}" for b in rest)
    return text


def describe_write(register: int, data: bytes, table: Table = REGISTERS) -> str:
    """'write 0x0F RANGE <- 0x02 (+-500 deg/s)': one register, or each byte of a burst
    (``table``: the part's register table, for its names and fields)."""
    if register & ~REGISTER_ADDRESS_MASK:  # bit 7 is not decoded (spec 2.4)
        return f"[0x{register:02X}: bit 7 not decoded] " + describe_write(
            register & REGISTER_ADDRESS_MASK, data, table)
    if len(data) == 1:
        return (f"write {register_label(register, table)} <- 0x{data[0]:02x}"
                f"{_field_text(register, data[0], table)}")
    parts = []
    for offset, value in enumerate(data):
        reg = register + offset
        if reg >= REGISTER_COUNT:
            parts.append(f"0x{reg:02X} <- 0x{value:02x} (outside the map, ignored)")
        else:
            parts.append(f"{register_label(reg, table)} <- 0x{value:02x}"
                         f"{_field_text(reg, value, table)}")
    return f"burst write {_register_span(register, len(data))}: " + ", ".join(parts)


def describe_read(register: int, data: bytes, table: Table = REGISTERS) -> str:
    """'burst read 0x02..0x07 -> x=-12 y=3 z=40' or 'read 0x00 CHIP_ID -> 0x0f (...)'."""
    if register & ~REGISTER_ADDRESS_MASK:  # bit 7 is not decoded (spec 2.4)
        return f"[0x{register:02X}: bit 7 not decoded] " + describe_read(
            register & REGISTER_ADDRESS_MASK, data, table)
    if len(data) == 1:
        value = data[0]
        if register >= REGISTER_COUNT:
            return f"read 0x{register:02X} (outside the map) -> 0x{value:02x}"
        return (f"read {register_label(register, table)} -> 0x{value:02x}"
                f"{_field_text(register, value, table)}")
    span = _register_span(register, len(data))
    words = _rate_words(register, data)
    if words is not None:
        return f"burst read {span} -> {words}"
    if register == FIFO_DATA:
        return f"burst read {span} (FIFO_DATA) -> {len(data)} bytes: {data[:12].hex(' ')}" + (
            " ..." if len(data) > 12 else ""
        )
    parts = []
    for offset, value in enumerate(data):
        reg = min(register + offset, FIFO_DATA) if register < FIFO_DATA else register
        name = register_name(reg, table) if reg < REGISTER_COUNT else hex(reg)
        parts.append(f"{name}=0x{value:02x}")
    return f"burst read {span} -> " + " ".join(parts)


def record_value(record: dict, *names: str, default: Any = None) -> Any:
    for name in names:
        if name in record and record[name] is not None:
            return record[name]
    return default


def _standin_label(spec: Any, reg: int) -> str:
    declared = spec.registers.get(reg)
    return f"0x{reg:02X} {declared.name}" if declared is not None and declared.name else f"0x{reg:02X}"


def _describe_standin(spec: Any, register: int, read: bytes, written: bytes) -> str:
    """A stand-in's traffic with its own register names (a BMG160 name would mislead):
    bursts advance one register a byte except on its FIFO registers (``no_increment``), within
    the register bits the chip decodes (``register_address_bits``)."""
    mask = spec.address_mask
    if register & ~mask:  # a bit the chip does not decode (its declaration's width)
        return f"[0x{register:02X}: bit 7 not decoded] " + _describe_standin(
            spec, register & mask, read, written)

    def span(data: bytes, start: int) -> list[int]:
        regs, reg = [], start
        for _ in data:
            regs.append(reg)
            if reg not in spec.no_increment:
                reg = (reg + 1) & mask
        return regs

    if read and written:  # a process call: write from register on, then read on from there
        regs = span(written, register)
        after = regs[-1] if regs[-1] in spec.no_increment else (regs[-1] + 1) & mask
        return (_describe_standin(spec, register, b"", written) + "; then "
                + _describe_standin(spec, after, read, b""))
    data, verb, arrow = (read, "read", "->") if read else (written, "write", "<-")
    if len(data) == 1:
        if read:
            return f"read {_standin_label(spec, register)} -> 0x{data[0]:02x}"
        return f"write {_standin_label(spec, register)} <- 0x{data[0]:02x}"
    parts = [f"{_standin_label(spec, reg)}{'=' if read else ' <- '}0x{value:02x}"
             for reg, value in zip(span(data, register), data)]
    return f"burst {verb} 0x{register:02X} x{len(data)} {arrow} " + ", ".join(parts)


def describe_transaction(record: dict, standins: dict[int, Any] | None = None,
                         parts: dict[int, Table] | None = None) -> str:
    """One line for a person from a transaction dictionary (``Transaction.to_dict()``).

    ``standins`` maps an address to its stand-in declaration (a trace header's), whose
    traffic is told with the stand-in's register names rather than the BMG160's; ``parts``
    maps an address to the register table of the part there (a BMI088 gyroscope's
    INT3_INT4_IO_CONF, not the BMG160's INT_EN_1; no field the part lacks). An SPI record
    (no address; bus ``spi<bus>.<cs>``) is told as the device on that chip select, the
    cs-th in address order."""
    time_s = record_value(record, "time", "time_s", default=float("nan"))
    bus = record_value(record, "bus", default="?")
    address = record_value(record, "address")
    cs = chip_select_of(bus) if address is None else None
    if cs is not None:
        devices = sorted({*(standins or {}), *(parts or {})})
        address = devices[cs] if cs < len(devices) else None
    where = f"{bus}" + (f" 0x{address:02x}" if isinstance(address, int) else "")
    head = f"{time_s:12.6f}s  {where:<10} "
    kind = str(record_value(record, "kind", default="?"))
    register = record_value(record, "register")
    error = record_value(record, "error")
    written = bytes_from_json(record_value(record, "written", "data_out", "write"))
    read = bytes_from_json(record_value(record, "read", "data_in", "result"))
    if kind.startswith(FAULT_KIND_PREFIX):  # an injected fault's onset, not bus traffic
        detail, _ = parse_fault_entry(written)
        return head + f"FAULT injected: {detail or kind[len(FAULT_KIND_PREFIX):]}  [{kind}]"
    if kind == TRUE_RATE_KIND:  # the session changed the chip's input, not bus traffic
        return head + f"{written.decode('utf-8', 'replace').partition(chr(10))[0]}  [{kind}]"
    table = (parts or {}).get(address, REGISTERS) if isinstance(address, int) else REGISTERS
    if kind == "spi_xfer" and written and not error:  # a raw frame, command byte first
        return head + _describe_spi_frame(written, read, table) + f"  [{kind}]"
    if kind == "spi_write" and isinstance(register, int) and len(written) > 1 and not error:
        # one register, then (address, data) pairs in the same frame (spec 2.2)
        frame = bytes([register & 0x7F]) + written
        return head + _describe_spi_frame(frame, b"", table) + f"  [{kind}]"
    standin = (standins or {}).get(address) if isinstance(address, int) else None
    if error:
        if standin is not None and isinstance(register, int):
            return head + f"{kind} {_standin_label(standin, register)} failed: {error}"
        named = isinstance(register, int) and register < REGISTER_COUNT
        target = f" {register_label(register, table)}" if named else ""
        return head + f"{kind}{target} failed: {error}"
    if standin is not None and isinstance(register, int):
        if read or written:
            return head + _describe_standin(standin, register, read, written) + f"  [{kind}]"
        return head + f"set pointer {_standin_label(standin, register)}  [{kind}]"
    if isinstance(register, int):
        if read and written:  # process calls: write from register on, then read on from there
            after = min(register + len(written), FIFO_DATA) if register < FIFO_DATA else register
            return (head + describe_write(register, written, table) + "; then "
                    + describe_read(after, read, table) + f"  [{kind}]")
        if read:
            return head + describe_read(register, read, table) + f"  [{kind}]"
        if written:
            return head + describe_write(register, written, table) + f"  [{kind}]"
        return head + f"set pointer {register_label(register, table)}  [{kind}]"
    if read:
        return head + f"{kind} -> {read.hex(' ')}"
    return head + f"{kind} {written.hex(' ')}".rstrip()


def iter_descriptions(records: Iterable[dict]) -> Iterator[str]:
    """One line per transaction dictionary (a trace's records)."""
    for record in records:
        yield describe_transaction(record)


def _describe_spi_frame(mosi: bytes, miso: bytes, table: Table = REGISTERS) -> str:
    """An SPI frame (spec 2.2): command byte, then read data, or write data and pairs."""
    command, register = mosi[0], mosi[0] & 0x7F
    if command & 0x80:
        if len(mosi) > 1:
            return "SPI " + describe_read(register, miso[1:], table)
        return "SPI read command only"
    if len(mosi) < 2:
        return f"SPI write command 0x{register:02X} without data"
    parts = [describe_write(register, mosi[1:2], table)]
    rest = mosi[2:]
    for i in range(0, len(rest) - 1, 2):  # further (address, data) pairs in the same frame
        parts.append(describe_write(rest[i] & 0x7F, rest[i + 1 : i + 2], table))
    return "SPI " + "; ".join(parts)


# --------------------------------------------------------------------------- diff


@dataclass(frozen=True)
class RegisterDifference:
    register: int
    a: int
    b: int

    @property
    def fields(self) -> str:
        return describe_value_difference(self.register, self.a, self.b).replace(
            " expected ", ": "
        ).replace(", got ", " -> ")


def diff_dumps(a: RegisterDump, b: RegisterDump) -> list[RegisterDifference]:
    """The registers whose values differ, in address order."""
    return [
        RegisterDifference(reg, va, vb) for reg, (va, vb) in enumerate(zip(a.values, b.values)) if va != vb
    ]


def format_diff(
    a: RegisterDump, b: RegisterDump, a_name: str = "A", b_name: str = "B", show_all: bool = False
) -> str:
    """Side by side: register, name, both values and the fields that differ, decoded."""
    differences = {d.register: d for d in diff_dumps(a, b)}
    width = max(len(r.name) for r in registers.REGISTERS)
    col = max(4, len(a_name), len(b_name))
    lines = [f"{'':6}{'register':<{width}} {a_name:>{col}} {b_name:>{col}}  fields that differ"]
    for reg in range(REGISTER_COUNT):
        d = differences.get(reg)
        if d is None and not show_all:
            continue
        mark = "*" if d else " "
        text = (d.fields or "reserved bits differ") if d else ""
        lines.append(
            f"{mark}0x{reg:02X} {register_name(reg):<{width}} {f'0x{a[reg]:02X}':>{col}} "
            f"{f'0x{b[reg]:02X}':>{col}}  {text}".rstrip()
        )
    count = len(differences)
    if count:
        lines.append(f"{count} register{'s differ' if count != 1 else ' differs'}")
    else:
        lines.append("no difference")
    return "\n".join(lines) + "\n"
