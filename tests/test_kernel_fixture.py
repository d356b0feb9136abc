"""The bmg160_kernel fixture (bmg160_emu/pytest_kernel.py): one guest for these tests, the
kernel's bmg160 driver bound per test, its register writes, IIO attributes, a triggered
buffer, bus faults, and a fresh guest after one died."""

from __future__ import annotations

import itertools
import statistics

import pytest

from bmg160_emu.linux.guest.harness import GuestDied

pytestmark = pytest.mark.kernel

CHIP_ID, RANGE, BW = 0x00, 0x0F, 0x10


def test_probe_writes_range_before_bandwidth_and_the_log_shows_them(bmg160_kernel):
    # drivers/iio/gyro/bmg160_core.c bmg160_chip_init: soft reset, LPM1 normal, BW, RANGE
    # (linux-kernel-notes.md: after probe RANGE = 0x02 and BW = 0x07); the order is BW first
    bmg160_kernel.assert_wrote(BGW_SOFTRESET=0xB6, before="BW")
    bmg160_kernel.assert_wrote(BW=0x07, before="RANGE")
    bmg160_kernel.assert_wrote(RANGE=0x02)
    with pytest.raises(AssertionError, match="never wrote RANGE = 0x03"):
        bmg160_kernel.assert_wrote(RANGE=0x03)
    with pytest.raises(AssertionError, match="not written before"):
        bmg160_kernel.assert_wrote(RANGE=0x02, before="BW")
    # the model holds what the driver wrote
    assert bmg160_kernel.chip.read(RANGE, 1)[0] & 0x07 == 0x02


def test_sysfs_attributes_read_and_write_through_to_the_model(bmg160_kernel):
    assert bmg160_kernel.attr("name") == "bmg160"
    assert bmg160_kernel.attr("in_anglvel_scale") == "0.000266"  # the driver's 500 deg/s
    bmg160_kernel.set_attr("in_anglvel_scale", "0.001065")  # 2000 deg/s: RANGE = 0
    assert bmg160_kernel.attr("in_anglvel_scale") == "0.001065"
    assert (RANGE, 0x00) in bmg160_kernel.writes()
    # each test starts from a reset chip: the previous test's scale is gone after the bind


def test_each_test_starts_at_the_probe_state(bmg160_kernel):
    assert bmg160_kernel.attr("in_anglvel_scale") == "0.000266"


@pytest.mark.bmg160_kernel(addresses=[0x69])
def test_raw_reads_follow_the_true_rate(bmg160_kernel):
    bmg160_kernel.chip.set_true_rate((20.0, -10.0, 5.0))
    # the new rate reaches the registers with the chip's next sample (10 ms at the driver's
    # 100 Hz): each read comes 50 ms after the last, the first too
    values = [int(v) for v in bmg160_kernel.run(
        f"for i in 1 2 3 4 5 6 7 8; do sleep 0.05; cat {bmg160_kernel.iio()}/in_anglvel_x_raw; "
        "done").stdout.split()]
    # 20 deg/s at 500 deg/s full scale: 1310.7 counts; the model's noise at the driver's
    # 32 Hz bandwidth is ~0.2 deg/s rms (13 counts): 8 samples' mean within 40 counts
    assert abs(statistics.fmean(values) - 20.0 * 32768 / 500) < 40, values


def test_triggered_buffer_with_the_drivers_data_ready_trigger(bmg160_kernel):
    bmg160_kernel.set_attr("in_anglvel_sampling_frequency", 100)
    frames = bmg160_kernel.capture(2.0)
    stamps = [f[3] for f in frames]
    assert len(frames) > 20, len(frames)  # 2 s at 100 Hz is 200; a loaded TCG guest keeps fewer
    assert all(b > a for a, b in itertools.pairwise(stamps))


@pytest.mark.bmg160_kernel(driver=None, faults=[{"kind": "nack", "on_register": 0x00}])
def test_a_bus_fault_reaches_the_guest_as_an_error(bmg160_kernel):
    failed = bmg160_kernel.run("i2cget -y $GUEST_I2C_BUS 0x68 0x00", check=False)
    assert failed.returncode != 0
    again = bmg160_kernel.run("i2cget -y $GUEST_I2C_BUS 0x68 0x00")  # the fault acted once
    assert again.stdout.strip() == "0x0f"
    assert [t.error for t in bmg160_kernel.bus.log.filter(register=CHIP_ID)][-2:] == [
        "EREMOTEIO", None]


@pytest.mark.bmg160_kernel(driver=None)
def test_a_guest_that_dies_fails_its_test_and_the_next_one_boots(bmg160_kernel,
                                                                 bmg160_kernel_session):
    boots = bmg160_kernel_session.boots
    with pytest.raises(GuestDied):  # sysrq b: an immediate reboot, which ends the guest
        bmg160_kernel.run("echo b > /proc/sysrq-trigger; sleep 30", timeout_s=120)
    assert not bmg160_kernel.guest.alive
    # what the fixture does for the next test: a fresh guest, the driver still there
    fresh = bmg160_kernel_session.ensure()
    assert fresh is not bmg160_kernel.guest and bmg160_kernel_session.boots == boots + 1
    assert fresh.run("i2cget -y $GUEST_I2C_BUS 0x68 0x00").stdout.strip() == "0x0f"
