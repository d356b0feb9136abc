"""A driver written against plain smbus2, the way drivers are written (spec 7), run unchanged
under patch_smbus through the package's pytest fixtures; time.sleep advances virtual time."""

from __future__ import annotations

import itertools
import time

import pytest
from smbus2 import SMBus

CHIP_ID, RATE_X_LSB, INT_STATUS_1, FIFO_STATUS = 0x00, 0x02, 0x0A, 0x0E  # spec 3
RANGE, BW, LPM1, BGW_SOFTRESET, INT_EN_0 = 0x0F, 0x10, 0x11, 0x14, 0x15
FIFO_CONFIG_1, FIFO_DATA = 0x3E, 0x3F
FIFO_MODE, STREAM_MODE = 0x40, 0x80  # FIFO_CONFIG_1 bits 7:6 (spec 4.26)


def _signed(value: int) -> int:
    return value - 0x10000 if value & 0x8000 else value


class Bmg160Driver:
    """What a hobbyist or vendor driver does: its own SMBus, sleeps, bursts, polling."""

    def __init__(self, bus_number: int = 1, address: int = 0x68) -> None:
        self.bus = SMBus(bus_number)
        self.address = address

    def init(self, range_code: int, bw_code: int) -> None:
        if self.bus.read_byte_data(self.address, CHIP_ID) != 0x0F:
            raise RuntimeError("no BMG160")
        self.bus.write_byte_data(self.address, BGW_SOFTRESET, 0xB6)
        time.sleep(0.030)  # data sheet start-up time (spec 6.6)
        if self.bus.read_byte_data(self.address, CHIP_ID) != 0x0F:
            raise RuntimeError("no BMG160 after reset")
        self.bus.write_byte_data(self.address, LPM1, 0x00)
        time.sleep(0.001)
        self.bus.write_byte_data(self.address, BW, bw_code)
        self.bus.write_byte_data(self.address, RANGE, range_code)

    def rates(self) -> list[int]:
        raw = self.bus.read_i2c_block_data(self.address, RATE_X_LSB, 6)
        return [_signed(raw[i] | raw[i + 1] << 8) for i in (0, 2, 4)]

    def rates_by_word(self) -> list[int]:
        return [
            _signed(self.bus.read_word_data(self.address, RATE_X_LSB + 2 * i)) for i in range(3)
        ]

    def wait_new_data(self, timeout_s: float = 0.1) -> None:
        self.bus.write_byte_data(self.address, INT_EN_0, 0x80)  # data_en
        deadline = time.monotonic() + timeout_s
        while not self.bus.read_byte_data(self.address, INT_STATUS_1) & 0x80:
            if time.monotonic() > deadline:
                raise TimeoutError("no new data")
            time.sleep(0.0005)

    def fifo_frames(self) -> list[list[int]]:
        count = self.bus.read_byte_data(self.address, FIFO_STATUS) & 0x7F
        data: list[int] = []
        remaining = count * 6
        while remaining:
            chunk = min(remaining, 30)  # whole frames per SMBus block (<= 32 bytes)
            data += self.bus.read_i2c_block_data(self.address, FIFO_DATA, chunk)
            remaining -= chunk
        return [
            [_signed(data[i + j] | data[i + j + 1] << 8) for j in (0, 2, 4)]
            for i in range(0, len(data), 6)
        ]

    def close(self) -> None:
        self.bus.close()


@pytest.fixture
def driver(bmg160_smbus, bmg160_virtual_sleep):
    d = Bmg160Driver()
    yield d
    d.close()


@pytest.mark.bmg160(noise=False, true_rate=(100.0, -42.5, 7.25))
@pytest.mark.parametrize("range_code", [0, 1, 2, 3, 4])
def test_init_then_bursts_read_round_rate_times_sensitivity(driver, bmg160_chip, range_code):
    driver.init(range_code=range_code, bw_code=0)
    time.sleep(0.2)  # filter settles (523 Hz bandwidth)
    s = bmg160_chip.sensitivity_table[range_code]
    expected = [max(-32768, min(32767, round(r * s))) for r in (100.0, -42.5, 7.25)]
    assert driver.rates() == expected
    assert driver.rates_by_word() == expected


@pytest.mark.bmg160(noise=False, true_rate=(5000.0, -5000.0, 0.0))
def test_beyond_full_scale_saturates(driver):
    driver.init(range_code=4, bw_code=0)
    time.sleep(0.2)
    assert driver.rates()[:2] == [32767, -32768]


