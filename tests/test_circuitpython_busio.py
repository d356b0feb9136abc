"""CircuitPython's busio/board/digitalio over the emulated bus: a public CircuitPython BMI088
driver's calls transcribed (through the real adafruit_bus_device), our own
CircuitPython-style driver, and CircuitPython's rules and errors.

The transcribed driver is a CircuitPython BMI088 driver for the Grove 6-axis board (MIT,
2023, "bmi088.py", on adafruit_bus_device), read, not copied: it builds an I2CDevice for
the accelerometer (0x19) and the gyroscope (0x69), each probing its address; resets the
accelerometer (0x7E <- 0xB6, 200 ms), powers it (ACC_PWR_CONF 0x7C <- 0x00, ACC_PWR_CTRL
0x7D <- 0x04), sets ACC_RANGE 0x41 <- 0x01 and ODR in ACC_CONF 0x40 by read-modify-write
(0x08 in bits 7:4); resets the gyroscope (0x14 <- 0xB6, 300 ms), writes LPM1 0x11 <- 0x00,
RANGE 0x0F <- 0x01 (+-1000 deg/s) and BANDWIDTH 0x10 <- 0x04 (200 Hz, 23 Hz filter),
10 ms after each gyro write; reads chip IDs as a write of the register then a read of one
byte, and the rates as write_then_readinto(0x02, 6 bytes), little-endian signed, times
1000/32768.
"""

from __future__ import annotations

import errno
import struct
import sys
import time

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.board import circuitpython_board
from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.clock import virtual_sleep
from bmg160_emu.device.parts import make_chip
from bmg160_emu.device.standin import StandinDevice
from bmg160_emu.io.standin_file import load_standin

TRUE_RATE_DPS = (20.0, -10.0, 5.0)
TOLERANCE_DPS = 1.5  # 23..32 Hz filter: ~0.2 deg/s rms per sample, > 5 sigma


def bmi088_as_transcribed(i2c) -> dict:
    from adafruit_bus_device.i2c_device import I2CDevice

    acc, gyro = I2CDevice(i2c, 0x19), I2CDevice(i2c, 0x69)

    def write(device, register, value, pause=0.0):
        with device as d:
            d.write(bytes([register, value]))
            time.sleep(pause)

    def read1(device, register):
        out = bytearray(1)
        with device as d:
            d.write(bytes([register]))
            d.readinto(out)
        return out[0]

    write(acc, 0x7E, 0xB6)
    time.sleep(0.2)
    write(acc, 0x7C, 0x00)
    write(acc, 0x7D, 0x04)
    write(acc, 0x41, 0x01)
    write(acc, 0x40, (read1(acc, 0x40) & 0x0F) | (0x08 << 4))
    write(gyro, 0x14, 0xB6, 0.01)
    time.sleep(0.3)
    for register, value in ((0x11, 0x00), (0x0F, 0x01), (0x10, 0x04)):
        write(gyro, register, value, 0.01)
    ids = (read1(acc, 0x00), read1(gyro, 0x00))
    samples = []
    for _ in range(5):
        time.sleep(0.005)
        data = bytearray(6)
        with gyro as d:
            d.write_then_readinto(bytes([0x02]), data)
        samples.append([v * 1000.0 / 32768.0 for v in struct.unpack("<hhh", data)])
    return {"ids": ids, "acc_conf": read1(acc, 0x40), "samples": samples}


def test_the_circuitpython_bmi088_driver_s_calls_reach_both_chips():
    gyro = make_chip("bmi088_gyro", seed=3, address=0x69, true_rate=TRUE_RATE_DPS)
    accel = StandinDevice(load_standin("bmi088_accel"), 0x19, clock=gyro.clock)
    bus = I2CBus(1, {0x69: gyro, 0x19: accel})
    with circuitpython_board(bus) as board, virtual_sleep(gyro):
        seen = bmi088_as_transcribed(board.I2C())
    assert seen["ids"] == (0x1E, 0x0F)
    assert seen["acc_conf"] == 0x88  # ODR 100 Hz over the reset value's bandwidth bits
    for rates in seen["samples"]:
        for measured, true in zip(rates, TRUE_RATE_DPS):
            assert abs(measured - true) < TOLERANCE_DPS, seen["samples"]
    assert "busio" not in sys.modules and "board" not in sys.modules


