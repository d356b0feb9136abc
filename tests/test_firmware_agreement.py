"""Driver-level behaviours the firmware implements, run against the Python model and the firmware.

Every test here runs twice through FakeSMBus: once with ``BMG160`` and once with the
ATmega328P firmware in simavr (``SimulatedFirmwareChip``). Expectations come from the register
table (``bmg160_emu.device.registers``) and the spec, never from one backend's output, so the two
backends must agree on every behaviour listed in docs/firmware.md.
"""

from __future__ import annotations

import itertools
import struct

import pytest
from _firmware_backends import require_firmware_build

from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import RESET_VALUES, WRITE_MASKS

pytestmark = pytest.mark.firmware

ADDRESS = 0x68
RANGE, BW, LPM1, LPM2, RATE_HBW, SOFTRESET = 0x0F, 0x10, 0x11, 0x12, 0x13, 0x14
INT_STATUS_1, FIFO_STATUS, INT_EN_0, FIFO_WM_EN, BIST = 0x0A, 0x0E, 0x15, 0x1E, 0x3C
FIFO_CONFIG_0, FIFO_CONFIG_1, FIFO_DATA = 0x3D, 0x3E, 0x3F
BW_200HZ = 0x04  # 200 Hz ODR, 23 Hz filter (spec 5.3)
BW_100HZ = 0x05
# Registers whose content follows the data path or time, checked by their own tests.
LIVE = {0x02, 0x03, 0x04, 0x05, 0x06, 0x07, 0x08, INT_STATUS_1, FIFO_STATUS, FIFO_DATA}
# Behaviours the firmware does not implement (docs/firmware.md): fast offset compensation
# (0x32 bit 3) and NVM programming (0x33 bit 1).
NOT_ON_FIRMWARE = {0x32, 0x33}


@pytest.fixture(scope="module")
def firmware_build():
    return require_firmware_build(profile="paper", seed=11)


@pytest.fixture(params=["model", "firmware"])
def chip(request):
    if request.param == "model":
        yield BMG160(seed=5)
        return
    from bmg160_emu.firmware.simulated import SimulatedFirmwareChip

    firmware = SimulatedFirmwareChip(request.getfixturevalue("firmware_build"))
    yield firmware
    firmware.close()


@pytest.fixture
def bus(chip):
    with FakeSMBus(1, devices={ADDRESS: chip}) as smbus:
        yield smbus


def rates(bus) -> tuple[int, int, int]:
    return struct.unpack("<3h", bytes(bus.read_i2c_block_data(ADDRESS, 0x02, 6)))


def rate_ok(bus) -> bool:
    return bool(bus.read_byte_data(ADDRESS, BIST) & 0x10)


def test_chip_id_reads_0x0f(bus):
    assert bus.read_byte_data(ADDRESS, 0x00) == 0x0F


def test_registers_read_their_reset_values(bus):
    for reg in range(0x40):
        if reg not in LIVE:
            assert bus.read_byte_data(ADDRESS, reg) == RESET_VALUES[reg], hex(reg)


@pytest.mark.parametrize("value", [0xFF, 0x00, 0xA5, 0x5A])
def test_writable_bits_read_back_as_written_and_others_keep_their_value(bus, value):
    skip = LIVE | NOT_ON_FIRMWARE | {0x00, LPM1, LPM2, SOFTRESET, BIST}
    for reg in range(0x40):
        if reg in skip:
            continue
        before = bus.read_byte_data(ADDRESS, reg)
        bus.write_byte_data(ADDRESS, reg, value)
        mask = WRITE_MASKS[reg]
        expected = (before & ~mask & 0xFF) | (value & mask)
        if reg == 0x21:
            expected &= 0x3F  # reset_int and offset_reset are triggers that read 0
        assert bus.read_byte_data(ADDRESS, reg) == expected, hex(reg)


def test_bw_bit7_always_reads_one(bus):
    bus.write_byte_data(ADDRESS, BW, 0x04)
    assert bus.read_byte_data(ADDRESS, BW) == 0x84
    bus.write_byte_data(ADDRESS, BW, 0x07)
    assert bus.read_byte_data(ADDRESS, BW) == 0x87


