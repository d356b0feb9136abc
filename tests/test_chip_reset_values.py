"""Every register reads its spec reset value (spec section 3), at power-up and after reset."""

import pytest
from _chip_helpers import quiet_chip

# Spec section 3 table (with 4.22 for TRIM_NVM_CTRL and 4.25 for BIST); dynamic registers
# listed separately below.
SPEC_RESET = {
    0x00: 0x0F, 0x0F: 0x00, 0x10: 0x80, 0x11: 0x00, 0x12: 0x00, 0x13: 0x00, 0x14: 0x00,
    0x15: 0x00, 0x16: 0x0F, 0x17: 0x00, 0x18: 0x00, 0x19: 0x00, 0x1A: 0x00, 0x1B: 0x04,
    0x1C: 0xA0, 0x1E: 0x00, 0x21: 0x00, 0x22: 0x02, 0x23: 0x19, 0x24: 0x02, 0x25: 0x19,
    0x26: 0x02, 0x27: 0x19, 0x31: 0x60, 0x32: 0xC0, 0x33: 0xF4, 0x34: 0x00, 0x36: 0x00,
    0x37: 0x00, 0x38: 0x00, 0x39: 0x00, 0x3A: 0x00, 0x3B: 0x00, 0x3D: 0x00, 0x3E: 0x00,
}
RESERVED = [0x01, 0x0D, 0x1D, 0x1F, 0x20, *range(0x28, 0x31), 0x35]
# right after a reset, before the first sample: rate, temperature, status, FIFO all 0
DYNAMIC_AFTER_RESET = {a: 0x00 for a in (*range(0x02, 0x0D), 0x0E, 0x3C)}


def _reset_chip():
    chip = quiet_chip(seed=1)
    chip.write(0x14, b"\xb6")
    return chip


@pytest.mark.parametrize("address, value", sorted(SPEC_RESET.items()))
def test_reset_value_after_soft_reset(address, value):
    assert _reset_chip().read(address)[0] == value


@pytest.mark.parametrize("address, value", sorted(SPEC_RESET.items()))
def test_reset_value_at_power_up(address, value):
    assert quiet_chip(seed=1).read(address)[0] == value


@pytest.mark.parametrize("address", RESERVED)
def test_reserved_register_reads_zero_and_ignores_writes(address):
    chip = quiet_chip()
    chip.write(address, b"\xff")
    assert chip.read(address) == b"\x00"


@pytest.mark.parametrize("address, value", sorted(DYNAMIC_AFTER_RESET.items()))
def test_data_registers_read_zero_until_the_first_sample_after_reset(address, value):
    chip = _reset_chip()
    chip.write(0x15, b"\xc0")  # even with data and FIFO interrupts enabled
    assert chip.read(address)[0] == value


def test_dump_after_reset_is_the_reset_map_with_rate_ok_clear():
    chip = _reset_chip()
    dump = chip.dump()
    for address, value in SPEC_RESET.items():
        assert dump[address] == value
    assert dump[0x3C] == 0x00  # rate_ok comes up with the first sample (6.8)
