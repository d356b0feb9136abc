"""Register-file stand-ins: the device's rules, and real drivers' probes finding them.

The probe sequences are transcribed (in our words, as smbus2 calls) from open drivers: the
Linux bmc150-accel and bmc150_magn drivers, the Bosch BMM150 and BMI08x sensor APIs and
PX4's BMI088 accelerometer driver. Each is run against the shipped stand-in over FakeSMBus
and must find the chip (its ID check passes) and configure it (its read-back checks pass).
"""

from __future__ import annotations

import errno

import pytest

from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.contract import RegisterDevice
from bmg160_emu.device.standin import StandinDevice
from bmg160_emu.io.standin_file import builtin_names, load_standin


def device(name: str, address: int | None = None) -> StandinDevice:
    return StandinDevice(load_standin(name), address)


def smbus(*devices: StandinDevice) -> FakeSMBus:
    return FakeSMBus(1, devices={d.address: d for d in devices})


def update_bits(bus: FakeSMBus, address: int, reg: int, mask: int, value: int) -> None:
    """regmap_update_bits as the kernel does it: read, modify, write only on a change."""
    old = bus.read_byte_data(address, reg)
    new = (old & ~mask) | (value & mask)
    if new != old:
        bus.write_byte_data(address, reg, new)


# --------------------------------------------------------------------------- the device


def test_every_builtin_is_a_register_device_with_its_chip_id():
    ids = {"bmi088_accel": (0x00, 0x1E), "bma2x2_accel": (0x00, 0xFA), "bmm150": (0x40, 0x32)}
    assert set(builtin_names()) == set(ids)
    for name, (reg, value) in ids.items():
        d = device(name)
        assert isinstance(d, RegisterDevice)
        assert load_standin(name).chip_id_register == reg
        if name == "bmm150":
            d.write(0x4B, b"\x01")  # out of suspend first (data sheet 5.3)
        assert d.read(reg, 1) == bytes([value])


def test_builtins_answer_at_their_address_pins_only():
    assert load_standin("bmi088_accel").addresses == (0x18, 0x19)
    assert load_standin("bma2x2_accel").addresses == (0x18, 0x19)
    assert load_standin("bmm150").addresses == (0x10, 0x11, 0x12, 0x13)


def test_reset_values_read_only_bits_and_write_masks():
    d = device("bma2x2_accel")
    assert d.read(0x0F, 2) == b"\x03\x0f"  # PMU_RANGE, PMU_BW reset values
    d.write(0x00, b"\x12")  # BGW_CHIPID is read-only
    assert d.read(0x00, 1) == b"\xfa"
    d.write(0x0F, b"\xff")  # PMU_RANGE: only bits 3..0 exist
    assert d.read(0x0F, 1) == b"\x0f"
    d.write(0x21, b"\x8f")  # INT_RST_LATCH: reset_int (bit 7) clears itself
    assert d.read(0x21, 1) == b"\x0f"


def test_a_command_register_reads_zero_and_a_soft_reset_restores_every_register():
    d = device("bma2x2_accel")
    d.write(0x0F, b"\x05")
    d.write(0x10, b"\x0b")
    d.write(0x14, b"\x12")  # not the reset command: nothing happens
    assert d.read(0x0F, 2) == b"\x05\x0b"
    assert d.read(0x14, 1) == b"\x00"
    d.write(0x14, b"\xb6")
    assert d.read(0x0F, 2) == b"\x03\x0f"


def test_absent_registers_read_the_absent_value_and_ignore_writes():
    d = device("bmi088_accel")
    assert d.read(0x01, 1) == b"\x00"
    d.write(0x01, b"\x55")
    assert d.read(0x01, 1) == b"\x00"
    assert d.read(0xFF, 1) == b"\x00"


def test_auto_increment_wraps_and_stays_on_fifo_data():
    d = device("bma2x2_accel")
    assert d.read(0x0E, 3) == b"\x00\x03\x0f"  # FIFO_STATUS, PMU_RANGE, PMU_BW
    assert d.pointer == 0x11
    d.read(0x3F, 4)  # FIFO_DATA does not advance the pointer
    assert d.pointer == 0x3F
    assert d.read(0xFF, 2) == b"\x00\xfa"  # 0xFF wraps to 0x00
    d.write(0x38, b"\x01\x02\x03")  # OFC_OFFSET_X..Z in one burst
    assert d.read(0x38, 3) == b"\x01\x02\x03"


def test_i2c_write_sets_the_pointer_for_the_next_plain_read():
    d = device("bmi088_accel")
    d.i2c_write(b"\x40")
    assert d.i2c_read(2) == b"\xa8\x01"  # ACC_CONF, ACC_RANGE reset values
    d.i2c_write(b"\x41\x03")
    assert d.peek(0x41) == 0x03
    assert d.pointer == 0x42