def test_burst_read_auto_increments_like_single_reads(bus):
    bus.write_byte_data(ADDRESS, RANGE, 0x83)
    bus.write_byte_data(ADDRESS, 0x1B, 0x35)
    singles = [bus.read_byte_data(ADDRESS, reg) for reg in range(0x0F, 0x1D)]
    assert bus.read_i2c_block_data(ADDRESS, 0x0F, 14) == singles


def test_burst_write_auto_increments(bus):
    bus.write_i2c_block_data(ADDRESS, 0x17, [0x0A, 0x81, 0x08])
    assert [bus.read_byte_data(ADDRESS, r) for r in (0x17, 0x18, 0x19)] == [0x0A, 0x81, 0x08]


def test_split_read_uses_the_pointer_of_the_previous_write(bus):
    bus.write_byte_data(ADDRESS, 0x1B, 0x22)
    bus.write_byte(ADDRESS, 0x1B)  # address-only write, then STOP
    assert bus.read_byte(ADDRESS) == 0x22
    assert bus.read_byte(ADDRESS) == RESET_VALUES[0x1C]  # the pointer moved on


def test_addresses_outside_the_map_read_zero_and_ignore_writes(bus):
    bus.write_byte_data(ADDRESS, 0x45, 0x55)
    assert bus.read_byte_data(ADDRESS, 0x45) == 0
    assert bus.read_i2c_block_data(ADDRESS, 0x7E, 4) == [0, 0, 0, 0]


def test_bit_7_of_the_register_byte_is_not_decoded(bus):
    # spec 2.4's choice (docs/unconfirmed-choices.md): 0x80..0xFF reach 0x00..0x7F, as
    # Zephyr's bmi08x driver reads them (reg | BIT(7))
    assert bus.read_byte_data(ADDRESS, 0x80) == 0x0F
    bus.write_byte_data(ADDRESS, 0x80 | RANGE, 0x02)
    assert bus.read_byte_data(ADDRESS, RANGE) == 0x02
    assert bus.read_i2c_block_data(ADDRESS, 0x80 | 0x1B, 2) == list(RESET_VALUES[0x1B:0x1D])
    # a transaction starts at the decoded address; the burst itself does not wrap
    assert bus.read_i2c_block_data(ADDRESS, 0xFE, 4) == [0, 0, 0, 0]


def test_a_read_from_a_pointer_a_burst_left_past_0x7f_starts_at_the_decoded_address(bus):
    bus.write_byte(ADDRESS, 0x70)  # the pointer, then single-byte reads walk it on
    assert [bus.read_byte(ADDRESS) for _ in range(0x10)] == [0] * 0x10  # 0x70..0x7F
    assert bus.read_byte(ADDRESS) == 0x0F  # pointer 0x80: CHIP_ID


def test_soft_reset_restores_reset_values(bus, chip):
    for reg, value in ((RANGE, 0x03), (BW, 0x05), (RATE_HBW, 0xC0), (0x16, 0x00), (0x1B, 0x7F)):
        bus.write_byte_data(ADDRESS, reg, value)
    bus.write_byte_data(ADDRESS, SOFTRESET, 0xB5)  # not the key: nothing happens
    assert bus.read_byte_data(ADDRESS, RANGE) == 0x03
    bus.write_byte_data(ADDRESS, SOFTRESET, 0xB6)
    for reg in range(0x40):
        if reg not in LIVE | {BIST}:
            assert bus.read_byte_data(ADDRESS, reg) == RESET_VALUES[reg], hex(reg)


def test_data_path_restarts_one_startup_time_after_soft_reset(bus, chip):
    bus.write_byte_data(ADDRESS, SOFTRESET, 0xB6)
    chip.advance(0.025)
    assert not rate_ok(bus)
    chip.advance(0.010)  # 35 ms after the reset: past the 30 ms start-up time (spec 6.6)
    assert rate_ok(bus)


