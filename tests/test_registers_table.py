"""The declarative register table: complete, consistent, and as the spec lays it out."""

import pytest

from bmg160_emu.device import registers
from bmg160_emu.device.registers import BY_NAME, REGISTERS, address_of, decode_dump


def test_table_has_64_registers_in_address_order():
    assert len(REGISTERS) == 64
    assert [r.address for r in REGISTERS] == list(range(64))


def test_register_names_are_unique():
    assert len({r.name for r in REGISTERS}) == 64


@pytest.mark.parametrize("name, address", [
    ("CHIP_ID", 0x00), ("RATE_X_LSB", 0x02), ("RATE_Z_MSB", 0x07), ("TEMP", 0x08),
    ("FIFO_STATUS", 0x0E), ("RANGE", 0x0F), ("BW", 0x10), ("LPM1", 0x11), ("LPM2", 0x12),
    ("RATE_HBW", 0x13), ("BGW_SOFTRESET", 0x14), ("INT_RST_LATCH", 0x21), ("A_FOC", 0x32),
    ("TRIM_NVM_CTRL", 0x33), ("OFC1", 0x36), ("TRIM_GP0", 0x3A), ("BIST", 0x3C),
    ("FIFO_CONFIG_0", 0x3D), ("FIFO_CONFIG_1", 0x3E), ("FIFO_DATA", 0x3F),
])
def test_spec_names_map_to_spec_addresses(name, address):
    assert address_of(name) == address
    assert address_of(name.lower()) == address


def test_unknown_register_name_is_a_clear_error():
    with pytest.raises(KeyError, match="no BMG160 register named"):
        address_of("RATE_W_LSB")


def test_fields_of_a_register_do_not_overlap_and_stay_in_one_byte():
    for reg in REGISTERS:
        seen = 0
        for f in reg.fields:
            assert 0 <= f.lsb <= f.msb <= 7, (reg.name, f.name)
            assert not seen & f.mask, (reg.name, f.name)
            seen |= f.mask


def test_field_insert_and_extract_round_trip():
    rng = BY_NAME["RANGE"].field("range")
    value = rng.insert(0x80, 3)
    assert value == 0x83
    assert rng.extract(value) == 3


def test_reserved_registers_have_no_writable_bits():
    for reg in REGISTERS:
        if reg.reserved:
            assert reg.write_mask == 0 and reg.reset == 0


def test_read_only_registers_take_no_writes():
    for name in ("CHIP_ID", "RATE_X_LSB", "TEMP", "INT_STATUS_1", "FIFO_STATUS", "FIFO_DATA"):
        assert BY_NAME[name].write_mask == 0


def test_trigger_bits_are_not_stored():
    assert BY_NAME["INT_RST_LATCH"].trigger_mask == 0xC0
    assert BY_NAME["INT_RST_LATCH"].write_mask == 0x1F
    assert BY_NAME["A_FOC"].trigger_mask == 0x08
    assert BY_NAME["TRIM_NVM_CTRL"].trigger_mask == 0x0A
    assert BY_NAME["BIST"].trigger_mask == 0x01


def test_nvm_backed_registers_are_0x36_to_0x3b():
    assert registers.NVM_ADDRESSES == (0x36, 0x37, 0x38, 0x39, 0x3A, 0x3B)


def test_decode_names_field_values():
    line = BY_NAME["RANGE"].describe(0x83)
    assert "range=3" in line and "250" in line
    assert BY_NAME["BW"].decode(0x84) == {"bw_fixed": 1, "bw": 4}


def test_decode_dump_gives_one_line_per_register_and_checks_length():
    lines = decode_dump(registers.RESET_VALUES)
    assert len(lines) == 64 and lines[0].startswith("0x00 CHIP_ID = 0x0F")
    with pytest.raises(ValueError):
        decode_dump(bytes(10))
