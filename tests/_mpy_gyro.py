"""A BMG160-family gyro driver written the MicroPython way (ours, for the tests): it takes a
``machine.I2C``, keeps one preallocated buffer, reads with ``readfrom_mem_into`` and waits
with ``time.sleep_ms``. Registers: spec 4.1, 4.2, 4.8, 4.9, 4.12; start-up 30 ms (6.6)."""

import time

import machine
import ustruct
from micropython import const

_CHIP_ID = const(0x00)
_RATE_X_LSB = const(0x02)
_RANGE = const(0x0F)
_BW = const(0x10)
_SOFTRESET = const(0x14)
_FULL_SCALE = (2000, 1000, 500, 250, 125)  # deg/s per RANGE code


class Gyro:
    def __init__(self, i2c, address=0x68):
        if not isinstance(i2c, (machine.I2C, machine.SoftI2C)):
            raise TypeError("i2c must be a machine.I2C")
        self.i2c = i2c
        self.address = address
        self._buf = bytearray(6)
        if self.i2c.readfrom_mem(address, _CHIP_ID, 1)[0] != 0x0F:
            raise OSError(f"no BMG160 at 0x{address:02x}")
        self.i2c.writeto_mem(address, _SOFTRESET, b"\xb6")
        time.sleep_ms(30)
        self._range = 0

    def configure(self, range_code, bw_code):
        self.i2c.writeto_mem(self.address, _RANGE, bytes([range_code]))
        self.i2c.writeto_mem(self.address, _BW, bytes([bw_code]))
        self._range = range_code

    def rates(self):
        self.i2c.readfrom_mem_into(self.address, _RATE_X_LSB, self._buf)
        scale = _FULL_SCALE[self._range] / 32768
        return tuple(v * scale for v in ustruct.unpack("<hhh", self._buf))
