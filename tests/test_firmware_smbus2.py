"""Unmodified smbus2 code against the simulated firmware, through patch_smbus."""

from __future__ import annotations

import errno
import struct

import pytest
import smbus2
from _firmware_backends import require_firmware_build

from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.firmware.simulated import SimulatedFirmwareChip

pytestmark = pytest.mark.firmware


def driver_read_gyro(bus_number: int, address: int) -> tuple[int, tuple[int, int, int]]:
    """What a user's driver does: check the chip ID, set 200 Hz and +-250 deg/s, read XYZ."""
    with smbus2.SMBus(bus_number) as bus:
        chip_id = bus.read_byte_data(address, 0x00)
        bus.write_byte_data(address, 0x10, 0x04)
        bus.write_byte_data(address, 0x0F, 0x03)
        msg_w = smbus2.i2c_msg.write(address, [0x02])
        msg_r = smbus2.i2c_msg.read(address, 6)
        bus.i2c_rdwr(msg_w, msg_r)
        return chip_id, struct.unpack("<3h", bytes(msg_r))


def test_unmodified_smbus2_driver_talks_to_the_firmware():
    build = require_firmware_build(profile="paper", seed=11)
    with SimulatedFirmwareChip(build) as chip, patch_smbus({1: {0x68: chip}}):
        chip.advance(0.05)
        chip_id, xyz = driver_read_gyro(1, 0x68)
        assert chip_id == 0x0F
        assert chip.peek(0x0F) == 0x03 and chip.peek(0x10) == 0x84
        # static gyro: bias 0.116 deg/s plus noise of std 0.25 deg/s at 131 LSB per deg/s;
        # |rate| < 2.5 deg/s (9 sigma) in counts
        assert all(abs(v) < 2.5 * 131.072 for v in xyz)


def test_firmware_built_for_0x69_nacks_0x68():
    build = require_firmware_build(profile="paper", seed=11, address=0x69)
    with SimulatedFirmwareChip(build) as chip:
        assert chip.address == 0x69 and chip.read(0x00, 1) == b"\x0f"
        chip.address = 0x68  # talk to the wrong address on the simulated bus
        with pytest.raises(OSError) as info:
            chip.read(0x00, 1)
        assert info.value.errno == errno.EREMOTEIO
