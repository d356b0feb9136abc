"""A BMG160 driver as flight software would write it: plain smbus2, nothing emulator-specific.

It reads the chip ID, soft-resets the chip, selects range and output data rate, puts the
FIFO in stream mode and drains it in bursts. Register addresses and encodings are those of
the BMG160 register map (docs: bmg160-registers.md sections 4.1, 4.7-4.9, 4.13, 4.26).
"""

from __future__ import annotations

import time

from smbus2 import SMBus

CHIP_ID, FIFO_STATUS, RANGE, BW, BGW_SOFTRESET, FIFO_CONFIG_1, FIFO_DATA = (
    0x00, 0x0E, 0x0F, 0x10, 0x14, 0x3E, 0x3F)
EXPECTED_CHIP_ID = 0x0F
SOFT_RESET = 0xB6
STARTUP_S = 0.030  # data sheet: 30 ms after a reset before the chip is used
RANGE_CODE = {2000: 0, 1000: 1, 500: 2, 250: 3, 125: 4}
BW_CODE = {2000: 1, 1000: 2, 400: 3, 200: 4, 100: 5}  # ODR -> BW code, narrowest filter
STREAM_XYZ = 0x80
FRAMES_PER_BURST = 5  # 30 bytes: an SMBus block transfer carries at most 32


class GyroError(RuntimeError):
    """The gyro is not there or not what we expect."""


class BMG160Driver:
    def __init__(self, bus: int = 1, address: int = 0x68, range_dps: int = 250,
                 odr_hz: int = 200) -> None:
        self.bus = SMBus(bus)
        self.address = address
        self.range_dps = range_dps
        self.odr_hz = odr_hz
        self.lsb_per_dps = 32768 / range_dps

    def init(self) -> None:
        chip_id = self.bus.read_byte_data(self.address, CHIP_ID)
        if chip_id != EXPECTED_CHIP_ID:
            raise GyroError(f"chip ID 0x{chip_id:02x}, expected 0x{EXPECTED_CHIP_ID:02x}")
        self.bus.write_byte_data(self.address, BGW_SOFTRESET, SOFT_RESET)
        time.sleep(STARTUP_S)
        self.bus.write_byte_data(self.address, RANGE, RANGE_CODE[self.range_dps])
        self.bus.write_byte_data(self.address, BW, BW_CODE[self.odr_hz])
        self.bus.write_byte_data(self.address, FIFO_CONFIG_1, STREAM_XYZ)

    def read_fifo_dps(self) -> list[tuple[float, float, float]]:
        """Every frame waiting in the FIFO, oldest first, in deg/s (sensor axes)."""
        frames = self.bus.read_byte_data(self.address, FIFO_STATUS) & 0x7F
        rates = []
        while frames:
            n = min(frames, FRAMES_PER_BURST)
            data = self.bus.read_i2c_block_data(self.address, FIFO_DATA, 6 * n)
            for i in range(n):
                words = [int.from_bytes(bytes(data[6 * i + 2 * a: 6 * i + 2 * a + 2]), "little",
                                        signed=True) for a in range(3)]
                rates.append(tuple(w / self.lsb_per_dps for w in words))
            frames -= n
        return rates

    def close(self) -> None:
        self.bus.close()