def test_suspend_freezes_the_rate_registers_and_ignores_other_writes(bus, chip):
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    bus.write_byte_data(ADDRESS, RANGE, 0x04)  # +-125 deg/s: the noise moves every sample
    chip.advance(0.02)
    bus.write_byte_data(ADDRESS, LPM1, 0x80)
    frozen = rates(bus)
    chip.advance(0.1)
    assert rates(bus) == frozen
    bus.write_byte_data(ADDRESS, RANGE, 0x01)  # ignored in suspend (spec 6.7)
    assert bus.read_byte_data(ADDRESS, RANGE) == 0x04
    assert not rate_ok(bus)
    bus.write_byte_data(ADDRESS, LPM1, 0x00)
    chip.advance(0.025)
    assert rates(bus) == frozen  # still waking up: 30 ms
    chip.advance(0.030)
    assert rates(bus) != frozen and rate_ok(bus)


def test_fast_power_up_wakes_after_10_ms(bus, chip):
    bus.write_byte_data(ADDRESS, LPM2, 0x80)
    bus.write_byte_data(ADDRESS, LPM1, 0x80)  # suspend + fast_power_up
    chip.advance(0.05)
    bus.write_byte_data(ADDRESS, LPM1, 0x00)
    chip.advance(0.006)
    assert not rate_ok(bus)
    chip.advance(0.008)
    assert rate_ok(bus)


def test_deep_suspend_accepts_only_lpm1_and_softreset_and_leaving_it_resets(bus, chip):
    bus.write_byte_data(ADDRESS, 0x1B, 0x11)
    bus.write_byte_data(ADDRESS, LPM1, 0x20)
    bus.write_byte_data(ADDRESS, LPM2, 0x40)  # ignored in deep suspend
    bus.write_byte_data(ADDRESS, RANGE, 0x02)  # ignored
    assert bus.read_byte_data(ADDRESS, LPM2) == 0x00
    assert bus.read_byte_data(ADDRESS, RANGE) == 0x00
    assert bus.read_byte_data(ADDRESS, 0x1B) == 0x11
    bus.write_byte_data(ADDRESS, LPM1, 0x00)  # leaving deep suspend is a reset (spec 6.7)
    assert bus.read_byte_data(ADDRESS, 0x1B) == RESET_VALUES[0x1B]
    chip.advance(0.035)
    assert rate_ok(bus)


def test_new_data_status_is_a_short_pulse_after_each_sample(bus, chip):
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    chip.advance(0.05)
    assert not any(_poll_data_int(bus, chip)[1] for _ in range(100))  # data_en = 0
    bus.write_byte_data(ADDRESS, INT_EN_0, 0x80)
    start = chip.time
    hits = [t for t, seen in (_poll_data_int(bus, chip) for _ in range(400)) if seen]
    periods = (chip.time - start) / 0.005
    clusters = [[hits[0]]]
    for t in hits[1:]:
        if t - clusters[-1][-1] < 0.001:
            clusters[-1].append(t)
        else:
            clusters.append([t])
    # A 300 us pulse (spec 6.3) after each 5 ms period: the polls that see one pulse span
    # less than the pulse plus a poll's own duration, pulses are one period apart, and
    # polls every 100..500 us (a poll is one or two bus transactions on the firmware) see
    # at least 40 % of the pulses.
    assert all(c[-1] - c[0] < 0.0005 for c in clusters)
    assert all(0.004 < b[0] - a[0] < 0.006 or b[0] - a[0] > 0.009
               for a, b in itertools.pairwise(clusters))  # fmt: skip
    assert 0.4 * periods <= len(clusters) <= periods + 1


def _poll_data_int(bus, chip) -> tuple[float, bool]:
    chip.advance(0.0001)
    seen = bool(bus.read_byte_data(ADDRESS, INT_STATUS_1) & 0x80)
    return chip.time, seen


