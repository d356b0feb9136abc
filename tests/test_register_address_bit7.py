"""Bit 7 of the register address is not decoded (spec 2.4, docs/unconfirmed-choices.md):
the bus and the side-effect-free look at a register agree on where 0x80..0xFF lead."""

from __future__ import annotations

from bmg160_emu.device.chip import BMG160


def test_peek_reaches_the_register_a_read_of_the_same_address_reaches():
    chip = BMG160()
    for address in (0x80, 0x8F, 0xBF, 0xFF):
        assert chip.peek(address) == chip.peek(address & 0x7F)
    assert chip.peek(0x80) == 0x0F  # CHIP_ID, as a driver reading 0x80 over I2C gets it
    assert chip.read(0x80, 1) == bytes([chip.peek(0x80)])
