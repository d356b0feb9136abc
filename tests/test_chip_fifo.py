"""The FIFO (spec 6.5): modes, frames, watermark, counter, overrun, empty pattern, clearing."""

import struct

import pytest
from _chip_helpers import period_s, quiet_chip


def _ramp_chip(**kwargs):
    # X counts equal the sample index at range 2000: easy to check order
    chip = quiet_chip(**kwargs)
    chip.write(0x10, b"\x04")  # 200 Hz
    chip.write(0x13, b"\x80")  # unfiltered data: the ramp passes without filter lag
    s, odr = chip.sensitivity, chip.odr_hz
    chip.set_true_rate(lambda t: (round(t * odr) / s, -round(t * odr) / s, 1.0))
    return chip


def _frames(data, size=6):
    return [struct.unpack("<3h", data[i:i + 6]) for i in range(0, len(data), size)]


def test_fifo_mode_stores_frames_in_order_and_drains():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(10 * period_s(chip))
    assert chip.read(0x0E)[0] == 10
    frames = _frames(chip.read(0x3F, 60))
    xs = [f[0] for f in frames]
    assert xs == list(range(xs[0], xs[0] + 10)) and all(f[1] == -f[0] for f in frames)
    assert chip.read(0x0E)[0] == 0
    assert chip.read(0x3F, 6) == b"\x00\x80" * 3


def test_fifo_mode_stops_at_100_frames_and_sets_overrun():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(150 * period_s(chip))
    status = chip.read(0x0E)[0]
    assert status == 0x80 | 100
    first = _frames(chip.read(0x3F, 6))[0][0]
    assert first == _frames(chip.read(0x3F, 6))[0][0] - 1
    # the oldest frames are kept: the first is 150 samples older than now
    assert struct.unpack("<h", chip.read(0x02, 2))[0] - first == 149


def test_stream_mode_keeps_the_newest_100_frames():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x80")
    chip.advance(150 * period_s(chip))
    assert chip.read(0x0E)[0] == 0x80 | 100
    frames = _frames(chip.read(0x3F, 600))
    newest = struct.unpack("<h", chip.read(0x02, 2))[0]
    assert [f[0] for f in frames] == list(range(newest - 99, newest + 1))


@pytest.mark.parametrize("mode", [0x40, 0x80])
def test_one_long_advance_fills_the_fifo_as_many_short_ones(mode):
    a, b = _ramp_chip(), _ramp_chip()
    for chip in (a, b):
        chip.write(0x3E, bytes([mode]))
    a.advance(130 * period_s(a))
    for _ in range(130):
        b.advance(period_s(b))
    assert a.dump() == b.dump()
    assert a.read(0x3F, 600) == b.read(0x3F, 600)


def test_bypass_holds_only_the_newest_sample_and_reading_consumes_it():
    chip = _ramp_chip()
    chip.advance(5 * period_s(chip))
    assert chip.read(0x0E)[0] == 1
    assert chip.read(0x3F, 6) == chip.read(0x02, 6)
    assert chip.read(0x0E)[0] == 0
    assert chip.read(0x3F, 6) == b"\x00\x80" * 3
    chip.advance(period_s(chip))
    assert chip.read(0x3F, 6) == chip.read(0x02, 6)


@pytest.mark.parametrize("select, axis", [(1, 0), (2, 1), (3, 2)])
def test_single_axis_frames_are_two_bytes(select, axis):
    chip = _ramp_chip()
    chip.write(0x3E, bytes([0x40 | select]))
    chip.advance(3 * period_s(chip))
    data = chip.read(0x3F, 6)
    values = struct.unpack("<3h", data)
    current = struct.unpack("<3h", chip.read(0x02, 6))[axis]
    assert values[-1] == current and chip.read(0x0E)[0] == 0


def test_tag_adds_two_interrupt_bytes_per_frame():
    chip = _ramp_chip()
    chip.write(0x3D, b"\x80")
    chip.write(0x3E, b"\x40")
    chip.advance(2 * period_s(chip))
    data = chip.read(0x3F, 16)
    assert chip.read(0x0E)[0] == 0 and data[6:8] in (b"\x00\x00", b"\x01\x00", b"\x00\x01",
                                                        b"\x01\x01")
    assert struct.unpack("<h", data[8:10])[0] == struct.unpack("<h", data[0:2])[0] + 1


def test_partial_frame_read_continues_in_the_next_transaction():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(2 * period_s(chip))
    whole = chip.peek(0x3F)
    part1 = chip.read(0x3F, 4)
    assert part1[0] == whole and chip.read(0x0E)[0] == 2
    part2 = chip.read(0x3F, 2)
    assert chip.read(0x0E)[0] == 1 and len(part1 + part2) == 6


def test_write_to_fifo_config_0_empties_the_fifo_but_keeps_overrun():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(120 * period_s(chip))
    chip.write(0x3D, b"\x0a")
    assert chip.read(0x0E)[0] == 0x80


def test_write_to_fifo_config_1_empties_the_fifo_and_clears_overrun():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(120 * period_s(chip))
    chip.write(0x3E, b"\x40")
    assert chip.read(0x0E)[0] == 0


def test_reserved_mode_behaves_as_bypass():
    chip = _ramp_chip()
    chip.write(0x3E, b"\xc0")
    chip.advance(5 * period_s(chip))
    assert chip.read(0x0E)[0] == 1 and chip.read(0x3E) == b"\xc0"


def test_fifo_config_1_reserved_bits_read_back():
    chip = quiet_chip()
    chip.write(0x3E, b"\x4c")
    assert chip.read(0x3E) == b"\x4c"


def test_no_frames_are_added_in_suspend_but_stored_frames_stay_readable():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(5 * period_s(chip))
    chip.write(0x11, b"\x80")
    chip.advance(1.0)
    assert chip.read(0x0E)[0] == 5
    assert chip.read(0x3F, 30)[-2:] != b"\x00\x80"


def test_watermark_interrupt_asserts_at_the_level_and_clears_below():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.write(0x3D, b"\x05")
    chip.write(0x1E, b"\x80")
    chip.write(0x15, b"\x40")
    chip.write(0x18, b"\x04")  # fifo -> INT1
    chip.advance(4 * period_s(chip))
    assert chip.read(0x0A)[0] & 0x10 == 0 and not chip.int1
    chip.advance(period_s(chip))
    assert chip.read(0x0A)[0] & 0x10 and chip.int1
    chip.read(0x3F, 6)
    assert chip.read(0x0A)[0] & 0x10 == 0


def test_fifo_interrupt_without_watermark_fires_when_full():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.write(0x15, b"\x40")
    chip.advance(99 * period_s(chip))
    assert chip.read(0x0A)[0] & 0x10 == 0
    chip.advance(period_s(chip))
    assert chip.read(0x0A)[0] & 0x10


def test_soft_reset_empties_the_fifo():
    chip = _ramp_chip()
    chip.write(0x3E, b"\x40")
    chip.advance(10 * period_s(chip))
    chip.write(0x14, b"\xb6")
    assert chip.read(0x0E)[0] == 0