def test_msb_read_after_new_samples_returns_the_msb_latched_by_the_lsb_read(bus, chip):
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    bus.write_byte_data(ADDRESS, RANGE, 0x04)  # 262 LSB per deg/s: MSB often changes
    changed = 0
    for _ in range(12):
        chip.advance(0.01)
        bus.read_byte_data(ADDRESS, 0x02)
        latched = chip.peek(0x03)
        chip.advance(0.05)  # ten new samples
        assert bus.read_byte_data(ADDRESS, 0x03) == latched
        changed += bus.read_byte_data(ADDRESS, 0x03) != latched  # no lock: current sample
    assert changed > 0  # the check above could have failed


def test_with_shadowing_disabled_the_msb_follows_the_current_sample(bus, chip):
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    bus.write_byte_data(ADDRESS, RANGE, 0x04)
    bus.write_byte_data(ADDRESS, RATE_HBW, 0x40)
    for _ in range(5):
        bus.read_byte_data(ADDRESS, 0x02)
        chip.advance(0.05)
        assert bus.read_byte_data(ADDRESS, 0x03) == bus.read_i2c_block_data(ADDRESS, 0x02, 2)[1]


def _fifo_setup(bus, chip, config1: int, config0: int = 0x00, seconds: float = 0.1) -> int:
    """Configure the FIFO at 200 Hz, collect for ``seconds``, then suspend (no new frames)."""
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    bus.write_byte_data(ADDRESS, FIFO_CONFIG_0, config0)
    bus.write_byte_data(ADDRESS, FIFO_CONFIG_1, config1)
    chip.advance(seconds)
    bus.write_byte_data(ADDRESS, LPM1, 0x80)
    return bus.read_byte_data(ADDRESS, FIFO_STATUS)


def test_fifo_mode_collects_one_frame_per_period_then_stops_with_overrun(bus, chip):
    status = _fifo_setup(bus, chip, 0x40, seconds=0.1)
    assert 19 <= status <= 21  # 0.1 s at 200 Hz, +-1 for the phase of the first sample
    bus.write_byte_data(ADDRESS, LPM1, 0x00)
    chip.advance(0.6)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == 0x80 | 100
    bus.write_byte_data(ADDRESS, FIFO_CONFIG_1, 0x40)  # a write empties it, clears overrun
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) & 0x80 == 0


def test_stream_mode_keeps_the_newest_100_frames_and_flags_overrun(bus, chip):
    status = _fifo_setup(bus, chip, 0x80, seconds=0.7)
    assert status == 0x80 | 100


def test_bypass_mode_holds_only_the_newest_frame(bus, chip):
    status = _fifo_setup(bus, chip, 0x00, seconds=0.1)
    assert status == 1
    frame = bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 6)
    assert frame == bus.read_i2c_block_data(ADDRESS, 0x02, 6)  # the newest sample
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == 0


def test_reading_past_the_last_frame_gives_the_empty_pattern(bus, chip):
    count = _fifo_setup(bus, chip, 0x40, seconds=0.03)
    assert count > 0
    for _ in range(count):
        assert bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 6) != [0x00, 0x80] * 3
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == 0
    assert bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 12) == [0x00, 0x80] * 6


def test_burst_into_fifo_data_stays_there(bus, chip):
    count = _fifo_setup(bus, chip, 0x40, seconds=0.05)
    data = bus.read_i2c_block_data(ADDRESS, FIFO_CONFIG_1, 7)
    assert data[0] == 0x40
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count - 1  # one frame of 6 bytes
    bus.read_byte(ADDRESS)  # the pointer is still at FIFO_DATA
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count - 1  # a partial frame


def test_a_partial_frame_is_finished_by_the_next_read(bus, chip):
    count = _fifo_setup(bus, chip, 0x40, seconds=0.05)
    first = bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 4)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count
    rest = bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 2)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count - 1
    assert len(first + rest) == 6


def test_single_axis_frames_are_2_bytes_and_tagged_frames_8(bus, chip):
    count = _fifo_setup(bus, chip, 0x41, seconds=0.05)  # FIFO mode, X only
    bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 2)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count - 1
    bus.write_byte_data(ADDRESS, LPM1, 0x00)
    count = _fifo_setup(bus, chip, 0x40, config0=0x80, seconds=0.05)  # XYZ with tag
    bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 6)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count
    tag = bus.read_i2c_block_data(ADDRESS, FIFO_DATA, 2)
    assert tag == [0x00, 0x00]  # no interrupt pin active
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) == count - 1


