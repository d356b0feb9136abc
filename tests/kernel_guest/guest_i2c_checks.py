"""Runs INSIDE the guest: i2c-dev checks that need one process (tests/test_kernel_virtio_i2c.py).

Usage: python guest_i2c_checks.py BUS ADDRESS GPIO_VALUE_FILE. Prints one JSON object:
the FIFO drained over /dev/i2c-BUS (its frame count before and after a 60-frame read) and
a latched FIFO interrupt status with its INT1 line (read through the GPIO controller's
sysfs value file): set while latched, left set by reads, cleared by reset_int.
"""

from __future__ import annotations

import json
import sys
import time

from smbus2 import SMBus, i2c_msg

FIFO_STATUS, INT_STATUS_1, FIFO_DATA = 0x0E, 0x0A, 0x3F
BW, INT_EN_0, INT_MAP_1, INT_RST_LATCH, BGW_SOFTRESET, FIFO_CONFIG_1 = (
    0x10, 0x15, 0x18, 0x21, 0x14, 0x3E)


def main() -> int:
    bus_number, address, gpio_value = int(sys.argv[1]), int(sys.argv[2], 0), sys.argv[3]
    out: dict = {}
    with SMBus(bus_number, force=True) as bus:

        def read(register: int, length: int = 1) -> bytes:
            write, get = i2c_msg.write(address, [register]), i2c_msg.read(address, length)
            bus.i2c_rdwr(write, get)
            return bytes(get)

        def line() -> int:
            with open(gpio_value) as handle:
                return int(handle.read())

        bus.write_byte_data(address, BW, 0x07)  # ODR 100 Hz
        bus.write_byte_data(address, INT_RST_LATCH, 0x8F)  # latched, reset_int
        bus.write_byte_data(address, INT_MAP_1, 0x04)  # int1_fifo
        bus.write_byte_data(address, INT_EN_0, 0x40)  # fifo_en
        bus.write_byte_data(address, FIFO_CONFIG_1, 0x40)  # FIFO mode (stop when full), XYZ
        out["line_before"] = line()
        time.sleep(1.3)  # 100 frames at 100 Hz fill it
        out["count_full"] = read(FIFO_STATUS)[0] & 0x7F
        out["status_full"] = read(INT_STATUS_1)[0]
        out["line_full"] = line()
        frames = read(FIFO_DATA, 6 * 60)
        out["count_after_60"] = read(FIFO_STATUS)[0] & 0x7F
        out["distinct_frames"] = len({frames[i:i + 6] for i in range(0, len(frames), 6)})
        out["status_after_drain"] = read(INT_STATUS_1)[0]
        out["status_read_again"] = read(INT_STATUS_1)[0]
        out["line_after_drain"] = line()
        bus.write_byte_data(address, FIFO_CONFIG_1, 0x00)  # bypass: empties it, not full
        out["status_bypass"] = read(INT_STATUS_1)[0]
        bus.write_byte_data(address, INT_RST_LATCH, 0x8F)
        out["status_after_reset_int"] = read(INT_STATUS_1)[0]
        out["line_after_reset_int"] = line()
        bus.write_byte_data(address, BGW_SOFTRESET, 0xB6)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
