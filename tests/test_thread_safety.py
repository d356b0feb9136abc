"""A reader thread and a configuration thread on one chip: with MSB shadowing on (spec 6.2) the
reader never pairs the LSB of one sample with the MSB of another, even when it reads them in
separate transactions; with shadowing off it does, which shows the test can see tearing."""

from __future__ import annotations

import sys
import threading
import time

import pytest

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.device.chip import BMG160

RATE_X_LSB, RATE_X_MSB, RATE_HBW = 0x02, 0x03, 0x13  # spec 4.2, 4.12
DATA_HIGH_BW, SHADOW_DIS = 0x80, 0x40
# X counts the chip cycles through; no mix of one's MSB with another's LSB is in the set.
COUNTS = (0x0102, 0x7F80, -0x2233)
RUN_S = 0.6


def _run(shadow_dis: bool) -> tuple[int, int]:
    chip = BMG160(seed=1, noise=False)
    s = chip.sensitivity
    chip.set_true_rate(lambda t: (COUNTS[int(t * 1000) % 3] / s, 0.0, 0.0))
    i2c = I2CBus(1, {0x68: chip})
    setup = FakeSMBus(i2c)
    # unfiltered output (spec 5.3) so each sample is exactly one of COUNTS
    setup.write_byte_data(0x68, RATE_HBW, DATA_HIGH_BW | (SHADOW_DIS if shadow_dis else 0))
    i2c.log.enabled = False
    chip.advance(0.05)  # past the start-up time: the registers hold a sample (spec 6.6)
    stop = threading.Event()
    valid = {c & 0xFFFF for c in COUNTS}
    result = {"reads": 0, "torn": 0}

    def reader() -> None:
        bus = FakeSMBus(i2c)
        while not stop.is_set():
            lsb = bus.read_byte_data(0x68, RATE_X_LSB)
            msb = bus.read_byte_data(0x68, RATE_X_MSB)
            result["reads"] += 1
            if lsb | msb << 8 not in valid:
                result["torn"] += 1
        bus.close()

    def configurer() -> None:
        bus = FakeSMBus(i2c)
        n = 0
        while not stop.is_set():
            bus.write_byte_data(0x68, 0x18, n & 0xA5)  # INT_MAP_1
            bus.write_byte_data(0x68, 0x1B, n & 0x7F)  # ANY_TH
            bus.write_byte_data(0x68, 0x3D, n & 0x3F)  # FIFO_CONFIG_0 watermark
            chip.advance(0.0005)  # 1 new sample per call at 2000 Hz
            n += 1
        bus.close()

    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)  # switch threads often, so reads interleave with samples
    try:
        threads = [threading.Thread(target=reader), threading.Thread(target=configurer)]
        for t in threads:
            t.start()
        time.sleep(RUN_S)
        stop.set()
        for t in threads:
            t.join()
    finally:
        sys.setswitchinterval(old)
        setup.close()
    return result["reads"], result["torn"]


def test_shadowing_on_no_torn_sample():
    reads, torn = _run(shadow_dis=False)
    assert reads > 1000
    assert torn == 0


def test_shadowing_off_tearing_is_visible():
    # With 10 us switch interval and ~0.6 s of interleaving, thousands of switches land
    # between the two reads; a tear needs only a new sample in between. Seen every run.
    reads, torn = _run(shadow_dis=True)
    if reads < 1000:
        pytest.skip("too few reads on a loaded machine to expect interleaving")
    assert torn > 0
