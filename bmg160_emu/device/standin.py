"""Register-file stand-ins: companion chips (accelerometers, magnetometers) as registers only.

A driver for a BMX055 or BMI088 board probes the accelerometer and magnetometer next to the
gyroscope before it reads anything: chip ID, soft reset, power bits, configuration writes
read back. A stand-in answers exactly that: a chip ID, reset values, read-only bits,
write masks, a soft-reset command, a power gate (the BMM150 answers nothing but its power
register until its power bit is set), auto-increment, and plain storage for everything
else. It holds registers and produces no motion data: its data registers keep their reset
values whatever is done to it, and no time-dependent behaviour (start-up delays, data
ready, FIFO filling) is modelled.

The bus side is declared too: how many bits of the register byte the chip decodes (7 for
the Bosch parts, whose SPI frame carries a 7-bit address after the R/W bit; 8 for a plain
register file) and how it frames SPI (:class:`SpiInterface`: the BMI088 accelerometer's
dummy byte before read data, its start in I2C mode, a 3-wire bit); the frames themselves are
decoded in :mod:`bmg160_emu.device.standin_spi`.

The declaration is data (:class:`StandinSpec`), read from a small TOML or a register dump
by :mod:`bmg160_emu.io.standin_file`; this module knows no file. The device offers the chip
primitives of :class:`~bmg160_emu.device.contract.RegisterDevice` and its own SPI framing
(:class:`~bmg160_emu.device.contract.SpiFramedDevice`), so I2CBus, FakeSMBus, FakeSpiDev,
``bmg160-emu run``, ``serve`` and trace replay take it like a chip.
"""

from __future__ import annotations

import threading
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from bmg160_emu.device import contract
from bmg160_emu.device.standin_spi import StandinSpiFrame

REGISTER_SPACE = 1 << 8  # an 8-bit register pointer: 256 registers
ALL_BITS = REGISTER_SPACE - 1  # every bit of a byte (a register's default write mask)
ADDRESS_BITS = (7, 8)  # register-address widths a declaration may give
DEFAULT_ADDRESS_BITS = 8  # a plain register file decodes the whole register byte


@dataclass(frozen=True)
class StandinRegister:
    """One declared register: its reset value, the bits a write changes (``writable``; 0
    for a read-only register) and whether it reads back at all (a command register does
    not: ``write_only`` reads 0x00)."""

    reset: int = 0
    writable: int = ALL_BITS
    write_only: bool = False
    name: str = ""


@dataclass(frozen=True)
class SoftReset:
    """A write of ``value`` (the bits in ``mask``) to ``register`` resets every register
    to its reset value except those in ``keeps``; the command bits themselves read 0."""

    register: int
    value: int
    mask: int = ALL_BITS
    keeps: tuple[int, ...] = ()

    def triggered_by(self, value: int) -> bool:
        return value & self.mask == self.value & self.mask


@dataclass(frozen=True)
class PowerGate:
    """While ``register & mask`` is 0 (the chip is suspended), every register but those in
    ``open`` reads ``closed_value`` and ignores writes."""

    register: int
    mask: int
    open: tuple[int, ...] = ()
    closed_value: int = 0

    def is_open(self, regs: bytearray) -> bool:
        return bool(regs[self.register] & self.mask)


@dataclass(frozen=True)
class SpiInterface:
    """How the chip frames SPI. The first byte of a frame is R/W (bit 7, 1 = read) and a
    7-bit register address; a read then shifts out ``dummy_bytes`` bytes before the data
    (1 on the BMI088 accelerometer, data sheet 6.1.2), a write writes the following bytes
    from the address on, or with ``write_pairs`` takes the bytes after the first data byte
    as (address, data) pairs (the BMA2x2's SPI write, as Bosch's support code sends it).
    ``starts_in_i2c`` : the chip is in I2C mode after power-on and after a soft reset and
    ignores a frame until chip select rises once (the BMI088 accelerometer, data sheet
    6.1). ``three_wire_register`` / ``three_wire_mask``: the bit that puts the chip's SPI in
    3-wire mode (None: it has none)."""

    dummy_bytes: int = 0
    starts_in_i2c: bool = False
    three_wire_register: int | None = None
    three_wire_mask: int = 0
    write_pairs: bool = False

    def to_dict(self) -> dict[str, Any]:
        document: dict[str, Any] = {"dummy_bytes": self.dummy_bytes,
                                    "starts_in_i2c": self.starts_in_i2c,
                                    "write_pairs": self.write_pairs}
        if self.three_wire_register is not None:
            document["three_wire_register"] = self.three_wire_register
            document["three_wire_mask"] = self.three_wire_mask
        return document


