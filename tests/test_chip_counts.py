"""Counts are right: a constant rate r reads round(r * S) for every range, saturating
(spec 5.1). Expected values come from the chip's sensitivity table, never literals."""

import pytest
from _chip_helpers import period_s, quiet_chip, rates

from bmg160_emu.device import spec_choices
from bmg160_emu.device.chip import BMG160

RATES_DPS = (0.0, 1.0, -1.0, 0.03, 12.345, -57.2, 123.4, -124.9, 249.0, 333.3, -499.9, 999.0,
             -1500.0, 1999.9, -2000.0, 2100.0, -5000.0)


def _expected(rate: float, sensitivity: float) -> int:
    return max(-32768, min(32767, round(rate * sensitivity)))


@pytest.mark.parametrize("table", ["binary", "nominal"])
@pytest.mark.parametrize("code", range(5))
def test_constant_rate_reads_round_rate_times_sensitivity(table, code):
    sens = spec_choices.SENSITIVITY_TABLES[table][code]
    for rate in RATES_DPS:
        chip = quiet_chip(sensitivity=table, true_rate=(rate, -rate, rate / 2))
        chip.write(0x0F, bytes([code]))
        chip.advance(period_s(chip))
        assert rates(chip) == (_expected(rate, sens), _expected(-rate, sens),
                               _expected(rate / 2, sens)), (table, code, rate)


def test_constant_rate_reads_exactly_from_the_first_sample():
    chip = quiet_chip(true_rate=(10.0, -20.0, 30.0))
    s = chip.sensitivity
    assert rates(chip) == (round(10 * s), round(-20 * s), round(30 * s))
    for _ in range(50):
        chip.advance(period_s(chip))
        assert rates(chip) == (round(10 * s), round(-20 * s), round(30 * s))


def test_default_table_is_binary_32768_over_full_scale():
    chip = quiet_chip()
    assert chip.sensitivity_table == tuple(32768 / fs for fs in (2000, 1000, 500, 250, 125))


def test_full_scale_saturates_at_int16_limits():
    chip = quiet_chip(true_rate=(1e6, -1e6, 0.0))
    chip.write(0x0F, b"\x04")
    chip.advance(period_s(chip))
    assert rates(chip)[:2] == (32767, -32768)


@pytest.mark.parametrize("code", [5, 6, 7])
def test_reserved_range_codes_read_back_and_scale_as_2000_dps(code):
    chip = quiet_chip(true_rate=(100.0, 0.0, 0.0))
    chip.write(0x0F, bytes([code]))
    chip.advance(period_s(chip))
    assert chip.read(0x0F)[0] == code
    assert rates(chip)[0] == round(100.0 * chip.sensitivity_table[0])


def test_range_upper_bits_read_back_as_written():
    chip = quiet_chip()
    chip.write(0x0F, b"\x83")
    assert chip.read(0x0F) == b"\x83"


def test_custom_sensitivity_table_is_used():
    table = (10.0, 20.0, 40.0, 80.0, 160.0)
    chip = quiet_chip(sensitivity=table, true_rate=(3.3, 0, 0))
    chip.write(0x0F, b"\x02")
    chip.advance(period_s(chip))
    assert rates(chip)[0] == round(3.3 * 40.0)


@pytest.mark.parametrize("bad", ["metric", (1, 2, 3), (1, 2, 3, 4, -5)])
def test_bad_sensitivity_table_is_refused(bad):
    with pytest.raises(ValueError):
        BMG160(noise=False, sensitivity=bad)


def test_range_change_applies_from_the_next_sample():
    chip = quiet_chip(true_rate=(50.0, 0, 0))
    before = rates(chip)[0]
    chip.write(0x0F, b"\x01")
    assert rates(chip)[0] == before  # same sample until the next one
    chip.advance(period_s(chip))
    assert rates(chip)[0] == round(50.0 * chip.sensitivity_table[1])
