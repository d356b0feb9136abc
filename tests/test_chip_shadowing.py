"""MSB shadowing (spec 6.2): reading an LSB latches its MSB; shadow_dis turns it off."""

from _chip_helpers import period_s, quiet_chip


def _ramp_chip():
    # X rises 300 counts per sample at 2000 Hz, so the MSB changes between samples
    chip = quiet_chip(true_rate=lambda t: (t * 2000 * 300 / 16.384, 0.0, 0.0))
    chip.advance(0.01)
    return chip


def test_reading_lsb_latches_msb():
    chip = _ramp_chip()
    expected = chip.peek(0x02) | chip.peek(0x03) << 8
    lsb = chip.read(0x02)[0]
    chip.advance(period_s(chip) * 3)
    msb = chip.read(0x03)[0]
    assert lsb | msb << 8 == expected


def test_msb_is_released_after_it_is_read():
    chip = _ramp_chip()
    chip.read(0x02)
    chip.read(0x03)
    chip.advance(period_s(chip) * 3)
    assert chip.read(0x03)[0] == chip.peek(0x03) == chip.read(0x02, 2)[1]


def test_shadowing_is_per_axis():
    chip = quiet_chip(true_rate=lambda t: (t * 1e5, -t * 1e5, t * 5e4))
    chip.advance(0.01)
    y_word = chip.peek(0x04) | chip.peek(0x05) << 8
    chip.read(0x04)
    chip.advance(0.002)
    chip.read(0x02)
    chip.read(0x03)
    assert chip.read(0x04 + 1)[0] << 8 | (y_word & 0xFF) == y_word


def test_msb_without_lsb_read_gives_current_sample():
    chip = _ramp_chip()
    chip.advance(period_s(chip))
    assert chip.read(0x03)[0] == chip.read(0x02, 2)[1]


def test_shadow_dis_lets_single_byte_reads_tear():
    chip = _ramp_chip()
    chip.write(0x13, b"\x40")
    chip.read(0x02)
    chip.advance(period_s(chip) * 3)
    current_msb = chip.read(0x02, 2)[1]
    assert chip.read(0x03)[0] == current_msb


def test_lsb_read_again_relatches_from_the_current_sample():
    chip = _ramp_chip()
    chip.read(0x02)
    chip.advance(period_s(chip) * 3)
    word = chip.peek(0x02)
    chip.read(0x02)
    assert chip.peek(0x03) == chip.read(0x02, 2)[1]
    assert word == chip.peek(0x02)
