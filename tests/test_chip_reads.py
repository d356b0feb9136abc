"""Bus reads and writes through the primitives: bursts, words, pointer rules (spec 2.4)."""

import struct

import pytest
from _chip_helpers import period_s, quiet_chip, rates


def test_six_byte_burst_reads_x_y_z_lsb_first():
    chip = quiet_chip(true_rate=(1.0, -2.0, 3.0))
    s = chip.sensitivity
    assert struct.unpack("<3h", chip.read(0x02, 6)) == (round(s), round(-2 * s), round(3 * s))


def test_word_read_is_lsb_then_msb_of_one_axis():
    chip = quiet_chip(true_rate=(-1.5, 0.0, 0.0))
    raw = chip.read(0x02, 2)
    word = raw[0] | raw[1] << 8  # SMBus word: byte0 | byte1 << 8, unsigned
    assert word == round(-1.5 * chip.sensitivity) & 0xFFFF


def test_seven_byte_burst_includes_temperature():
    chip = quiet_chip(temperature_c=33.0)
    assert chip.read(0x02, 7)[6] == round((33.0 - 23.0) / 0.5)


def test_twelve_byte_burst_reaches_the_status_registers():
    chip = quiet_chip()
    data = chip.read(0x02, 12)
    assert len(data) == 12 and data[11] == 0x00  # 0x0D reserved reads 0


def test_chip_id_reads_0x0f():
    assert quiet_chip().read(0x00) == b"\x0f"


def test_burst_into_fifo_data_stays_on_0x3f():
    chip = quiet_chip(true_rate=(1.0, 2.0, 3.0))
    data = chip.read(0x3E, 1 + 6 + 6)
    assert data[0] == 0x00
    assert data[1:7] == chip.read(0x02, 6)  # bypass: the newest sample
    assert data[7:] == b"\x00\x80" * 3  # then the empty pattern


def test_reads_at_0x40_and_above_return_zero():
    chip = quiet_chip()
    assert chip.read(0x40, 4) == bytes(4)
    assert chip.read(0xFF) == b"\x00"


def test_writes_at_0x40_and_above_are_ignored():
    chip = quiet_chip()
    before = chip.dump()
    chip.write(0x40, b"\x12\x34")
    assert chip.dump() == before


def test_writes_to_read_only_registers_are_ignored():
    chip = quiet_chip()
    chip.write(0x00, b"\x55")
    chip.write(0x0E, b"\xff")
    assert chip.read(0x00) == b"\x0f" and chip.read(0x0E)[0] & 0x80 == 0


def test_bw_bit7_reads_one_and_reserved_bits_read_zero():
    chip = quiet_chip()
    chip.write(0x10, b"\x74")
    assert chip.read(0x10) == b"\x84"


def test_multi_byte_write_auto_increments():
    chip = quiet_chip()
    chip.write(0x0F, b"\x02\x03")
    assert chip.read(0x0F, 2) == b"\x02\x83"


def test_i2c_split_read_uses_the_pointer_set_by_an_address_only_write():
    chip = quiet_chip(true_rate=(4.0, 5.0, 6.0))
    chip.i2c_write(b"\x02")
    assert chip.pointer == 0x02
    assert chip.i2c_read(6) == chip.read(0x02, 6)
    chip.i2c_write(b"\x00")
    assert chip.i2c_read(1) == b"\x0f"
    assert chip.i2c_read(1) == b"\x00"  # the pointer moved on to 0x01


def test_i2c_write_writes_from_the_pointer():
    chip = quiet_chip()
    chip.i2c_write(b"\x0f\x03")
    assert chip.peek(0x0F) == 0x03


@pytest.mark.parametrize("reg", [-1, 0x100])
def test_register_out_of_range_is_a_value_error(reg):
    with pytest.raises(ValueError):
        quiet_chip().read(reg, 1)


@pytest.mark.parametrize("bad", [1.5, "2", None])
def test_register_of_wrong_type_is_a_type_error(bad):
    with pytest.raises(TypeError):
        quiet_chip().read(bad, 1)


def test_write_data_must_be_bytes():
    chip = quiet_chip()
    with pytest.raises(TypeError):
        chip.write(0x0F, 3)
    with pytest.raises(ValueError):
        chip.write(0x0F, [256])


def test_zero_length_read_returns_nothing():
    assert quiet_chip().read(0x02, 0) == b""


def test_peek_and_dump_have_no_side_effects():
    chip = quiet_chip(true_rate=(7.0, 0, 0))
    chip.write(0x3E, b"\x40")  # FIFO mode
    for _ in range(3):
        chip.advance(period_s(chip))
    first = chip.dump()
    assert chip.dump() == first
    assert chip.peek(0x0E) == 3
    assert chip.peek(0x3F) == chip.peek(0x3F)
    assert chip.read(0x0E) == b"\x03"


def test_new_samples_never_change_a_transaction_in_progress():
    chip = quiet_chip(true_rate=lambda t: (1000.0 * t, 0.0, 0.0))
    chip.advance(0.01)
    one = chip.read(0x02, 6)
    assert one == chip.read(0x02, 6)  # no time passed: same sample
    chip.advance(period_s(chip))
    assert rates(chip) != struct.unpack("<3h", one)


def test_read_leaves_the_i2c_pointer_after_its_last_byte():
    chip = quiet_chip()
    chip.read(0x00, 1)
    assert chip.i2c_read(1) == b"\x00"  # 0x01, reserved
    chip.read(0x3E, 3)
    assert chip.pointer == 0x3F


def test_a_hook_that_calls_a_primitive_does_not_reorder_samples():
    chip = quiet_chip(true_rate=lambda t: (1000.0 * t, 0, 0))
    chip.read(0x00)
    chip.sample_hooks.append(lambda c, t, r: (c.read(0x0F), r)[1])
    for _ in range(5):
        chip.advance(period_s(chip))
    expected = round(1000.0 * chip.time * chip.sensitivity)
    assert abs(rates(chip)[0] - expected) <= 20  # filter lag of a few samples at most