def test_fifo_watermark_sets_fifo_int_when_enabled(bus, chip):
    bus.write_byte_data(ADDRESS, INT_EN_0, 0x40)
    bus.write_byte_data(ADDRESS, FIFO_WM_EN, 0x80)
    count = _fifo_setup(bus, chip, 0x40, config0=10, seconds=0.03)
    assert count < 10 and not bus.read_byte_data(ADDRESS, INT_STATUS_1) & 0x10
    bus.write_byte_data(ADDRESS, LPM1, 0x00)
    chip.advance(0.1)
    assert bus.read_byte_data(ADDRESS, FIFO_STATUS) >= 10
    assert bus.read_byte_data(ADDRESS, INT_STATUS_1) & 0x10


def test_range_code_scales_the_rate_counts(bus, chip):
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    spreads = []
    for code in (0x00, 0x04):  # +-2000 and +-125 deg/s: 16 times the sensitivity (spec 5.1)
        bus.write_byte_data(ADDRESS, RANGE, code)
        chip.advance(0.01)
        xs = []
        for _ in range(300):
            chip.advance(0.005)
            xs.append(rates(bus)[0])
        mean = sum(xs) / len(xs)
        spreads.append((sum((x - mean) ** 2 for x in xs) / (len(xs) - 1)) ** 0.5)
    # 300 samples: the std estimate has 4 % relative error (1/sqrt(2n)); 25 % is > 5 sigma
    # of the ratio, and quantization at +-2000 deg/s (0.06 deg/s per LSB) is well below it.
    assert 16 * 0.75 < spreads[1] / spreads[0] < 16 * 1.25


def test_no_frame_is_lost_while_a_long_fifo_burst_is_read(bus, chip):
    import smbus2

    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    bus.write_byte_data(ADDRESS, FIFO_CONFIG_1, 0x40)
    start = chip.time
    chip.advance(0.4)
    stored = bus.read_byte_data(ADDRESS, FIFO_STATUS)
    # One transaction: every stored frame, then 50 frames' worth of empty pattern. On the
    # firmware at 400 kHz (9 SCL periods plus the interrupt's clock stretching per byte) it
    # spans several output periods, whose samples must all reach the FIFO when it ends.
    length = 6 * (stored + 50)
    write, read = smbus2.i2c_msg.write(ADDRESS, [FIFO_DATA]), smbus2.i2c_msg.read(ADDRESS, length)
    bus.i2c_rdwr(write, read)
    data = list(read)
    frames = [data[i : i + 6] for i in range(0, length, 6)]
    assert [0x00, 0x80] * 3 not in frames[:stored]
    assert frames[stored:] == [[0x00, 0x80] * 3] * 50
    chip.advance(0.1)
    total = stored + (bus.read_byte_data(ADDRESS, FIFO_STATUS) & 0x7F)
    # every output period since the FIFO was configured left one frame (+-1 for the phase
    # of the first sample and for the period in progress)
    assert abs(total - (chip.time - start) * 200) <= 1.5, (total, chip.time - start)


def test_temp_reads_zero_at_23_degrees(bus, chip):
    # spec 4.3 / 5.2: signed, 0.5 K per LSB, 0 <-> 23 degC; both backends sit at 23 degC
    chip.advance(0.05)
    assert bus.read_byte_data(ADDRESS, 0x08) == 0x00


def _offset_registers(x: int, y: int, z: int) -> dict[int, int]:
    """OFC1..OFC4 and TRIM_GP0 for 12-bit offsets (spec 4.24), gp0 bits left at 0."""
    x, y, z = (v & 0xFFF for v in (x, y, z))
    return {
        0x36: (x >> 2 & 0x3) << 6 | (y >> 1 & 0x7) << 3 | (z >> 1 & 0x7),
        0x37: x >> 4, 0x38: y >> 4, 0x39: z >> 4,
        0x3A: (x & 0x3) << 2 | (y & 0x1) << 1 | (z & 0x1),
    }


