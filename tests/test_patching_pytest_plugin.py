"""The pytest plugin (entry point bmg160_emu) gives its fixtures and marker to any test suite."""

from __future__ import annotations

pytest_plugins = ["pytester"]

SUITE = """
import time
import pytest
import smbus2

@pytest.mark.bmg160(noise=False, true_rate=(100.0, 0.0, 0.0), bus=3)
def test_driver_under_fixtures(bmg160_smbus, bmg160_virtual_sleep, bmg160_chip):
    with smbus2.SMBus(3) as bus:
        assert bus.read_byte_data(0x68, 0x00) == 0x0F
        time.sleep(0.2)
        raw = bus.read_i2c_block_data(0x68, 0x02, 2)
    assert raw[0] | raw[1] << 8 == round(100.0 * bmg160_chip.sensitivity)
    assert bmg160_smbus.number == 3 and len(bmg160_smbus.log) == 2

def test_fake_smbus_and_fake_spidev(fake_smbus, fake_spidev):
    assert fake_smbus.read_byte_data(0x68, 0x00) == 0x0F
    assert fake_spidev.xfer2([0x80, 0]) == [0, 0x0F]

def test_patched_spidev(bmg160_spidev):
    import spidev
    assert spidev.SpiDev(0, 0).xfer2([0x80, 0])[1] == 0x0F

@pytest.mark.bmg160(address=0x69, seed=3)
def test_marker_options_reach_the_chip(bmg160_chip):
    assert bmg160_chip.address == 0x69 and bmg160_chip.seed == 3
"""


def test_fixtures_and_marker_work_in_another_suite(pytester):
    pytester.makepyfile(test_suite=SUITE)
    result = pytester.runpytest("-p", "no:cacheprovider", "--strict-markers")
    result.assert_outcomes(passed=4)
