"""A BMG160-family gyro driver written the CircuitPython way (ours, for the tests): an
``adafruit_bus_device`` I2CDevice on the ``busio.I2C`` it is given, properties, ``struct``.
Registers: spec 4.1, 4.2, 4.8, 4.9, 4.12; start-up 30 ms (6.6)."""

import struct
import time

from adafruit_bus_device.i2c_device import I2CDevice
from micropython import const

_CHIP_ID = const(0x00)
_RATE_X_LSB = const(0x02)
_RANGE = const(0x0F)
_BW = const(0x10)
_SOFTRESET = const(0x14)
_FULL_SCALE = (2000, 1000, 500, 250, 125)


class Gyro:
    def __init__(self, i2c, address=0x68):
        self._device = I2CDevice(i2c, address)
        self._buf = bytearray(6)
        if self._read(_CHIP_ID, 1)[0] != 0x0F:
            raise RuntimeError(f"no BMG160 at 0x{address:02x}")
        self._write(_SOFTRESET, 0xB6)
        time.sleep(0.030)
        self._range = 0

    def _write(self, register, value):
        with self._device as i2c:
            i2c.write(bytes([register, value]))

    def _read(self, register, count):
        out = bytearray(count)
        with self._device as i2c:
            i2c.write_then_readinto(bytes([register]), out)
        return out

    @property
    def range_code(self):
        return self._read(_RANGE, 1)[0] & 0x07

    @range_code.setter
    def range_code(self, code):
        self._write(_RANGE, code)
        self._range = code

    @property
    def bandwidth_code(self):
        return self._read(_BW, 1)[0] & 0x0F

    @bandwidth_code.setter
    def bandwidth_code(self, code):
        self._write(_BW, code)

    @property
    def rates(self):
        with self._device as i2c:
            i2c.write_then_readinto(bytes([_RATE_X_LSB]), self._buf)
        scale = _FULL_SCALE[self._range] / 32768
        return tuple(v * scale for v in struct.unpack("<hhh", self._buf))