def test_the_bmm150_answers_only_its_power_register_while_suspended():
    d = device("bmm150")
    assert d.read(0x4B, 1) == b"\x00"  # suspended after power-on (data sheet 4.2)
    assert d.read(0x40, 1) == b"\x00"  # chip ID hidden until the power bit is set (5.3)
    d.write(0x51, b"\x04")  # ignored while suspended
    d.write(0x4B, b"\x01")
    assert d.read(0x40, 1) == b"\x32"
    assert d.read(0x4C, 3) == b"\x06\x3f\x07"  # OPMODE_ODR, INT_ENABLE, INT_DRDY resets
    assert d.read(0x51, 1) == b"\x00"
    d.write(0x40, b"\x00")  # 0x40..0x4A read-only (5.1)
    assert d.read(0x40, 1) == b"\x32"
    d.write(0x4B, b"\x00")  # back to suspend
    assert d.read(0x40, 1) == b"\x00"


def test_the_bmm150_soft_reset_keeps_its_power_register_and_clears_the_command_bits():
    d = device("bmm150")
    d.write(0x4B, b"\x01")
    d.write(0x51, b"\x04")
    d.write(0x4B, b"\x83")  # soft reset (bits 7 and 1) with the power bit kept set
    assert d.read(0x4B, 1) == b"\x01"
    assert d.read(0x51, 1) == b"\x00"
    assert d.read(0x40, 1) == b"\x32"


def test_the_trim_registers_give_compensation_code_no_zero_divisor():
    d = device("bmm150")
    d.write(0x4B, b"\x01")
    trim = d.read(0x5D, 0x71 - 0x5D + 1)
    z2 = int.from_bytes(trim[0x68 - 0x5D : 0x6A - 0x5D], "little")
    z1 = int.from_bytes(trim[0x6A - 0x5D : 0x6C - 0x5D], "little")
    xyz1 = int.from_bytes(trim[0x6C - 0x5D : 0x6E - 0x5D], "little")
    assert z2 and z1 and xyz1


def test_time_follows_the_session_clock():
    clock = VirtualClock()
    d = StandinDevice(load_standin("bmi088_accel"), 0x19, clock)
    clock.advance(0.25)
    assert d.time == pytest.approx(0.25)
    d.advance(0.5)
    assert clock.now() == pytest.approx(0.75)
    alone = device("bmi088_accel")
    alone.advance(0.1)
    assert alone.time == pytest.approx(0.1)


def test_a_missing_address_on_the_bus_is_nacked_next_to_a_stand_in():
    with smbus(device("bma2x2_accel")) as bus:
        assert bus.read_byte_data(0x18, 0x00) == 0xFA
        with pytest.raises(OSError) as info:
            bus.read_byte_data(0x19, 0x00)
        assert info.value.errno == errno.EREMOTEIO


# --------------------------------------------------------------------------- driver probes


def test_linux_bmc150_accel_probe_finds_and_configures_the_bma2x2():
    # drivers/iio/accel/bmc150-accel-core.c, bmc150_accel_chip_init (and update_slope)
    with smbus(device("bma2x2_accel")) as bus:
        bus.write_byte_data(0x18, 0x14, 0xB6)  # soft reset, then 1.8 ms
        assert bus.read_byte_data(0x18, 0x00) == 0xFA  # "BMA253/BMA254/BMA255/BMC150/BMI055"
        bus.write_byte_data(0x18, 0x11, 0x00)  # PMU_LPW: normal mode
        bus.write_byte_data(0x18, 0x10, 0x0B)  # PMU_BW: 125 Hz
        bus.write_byte_data(0x18, 0x0F, 0x05)  # PMU_RANGE: 4 g
        bus.write_byte_data(0x18, 0x28, 0x01)  # INT_6: slope threshold
        update_bits(bus, 0x18, 0x27, 0x03, 0x01)  # INT_5: slope duration
        bus.write_byte_data(0x18, 0x21, 0x80 | 0x0F)  # INT_RST_LATCH: reset, latched
        assert bus.read_byte_data(0x18, 0x10) == 0x0B
        assert bus.read_byte_data(0x18, 0x0F) == 0x05
        assert bus.read_byte_data(0x18, 0x27) & 0x03 == 0x01
        assert bus.read_i2c_block_data(0x18, 0x02, 6) == [0] * 6  # no motion data


