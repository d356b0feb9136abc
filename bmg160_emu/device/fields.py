"""A register byte decoded field by field with the register table's names and labels.

Below every file format and every tool: the ``table`` dump format and the transaction text
for people (:mod:`bmg160_emu.session.decode`) both print fields this way, so they cannot disagree.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from bmg160_emu.device import registers, spec_choices
from bmg160_emu.device.registers import REGISTER_COUNT, Register


def ascii_text(text: str) -> str:
    """The register table's labels in plain ASCII, for terminals and logs (+-500 deg/s)."""
    return text.replace("±", "+-").replace("°/s", "deg/s").replace("°C", "deg C").replace(
        "µs", "us"
    ).replace("·", "*")


@dataclass(frozen=True)
class DecodedField:
    """One field of a register byte: its value and what it means."""

    name: str
    raw: int
    label: str  # the table's name for this value, or ""
    on_off: bool  # the field is a flag whose values are named off/on
    qualified: bool = False  # the short text needs the field name (several named fields)
    width: int = 1  # bits

    @property
    def value_text(self) -> str:
        """A whole byte reads best in hex (0xb6), a narrow field in decimal."""
        return f"0x{self.raw:02x}" if self.width >= 8 else str(self.raw)

    @property
    def text(self) -> str:
        """Short form for logs: the flag name when set, the label, or name=value."""
        if self.on_off:
            return self.name if self.raw else ""
        if self.label:
            bare_quantity = self.label[0].isdigit()  # "2 ms" alone does not say what it is
            return f"{self.name} {self.label}" if self.qualified or bare_quantity else self.label
        return f"{self.name}={self.value_text}" if self.raw else ""

    @property
    def full_text(self) -> str:
        return f"{self.name}={self.value_text}" + (f" ({self.label})" if self.label else "")


def register_name(register: int, table: Sequence[Register] = registers.REGISTERS) -> str:
    """The spec name of a register (``RESERVED_0x01`` for reserved ones); ``table``: a
    part's own register table (device.part_spec) instead of the BMG160's."""
    return table[register].name


def register_label(register: int, table: Sequence[Register] = registers.REGISTERS) -> str:
    """``0x0F RANGE``: address and name, as every log line names a register."""
    if not 0 <= register < REGISTER_COUNT:
        return f"0x{register:02X} (outside the map)"
    return f"0x{register:02X} {register_name(register, table)}"


def resolve_register_name(name: str) -> int | None:
    """Address of a spec register name (case-insensitive), or None."""
    try:
        return registers.address_of(name)
    except KeyError:
        return None


def decode_register(register: int, value: int, sensitivity: str | None = None,
                    table: Sequence[Register] = registers.REGISTERS) -> list[DecodedField]:
    """The fields of one register byte, decoded with the register table (``table``: a
    part's own, whose absent registers have no fields and narrowed ones fewer).

    With ``sensitivity`` (``binary`` or ``nominal``, spec 5.1), the RANGE field's label also
    gives the LSB per deg/s of that range.
    """
    reg = table[register]
    named = [f for f in reg.fields if f.values and set(f.values.values()) != {"off", "on"}]
    decoded = []
    for f in reg.fields:
        raw = f.extract(value)
        on_off = set(f.values.values()) == {"off", "on"}
        label = ascii_text(f.values.get(raw, ""))
        if sensitivity and reg.name == "RANGE" and f.name == "range":
            lsb_per_dps = spec_choices.SENSITIVITY_TABLES[sensitivity]
            code = raw if raw < len(lsb_per_dps) else spec_choices.RESERVED_RANGE_AS_CODE
            label += f", {lsb_per_dps[code]:g} LSB/(deg/s)"
        decoded.append(DecodedField(f.name, raw, label, on_off, len(named) > 1, f.msb - f.lsb + 1))
    return decoded


def describe_register(register: int, value: int, sensitivity: str | None = None) -> str:
    """Every field by name: ``range=2 (+-500 deg/s, 65.536 LSB/(deg/s))``."""
    fields = decode_register(register, value, sensitivity)
    if not fields:
        return "reserved"
    return " ".join(f.full_text for f in fields)


def describe_value_difference(register: int, expected: int, actual: int, mask: int = 0xFF) -> str:
    """The fields (within ``mask``) whose value differs, expected -> actual."""
    if not 0 <= register < REGISTER_COUNT:
        return ""
    reg = registers.REGISTERS[register]
    parts = []
    for f in reg.fields:
        if not f.mask & mask:
            continue
        want, got = f.extract(expected), f.extract(actual)
        if want != got:
            lw, lg = (ascii_text(f.values.get(v, "")) for v in (want, got))
            parts.append(
                f"{f.name} expected {want}" + (f" ({lw})" if lw else "")
                + f", got {got}" + (f" ({lg})" if lg else "")
            )
    return "; ".join(parts)
