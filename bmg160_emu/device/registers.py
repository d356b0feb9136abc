"""The BMG160 register map as data: 64 registers, their access, reset values and fields.

This table is the single source for the device model, the dump decoder, the script
language and the documentation, so a correction to the specification is one edit here.
Section numbers refer to the project's register specification (bmg160-registers.md).

Access of a field:
    ``rw``  stored as written;       ``r``  read-only (written by the chip);
    ``w1``  write 1 to trigger, reads 0 (self-clearing);  ``w``  write-only command.
Bits not covered by a field are reserved: they read 0 and ignore writes.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

REGISTER_COUNT = 64  # 0x00..0x3F, spec 3
FIRST_OUTSIDE_MAP = 0x40  # spec 2.4: reads return 0x00, writes are ignored


@dataclass(frozen=True)
class Field:
    """A bit field ``msb..lsb`` of one register, with its meaning and value names."""

    name: str
    msb: int
    lsb: int
    access: str
    meaning: str
    values: Mapping[int, str] = field(default_factory=dict)

    @functools.cached_property
    def mask(self) -> int:
        """The field's bits in the register (computed once: engines extract fields per
        sample)."""
        return ((1 << (self.msb - self.lsb + 1)) - 1) << self.lsb

    def extract(self, value: int) -> int:
        return (value & self.mask) >> self.lsb

    def insert(self, value: int, field_value: int) -> int:
        return (value & ~self.mask & 0xFF) | ((field_value << self.lsb) & self.mask)

    @property
    def bits(self) -> str:
        return str(self.msb) if self.msb == self.lsb else f"{self.msb}:{self.lsb}"


@dataclass(frozen=True)
class Register:
    """One register: address, spec name, access summary, reset value and fields."""

    address: int
    name: str
    access: str
    reset: int
    fields: tuple[Field, ...] = ()
    meaning: str = ""
    nvm: bool = False  # loaded from NVM at power-up and soft reset (spec 6.10)

    def _mask(self, *kinds: str) -> int:
        mask = 0
        for f in self.fields:
            if f.access in kinds:
                mask |= f.mask
        return mask

    @property
    def write_mask(self) -> int:
        """Bits a bus write stores."""
        return self._mask("rw")

    @property
    def trigger_mask(self) -> int:
        """Write-1-to-trigger bits: they act on a write and always read 0."""
        return self._mask("w1")

    @property
    def reserved(self) -> bool:
        return not self.fields

    def field(self, name: str) -> Field:
        for f in self.fields:
            if f.name == name:
                return f
        raise KeyError(f"{self.name} has no field {name!r}")

    def decode(self, value: int) -> dict[str, int]:
        """Field values of a register byte, most significant field first."""
        return {f.name: f.extract(value) for f in self.fields}

    def describe(self, value: int) -> str:
        """One line, e.g. ``RANGE = 0x03: fixed=0 range=3 (±250 °/s)``."""
        parts = []
        for f in self.fields:
            v = f.extract(value)
            label = f.values.get(v)
            parts.append(f"{f.name}={v}" + (f" ({label})" if label else ""))
        body = " ".join(parts) if parts else "reserved"
        return f"{self.name} = 0x{value:02X}: {body}"


def _f(name: str, bits: str, access: str, meaning: str, values: Mapping[int, str] | None = None):
    hi, _, lo = bits.partition(":")
    return Field(name, int(hi), int(lo or hi), access, meaning, MappingProxyType(dict(values or {})))


def _reserved(address: int) -> Register:
    return Register(address, f"RESERVED_0x{address:02X}", "r", 0x00, (), "reserved: reads 0x00")


_RANGES = {0: "±2000 °/s", 1: "±1000 °/s", 2: "±500 °/s", 3: "±250 °/s", 4: "±125 °/s",
           5: "reserved (as ±2000)", 6: "reserved (as ±2000)", 7: "reserved (as ±2000)"}
_BW = {0: "ODR 2000 Hz, 523 Hz", 1: "ODR 2000 Hz, 230 Hz", 2: "ODR 1000 Hz, 116 Hz",
       3: "ODR 400 Hz, 47 Hz", 4: "ODR 200 Hz, 23 Hz", 5: "ODR 100 Hz, 12 Hz",
       6: "ODR 200 Hz, 64 Hz", 7: "ODR 100 Hz, 32 Hz"}
_BW.update({code: f"reserved (as code {code & 7})" for code in range(8, 16)})
_SLEEP_DUR = {0: "2 ms", 1: "4 ms", 2: "5 ms", 3: "8 ms", 4: "10 ms", 5: "15 ms", 6: "18 ms",
              7: "20 ms"}
_AUTOSLEEP = {0: "not allowed", 1: "4 ms", 2: "5 ms", 3: "8 ms", 4: "10 ms", 5: "15 ms",
              6: "20 ms", 7: "40 ms"}
_LATCH = {0x0: "non-latched", 0x8: "non-latched", 0x7: "latched", 0xF: "latched",
          0x1: "250 ms", 0x2: "500 ms", 0x3: "1 s", 0x4: "2 s", 0x5: "4 s", 0x6: "8 s",
          0x9: "250 µs", 0xA: "500 µs", 0xB: "1 ms", 0xC: "12.5 ms", 0xD: "25 ms",
          0xE: "50 ms"}
_WORDLENGTH = {0: "32 samples", 1: "64 samples", 2: "128 samples", 3: "256 samples"}
_ONOFF = {0: "off", 1: "on"}


def _high_th(axis: str, address: int) -> Register:
    return Register(address, f"HIGH_TH_{axis.upper()}", "rw", 0x02, (
        _f(f"high_hy_{axis}", "7:6", "rw", "hysteresis (255 + 256·hy)·4 LSB"),
        _f(f"high_th_{axis}", "5:1", "rw", "threshold (255 + 256·th)·4 LSB"),
        _f(f"high_en_{axis}", "0", "rw", "enable high-rate detection", _ONOFF),
    ), "high-rate threshold (4.20); reset U (BNO)")


def _high_dur(axis: str, address: int) -> Register:
    return Register(address, f"HIGH_DUR_{axis.upper()}", "rw", 0x19, (
        _f(f"high_dur_{axis}", "7:0", "rw", "hold time (1 + dur)·2.5 ms"),
    ), "high-rate duration (4.20); reset U (BNO)")


def _rate(axis: str, part: str, address: int) -> Register:
    bits = "7:0"
    label = f"rate_{axis}[7:0]" if part == "LSB" else f"rate_{axis}[15:8]"
    return Register(address, f"RATE_{axis.upper()}_{part}", "r", 0x00, (
        _f(f"rate_{axis}_{part.lower()}", bits, "r", label),
    ), f"{axis.upper()} angular rate {part} (4.2); MSB shadowed (6.2)")


def _build() -> tuple[Register, ...]:
    regs: dict[int, Register] = {}

    def add(reg: Register) -> None:
        regs[reg.address] = reg

    add(Register(0x00, "CHIP_ID", "r", 0x0F, (_f("chip_id", "7:0", "r", "always 0x0F"),),
                 "chip identifier (4.1)"))
    for i, axis in enumerate("xyz"):
        add(_rate(axis, "LSB", 0x02 + 2 * i))
        add(_rate(axis, "MSB", 0x03 + 2 * i))
    add(Register(0x08, "TEMP", "r", 0x00, (
        _f("temp", "7:0", "r", "signed, 0.5 K/LSB, 0 = 23 °C"),), "temperature (4.3, 5.2)"))
    add(Register(0x09, "INT_STATUS_0", "r", 0x00, (
        _f("any_int", "2", "r", "any-motion interrupt active"),
        _f("high_int", "1", "r", "high-rate interrupt active"),
    ), "interrupt status (4.4)"))
    add(Register(0x0A, "INT_STATUS_1", "r", 0x00, (
        _f("data_int", "7", "r", "new-data interrupt active"),
        _f("auto_offset_int", "6", "r", "auto-offset interrupt active"),
        _f("fast_offset_int", "5", "r", "fast-offset interrupt active"),
        _f("fifo_int", "4", "r", "FIFO interrupt active"),
    ), "interrupt status (4.5)"))
    for address, kind in ((0x0B, "any"), (0x0C, "high")):
        add(Register(address, f"INT_STATUS_{address - 0x09}", "r", 0x00, (
            _f(f"{kind}_sign", "3", "r", "sign of the triggering motion (1 = negative, U)"),
            _f(f"{kind}_first_z", "2", "r", "Z axis triggered"),
            _f(f"{kind}_first_y", "1", "r", "Y axis triggered"),
            _f(f"{kind}_first_x", "0", "r", "X axis triggered"),
        ), f"{kind} interrupt axis and sign (4.6)"))
    add(Register(0x0E, "FIFO_STATUS", "r", 0x00, (
        _f("fifo_overrun", "7", "r", "frames lost since the last FIFO configuration write"),
        _f("fifo_frame_counter", "6:0", "r", "complete frames stored, 0..100"),
    ), "FIFO status (4.7)"))
    add(Register(0x0F, "RANGE", "rw", 0x00, (
        _f("fixed", "7:3", "rw", "stored as written; drivers write 0b10 to bits 7:6"),
        _f("range", "2:0", "rw", "full-scale range", _RANGES),
    ), "full-scale range (4.8)"))
    add(Register(0x10, "BW", "rw", 0x80, (
        _f("bw_fixed", "7", "r", "always reads 1"),
        _f("bw", "3:0", "rw", "output data rate and filter", _BW),
    ), "bandwidth and output data rate (4.9, 5.3)"))
    add(Register(0x11, "LPM1", "rw", 0x00, (
        _f("suspend", "7", "rw", "suspend (fast power-up with fast_power_up)", _ONOFF),
        _f("deep_suspend", "5", "rw", "deep suspend", _ONOFF),
        _f("sleep_dur", "3:1", "rw", "sleep phase in advanced power saving", _SLEEP_DUR),
    ), "power mode 1 (4.10, 6.7)"))
    add(Register(0x12, "LPM2", "rw", 0x00, (
        _f("fast_power_up", "7", "rw", "fast power-up (with suspend)", _ONOFF),
        _f("power_save_mode", "6", "rw", "advanced power-saving mode", _ONOFF),
        _f("ext_trig_sel", "5:4", "rw", "wake-up trigger",
           {0: "none", 1: "INT1 pin", 2: "INT2 pin", 3: "SDO pin"}),
        _f("autosleep_dur", "2:0", "rw", "awake phase in power saving", _AUTOSLEEP),
    ), "power mode 2 (4.11, 6.7)"))
    add(Register(0x13, "RATE_HBW", "rw", 0x00, (
        _f("data_high_bw", "7", "rw", "1 = unfiltered rate data", _ONOFF),
        _f("shadow_dis", "6", "rw", "1 = MSB shadowing disabled", _ONOFF),
    ), "data selection and shadowing (4.12, 6.2)"))
    add(Register(0x14, "BGW_SOFTRESET", "w", 0x00, (
        _f("softreset", "7:0", "w", "write 0xB6 to reset; reads 0x00"),
    ), "soft reset (4.13, 6.6)"))
    add(Register(0x15, "INT_EN_0", "rw", 0x00, (
        _f("data_en", "7", "rw", "new-data interrupt", _ONOFF),
        _f("fifo_en", "6", "rw", "FIFO interrupt", _ONOFF),
        _f("auto_offset_en", "2", "rw", "auto-offset compensation and interrupt", _ONOFF),
    ), "interrupt enable 0 (4.14)"))
    add(Register(0x16, "INT_EN_1", "rw", 0x0F, (
        _f("int2_od", "3", "rw", "INT2 output", {0: "push-pull", 1: "open drain"}),
        _f("int2_lvl", "2", "rw", "INT2 active level", {0: "low", 1: "high"}),
        _f("int1_od", "1", "rw", "INT1 output", {0: "push-pull", 1: "open drain"}),
        _f("int1_lvl", "0", "rw", "INT1 active level", {0: "low", 1: "high"}),
    ), "interrupt pin configuration (4.15); reset U"))
    add(Register(0x17, "INT_MAP_0", "rw", 0x00, (
        _f("int1_high", "3", "rw", "high-rate to INT1", _ONOFF),
        _f("int1_any", "1", "rw", "any-motion to INT1", _ONOFF),
    ), "interrupt map 0 (4.16)"))
    add(Register(0x18, "INT_MAP_1", "rw", 0x00, (
        _f("int2_data", "7", "rw", "new data to INT2", _ONOFF),
        _f("int2_fast_offset", "6", "rw", "fast offset to INT2", _ONOFF),
        _f("int2_fifo", "5", "rw", "FIFO to INT2", _ONOFF),
        _f("int2_auto_offset", "4", "rw", "auto offset to INT2", _ONOFF),
        _f("int1_auto_offset", "3", "rw", "auto offset to INT1", _ONOFF),
        _f("int1_fifo", "2", "rw", "FIFO to INT1", _ONOFF),
        _f("int1_fast_offset", "1", "rw", "fast offset to INT1", _ONOFF),
        _f("int1_data", "0", "rw", "new data to INT1", _ONOFF),
    ), "interrupt map 1 (4.16)"))
    add(Register(0x19, "INT_MAP_2", "rw", 0x00, (
        _f("int2_high", "3", "rw", "high-rate to INT2", _ONOFF),
        _f("int2_any", "1", "rw", "any-motion to INT2", _ONOFF),
    ), "interrupt map 2 (4.16)"))
    add(Register(0x1A, "INT_DATA_SRC", "rw", 0x00, (
        _f("slow_offset_unfilt", "5", "rw", "slow offset uses unfiltered data", _ONOFF),
        _f("high_unfilt_data", "3", "rw", "high-rate uses unfiltered data", _ONOFF),
        _f("any_unfilt_data", "1", "rw", "any-motion uses unfiltered data", _ONOFF),
    ), "interrupt data source (4.17)"))
    add(Register(0x1B, "ANY_TH", "rw", 0x04, (
        _f("fast_offset_unfilt", "7", "rw", "fast offset uses unfiltered data", _ONOFF),
        _f("any_th", "6:0", "rw", "any-motion threshold (1 + any_th)·16 LSB"),
    ), "any-motion threshold (4.17); reset U (BNO)"))
    add(Register(0x1C, "ANY_EN", "rw", 0xA0, (
        _f("awake_dur", "7:6", "rw", "samples awake after motion",
           {0: "8", 1: "16", 2: "32", 3: "64"}),
        _f("any_dursample", "5:4", "rw", "samples for the any-motion test",
           {0: "4", 1: "8", 2: "12", 3: "16"}),
        _f("any_en_z", "2", "rw", "any-motion on Z", _ONOFF),
        _f("any_en_y", "1", "rw", "any-motion on Y", _ONOFF),
        _f("any_en_x", "0", "rw", "any-motion on X", _ONOFF),
    ), "any-motion enable (4.17); reset U"))
    add(Register(0x1E, "FIFO_WM_EN", "rw", 0x00, (
        _f("fifo_wm_en", "7", "rw", "FIFO interrupt on watermark", _ONOFF),
        _f("fifo_wm_reserved", "6:0", "rw", "stored as written (bit 3: see 4.18)"),
    ), "FIFO watermark interrupt (4.18); reset U"))
    add(Register(0x21, "INT_RST_LATCH", "rw", 0x00, (
        _f("reset_int", "7", "w1", "clear latched interrupts"),
        _f("offset_reset", "6", "w1", "clear offset registers"),
        _f("latch_status_bits", "4", "rw", "status bits latch until reset_int (U)", _ONOFF),
        _f("latch_int", "3:0", "rw", "latch mode", _LATCH),
    ), "interrupt reset and latch (4.19)"))
    for i, axis in enumerate("xyz"):
        add(_high_th(axis, 0x22 + 2 * i))
        add(_high_dur(axis, 0x23 + 2 * i))
    add(Register(0x31, "SOC", "rw", 0x60, (
        _f("slow_offset_th", "7:6", "rw", "threshold",
           {0: "0.1 °/s", 1: "0.2 °/s", 2: "0.5 °/s", 3: "1 °/s"}),
        _f("slow_offset_dur", "5:3", "rw", "duration",
           {0: "40 ms", 1: "80 ms", 2: "160 ms", 3: "320 ms", 4: "640 ms", 5: "1280 ms"}),
        _f("slow_offset_en_z", "2", "rw", "slow offset on Z", _ONOFF),
        _f("slow_offset_en_y", "1", "rw", "slow offset on Y", _ONOFF),
        _f("slow_offset_en_x", "0", "rw", "slow offset on X", _ONOFF),
    ), "slow offset compensation (4.21); reset U"))
    add(Register(0x32, "A_FOC", "rw", 0xC0, (
        _f("auto_offset_wordlength", "7:6", "rw", "auto offset samples", _WORDLENGTH),
        _f("fast_offset_wordlength", "5:4", "rw", "fast offset samples", _WORDLENGTH),
        _f("fast_offset_en", "3", "w1", "start fast offset compensation; 1 while running"),
        _f("fast_offset_en_z", "2", "rw", "FOC on Z", _ONOFF),
        _f("fast_offset_en_y", "1", "rw", "FOC on Y", _ONOFF),
        _f("fast_offset_en_x", "0", "rw", "FOC on X", _ONOFF),
    ), "auto and fast offset compensation (4.21, 6.9); reset U"))
    add(Register(0x33, "TRIM_NVM_CTRL", "mixed", 0xF4, (
        _f("nvm_remain", "7:4", "r", "NVM programming cycles left"),
        _f("nvm_load", "3", "w1", "reload NVM-backed registers"),
        _f("nvm_rdy", "2", "r", "1 = NVM ready", {0: "busy", 1: "ready"}),
        _f("nvm_prog_trig", "1", "w1", "program NVM"),
        _f("nvm_prog_mode", "0", "rw", "NVM programming unlocked", _ONOFF),
    ), "NVM control (4.22, 6.10); reset U"))
    add(Register(0x34, "BGW_SPI3_WDT", "rw", 0x00, (
        _f("i2c_wdt_en", "2", "rw", "I2C watchdog", _ONOFF),
        _f("i2c_wdt_sel", "1", "rw", "watchdog period", {0: "1 ms", 1: "50 ms"}),
        _f("spi3", "0", "rw", "SPI wires", {0: "4-wire", 1: "3-wire"}),
    ), "SPI 3-wire and I2C watchdog (4.23)"))
    add(Register(0x36, "OFC1", "rw", 0x00, (
        _f("offset_x_3_2", "7:6", "rw", "offset_x[3:2]"),
        _f("offset_y_3_1", "5:3", "rw", "offset_y[3:1]"),
        _f("offset_z_3_1", "2:0", "rw", "offset_z[3:1]"),
    ), "offset compensation 1 (4.24)", nvm=True))
    for i, axis in enumerate("xyz"):
        add(Register(0x37 + i, f"OFC{2 + i}", "rw", 0x00, (
            _f(f"offset_{axis}_11_4", "7:0", "rw", f"offset_{axis}[11:4]"),
        ), f"offset compensation {2 + i} (4.24)", nvm=True))
    add(Register(0x3A, "TRIM_GP0", "rw", 0x00, (
        _f("gp0", "7:4", "rw", "general-purpose bits, NVM-backed"),
        _f("offset_x_1_0", "3:2", "rw", "offset_x[1:0]"),
        _f("offset_y_0", "1", "rw", "offset_y[0]"),
        _f("offset_z_0", "0", "rw", "offset_z[0]"),
    ), "general purpose 0 and offset low bits (4.24)", nvm=True))
    add(Register(0x3B, "TRIM_GP1", "rw", 0x00, (
        _f("gp1", "7:0", "rw", "general-purpose byte, NVM-backed"),
    ), "general purpose 1 (4.24)", nvm=True))
    add(Register(0x3C, "BIST", "mixed", 0x10, (
        _f("rate_ok", "4", "r", "sensor output valid", _ONOFF),
        _f("bist_fail", "2", "r", "last self-test failed", _ONOFF),
        _f("bist_rdy", "1", "r", "last self-test finished", _ONOFF),
        _f("trig_bist", "0", "w1", "start the self-test"),
    ), "built-in self-test (4.25, 6.8)"))
    add(Register(0x3D, "FIFO_CONFIG_0", "rw", 0x00, (
        _f("tag", "7", "rw", "2 tag bytes per frame", _ONOFF),
        _f("fifo_water_mark_level_trigger_retain", "6:0", "rw", "watermark in frames"),
    ), "FIFO configuration 0 (4.26); a write empties the FIFO"))
    add(Register(0x3E, "FIFO_CONFIG_1", "rw", 0x00, (
        _f("fifo_mode", "7:6", "rw", "FIFO mode",
           {0: "bypass", 1: "FIFO", 2: "stream", 3: "reserved (as bypass)"}),
        _f("fifo_reserved", "5:2", "rw", "stored as written"),
        _f("fifo_data_select", "1:0", "rw", "axes per frame",
           {0: "X,Y,Z", 1: "X", 2: "Y", 3: "Z"}),
    ), "FIFO configuration 1 (4.26); a write empties the FIFO, clears overrun"))
    add(Register(0x3F, "FIFO_DATA", "r", 0x00, (
        _f("fifo_data", "7:0", "r", "next FIFO byte; the pointer stays at 0x3F"),
    ), "FIFO data (4.27, 6.5)"))
    for address in range(REGISTER_COUNT):
        if address not in regs:
            add(_reserved(address))
    return tuple(regs[a] for a in range(REGISTER_COUNT))


REGISTERS: tuple[Register, ...]
BY_NAME: Mapping[str, Register]
RESET_VALUES: bytes
WRITE_MASKS: bytes
NVM_ADDRESSES: tuple[int, ...]


def _install(table: tuple[Register, ...]) -> None:
    """Make ``table`` the register map and derive the names above from it. Called once at
    import; a test of a spec correction calls it with a corrected copy before the model is
    imported (the model evaluates addresses and masks at import)."""
    global REGISTERS, BY_NAME, RESET_VALUES, WRITE_MASKS, NVM_ADDRESSES
    if [r.address for r in table] != list(range(REGISTER_COUNT)):
        raise ValueError(f"a register table lists addresses 0x00..0x{REGISTER_COUNT - 1:02X} in order")
    REGISTERS = table
    BY_NAME = MappingProxyType({r.name: r for r in table})
    RESET_VALUES = bytes(r.reset for r in table)
    WRITE_MASKS = bytes(r.write_mask for r in table)
    NVM_ADDRESSES = tuple(r.address for r in table if r.nvm)


_install(_build())


# ---------------------------------------------------------------- registers of other parts

ABSENT_READ = 0x00  # a register a part lacks reads as a BMG160 reserved one (2.4, docs/parts.md)

# BMI088 data sheet 5.5.13: FIFO synchronisation with an input pin, at the address of the
# BMG160's BGW_SPI3_WDT (device/part_bmi088_gyro.py uses it).
BMI088_FIFO_EXT_INT_S = Register(0x34, "FIFO_EXT_INT_S", "rw", 0x00, (
    _f("ext_fifo_s_en", "5", "rw", "tag FIFO frames (z LSB) from an input pin", _ONOFF),
    _f("ext_fifo_s_sel", "4", "rw", "tag input pin", {0: "INT3", 1: "INT4"}),
), "FIFO external synchronisation (BMI088 DS 5.5.13)")


def address_of(name: str) -> int:
    """Register address for a spec name such as ``"RATE_X_LSB"`` (case-insensitive)."""
    try:
        return BY_NAME[name.upper()].address
    except KeyError:
        raise KeyError(f"no BMG160 register named {name!r}") from None


def register(address_or_name: int | str) -> Register:
    """The register at an address 0x00..0x3F, or with a spec name."""
    if isinstance(address_or_name, str):
        return BY_NAME[REGISTERS[address_of(address_or_name)].name]
    if not 0 <= address_or_name < REGISTER_COUNT:
        raise KeyError(f"0x{address_or_name:02X} is outside the register map 0x00..0x3F")
    return REGISTERS[address_or_name]


def field_of(register_name: str, field_name: str) -> Field:
    """A field by spec names, e.g. ``field_of("RANGE", "range").mask``: code outside this
    module takes register addresses and field masks from here, never as typed numbers."""
    return register(register_name).field(field_name)


@functools.cache  # the table is fixed: scanned once (71 scans were ~10 % of a cold start)
def offset_parts() -> tuple[tuple[tuple[int, Field, int], ...], ...]:
    """The pieces of the three axis offsets (4.24) as ``(address, field, position)`` per axis
    X, Y, Z: the field holds offset bits ``position + width - 1 .. position``. Read from the
    field names ``offset_<axis>_<msb>_<lsb>`` (or ``offset_<axis>_<bit>``), so moving an
    offset bit in the table moves it in the model."""
    parts: dict[str, list[tuple[int, Field, int]]] = {axis: [] for axis in "xyz"}
    for reg in REGISTERS:
        for f in reg.fields:
            match = re.fullmatch(r"offset_([xyz])_(\d+)(?:_(\d+))?", f.name)
            if match:
                hi = int(match[2])
                lo = int(match[3]) if match[3] else hi
                if hi - lo != f.msb - f.lsb:
                    raise ValueError(f"{reg.name}.{f.name} is {f.msb - f.lsb + 1} bits wide, "
                                     f"its name says {hi - lo + 1}")
                parts[match[1]].append((reg.address, f, lo))
    return tuple(tuple(parts[axis]) for axis in "xyz")


def offset_bits() -> int:
    """Width of one axis offset (12 in spec 4.24), from the fields that hold it."""
    return max(pos + f.msb - f.lsb + 1 for axis in offset_parts() for _, f, pos in axis)


def offset_mask(address: int) -> int:
    """Bits of a register that hold offset bits (0 for a register without any)."""
    return sum(f.mask for axis in offset_parts() for a, f, _ in axis if a == address)


def decode_dump(dump: bytes) -> list[str]:
    """One line per register of a 64-byte dump, as ``0xAA NAME = 0xVV: fields``."""
    if len(dump) != REGISTER_COUNT:
        raise ValueError(f"a register dump has {REGISTER_COUNT} bytes, not {len(dump)}")
    return [f"0x{r.address:02X} {r.describe(v)}" for r, v in zip(REGISTERS, dump)]


def markdown_table(table: tuple[Register, ...] | None = None) -> str:
    """The register map (or another part's ``table``) as a Markdown table (embedded in
    docs/device-model.md and docs/parts.md)."""
    lines = ["| addr | name | access | reset | fields (bits, access) |",
             "| --- | --- | --- | --- | --- |"]
    for r in REGISTERS if table is None else table:
        fields = ", ".join(f"`{f.name}` [{f.bits}] {f.access}" for f in r.fields) or "reserved"
        reset = f"0x{r.reset:02X}" + (" (NVM)" if r.nvm else "")
        lines.append(f"| 0x{r.address:02X} | {r.name} | {r.access} | {reset} | {fields} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown_table(), end="")
