"""The chip driven the way real drivers drive it (spec section 7)."""

import struct
import time

from bmg160_emu.clock import virtual_sleep
from bmg160_emu.device.chip import BMG160


def test_linux_style_init_sequence_then_burst_reads():
    chip = BMG160(seed=4, true_rate=(12.0, -4.0, 0.5))
    with virtual_sleep(chip):
        assert chip.read(0x00) == b"\x0f"
        chip.write(0x14, b"\xb6")
        time.sleep(0.030)
        assert chip.read(0x00) == b"\x0f"
        chip.write(0x11, b"\x00")  # normal mode
        time.sleep(0.001)
        chip.write(0x10, b"\x04")  # 200 Hz / 23 Hz
        chip.write(0x0F, b"\x03")  # +-250 deg/s
        time.sleep(0.5)  # let the filter settle
        total = [0.0, 0.0, 0.0]
        for _ in range(200):
            time.sleep(0.005)
            x, y, z = struct.unpack("<3h", chip.read(0x02, 6))
            total = [total[0] + x, total[1] + y, total[2] + z]
    mean = [v / 200 / chip.sensitivity for v in total]
    # noise ~0.25 deg/s per sample at 200 Hz; mean of 200 within 0.05, bias 0.116 deg/s
    assert abs(mean[0] - 12.0) < 0.4 and abs(mean[1] + 4.0) < 0.4 and abs(mean[2] - 0.5) < 0.4


def test_bosch_api_style_read_modify_write_and_status_polling():
    chip = BMG160(seed=4, hold_data_int=False)
    chip.write(0x11, bytes([chip.read(0x11)[0] & ~0xA0 & 0xFF]))
    chip.write(0x10, bytes([(chip.read(0x10)[0] & ~0x07) | 0x02]))
    chip.write(0x15, b"\x80")
    assert chip.read(0x10) == b"\x82"
    seen = 0
    for _ in range(50):
        chip.advance(0.0001)
        if chip.read(0x0A)[0] & 0x80:
            seen += 1
            chip.read(0x02, 6)
    # 1000 Hz for 5 ms: 5 new samples, each seen by one poll in its 300 us pulse window
    assert seen >= 5


def test_fifo_driver_drains_in_fifo_mode_like_px4():
    chip = BMG160(seed=4)
    chip.write(0x10, b"\x02")  # 1000 Hz
    chip.write(0x3E, b"\x40")  # FIFO mode, XYZ
    for _ in range(10):
        chip.advance(0.004)
        count = chip.read(0x0E)[0] & 0x7F
        data = chip.read(0x3F, count * 6)
        assert len(data) == count * 6 and chip.read(0x0E)[0] == 0
        words = struct.unpack(f"<{3 * count}h", data)
        assert -32768 not in words


def test_single_byte_reads_per_register_get_matching_pairs():
    chip = BMG160(seed=4, true_rate=lambda t: (1000 * t, 0, 0))
    for _ in range(100):
        chip.advance(0.0005)
        word = chip.peek(0x02) | chip.peek(0x03) << 8
        lsb = chip.read(0x02)[0]
        chip.advance(0.0005)  # a new sample between the two transactions
        assert lsb | chip.read(0x03)[0] << 8 == word
