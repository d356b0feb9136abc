"""What each part does: power modes, FIFO, interrupts and self-test, as its data sheet says.

BMI088 expectations cite BST-BMI088-DS001 (sections 4.1.2, 4.6.2, 4.7.2, 4.9.4, 5.5); the
BMI055 and BMX055 gyroscopes are the BMG160 die, so they keep the engines the BMI088 lacks.
"""

from __future__ import annotations

import itertools
import struct

import pytest
from _chip_helpers import period_s, rates

from bmg160_emu.device.parts import make_chip
from bmg160_emu.device.power_modes import DEEP_SUSPEND, NORMAL, POWER_SAVE, SUSPEND

DPS = (30.0, -20.0, 10.0)


def _bmi088(**options):
    options.setdefault("noise", False)
    return make_chip("bmi088_gyro", **options)


def _ramp(chip):
    """X counts grow by one per sample (filtered, so with the filter's delay)."""
    s, odr = chip.sensitivity, chip.odr_hz
    chip.set_true_rate(lambda t: (round(t * odr) / s, 0.0, 1.0))
    return chip


def _frames(data):
    return [struct.unpack("<3h", data[i:i + 6]) for i in range(0, len(data), 6)]


# ------------------------------------------------------------------------- power modes


@pytest.mark.parametrize("lpm1, mode", [(0x00, NORMAL), (0x80, SUSPEND), (0x20, DEEP_SUSPEND)])
def test_bmi088_lpm1_values_select_the_three_modes(lpm1, mode):
    chip = _bmi088()
    chip.write(0x11, bytes([lpm1]))  # DS 5.5.7
    assert chip.power_mode == mode


def test_bmi088_suspend_stops_data_and_keeps_it_readable():
    chip = _bmi088(true_rate=DPS)
    chip.advance(0.05)
    before = rates(chip)
    chip.write(0x11, b"\x80")  # DS 4.1.2: no acquisition, latest data kept
    chip.set_true_rate((0.0, 0.0, 0.0))
    chip.advance(0.1)
    assert rates(chip) == before != (0, 0, 0)
    chip.write(0x11, b"\x00")
    chip.advance(0.031)  # 30 ms wake-up (DS table 3)
    assert rates(chip) == (0, 0, 0)


def test_bmi088_deep_suspend_loses_the_configuration():
    chip = _bmi088()
    chip.write(0x0F, b"\x03")
    chip.write(0x11, b"\x20")  # DS 4.1.2: configuration registers lost
    chip.write(0x11, b"\x00")
    assert chip.read(0x0F) == b"\x00" and chip.power_mode == NORMAL


def test_bmi088_has_no_fast_power_up_or_power_saving():
    chip = _bmi088()
    chip.write(0x12, b"\xc0")  # the BMG160's LPM2 (fast_power_up, power_save): reserved here
    chip.write(0x11, b"\x80")
    assert chip.power_mode == SUSPEND and chip.read(0x12) == b"\x00"
    chip.write(0x11, b"\x00")
    assert chip.power_mode == NORMAL


# ----------------------------------------------------------------------------- FIFO


def test_bmi088_fifo_mode_stops_at_100_frames_of_xyz():
    chip = _ramp(_bmi088())
    chip.write(0x10, b"\x04")  # 200 Hz
    chip.write(0x3E, b"\x40")  # FIFO mode (DS 5.5.16)
    chip.advance(150 * period_s(chip))
    assert chip.read(0x0E)[0] == 0x80 | 100  # overrun, 100 frames (DS 4.9.4.3)
    frames = _frames(chip.read(0x3F, 600))
    xs = [f[0] for f in frames]
    assert all(b > a for a, b in itertools.pairwise(xs[30:]))  # oldest first, past the filter lag
    assert all(f[2] == round(chip.sensitivity) for f in frames[30:])  # Z = 1 deg/s


def test_bmi088_stream_mode_holds_99_frames_the_bmg160_100():
    # DS 4.9.4.4 / 5.5.16: stream mode "filled with 99 frames"
    for part, depth in (("bmi088_gyro", 99), ("bmg160", 100)):
        chip = _ramp(make_chip(part, noise=False))
        chip.write(0x10, b"\x04")
        chip.write(0x3E, b"\x80")
        chip.advance(150 * period_s(chip))
        assert chip.read(0x0E)[0] & 0x7F == depth, part
        frames = _frames(chip.read(0x3F, 6 * depth))
        assert frames[-1] == rates(chip), part  # the newest frame is the current sample


def test_bmi088_fifo_full_interrupt_at_99_frames_in_stream_mode():
    chip = _bmi088()
    chip.write(0x3E, b"\x80")
    chip.write(0x15, b"\x40")  # fifo_en (DS 5.5.9)
    chip.advance(98 * period_s(chip))
    assert chip.read(0x0A)[0] & 0x10 == 0
    chip.advance(period_s(chip))
    assert chip.read(0x0A)[0] == 0x10  # fifo_int only (DS 5.5.3)