def test_our_circuitpython_driver_probes_configures_and_reads_the_true_rate(
        bmg160_circuitpython, bmg160_chip, bmg160_virtual_sleep):
    import busio
    from _cpy_gyro import Gyro

    bmg160_chip.set_true_rate(TRUE_RATE_DPS)
    gyro = Gyro(busio.I2C(bmg160_circuitpython.SCL, bmg160_circuitpython.SDA))
    gyro.range_code, gyro.bandwidth_code = 0x01, 0x07
    assert (gyro.range_code, gyro.bandwidth_code) == (0x01, 0x07)
    time.sleep(0.25)
    samples = []
    for _ in range(8):
        time.sleep(0.01)
        samples.append(gyro.rates)
    sys.modules.pop("_cpy_gyro", None)
    for rates in samples:
        for measured, true in zip(rates, TRUE_RATE_DPS):
            assert abs(measured - true) < TOLERANCE_DPS, samples


def test_busio_rules_and_errors_are_circuitpython_s(bmg160_circuitpython, bmg160_i2c_bus):
    import busio

    board = bmg160_circuitpython
    i2c = board.I2C()
    assert board.I2C() is i2c  # the board's singleton
    with pytest.raises(RuntimeError, match="Function requires lock"):
        i2c.writeto(0x68, b"\x00")
    with pytest.raises(ValueError, match="SCL in use"):
        busio.I2C(board.SCL, board.SDA)
    with pytest.raises(ValueError, match="Invalid pins"):
        busio.I2C(board.D4, board.D5)
    assert i2c.try_lock() and not i2c.try_lock()
    assert i2c.scan() == [0x68] and i2c.probe(0x68) and not i2c.probe(0x18)
    with pytest.raises(OSError) as info:
        i2c.writeto(0x18, b"\x00")
    assert info.value.errno == errno.ENODEV
    out = bytearray(4)
    i2c.writeto_then_readfrom(0x68, b"\xff\x00\xff", out, out_start=1, out_end=2, in_end=1)
    assert out[0] == 0x0F and out[1:] == bytearray(3)  # register 0x00 only, one byte in
    assert bmg160_i2c_bus.log.kinds()[-2:] == ["i2c_write", "i2c_read"]  # one transfer
    i2c.unlock()
    i2c.deinit()
    busio.I2C(board.SCL, board.SDA).deinit()  # the pins are free again


def test_spi_through_digitalio_and_adafruit_bus_device():
    from adafruit_bus_device.spi_device import SPIDevice

    chip = make_chip("bmg160", seed=1)
    with circuitpython_board(spi={"D5": chip}) as board:
        import digitalio

        cs = digitalio.DigitalInOut(board.D5)
        device = SPIDevice(board.SPI(), cs, baudrate=1_000_000, polarity=1, phase=1)
        result = bytearray(1)
        with device as spi:
            spi.write(bytes([0x80]))  # read CHIP_ID (mode 3)
            spi.readinto(result)
        assert result == bytearray(b"\x0f")
        with device as spi:
            spi.write(bytes([0x0F, 0x02]))
        assert chip.peek(0x0F) == 0x02


@pytest.mark.bmg160(faults=[{"kind": "nack", "address": 0x68, "on_register": 0x0F}])
def test_a_nack_on_one_register_reaches_a_circuitpython_driver(bmg160_circuitpython):
    from adafruit_bus_device.i2c_device import I2CDevice

    device = I2CDevice(bmg160_circuitpython.I2C(), 0x68)
    with device as d:
        d.write(bytes([0x10, 0x07]))  # BW: fine
        with pytest.raises(OSError) as info:
            d.write(bytes([0x0F, 0x01]))  # RANGE: not acknowledged
        assert info.value.errno == errno.ENODEV
        d.write(bytes([0x0F, 0x01]))  # the fault acted once


def test_the_board_module_is_usable_directly_with_a_register_file():
    with circuitpython_board({0x68: RegisterFileChip()}, i2c_number=3) as board:
        i2c = board.I2C()
        i2c.try_lock()
        out = bytearray(2)
        i2c.writeto_then_readfrom(0x68, b"\x05", out)
        assert out == bytearray(b"\x05\x06")
