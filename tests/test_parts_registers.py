"""Every register of every part: reset values, which registers exist, what a write keeps.

Expected values are typed from the data sheets (BMI088: BST-BMI088-DS001 section 5.4, the
gyroscope register map, and 5.5; BMI055/BMX055: the BMG160 map, tests/test_chip_reset_values
.py), not taken from the tables under test.
"""

from __future__ import annotations

import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.parts import PART_NAMES, make_chip, part_table
from bmg160_emu.device.registers import REGISTERS

# BMI088 DS 5.4: reset values of the configuration registers.
BMI088_RESET = {0x00: 0x0F, 0x0F: 0x00, 0x10: 0x80, 0x11: 0x00, 0x14: 0x00, 0x15: 0x00,
                0x16: 0x0F, 0x18: 0x00, 0x1E: 0x00, 0x34: 0x00, 0x3D: 0x00, 0x3E: 0x00}
# DS 5.4: the addresses it marks reserved (0x01, 0x08-0x09, 0x0B-0x0D, 0x12-0x13, 0x17,
# 0x19-0x1D, 0x1F-0x33, 0x35-0x3B).
BMI088_RESERVED = [0x01, 0x08, 0x09, 0x0B, 0x0C, 0x0D, 0x12, 0x13, 0x17, *range(0x19, 0x1E),
                   *range(0x1F, 0x34), *range(0x35, 0x3C)]
# DS 5.5: the bits a write of 0xFF keeps, per configuration register (bit 7 of
# GYRO_BANDWIDTH reads 1 always, 5.5.6).
BMI088_WRITE_KEEPS = {
    0x0F: 0xFF,  # 5.5.5 GYRO_RANGE [7:0] RW
    0x10: 0x8F,  # 5.5.6 gyro_bw (codes 0..7, the BMG160's 4-bit field), bit 7 read-only 1
    0x15: 0xC0,  # 5.5.9 data_en, fifo_en
    0x16: 0x0F,  # 5.5.10 int4_od, int4_lvl, int3_od, int3_lvl
    0x18: 0xA5,  # 5.5.11 int4_data, int4_fifo, int3_fifo, int3_data
    0x1E: 0xFF,  # 5.5.12 fifo_watermark_enable (PX4 writes 0x88 and reads it back)
    0x34: 0x30,  # 5.5.13 ext_fifo_s_en, ext_fifo_s_sel
    0x3D: 0x7F,  # 5.5.15 watermark 6:0, bit 7 reserved
    0x3E: 0xC0,  # 5.5.16 / 5.4 fifo_mode 7:6
}
SAME_DIE = ("bmi055_gyro", "bmx055_gyro")


def _quiet(part: str) -> BMG160:
    return make_chip(part, noise=False, seed=1)


def test_part_names_and_unknown_part():
    assert PART_NAMES == ("bmg160", "bmi055_gyro", "bmx055_gyro", "bmi088_gyro")
    with pytest.raises(ValueError, match="unknown part 'bmi160': choose from bmg160, "):
        make_chip("bmi160")


def test_bmg160_part_is_the_bmg160():
    chip = make_chip("bmg160", noise=False)
    assert type(chip) is BMG160 and chip.part is part_table("bmg160")
    assert chip.dump() == BMG160(noise=False).dump()


@pytest.mark.parametrize("name", PART_NAMES)
def test_every_part_is_a_bmg160_with_chip_id_0x0f(name):
    chip = _quiet(name)
    assert isinstance(chip, BMG160) and chip.part.name == name
    assert chip.read(0x00) == b"\x0f"  # 0x0F on all four data sheets (BMI088 DS 5.5.1)


@pytest.mark.parametrize("name", SAME_DIE)
def test_bmi055_and_bmx055_have_the_bmg160_table_bit_for_bit(name):
    p, base = part_table(name), part_table("bmg160")
    assert p.registers == base.registers
    assert (p.reset_values, p.write_masks) == (base.reset_values, base.write_masks)
    assert p.absent == frozenset() and p.pins == ("INT3", "INT4")


@pytest.mark.parametrize("name", SAME_DIE)
def test_bmi055_and_bmx055_dump_and_write_like_the_bmg160(name):
    chip, reference = _quiet(name), BMG160(noise=False, seed=1)
    assert chip.dump() == reference.dump()
    for address in range(0x40):
        if address in (0x14, 0x3F):  # soft reset, FIFO data
            continue
        for c in (chip, reference):
            c.write(address, b"\x5a")
        assert chip.dump() == reference.dump(), hex(address)


@pytest.mark.parametrize("address, value", sorted(BMI088_RESET.items()))
def test_bmi088_reset_values_at_power_up_and_after_soft_reset(address, value):
    chip = _quiet("bmi088_gyro")
    assert chip.read(address)[0] == value
    chip.write(address, b"\x55")
    chip.write(0x14, b"\xb6")  # 5.5.8
    assert chip.read(address)[0] == value


@pytest.mark.parametrize("address", BMI088_RESERVED)
def test_bmi088_reserved_registers_read_zero_ignore_writes_and_upsets(address):
    chip = _quiet("bmi088_gyro")
    chip.advance(0.1)  # sampling: TEMP, status registers would be nonzero on a BMG160
    chip.write(address, b"\xff")
    chip.poke(address, 0xFF)
    chip.advance(0.01)
    assert chip.read(address) == b"\x00"
    assert chip.dump()[address] == 0