def _mean_rates(bus, chip, samples: int = 40) -> list[float]:
    sums = [0.0, 0.0, 0.0]
    for _ in range(samples):
        chip.advance(0.005)
        for axis, value in enumerate(rates(bus)):
            sums[axis] += value
    return [s / samples for s in sums]


def test_offset_registers_shift_the_output_and_offset_reset_clears_them(bus, chip):
    # spec 6.9: the 12-bit offset is added before range scaling; 1 offset LSB is one LSB of
    # the +-2000 deg/s range (16.4 or 16.384 per deg/s: 0.1 % apart, far inside the bound)
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)  # RANGE stays 0: +-2000 deg/s
    chip.advance(0.05)
    before = _mean_rates(bus, chip)
    offsets = (400, -300, 1000)
    for reg, value in _offset_registers(*offsets).items():
        bus.write_byte_data(ADDRESS, reg, value)
    chip.advance(0.01)
    shifted = _mean_rates(bus, chip)
    # 40 samples of noise with std 0.25 deg/s (4 LSB): each mean is within about 0.7 LSB,
    # and the bias drifts far less in 0.4 s; 8 LSB is over 5 sigma of the difference.
    for axis in range(3):
        assert abs(shifted[axis] - before[axis] - offsets[axis]) < 8, (axis, before, shifted)
    bus.write_byte_data(ADDRESS, 0x21, 0x40)  # offset_reset (spec 4.19)
    assert [bus.read_byte_data(ADDRESS, r) for r in range(0x36, 0x3B)] == [0] * 5
    chip.advance(0.01)
    after = _mean_rates(bus, chip)
    for axis in range(3):
        assert abs(after[axis] - before[axis]) < 8, (axis, before, after)


def test_self_test_reports_ready_and_passed_within_the_10_ms_drivers_wait(bus, chip):
    # spec 4.25 / 6.8: trig_bist starts the test and reads 0; bist_rdy comes up (the
    # emulators take 5 ms, under the 10 ms BAPI waits) with bist_fail = 0; rate_ok stays 1
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    chip.advance(0.05)
    bus.write_byte_data(ADDRESS, BIST, 0x01)
    assert bus.read_byte_data(ADDRESS, BIST) & 0x07 == 0x00  # running: not ready, trig reads 0
    chip.advance(0.010)
    status = bus.read_byte_data(ADDRESS, BIST)
    assert status & 0x02 and not status & 0x04 and status & 0x10, hex(status)


def test_nvm_load_brings_back_the_nvm_offsets(bus, chip):
    # spec 4.22 / 4.24: the offsets are NVM-backed; nvm_load reloads them from the NVM image,
    # which both backends keep at its factory content, all zero (nothing was programmed)
    for reg, value in _offset_registers(400, -300, 1000).items():
        bus.write_byte_data(ADDRESS, reg, value)
    bus.write_byte_data(ADDRESS, 0x33, 0x08)
    chip.advance(0.001)
    assert [bus.read_byte_data(ADDRESS, r) for r in range(0x36, 0x3B)] == [0] * 5


def test_peek_and_dump_of_bist_equal_what_a_read_returns(bus, chip):
    # the firmware computes BIST on each read, so its RAM copy (0x10) was stale: after a
    # self-test a read gives 0x12 and in suspend 0x02, and the side-effect-free views must too
    bus.write_byte_data(ADDRESS, BW, BW_200HZ)
    chip.advance(0.05)
    assert chip.peek(BIST) == chip.dump()[BIST] == bus.read_byte_data(ADDRESS, BIST) == 0x10
    bus.write_byte_data(ADDRESS, BIST, 0x01)
    chip.advance(0.010)
    assert chip.peek(BIST) == chip.dump()[BIST] == bus.read_byte_data(ADDRESS, BIST) == 0x12
    bus.write_byte_data(ADDRESS, LPM1, 0x80)  # suspend: no sampling, rate_ok drops
    chip.advance(0.010)
    assert chip.peek(BIST) == chip.dump()[BIST] == bus.read_byte_data(ADDRESS, BIST) == 0x02
