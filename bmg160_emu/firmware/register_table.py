"""What the firmware does with each of the 64 registers: the table behind docs/firmware.md.

Each register is one of:

- ``modelled``: behaviour implemented in ``firmware/src/regmap.c`` (data path, shadowing,
  FIFO, triggers, power modes);
- ``stored``: written bits (the write mask) are kept and read back, with no further effect;
- ``unmodelled``: reads the spec's reset value, writes are ignored.

Reset values are those of the register spec (docs: bmg160-registers.md, section 3 and 5.4);
masks follow the field tables of section 4 (reserved bits read 0).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class FirmwareRegister:
    address: int
    name: str
    reset: int
    write_mask: int
    kind: str  # "modelled", "stored", "unmodelled"
    note: str = ""


def _table() -> list[FirmwareRegister]:
    rows: dict[int, FirmwareRegister] = {}

    def add(addr: int, name: str, reset: int, mask: int, kind: str, note: str = "") -> None:
        rows[addr] = FirmwareRegister(addr, name, reset, mask, kind, note)

    add(0x00, "CHIP_ID", 0x0F, 0x00, "modelled", "always 0x0F (spec 4.1)")
    for i, axis in enumerate("XYZ"):
        add(0x02 + 2 * i, f"RATE_{axis}_LSB", 0x00, 0x00, "modelled", "latches the MSB (6.2)")
        add(0x03 + 2 * i, f"RATE_{axis}_MSB", 0x00, 0x00, "modelled", "shadowed (6.2)")
    add(0x08, "TEMP", 0x00, 0x00, "modelled", "constant 23 degC (raw 0): no thermal model")
    add(0x09, "INT_STATUS_0", 0x00, 0x00, "unmodelled", "any/high-rate engines not on chip")
    add(0x0A, "INT_STATUS_1", 0x00, 0x00, "modelled", "data_int pulse, fifo_int")
    add(0x0B, "INT_STATUS_2", 0x00, 0x00, "unmodelled", "any-motion engine not on chip")
    add(0x0C, "INT_STATUS_3", 0x00, 0x00, "unmodelled", "high-rate engine not on chip")
    add(0x0E, "FIFO_STATUS", 0x00, 0x00, "modelled", "overrun, frame counter")
    add(0x0F, "RANGE", 0x00, 0xFF, "modelled", "bits 2:0 scale the output; 7:3 stored")
    add(0x10, "BW", 0x80, 0x0F, "modelled", "bit 7 reads 1; code sets the ODR timer")
    add(0x11, "LPM1", 0x00, 0xAE, "modelled", "suspend / deep suspend stop sampling")
    add(0x12, "LPM2", 0x00, 0xF7, "modelled", "fast power-up, power-save (samples as normal)")
    add(0x13, "RATE_HBW", 0x00, 0xC0, "modelled", "shadow_dis; data_high_bw stored")
    add(0x14, "BGW_SOFTRESET", 0x00, 0x00, "modelled", "0xB6 resets; reads 0x00")
    add(0x15, "INT_EN_0", 0x00, 0xC4, "modelled", "data_en, fifo_en gate the status bits")
    add(0x16, "INT_EN_1", 0x0F, 0x0F, "stored", "no interrupt pins driven")
    add(0x17, "INT_MAP_0", 0x00, 0x0A, "stored")
    add(0x18, "INT_MAP_1", 0x00, 0xFF, "stored")
    add(0x19, "INT_MAP_2", 0x00, 0x0A, "stored")
    add(0x1A, "INT_DATA_SRC", 0x00, 0x2A, "stored")
    add(0x1B, "ANY_TH", 0x04, 0xFF, "stored")
    add(0x1C, "ANY_EN", 0xA0, 0xF7, "stored")
    add(0x1E, "FIFO_WM_EN", 0x00, 0xFF, "modelled", "bit 7 selects the watermark interrupt")
    add(
        0x21,
        "INT_RST_LATCH",
        0x00,
        0x1F,
        "modelled",
        "offset_reset clears offsets; latch modes stored",
    )
    for i, axis in enumerate("XYZ"):
        add(0x22 + 2 * i, f"HIGH_TH_{axis}", 0x02, 0xFF, "stored")
        add(0x23 + 2 * i, f"HIGH_DUR_{axis}", 0x19, 0xFF, "stored")
    add(0x31, "SOC", 0x60, 0xFF, "stored", "slow offset compensation not on chip")
    add(0x32, "A_FOC", 0xC0, 0xF7, "stored", "fast offset compensation not on chip: bit 3 ignored")
    add(
        0x33,
        "TRIM_NVM_CTRL",
        0xF4,
        0x01,
        "modelled",
        "nvm_load restores the zero image; no programming",
    )
    add(0x34, "BGW_SPI3_WDT", 0x00, 0x07, "stored")
    for addr, name in zip(range(0x36, 0x3B), ("OFC1", "OFC2", "OFC3", "OFC4", "TRIM_GP0")):
        add(addr, name, 0x00, 0xFF, "modelled", "offsets added to the output (6.9)")
    add(0x3B, "TRIM_GP1", 0x00, 0xFF, "stored", "general-purpose byte")
    add(0x3C, "BIST", 0x10, 0x00, "modelled", "rate_ok while sampling; bist_rdy 5 ms after trig")
    add(0x3D, "FIFO_CONFIG_0", 0x00, 0xFF, "modelled", "tag, watermark; a write empties the FIFO")
    add(0x3E, "FIFO_CONFIG_1", 0x00, 0xFF, "modelled", "mode, data select; a write empties it")
    add(0x3F, "FIFO_DATA", 0x00, 0x00, "modelled", "pointer stays; empty pattern 0x00 0x80")
    for addr in range(0x40):
        if addr not in rows:
            add(addr, "reserved", 0x00, 0x00, "unmodelled", "reads 0x00")
    return [rows[a] for a in range(0x40)]


FIRMWARE_REGISTERS: tuple[FirmwareRegister, ...] = tuple(_table())


def reset_values() -> list[int]:
    return [r.reset for r in FIRMWARE_REGISTERS]


def write_masks() -> list[int]:
    return [r.write_mask for r in FIRMWARE_REGISTERS]