@dataclass(frozen=True)
class StandinSpec:
    """A stand-in's declaration: what it answers at which addresses.

    ``register_address_bits``: how many low bits of the register byte the chip decodes (an
    I2C register byte or a register primitive's argument); with 7, 0x80..0xFF reach
    0x00..0x7F, as on the gyroscope (docs/unconfirmed-choices.md, spec 2.4)."""

    name: str
    chip_id_register: int
    chip_id: int
    addresses: tuple[int, ...]  # where the chip can answer (its address pins); () : anywhere
    registers: Mapping[int, StandinRegister]
    description: str = ""
    absent_value: int = 0  # what a register not declared reads (writes to it are ignored)
    no_increment: tuple[int, ...] = ()  # FIFO data registers: the pointer stays on them
    soft_reset: SoftReset | None = None
    power_gate: PowerGate | None = None
    source: str = ""  # where the declaration came from (a file, a built-in name)
    register_address_bits: int = DEFAULT_ADDRESS_BITS
    spi: SpiInterface = field(default_factory=SpiInterface)

    @property
    def address_mask(self) -> int:
        """The register-byte bits the chip decodes."""
        return (1 << self.register_address_bits) - 1

    def reset_image(self) -> bytearray:
        regs = bytearray([self.absent_value]) * REGISTER_SPACE
        for reg, spec in self.registers.items():
            regs[reg] = spec.reset
        return regs

    def to_dict(self) -> dict[str, Any]:
        """The declaration as plain data (the TOML layout; what a trace header carries)."""
        document: dict[str, Any] = {
            "name": self.name,
            "description": self.description,
            "chip_id_register": self.chip_id_register,
            "chip_id": self.chip_id,
            "addresses": list(self.addresses),
            "absent_value": self.absent_value,
            "no_increment": list(self.no_increment),
            "register_address_bits": self.register_address_bits,
            "spi": self.spi.to_dict(),
        }
        if self.soft_reset is not None:
            s = self.soft_reset
            document["soft_reset"] = {"register": s.register, "value": s.value,
                                      "mask": s.mask, "keeps": list(s.keeps)}
        if self.power_gate is not None:
            g = self.power_gate
            document["power_gate"] = {"register": g.register, "mask": g.mask,
                                      "open": list(g.open), "closed_value": g.closed_value}
        document["registers"] = {
            f"0x{reg:02X}": {"name": r.name, "reset": r.reset, "writable": r.writable,
                             "write_only": r.write_only}
            for reg, r in sorted(self.registers.items())
        }
        return document


