"""Interrupts (spec 6.3, 6.4): data_int, any-motion, high-rate, latching, pins."""

import pytest
from _chip_helpers import period_s, quiet_chip


def _status1(chip):
    return chip.read(0x0A)[0]


def test_data_int_is_a_short_pulse_after_each_sample():
    chip = quiet_chip()
    chip.write(0x15, b"\x80")
    chip.write(0x18, b"\x01")  # data -> INT1
    chip.advance(period_s(chip))
    assert _status1(chip) & 0x80 and chip.int1
    chip.advance(0.0003)  # the pulse (300 us) is over before the next sample (500 us)
    assert _status1(chip) & 0x80 == 0 and not chip.int1


def test_data_int_stays_zero_when_disabled():
    chip = quiet_chip()
    chip.advance(period_s(chip))
    assert _status1(chip) & 0x80 == 0


def test_hold_data_int_option_holds_until_the_rate_registers_are_read():
    chip = quiet_chip(hold_data_int=True)
    chip.write(0x15, b"\x80")
    chip.advance(period_s(chip) + 0.0004)
    assert _status1(chip) & 0x80
    chip.read(0x02, 6)
    assert _status1(chip) & 0x80 == 0
    chip.advance(period_s(chip))
    assert _status1(chip) & 0x80


def test_pin_level_follows_int_en_1():
    chip = quiet_chip()
    chip.write(0x15, b"\x80")
    chip.write(0x18, b"\x81")  # data -> INT1 and INT2
    chip.write(0x16, b"\x01")  # INT1 active high, INT2 active low
    chip.advance(period_s(chip))
    assert chip.int_pin_level(1) == 1 and chip.int_pin_level(2) == 0
    chip.advance(0.0004)
    assert chip.int_pin_level(1) == 0 and chip.int_pin_level(2) == 1


def _high_rate_chip(latch=0x00):
    chip = quiet_chip()
    chip.write(0x10, b"\x04")  # 200 Hz
    # X enabled, threshold (255 + 2*256)*4 = 3068 LSB, hysteresis 1020: clears below 2048
    chip.write(0x22, b"\x05")
    chip.write(0x23, b"\x01")  # (1+1)*2.5 ms = 5 ms = 1 sample at 200 Hz
    chip.write(0x17, b"\x08")  # high -> INT1
    chip.write(0x21, bytes([latch]))
    chip.write(0x13, b"\x80")  # unfiltered: steps are immediate
    chip.write(0x1A, b"\x08")  # high-rate engine on unfiltered data too
    return chip


def test_high_rate_sets_status_axis_and_sign():
    chip = _high_rate_chip()
    chip.set_true_rate((-200.0, 0.0, 0.0))  # 3277 LSB > 3068
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] & 0x02 and chip.int1
    assert chip.read(0x0C)[0] == 0x08 | 0x01  # sign negative, first X


def test_high_rate_stays_clear_below_threshold_and_when_disabled():
    chip = _high_rate_chip()
    chip.set_true_rate((150.0, 0.0, 0.0))  # 2458 LSB < 3068
    chip.advance(10 * period_s(chip))
    assert chip.read(0x09)[0] == 0
    chip.write(0x22, b"\x00")
    chip.set_true_rate((500.0, 0.0, 0.0))
    chip.advance(10 * period_s(chip))
    assert chip.read(0x09)[0] == 0


def test_non_latched_high_rate_clears_when_rate_drops():
    chip = _high_rate_chip()
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    chip.set_true_rate((0.0, 0, 0))
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] == 0 and not chip.int1


def test_latched_interrupt_stays_until_reset_int():
    chip = _high_rate_chip(latch=0x07)
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    chip.set_true_rate((0.0, 0, 0))
    chip.advance(1.0)
    assert chip.read(0x09)[0] & 0x02 and chip.int1
    chip.write(0x21, b"\x87")
    assert chip.read(0x09)[0] == 0 and not chip.int1
    assert chip.read(0x21) == b"\x07"  # reset_int reads 0


@pytest.mark.parametrize("code, hold_s", [(0x1, 0.25), (0xB, 0.001), (0xC, 0.0125)])
def test_temporary_latch_holds_for_its_time(code, hold_s):
    chip = _high_rate_chip(latch=code)
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    chip.set_true_rate((0.0, 0, 0))
    chip.advance(period_s(chip))  # condition ends at this sample
    chip.advance(hold_s - 1e-6)
    assert chip.read(0x09)[0] & 0x02
    chip.advance(2e-6)
    assert chip.read(0x09)[0] == 0


def test_latch_status_bits_keep_status_but_not_the_pin():
    chip = _high_rate_chip(latch=0x10)
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    chip.set_true_rate((0.0, 0, 0))
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] & 0x02 and not chip.int1
    chip.write(0x21, b"\x90")
    assert chip.read(0x09)[0] == 0


def _any_motion_chip():
    chip = quiet_chip()
    chip.write(0x10, b"\x04")  # 200 Hz: slope every sample
    chip.write(0x13, b"\x80")
    chip.write(0x1A, b"\x02")  # any-motion engine on unfiltered data
    chip.write(0x1B, b"\x00")  # threshold 16 LSB
    chip.write(0x1C, b"\x02")  # Y only, N = 4
    chip.write(0x19, b"\x02")  # any -> INT2
    return chip


def test_any_motion_needs_n_consecutive_slopes_above_threshold():
    chip = _any_motion_chip()
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (0.0, 20 * round(t * 200) / s, 0.0))  # slope 20 LSB
    chip.advance(4 * period_s(chip))
    assert chip.read(0x09)[0] & 0x04 == 0
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] & 0x04 and chip.int2
    assert chip.read(0x0B)[0] == 0x02  # first Y, positive slope


def test_any_motion_clears_after_n_quiet_slopes():
    chip = _any_motion_chip()
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (0.0, 20 * round(t * 200) / s, 0.0))
    chip.advance(10 * period_s(chip))
    chip.set_true_rate((0.0, 5.0, 0.0))
    chip.advance(6 * period_s(chip))
    assert chip.read(0x09)[0] & 0x04 == 0


def test_any_motion_ignores_disabled_axes():
    chip = _any_motion_chip()
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (50 * round(t * 200) / s, 0.0, 0.0))
    chip.advance(20 * period_s(chip))
    assert chip.read(0x09)[0] == 0


def test_interrupt_maps_route_each_source_to_its_pin():
    chip = _high_rate_chip()
    chip.write(0x17, b"\x00")
    chip.write(0x19, b"\x08")  # high -> INT2 only
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    assert chip.int2 and not chip.int1


def test_high_rate_clears_only_below_threshold_minus_hysteresis():
    chip = _high_rate_chip()
    chip.set_true_rate((200.0, 0, 0))
    chip.advance(period_s(chip))
    chip.set_true_rate((130.0, 0, 0))  # 2130 LSB: below threshold, above 2048
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] & 0x02
    chip.set_true_rate((120.0, 0, 0))  # 1966 LSB
    chip.advance(period_s(chip))
    assert chip.read(0x09)[0] == 0


def test_held_data_int_counts_only_samples_taken_after_data_en():
    chip = quiet_chip(hold_data_int=True)
    chip.advance(period_s(chip))  # a sample while data_en = 0: no data-ready for it (6.3)
    chip.write(0x15, b"\x80")
    assert _status1(chip) & 0x80 == 0
    chip.advance(period_s(chip))
    assert _status1(chip) & 0x80