def test_bmi088_existing_registers_are_exactly_the_data_sheet_map():
    p = part_table("bmi088_gyro")
    present = {a for a in range(0x40) if a not in p.absent and not p.registers[a].reserved}
    assert present == set(range(0x40)) - set(BMI088_RESERVED)
    names = {a: p.registers[a].name for a in (0x00, 0x0A, 0x11, 0x15, 0x16, 0x18, 0x34, 0x3C)}
    assert names == {0x00: "GYRO_CHIP_ID", 0x0A: "GYRO_INT_STAT_1", 0x11: "GYRO_LPM1",
                     0x15: "GYRO_INT_CTRL", 0x16: "INT3_INT4_IO_CONF",
                     0x18: "INT3_INT4_IO_MAP", 0x34: "FIFO_EXT_INT_S",
                     0x3C: "GYRO_SELF_TEST"}
    assert p.address_of("gyro_int_ctrl") == p.address_of("INT_EN_0") == 0x15
    with pytest.raises(KeyError, match="no BMI088 gyroscope register named 'TEMP'"):
        p.address_of("TEMP")
    assert p.address_of("fifo_ext_int_s") == 0x34
    with pytest.raises(KeyError, match="named 'BGW_SPI3_WDT'"):
        p.address_of("BGW_SPI3_WDT")  # replaced by FIFO_EXT_INT_S at the same address


@pytest.mark.parametrize("address, kept", sorted(BMI088_WRITE_KEEPS.items()))
def test_bmi088_write_keeps_only_the_data_sheet_bits(address, kept):
    chip = _quiet("bmi088_gyro")
    chip.write(address, b"\xff")
    assert chip.read(address)[0] == kept
    chip.write(address, b"\x00")
    assert chip.read(address)[0] == (0x80 if address == 0x10 else 0)


def test_bmi088_lpm1_keeps_the_two_mode_bits():
    chip = _quiet("bmi088_gyro")
    chip.write(0x11, b"\x9e")  # suspend + the BMG160's sleep_dur bits 3:1 (absent here)
    assert chip.read(0x11) == b"\x80"


def test_bmi088_no_temperature_register_the_bmg160_has_one():
    bmi088, bmg160 = (make_chip(p, noise=False, temperature_c=40.0) for p in ("bmi088_gyro", "bmg160"))
    for c in (bmi088, bmg160):
        c.advance(0.05)
    assert bmg160.read(0x08) == bytes([(40 - 23) * 2])  # 0.5 K/LSB (BMG160 spec 4.3)
    assert bmi088.read(0x08) == b"\x00"  # DS 5.4: 0x08 reserved (temperature on the accel die)


def test_bmi088_burst_over_reserved_registers_reads_zero_there():
    chip = make_chip("bmi088_gyro", noise=False, true_rate=(100.0, 0.0, 0.0))
    chip.advance(0.05)
    block = chip.read(0x00, 0x12)
    assert block[0] == 0x0F and block[2:4] != b"\x00\x00"
    assert block[0x08:0x0A] == b"\x00\x00" and block[0x0B:0x0E] == b"\x00\x00\x00"
    assert block[0x12 - 1] == 0x00 and block[0x10] == 0x80


def test_bmi088_decode_dump_uses_the_part_names():
    lines = part_table("bmi088_gyro").decode_dump(_quiet("bmi088_gyro").dump())
    assert lines[0x15].startswith("0x15 GYRO_INT_CTRL = 0x00: data_en=0 (off) fifo_en=0 (off)")
    assert lines[0x08] == "0x08 RESERVED_0x08 = 0x00: reserved"
    assert len(lines) == len(REGISTERS)


def _stem(name: str) -> str:
    """A register family as the docs table groups it (HIGH_TH_Y -> HIGH_TH, OFC3 -> OFC)."""
    if name.startswith(("HIGH_", "OFC", "INT_STATUS_", "INT_MAP_", "TRIM_GP")):
        return name.rstrip("XYZ_0123456789")
    return name


def test_docs_parts_page_names_every_bmi088_difference():
    # docs/parts.md's differences table must keep up with the part's data
    from pathlib import Path

    from bmg160_emu.device import part_bmi088_gyro as bmi088

    page = (Path(__file__).resolve().parents[1] / "docs" / "parts.md").read_text(encoding="utf-8")
    table = page[page.index("## BMI088 gyroscope"):page.index("### What the sources")]
    named = [n for n in bmi088.ABSENT if not n.startswith("RESERVED_")]
    named += [*bmi088.FIELDS, *bmi088.RENAMED.values(), *bmi088.DIFFERENCES.replaced,
              bmi088.FIFO_EXT_INT_S.name]
    assert len(named) > 40
    assert [n for n in named if _stem(n) not in table] == []


def test_docs_parts_page_embeds_the_bmi088_register_map():
    from pathlib import Path

    page = (Path(__file__).resolve().parents[1] / "docs" / "parts.md").read_text(encoding="utf-8")
    start = page.index("<!-- bmi088-map:start -->\n") + len("<!-- bmi088-map:start -->\n")
    assert page[start:page.index("<!-- bmi088-map:end -->")] == part_table("bmi088_gyro").markdown_table()
