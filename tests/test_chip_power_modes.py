"""Soft reset (6.6) and power modes (6.7): what each mode allows and when data returns."""

import pytest
from _chip_helpers import period_s, quiet_chip, rates

from bmg160_emu.device.chip import BMG160


def _sample_count(chip):
    return chip.state.sample_seq


def test_soft_reset_restores_the_reset_map_and_empties_the_fifo():
    chip = quiet_chip(true_rate=(5.0, 0, 0))
    reset_dump = BMG160(noise=False).dump()
    for reg, value in ((0x0F, 0x03), (0x10, 0x05), (0x13, 0xC0), (0x16, 0x00), (0x3D, 0x85),
                       (0x3E, 0x40), (0x21, 0x8F), (0x1B, 0x7F)):
        chip.write(reg, bytes([value]))
    chip.advance(0.1)
    assert chip.read(0x0E)[0] > 0
    chip.write(0x14, b"\xb6")
    after = chip.dump()
    for address in range(64):
        if address in (0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x0E, 0x3C, 0x3F):
            continue  # data registers: checked below
        assert after[address] == reset_dump[address], hex(address)
    assert after[0x0E] == 0 and after[2:8] == bytes(6)


def test_other_values_in_softreset_register_do_nothing():
    chip = quiet_chip()
    chip.write(0x0F, b"\x02")
    chip.write(0x14, b"\xb5")
    assert chip.read(0x0F) == b"\x02" and chip.read(0x14) == b"\x00"


def test_data_path_restarts_one_startup_time_after_soft_reset():
    chip = quiet_chip(true_rate=(3.0, 0, 0), startup_time_s=0.030)
    chip.write(0x14, b"\xb6")
    chip.advance(0.0299)
    assert rates(chip) == (0, 0, 0) and chip.read(0x3C)[0] & 0x10 == 0
    chip.advance(0.0001)
    assert rates(chip)[0] == round(3.0 * chip.sensitivity)
    assert chip.read(0x3C)[0] & 0x10  # rate_ok


def test_registers_accept_writes_right_after_reset():
    chip = quiet_chip()
    chip.write(0x14, b"\xb6")
    chip.write(0x0F, b"\x01")
    assert chip.read(0x0F) == b"\x01"


def test_power_on_reset_restores_reset_values():
    chip = quiet_chip()
    chip.write(0x0F, b"\x04")
    chip.i2c_write(b"\x10")
    chip.power_on_reset()
    assert chip.pointer == 0 and chip.read(0x0F) == b"\x00"


@pytest.mark.parametrize("lpm1, lpm2, mode", [
    (0x00, 0x00, "normal"), (0x20, 0x00, "deep suspend"), (0x80, 0x00, "suspend"),
    (0x80, 0x80, "fast power-up"), (0x00, 0x40, "advanced power saving"),
    (0xA0, 0x00, "deep suspend"), (0x00, 0x80, "normal"),
])
def test_power_mode_decoding_follows_the_priority_rule(lpm1, lpm2, mode):
    chip = quiet_chip()
    chip.write(0x12, bytes([lpm2]))
    chip.write(0x11, bytes([lpm1]))
    assert chip.power_mode == mode


def test_suspend_stops_sampling_and_keeps_the_last_values():
    chip = quiet_chip(true_rate=lambda t: (100 * t, 0, 0))
    chip.advance(0.01)
    chip.write(0x11, b"\x80")
    before, count = chip.read(0x02, 6), _sample_count(chip)
    chip.advance(0.5)
    assert chip.read(0x02, 6) == before and _sample_count(chip) == count


def test_suspend_ignores_writes_except_power_and_reset_registers():
    chip = quiet_chip()
    chip.write(0x11, b"\x80")
    chip.write(0x0F, b"\x03")
    assert chip.read(0x0F) == b"\x00"
    chip.write(0x12, b"\x80")
    assert chip.power_mode == "fast power-up"


def test_deep_suspend_accepts_only_lpm1_and_softreset():
    chip = quiet_chip()
    chip.write(0x11, b"\x20")
    chip.write(0x12, b"\x40")
    chip.write(0x0F, b"\x03")
    assert chip.read(0x12) == b"\x00" and chip.read(0x0F) == b"\x00"
    assert chip.read(0x00) == b"\x0f"  # readable in every mode


def test_leaving_deep_suspend_behaves_like_a_soft_reset():
    chip = quiet_chip()
    chip.write(0x10, b"\x04")
    chip.write(0x11, b"\x20")
    chip.write(0x11, b"\x00")
    assert chip.read(0x10) == b"\x80" and chip.power_mode == "normal"


@pytest.mark.parametrize("lpm2, wake_s", [(0x00, 0.030), (0x80, 0.010)])
def test_first_sample_after_wake_up_comes_after_the_wake_up_time(lpm2, wake_s):
    chip = quiet_chip(true_rate=(1.0, 0, 0))
    chip.write(0x12, bytes([lpm2]))
    chip.write(0x11, b"\x80")
    chip.advance(1.0)
    count = _sample_count(chip)
    chip.write(0x11, b"\x00")
    chip.advance(wake_s - 1e-6)
    assert _sample_count(chip) == count
    chip.advance(1e-6)
    assert _sample_count(chip) == count + 1


def test_advanced_power_saving_produces_samples():
    chip = quiet_chip()
    chip.write(0x12, b"\x40")
    count = _sample_count(chip)
    chip.advance(10 * period_s(chip))
    assert _sample_count(chip) == count + 10


def test_strict_mode_logs_suspend_to_deep_suspend_and_multi_byte_writes():
    chip = quiet_chip(strict=True)
    chip.write(0x11, b"\x80")
    chip.write(0x11, b"\x20")
    chip.write(0x14, b"\xb6")
    chip.write(0x0F, b"\x00\x80")
    text = "\n".join(chip.strict_log)
    assert "suspend -> deep suspend" in text and "multi-byte write" in text


def test_strict_mode_off_logs_nothing():
    chip = quiet_chip()
    chip.write(0x0F, b"\x00\x80")
    assert chip.strict_log == []