def test_linux_bmc150_magn_probe_finds_and_configures_the_bmm150():
    # drivers/iio/magnetometer/bmc150_magn.c, bmc150_magn_init (regmap update_bits)
    with smbus(device("bmm150")) as bus:
        update_bits(bus, 0x10, 0x4B, 0x01, 0x01)  # out of suspend, then 3 ms
        assert bus.read_byte_data(0x10, 0x40) == 0x32
        update_bits(bus, 0x10, 0x4C, 0x38, 0x00 << 3)  # ODR 10 Hz (code 0)
        bus.write_byte_data(0x10, 0x51, (9 - 1) // 2)  # REP_XY for the regular preset
        bus.write_byte_data(0x10, 0x52, 15 - 1)  # REP_Z
        update_bits(bus, 0x10, 0x4C, 0x06, 0x00)  # normal mode
        assert bus.read_byte_data(0x10, 0x51) == 4
        assert bus.read_byte_data(0x10, 0x52) == 14
        assert bus.read_byte_data(0x10, 0x4C) & 0x3E == 0x00
        trim = bus.read_i2c_block_data(0x10, 0x5D, 21)  # the trim block it reads per sample
        assert len(trim) == 21


def test_bosch_bmm150_api_init_and_soft_reset():
    # BMM150_SensorAPI bmm150.c: bmm150_init (power bit, 3 ms, chip ID), bmm150_soft_reset
    with smbus(device("bmm150", 0x13)) as bus:
        power = bus.read_byte_data(0x13, 0x4B)
        bus.write_byte_data(0x13, 0x4B, (power & ~0x01) | 0x01)
        assert bus.read_byte_data(0x13, 0x40) == 0x32
        bus.write_byte_data(0x13, 0x4E, 0xC7)
        power = bus.read_byte_data(0x13, 0x4B)
        bus.write_byte_data(0x13, 0x4B, power | 0x82)  # soft reset, 1 ms
        assert bus.read_byte_data(0x13, 0x4E) == 0x07  # back to reset
        assert bus.read_byte_data(0x13, 0x40) == 0x32  # 0x4B kept: still out of suspend


def test_px4_bmi088_accel_probe_and_configure_check_pass():
    # PX4 src/drivers/imu/bosch/bmi088/BMI088_Accelerometer.cpp: probe, RESET, CONFIGURE
    # (set and clear bits, then every register read back and checked)
    config = [  # register, bits set, bits cleared
        (0x7D, 0x04, 0x00),  # ACC_PWR_CTRL: accelerometer on
        (0x40, 0xA0 | 0x0C, 0x03),  # ACC_CONF: normal filter, 1600 Hz
        (0x41, 0x03, 0x00),  # ACC_RANGE: 24 g
        (0x48, 0x03, 0x00),  # FIFO_CONFIG_0: bit 1 always set, FIFO mode
        (0x49, 0x10 | 0x40, 0x00),  # FIFO_CONFIG_1: bit 4 always set, accelerometer in FIFO
        (0x53, 0x08 | 0x02, 0x00),  # INT1_IO_CONF: output, active high
        (0x58, 0x02, 0x00),  # INT_MAP_DATA: watermark to INT1
    ]
    with smbus(device("bmi088_accel", 0x19)) as bus:
        assert bus.read_byte_data(0x19, 0x00) == 0x1E
        bus.write_byte_data(0x19, 0x7E, 0xB6)  # soft reset, 1 ms
        assert bus.read_byte_data(0x19, 0x00) == 0x1E
        bus.write_byte_data(0x19, 0x7C, 0x00)  # ACC_PWR_CONF: active
        for reg, set_bits, clear_bits in config:
            old = bus.read_byte_data(0x19, reg)
            new = (old & ~clear_bits) | set_bits
            if new != old:
                bus.write_byte_data(0x19, reg, new)
        for reg, set_bits, clear_bits in config:
            value = bus.read_byte_data(0x19, reg)
            assert value & set_bits == set_bits, hex(reg)
            assert value & clear_bits == 0, hex(reg)
        length = bus.read_i2c_block_data(0x19, 0x24, 2)  # FIFO_LENGTH: empty
        assert length[0] | (length[1] & 0x3F) << 8 == 0


def test_bosch_bmi08x_api_accel_init_sequence():
    # BMI08x SensorAPI: bmi08a_init (chip ID), bmi08a_soft_reset, bmi08a_set_power_mode,
    # bmi08a_set_meas_conf, then the configuration read back (bmi08a_get_meas_conf)
    with smbus(device("bmi088_accel", 0x18)) as bus:
        assert bus.read_byte_data(0x18, 0x00) == 0x1E
        bus.write_byte_data(0x18, 0x7E, 0xB6)
        assert bus.read_byte_data(0x18, 0x7C) == 0x03  # suspended after the reset
        bus.write_byte_data(0x18, 0x7C, 0x00)
        bus.write_byte_data(0x18, 0x7D, 0x04)
        bus.write_i2c_block_data(0x18, 0x40, [0xA8, 0x01])  # 100 Hz normal, 6 g
        assert bus.read_i2c_block_data(0x18, 0x40, 2) == [0xA8, 0x01]
        assert bus.read_i2c_block_data(0x18, 0x7C, 2) == [0x00, 0x04]
        assert bus.read_i2c_block_data(0x18, 0x12, 6) == [0] * 6  # no motion data
