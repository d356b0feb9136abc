"""What the firmware does with each of the 64 registers (the table behind docs/firmware.md),
and the C header of the register map it is built with.

Addresses, reset values, write masks and field masks all come from the project's register
table, :mod:`bmg160_emu.device.registers` (read when called, so a corrected table is the
firmware's at the next build); this module adds only what the firmware does with each:

- ``modelled``: behaviour implemented in ``firmware/src/regmap.c`` (data path, shadowing,
  FIFO, triggers, power modes);
- ``stored``: written bits (the write mask) are kept and read back, with no further effect;
- ``unmodelled``: reads the spec's reset value, writes are ignored.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bmg160_emu.device import registers, spec_choices

REGISTERS_HEADER = "bmg160_registers.h"


@dataclass(frozen=True)
class FirmwareRegister:
    address: int
    name: str
    reset: int
    write_mask: int
    kind: str  # "modelled", "stored", "unmodelled"
    note: str = ""


# register name -> (kind, note); registers not named here are reserved: unmodelled
_KINDS: dict[str, tuple[str, str]] = {
    "CHIP_ID": ("modelled", "always 0x0F (spec 4.1)"),
    **{f"RATE_{axis}_LSB": ("modelled", "latches the MSB (6.2)") for axis in "XYZ"},
    **{f"RATE_{axis}_MSB": ("modelled", "shadowed (6.2)") for axis in "XYZ"},
    "TEMP": ("modelled", "constant 23 degC (raw 0): no thermal model"),
    "INT_STATUS_0": ("unmodelled", "any/high-rate engines not on chip"),
    "INT_STATUS_1": ("modelled", "data_int pulse, fifo_int"),
    "INT_STATUS_2": ("unmodelled", "any-motion engine not on chip"),
    "INT_STATUS_3": ("unmodelled", "high-rate engine not on chip"),
    "FIFO_STATUS": ("modelled", "overrun, frame counter"),
    "RANGE": ("modelled", "bits 2:0 scale the output; 7:3 stored"),
    "BW": ("modelled", "bit 7 reads 1; code sets the ODR timer"),
    "LPM1": ("modelled", "suspend / deep suspend stop sampling"),
    "LPM2": ("modelled", "fast power-up, power-save (samples as normal)"),
    "RATE_HBW": ("modelled", "shadow_dis; data_high_bw stored"),
    "BGW_SOFTRESET": ("modelled", "0xB6 resets; reads 0x00"),
    "INT_EN_0": ("modelled", "data_en, fifo_en gate the status bits"),
    "INT_EN_1": ("stored", "no interrupt pins driven"),
    "INT_MAP_0": ("stored", ""),
    "INT_MAP_1": ("stored", ""),
    "INT_MAP_2": ("stored", ""),
    "INT_DATA_SRC": ("stored", ""),
    "ANY_TH": ("stored", ""),
    "ANY_EN": ("stored", ""),
    "FIFO_WM_EN": ("modelled", "bit 7 selects the watermark interrupt"),
    "INT_RST_LATCH": ("modelled", "offset_reset clears offsets; latch modes stored"),
    **{f"HIGH_{kind}_{axis}": ("stored", "") for kind in ("TH", "DUR") for axis in "XYZ"},
    "SOC": ("stored", "slow offset compensation not on chip"),
    "A_FOC": ("stored", "fast offset compensation not on chip: bit 3 ignored"),
    "TRIM_NVM_CTRL": ("modelled", "nvm_load restores the zero image; no programming"),
    "BGW_SPI3_WDT": ("stored", ""),
    **{name: ("modelled", "offsets added to the output (6.9)")
       for name in ("OFC1", "OFC2", "OFC3", "OFC4", "TRIM_GP0")},
    "TRIM_GP1": ("stored", "general-purpose byte"),
    "BIST": ("modelled", "rate_ok while sampling; bist_rdy 5 ms after trig"),
    "FIFO_CONFIG_0": ("modelled", "tag, watermark; a write empties the FIFO"),
    "FIFO_CONFIG_1": ("modelled", "mode, data select; a write empties it"),
    "FIFO_DATA": ("modelled", "pointer stays; empty pattern 0x00 0x80"),
}


def firmware_registers() -> tuple[FirmwareRegister, ...]:
    """The firmware's view of every register of the current register table."""
    rows = []
    for r in registers.REGISTERS:
        kind, note = _KINDS.get(r.name, ("unmodelled", "reads 0x00"))
        rows.append(FirmwareRegister(r.address, "reserved" if r.reserved else r.name, r.reset,
                                     r.write_mask, kind, note))
    return tuple(rows)


FIRMWARE_REGISTERS: tuple[FirmwareRegister, ...] = firmware_registers()


def reset_values() -> list[int]:
    return [r.reset for r in registers.REGISTERS]


def write_masks() -> list[int]:
    return [r.write_mask for r in registers.REGISTERS]


def _c_bytes(values: list[int]) -> str:
    rows = []
    for start in range(0, len(values), 8):
        rows.append("\t" + ", ".join(f"0x{v:02X}" for v in values[start : start + 8]) + ",")
    return "\n".join(rows)


def render_registers_header() -> str:
    """The text of bmg160_registers.h: register count, the register-byte bits the chip
    decodes (``BMG_REGISTER_ADDRESS_MASK``, spec 2.4's choice), an address macro per register
    (``BMG_REG_<NAME>``), mask and shift per field (``BMG_<REG>_<FIELD>_MASK/_SHIFT``), the
    reset values and the write masks, all from the register table and the spec choices."""
    lines = [
        "/* Generated from bmg160_emu/device/registers.py by `bmg160-emu firmware build`:",
        " * do not edit; correct the register table instead. */",
        "#ifndef BMG160_REGISTERS_H",
        "#define BMG160_REGISTERS_H",
        "#include <avr/pgmspace.h>",
        "#include <stdint.h>",
        "",
        f"#define BMG_REG_COUNT {registers.REGISTER_COUNT}",
        "/* register-byte bits decoded: a transaction starts at (byte & mask), spec 2.4 */",
        f"#define BMG_REGISTER_ADDRESS_MASK 0x{spec_choices.REGISTER_ADDRESS_MASK:02X}",
        "",
    ]
    for r in registers.REGISTERS:
        if r.reserved:
            continue
        lines.append(f"#define BMG_REG_{r.name} 0x{r.address:02X}")
        for f in r.fields:
            stem = f"BMG_{r.name}_{f.name.upper()}"
            lines.append(f"#define {stem}_MASK 0x{f.mask:02X}")
            lines.append(f"#define {stem}_SHIFT {f.lsb}")
    lines += [
        "",
        f"static const uint8_t bmg_reset_values[{registers.REGISTER_COUNT}] PROGMEM = {{",
        _c_bytes(reset_values()),
        "};",
        f"static const uint8_t bmg_write_masks[{registers.REGISTER_COUNT}] PROGMEM = {{",
        _c_bytes(write_masks()),
        "};",
        "",
        "#endif",
        "",
    ]
    return "\n".join(lines)


def write_registers_header(path: str | Path) -> Path:
    """Write the header to path (a file, or a directory to hold bmg160_registers.h)."""
    target = Path(path)
    if target.is_dir():
        target = target / REGISTERS_HEADER
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(render_registers_header(), encoding="utf-8")
    return target
