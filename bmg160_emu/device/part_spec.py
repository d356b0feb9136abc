"""A part of the BMG160 family as data: the BMG160 register table plus a table of differences.

The BMG160 die is also the gyroscope of the BMI055 and BMX055; the BMI088 gyroscope keeps a
subset of its registers (docs/parts.md). A part is therefore not a second model: it is the
BMG160 table (``registers.REGISTERS``) with registers removed, narrowed to some of their
fields, renamed after the part's data sheet, given other reset values, or replaced by a
register of the same address. Behaviour follows from the derived table alone: the per-address
write masks, reset values and register hooks (``regmap``) the model reads come from here, so
an absent register reads 0x00 and ignores writes and upsets, and the engines behind it
(any-motion, high-rate, offsets, NVM, power saving) can never be switched on.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import Any

from bmg160_emu.device import fifo as fifo_mod
from bmg160_emu.device import regmap
from bmg160_emu.device.nvm import Nvm
from bmg160_emu.device.registers import (
    ABSENT_READ,
    REGISTER_COUNT,
    REGISTERS,
    Field,
    Register,
    markdown_table,
)
from bmg160_emu.device.spec_choices import VALID_ADDRESSES
from bmg160_emu.device.state import ChipState


@dataclass(frozen=True)
class Differences:
    """What a part changes on the BMG160 table, every entry by BMG160 register name.

    ``absent``: registers the part does not have (read 0x00, writes ignored). ``fields``:
    registers kept with only these fields (the other bits reserved: read 0, writes ignored).
    ``renamed``: the part's data-sheet name of a register. ``reset``: other reset values.
    ``replaced``: a register of the part at the address of the named BMG160 register, with
    no behaviour beyond storage. ``pin_fields``: the pins the part's data sheet names the
    interrupt fields after (the BMI088's int3_od where the BMG160 has int1_od)."""

    absent: tuple[str, ...] = ()
    fields: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    renamed: Mapping[str, str] = field(default_factory=dict)
    reset: Mapping[str, int] = field(default_factory=dict)
    replaced: Mapping[str, Register] = field(default_factory=dict)
    pin_fields: tuple[str, str] | None = None


@dataclass(frozen=True)
class Part:
    """One part: its name, pins, noise profile and the register table derived for it."""

    name: str
    title: str
    differences: Differences = Differences()
    pins: tuple[str, str] = ("INT1", "INT2")  # the pins chip.int1 / chip.int2 stand for
    noise_profile: str = "paper"
    i2c_addresses: tuple[int, ...] = tuple(VALID_ADDRESSES)
    stream_depth: int | None = None  # frames the FIFO holds in stream mode (None: capacity)
    registers: tuple[Register, ...] = ()
    absent: frozenset[int] = frozenset()
    reset_values: bytes = b""
    write_masks: bytes = b""
    peek_at: tuple[Callable[[ChipState, int], int] | None, ...] = ()  # regmap.PEEK by address
    action_at: tuple[Callable[[ChipState, int, int], None] | None, ...] = ()
    effect_at: tuple[Callable[[ChipState, int, int, int], None] | None, ...] = ()

    def address_of(self, name: str) -> int:
        """Address of a register by the part's name or its BMG160 name."""
        upper = name.upper()
        for reg, base in zip(self.registers, REGISTERS):
            names = {reg.name} if base.name in self.differences.replaced else {reg.name, base.name}
            if upper in names and reg.address not in self.absent:
                return reg.address
        raise KeyError(f"no {self.title} register named {name!r}")

    def register(self, address: int) -> Register:
        return self.registers[address]

    def fifo_depth(self, mode: int) -> int:
        """Frames the FIFO holds in ``mode`` (fifo.FIFO or fifo.STREAM)."""
        if mode == fifo_mod.STREAM and self.stream_depth is not None:
            return self.stream_depth
        return fifo_mod.Fifo.capacity

    def load_nvm(self, nvm: Nvm, regs: bytearray) -> None:
        """Power-up and soft reset: the NVM-backed registers the part has get their image."""
        nvm.load_into(regs)
        for address in self.absent:
            regs[address] = 0

    def markdown_table(self) -> str:
        """The part's register map as a Markdown table (docs/parts.md embeds the BMI088's)."""
        return markdown_table(self.registers)

    def decode_dump(self, dump: bytes) -> list[str]:
        """One line per register of a 64-byte dump, in the part's register names."""
        if len(dump) != REGISTER_COUNT:
            raise ValueError(f"a register dump has {REGISTER_COUNT} bytes, not {len(dump)}")
        return [f"0x{r.address:02X} {r.describe(v)}" for r, v in zip(self.registers, dump)]


def _masked(hook: Callable[[ChipState, int], int], bits: int) -> Callable[[ChipState, int], int]:
    def peek(s: ChipState, now: int) -> int:
        return hook(s, now) & bits

    return peek


def _narrow(reg: Register, keep: tuple[str, ...]) -> Register:
    unknown = set(keep) - {f.name for f in reg.fields}
    if unknown:
        raise KeyError(f"{reg.name} has no fields {sorted(unknown)}")
    kept: tuple[Field, ...] = tuple(f for f in reg.fields if f.name in keep)
    mask = sum(f.mask for f in kept)
    return replace(reg, fields=kept, reset=reg.reset & mask)


def _pin_names(reg: Register, pins: tuple[str, str]) -> Register:
    """The register with its fields named after the part's interrupt pins: the BMI088
    gyroscope's INT3_INT4_IO_CONF has int3_od, int4_lvl ... where the BMG160's INT_EN_1 has
    int1_od, int2_lvl (BMI088 data sheet 5.5.10, 5.5.11)."""
    words = {"int1": pins[0].lower(), "int2": pins[1].lower(),
             "INT1": pins[0], "INT2": pins[1]}

    def renamed(text: str) -> str:
        for old, new in words.items():
            text = text.replace(old, new)
        return text

    fields = tuple(replace(f, name=renamed(f.name), meaning=renamed(f.meaning))
                   for f in reg.fields)
    return replace(reg, fields=fields) if fields != reg.fields else reg


def derive(name: str, title: str, differences: Differences = Differences(), **details: Any) -> Part:
    """The part ``name``: the BMG160 table with ``differences`` applied, and what follows."""
    d = differences
    names = {r.name for r in REGISTERS}
    for table in (d.absent, d.fields, d.renamed, d.reset, d.replaced):
        unknown = set(table) - names
        if unknown:
            raise KeyError(f"part {name}: no BMG160 registers named {sorted(unknown)}")
    regs: list[Register] = []
    absent: set[int] = set()
    peek, action, effect = list(regmap.PEEK_AT), list(regmap.ACTION_AT), list(regmap.EFFECT_AT)
    for base in REGISTERS:
        reg = base
        a = base.address
        if base.name in d.absent:
            # stored as 0 for ever: reset 0, write mask 0, no upsets (register_access.poke_reg), no hook
            reg = Register(a, f"RESERVED_0x{a:02X}", "r", ABSENT_READ, (), "reserved on this part")
            absent.add(a)
            peek[a], action[a], effect[a] = None, None, None
        elif base.name in d.replaced:
            reg = d.replaced[base.name]
            if reg.address != a:
                raise ValueError(f"part {name}: {reg.name} replaces 0x{a:02X}, not 0x{reg.address:02X}")
            peek[a], action[a], effect[a] = None, None, None
        elif base.name in d.fields:
            reg = _narrow(base, d.fields[base.name])
            hook, bits = peek[a], sum(f.mask for f in reg.fields)
            if hook is not None:  # a computed register shows only the bits the part has
                peek[a] = _masked(hook, bits)
        if base.name in d.renamed:
            reg = replace(reg, name=d.renamed[base.name])
        if base.name in d.reset:
            reg = replace(reg, reset=d.reset[base.name])
        regs.append(_pin_names(reg, d.pin_fields) if d.pin_fields else reg)
    return Part(
        name=name, title=title, differences=d, registers=tuple(regs), absent=frozenset(absent),
        reset_values=bytes(r.reset for r in regs), write_masks=bytes(r.write_mask for r in regs),
        peek_at=tuple(peek), action_at=tuple(action), effect_at=tuple(effect), **details)


BMG160_PART = derive("bmg160", "BMG160")


def frozen(mapping: Mapping[str, Any]) -> Mapping[str, Any]:
    """A read-only copy, for the tables of the part modules."""
    return MappingProxyType(dict(mapping))