class StandinDevice:
    """A register file that answers like the declared chip (no motion data, no timing).

    ``clock`` is the session's clock (shared with the gyros, so ``time`` agrees with
    theirs); without one the device keeps its own virtual time.
    """

    def __init__(self, spec: StandinSpec, address: int | None = None, clock: Any = None) -> None:
        if address is None:
            if not spec.addresses:
                raise ValueError(f"stand-in {spec.name!r} declares no address: give one")
            address = spec.addresses[0]
        self.spec = spec
        self.name = spec.name
        self.address = address
        self.clock = clock
        self.lock = threading.RLock()
        self._own_time_s = 0.0
        self._mask = spec.address_mask
        self.regs = spec.reset_image()
        self.pointer = 0
        self.spi_mode = not spec.spi.starts_in_i2c  # False: I2C mode, SPI frames ignored
        self.last_shifted_out = 0  # the byte the SPI output register holds

    # ----------------------------------------------------------------- time

    @property
    def time(self) -> float:
        return self.clock.now() if self.clock is not None else self._own_time_s

    def advance(self, seconds: float) -> None:
        ns = contract.duration_ns(seconds)
        if self.clock is not None:
            self.clock.advance_ns(ns)
        else:
            self._own_time_s += ns / 1e9

    # ----------------------------------------------------------------- registers

    def _readable(self, reg: int) -> bool:
        gate = self.spec.power_gate
        return gate is None or reg == gate.register or reg in gate.open or gate.is_open(self.regs)

    def _value(self, reg: int) -> int:
        if not self._readable(reg):
            return self.spec.power_gate.closed_value  # type: ignore[union-attr]
        declared = self.spec.registers.get(reg)
        if declared is not None and declared.write_only:
            return 0
        return self.regs[reg]

    def _store(self, reg: int, value: int) -> None:
        declared = self.spec.registers.get(reg)
        if declared is None or not self._readable(reg):
            return  # not in the map, or the chip is suspended: the write is ignored
        reset = self.spec.soft_reset
        if reset is not None and reg == reset.register and reset.triggered_by(value):
            kept = {r: self.regs[r] for r in reset.keeps}
            self.regs[:] = self.spec.reset_image()
            for r, v in kept.items():
                self.regs[r] = v
            if reg in reset.keeps:  # the rest of the written byte applies; the command bits clear
                value &= ~reset.mask
                self.regs[reg] = (self.regs[reg] & ~declared.writable) | (value & declared.writable)
            self.spi_mode = not self.spec.spi.starts_in_i2c  # "largely a power cycle"
            return
        self.regs[reg] = (self.regs[reg] & ~declared.writable & ALL_BITS) | (value & declared.writable)

    def _next(self, reg: int) -> int:
        return reg if reg in self.spec.no_increment else (reg + 1) & self._mask

    def read(self, reg: int, n: int) -> bytes:
        """``n`` registers from ``reg`` on (the register byte's undecoded bits ignored)."""
        reg, n = contract.check_register(reg) & self._mask, contract.check_count(n)
        with self.lock:
            out = bytearray()
            for _ in range(n):
                out.append(self._value(reg))
                reg = self._next(reg)
            self.pointer = reg
            return bytes(out)

    def write(self, reg: int, data: bytes) -> None:
        reg, data = contract.check_register(reg) & self._mask, contract.check_data(data)
        with self.lock:
            for value in data:
                self._store(reg, value)
                reg = self._next(reg)
            self.pointer = reg

    def i2c_write(self, data: bytes) -> None:
        data = contract.check_data(data)
        if not data:
            return
        with self.lock:
            self.pointer = data[0] & self._mask
            if len(data) > 1:
                self.write(data[0], data[1:])

    def i2c_read(self, n: int) -> bytes:
        with self.lock:
            return self.read(self.pointer, n)

    def peek(self, reg: int) -> int:
        """A register as a read would give it, without moving the pointer."""
        reg = contract.check_register(reg) & self._mask
        with self.lock:
            return self._value(reg)

    def dump(self) -> bytes:
        """All 256 register bytes as reads would give them (no side effects): with a 7-bit
        address, 0x80..0xFF repeat 0x00..0x7F, as an i2cdump of the chip would show."""
        with self.lock:
            return bytes(self._value(reg & self._mask) for reg in range(REGISTER_SPACE))

    def reset(self) -> None:
        """Power-on reset: every register back to its reset value, the interface as at
        power-on."""
        with self.lock:
            self.regs[:] = self.spec.reset_image()
            self.pointer = 0
            self.spi_mode = not self.spec.spi.starts_in_i2c
            self.last_shifted_out = 0

    # ----------------------------------------------------------------- SPI

    def spi_frame(self) -> StandinSpiFrame:
        """Chip select has fallen: the frame, decoded as this chip decodes SPI."""
        return StandinSpiFrame(self)

    def spi_three_wire(self) -> bool:
        """Whether the chip answers on its one data line (its 3-wire bit is set)."""
        spi = self.spec.spi
        if spi.three_wire_register is None:
            return False
        return bool(self.peek(spi.three_wire_register) & spi.three_wire_mask)

    def __repr__(self) -> str:
        return f"StandinDevice({self.name!r}, address=0x{self.address:02x})"


@dataclass
class StandinConfig:
    """One stand-in of a session: its declaration, address and bus (None: the command's)."""

    spec: StandinSpec
    address: int
    bus: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def build(self, seed: int | None = None, clock: Any = None) -> StandinDevice:
        """The device (``seed`` is accepted and unused: a stand-in has no noise)."""
        return StandinDevice(self.spec, self.address, clock)

    def to_dict(self) -> dict[str, Any]:
        """A trace header entry: the whole declaration, so replay needs no file."""
        entry: dict[str, Any] = {"standin": self.spec.to_dict(), "address": self.address}
        if self.bus is not None:
            entry["bus"] = self.bus
        return entry