def test_bmi088_fifo_frames_have_no_tag_and_no_axis_select():
    # DS 5.5.15-5.5.17: bit 7 of FIFO_CONFIG_0 and bits 5:0 of FIFO_CONFIG_1 are reserved,
    # a frame is always X, Y, Z (6 bytes); the BMG160 would add tags and select one axis
    chip = _bmi088(true_rate=DPS)
    chip.write(0x3D, b"\x80")
    chip.write(0x3E, b"\x41")
    chip.advance(10 * period_s(chip))
    assert chip.read(0x0E)[0] == 10
    data = chip.read(0x3F, 60)
    assert chip.read(0x0E)[0] == 0 and len(_frames(data)) == 10


def test_bmi088_watermark_interrupt_on_int3_as_px4_sets_it_up():
    chip = _bmi088()
    chip.write(0x3E, b"\x40")
    chip.write(0x3D, b"\x05")  # watermark 5 frames
    chip.write(0x1E, b"\x88")  # FIFO_WM_EN: PX4 writes 0x88 (enable), 0x08 (disable)
    chip.write(0x15, b"\x40")
    chip.write(0x18, b"\x04")  # int3_fifo (DS 5.5.11)
    chip.advance(4 * period_s(chip))
    assert not chip.int1
    chip.advance(period_s(chip))
    assert chip.read(0x0A)[0] & 0x10 and chip.int1 and not chip.int2  # INT3, not INT4
    chip.read(0x3F, 6)
    assert not chip.int1


def test_bmi088_writing_fifo_config_1_clears_overrun():
    chip = _bmi088()
    chip.write(0x3E, b"\x40")
    chip.advance(120 * period_s(chip))
    assert chip.read(0x0E)[0] & 0x80
    chip.write(0x3E, b"\x40")  # DS 5.5.4: the overrun flag clears on this write only
    assert chip.read(0x0E)[0] == 0


# ------------------------------------------------------------------------ interrupts


def test_bmi088_data_ready_on_int3_and_int4_with_their_levels():
    chip = _bmi088()
    chip.write(0x15, b"\x80")  # data_en (DS 4.7.2: must be enabled explicitly)
    chip.write(0x18, b"\x81")  # int4_data, int3_data
    chip.write(0x16, b"\x01")  # INT3 active high, INT4 active low (DS 5.5.10)
    chip.advance(period_s(chip))
    assert chip.read(0x0A)[0] == 0x80 and chip.int1 and chip.int2
    assert chip.int_pin_level(1) == 1 and chip.int_pin_level(2) == 0
    chip.advance(0.0004)  # cleared after 280-400 us (DS 5.5.3)
    assert chip.read(0x0A)[0] == 0 and not chip.int1


def test_bmi088_has_no_motion_or_offset_engines():
    # the BMG160's any-motion, high-rate, latch and fast-offset set-up: reserved on the
    # BMI088 (DS 5.4); the same writes on a BMG160 raise any-motion and move the offsets
    chips = {part: make_chip(part, noise=False) for part in ("bmi088_gyro", "bmg160")}
    for chip in chips.values():
        for reg, value in ((0x1B, 0x00), (0x1C, 0x07), (0x17, 0x02), (0x19, 0x02),
                           (0x22, 0x01), (0x21, 0x0F), (0x32, 0x0F)):
            chip.write(reg, bytes([value]))
        s = chip.sensitivity
        chip.set_true_rate(lambda t, s=s: (200 * round(t * 2000) / s, 0.0, 0.0))
        chip.advance(0.1)
    bmi088, bmg160 = chips["bmi088_gyro"], chips["bmg160"]
    assert bmg160.read(0x09)[0] & 0x04 and bmg160.int1 and bmg160.offsets_lsb() != (0, 0, 0)
    assert bmi088.read(0x09, 5) == bytes(5)
    assert not bmi088.int1 and not bmi088.int2 and bmi088.offsets_lsb() == (0, 0, 0)


@pytest.mark.parametrize("part", ["bmi055_gyro", "bmx055_gyro"])
def test_bmi055_and_bmx055_keep_any_motion_and_power_saving(part):
    chip = make_chip(part, noise=False)
    chip.write(0x13, b"\x80")
    chip.write(0x10, b"\x04")
    chip.write(0x1A, b"\x02")
    chip.write(0x1B, b"\x00")
    chip.write(0x1C, b"\x02")
    chip.write(0x19, b"\x02")  # any -> the gyro's second pin (INT4 on the package)
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (0.0, 20 * round(t * 200) / s, 0.0))
    chip.advance(5 * period_s(chip))
    assert chip.read(0x09)[0] & 0x04 and chip.int2 and chip.part.pins[1] == "INT4"
    chip.write(0x12, b"\x40")  # advanced power saving: the BMG160 die has it
    assert chip.power_mode == POWER_SAVE


# ------------------------------------------------------------------------- self-test


@pytest.mark.parametrize("part", ["bmi088_gyro", "bmi055_gyro", "bmx055_gyro"])
def test_self_test_sets_bist_rdy_and_reports_pass_or_fail(part):
    chip = make_chip(part, noise=False)
    assert chip.read(0x3C)[0] == 0x10  # rate_ok (DS 4.6.2: bit 4)
    chip.write(0x3C, b"\x01")  # trig_bist
    chip.advance(0.010)
    assert chip.read(0x3C)[0] == 0x12  # bist_rdy, bist_fail 0
    chip.inject_bist_failure = True
    chip.write(0x3C, b"\x01")
    chip.advance(0.010)
    assert chip.read(0x3C)[0] == 0x16  # bist_fail (bit 2)
