"""Self-test (6.8), offset registers and fast offset compensation (6.9), NVM (6.10)."""

import numpy as np
import pytest
from _chip_helpers import period_s, quiet_chip, rates

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.offsets import set_offsets


def test_self_test_reports_ready_and_pass_after_its_test_time():
    chip = quiet_chip()
    assert chip.read(0x3C)[0] == 0x10  # rate_ok, no test yet
    chip.write(0x3C, b"\x01")
    assert chip.read(0x3C)[0] & 0x03 == 0  # running, trig_bist reads 0
    chip.advance(0.010)
    assert chip.read(0x3C)[0] == 0x12  # rate_ok, bist_rdy, no bist_fail


def test_injected_self_test_failure_sets_bist_fail():
    chip = quiet_chip()
    chip.inject_bist_failure = True
    chip.write(0x3C, b"\x01")
    chip.advance(0.010)
    assert chip.read(0x3C)[0] == 0x16


def test_self_test_after_soft_reset_as_qc_does_it():
    chip = quiet_chip()
    chip.write(0x14, b"\xb6")
    chip.advance(0.040)
    assert chip.read(0x3C)[0] & 0x10
    chip.write(0x3C, b"\x01")
    for _ in range(100):
        chip.advance(0.002)
        if chip.read(0x3C)[0] & 0x02:
            break
    assert chip.read(0x3C)[0] & 0x06 == 0x02


def _offset_registers(chip, x, y, z):
    set_offsets(chip.state.regs, (x, y, z))  # as the bytes of 4.24 below check
    return chip.read(0x36, 6)


@pytest.mark.parametrize("x, y, z", [(0, 0, 0), (1, 2, 3), (-1, -2048, 2047), (0x123, -0x456, 7)])
def test_offset_fields_assemble_as_in_the_spec(x, y, z):
    chip = quiet_chip()
    ofc1, ofc2, ofc3, ofc4, gp0, _ = _offset_registers(chip, x, y, z)

    def sx(v):
        return v - 4096 if v & 0x800 else v

    assert sx(ofc2 << 4 | (ofc1 >> 6) << 2 | (gp0 >> 2 & 3)) == x
    assert sx(ofc3 << 4 | (ofc1 >> 3 & 7) << 1 | (gp0 >> 1 & 1)) == y
    assert sx(ofc4 << 4 | (ofc1 & 7) << 1 | (gp0 & 1)) == z
    assert chip.offsets_lsb() == (x, y, z)


def test_offset_registers_add_to_the_output_range_independently():
    chip = quiet_chip(true_rate=(10.0, 10.0, 10.0))
    chip.write(0x37, b"\x02")  # offset_x = 32 LSB
    chip.write(0x39, b"\xff")  # offset_z = -16 LSB
    for code in (0, 3):
        chip.write(0x0F, bytes([code]))
        chip.advance(period_s(chip))
        s = chip.sensitivity
        lsb = chip.offset_lsb_dps
        assert rates(chip) == (round((10 + 32 * lsb) * s), round(10 * s),
                               round((10 - 16 * lsb) * s))


def test_offset_reset_clears_the_offsets_and_keeps_gp_bits():
    chip = quiet_chip()
    chip.write(0x37, b"\x12")
    chip.write(0x3A, b"\xaf")
    chip.write(0x21, b"\x40")
    assert chip.offsets_lsb() == (0, 0, 0)
    assert chip.read(0x3A)[0] == 0xA0 and chip.read(0x21) == b"\x00"


def test_fast_offset_compensation_cancels_the_bias():
    chip = BMG160(seed=3, true_rate=(1.5, -0.7, 0.0))
    chip.write(0x0F, b"\x04")  # lowest range for accuracy
    chip.write(0x32, b"\x3f")  # 256 samples, X Y Z, start
    assert chip.read(0x32)[0] & 0x08
    chip.advance(256 * period_s(chip))
    assert chip.read(0x32)[0] & 0x08 == 0
    assert chip.read(0x0A)[0] & 0x20  # fast_offset_int
    chip.advance(period_s(chip))
    n = 400
    total = np.zeros(3)
    for _ in range(n):
        chip.advance(period_s(chip))
        total += rates(chip)
    mean_dps = total / n / chip.sensitivity
    # per-sample noise is ~0.8 deg/s at 2000 Hz (N = 0.0178 deg/s/sqrt(Hz)); FOC averages
    # 256 samples (0.05 deg/s), the check 400 (0.04): 0.3 deg/s is > 4 sigma, and still
    # far below the 1.5 deg/s rate that FOC removed
    assert np.all(np.abs(mean_dps) < 0.3), mean_dps


def test_fast_offset_only_touches_selected_axes():
    chip = quiet_chip(true_rate=(2.0, 3.0, 4.0))
    chip.write(0x32, b"\x0a")  # Y only, 32 samples
    chip.advance(40 * period_s(chip))
    x, y, z = chip.offsets_lsb()
    assert x == 0 and z == 0 and y == round(-3.0 / chip.offset_lsb_dps)


def test_nvm_programming_stores_offsets_that_survive_soft_reset():
    chip = quiet_chip()
    chip.write(0x37, b"\x05")
    chip.write(0x3B, b"\x77")
    chip.write(0x33, b"\x01")  # unlock
    chip.write(0x33, b"\x03")  # program
    assert chip.read(0x33)[0] & 0x04 == 0  # busy
    chip.advance(0.01)
    assert chip.read(0x33)[0] == 0xE5  # 14 cycles left, ready, prog_mode
    chip.write(0x14, b"\xb6")
    assert chip.read(0x37) == b"\x05" and chip.read(0x3B) == b"\x77"
    assert chip.read(0x33)[0] == 0xE4


def test_nvm_programming_needs_prog_mode():
    chip = quiet_chip()
    chip.write(0x37, b"\x05")
    chip.write(0x33, b"\x02")
    chip.write(0x14, b"\xb6")
    assert chip.read(0x37) == b"\x00" and chip.read(0x33)[0] == 0xF4


def test_nvm_load_restores_registers_from_nvm():
    chip = quiet_chip(nvm_image=bytes([0, 0x10, 0, 0, 0, 0x42]))
    assert chip.read(0x3B) == b"\x42" and chip.offsets_lsb()[0] == 0x100
    chip.write(0x3B, b"\x00")
    chip.write(0x33, b"\x08")
    assert chip.read(0x3B) == b"\x42"