def test_init_sequence_is_what_the_log_shows(driver, bmg160_smbus):
    driver.init(range_code=2, bw_code=4)
    kinds = [(t.kind, t.register) for t in bmg160_smbus.log]
    assert kinds == [
        ("read_byte_data", CHIP_ID),
        ("write_byte_data", BGW_SOFTRESET),
        ("read_byte_data", CHIP_ID),
        ("write_byte_data", LPM1),
        ("write_byte_data", BW),
        ("write_byte_data", RANGE),
    ]


@pytest.mark.bmg160(hold_data_int=True)
def test_polling_new_data_sees_each_sample(driver, bmg160_chip):
    driver.init(range_code=0, bw_code=4)  # 200 Hz
    time.sleep(0.05)
    seen = []
    for _ in range(5):
        driver.wait_new_data()
        seen.append(bmg160_chip.time)
        driver.rates()
    gaps = [b - a for a, b in itertools.pairwise(seen)]
    assert all(abs(g - 1 / 200) < 1e-3 for g in gaps)  # polling every 0.5 ms


@pytest.mark.bmg160(noise=False, true_rate=(10.0, 20.0, -30.0))
def test_fifo_mode_collects_frames_that_drain_in_bursts(driver, bmg160_smbus, bmg160_chip):
    driver.init(range_code=3, bw_code=5)  # 100 Hz
    time.sleep(0.5)
    driver.bus.write_byte_data(0x68, FIFO_CONFIG_1, FIFO_MODE)  # empties the FIFO (spec 6.5)
    time.sleep(0.2)  # 20 samples
    frames = driver.fifo_frames()
    s = bmg160_chip.sensitivity_table[3]
    assert len(frames) == 20
    assert frames[-1] == [round(r * s) for r in (10.0, 20.0, -30.0)]
    assert driver.bus.read_byte_data(0x68, FIFO_STATUS) == 0


@pytest.mark.bmg160(noise=False)
def test_fifo_mode_stops_at_100_frames_and_flags_overrun(driver):
    driver.init(range_code=0, bw_code=5)
    time.sleep(0.1)
    driver.bus.write_byte_data(0x68, FIFO_CONFIG_1, FIFO_MODE)
    time.sleep(1.5)  # 150 samples at 100 Hz
    status = driver.bus.read_byte_data(0x68, FIFO_STATUS)
    assert status == 0x80 | 100
    assert len(driver.fifo_frames()) == 100


def test_stream_mode_keeps_the_newest_100(driver, bmg160_chip):
    driver.init(range_code=0, bw_code=5)
    time.sleep(0.1)
    driver.bus.write_byte_data(0x68, FIFO_CONFIG_1, STREAM_MODE)
    time.sleep(1.5)
    frames = driver.fifo_frames()
    assert len(frames) == 100
    latest = driver.rates()
    assert frames[-1] == latest  # the last frame is the current sample


def test_bypass_mode_holds_only_the_newest_sample_and_reads_empty_after(driver):
    driver.init(range_code=0, bw_code=5)
    time.sleep(0.1)
    driver.bus.write_byte_data(0x68, FIFO_CONFIG_1, 0x00)  # bypass (spec 6.5)
    time.sleep(0.05)
    assert driver.bus.read_byte_data(0x68, FIFO_STATUS) & 0x7F == 1
    frame = driver.bus.read_i2c_block_data(0x68, FIFO_DATA, 6)
    again = driver.bus.read_i2c_block_data(0x68, FIFO_DATA, 6)
    assert frame == driver.bus.read_i2c_block_data(0x68, RATE_X_LSB, 6)
    assert again == [0x00, 0x80] * 3  # empty pattern, -32768 per word


def test_self_test_as_the_bosch_api_runs_it(driver):
    bist = 0x3C  # spec 4.25
    driver.init(range_code=0, bw_code=0)
    time.sleep(0.05)
    assert driver.bus.read_byte_data(0x68, bist) & 0x10  # rate_ok before the trigger
    driver.bus.write_byte_data(0x68, bist, 0x01)  # trig_bist
    time.sleep(0.010)  # BAPI waits 10 ms (spec 6.8)
    status = driver.bus.read_byte_data(0x68, bist)
    assert status & 0x02 and not status & 0x04  # bist_rdy, no bist_fail
