"""PX4's BMI088 gyroscope driver, transcribed as a scripted client over SPI, with its FIFO reads.

Read from PX4-Autopilot ``src/drivers/imu/bosch/bmi088/BMI088_Gyroscope.cpp`` and ``.hpp``
(and its register header) to learn the sequence, then written here as Python (nothing
copied): probe the chip ID; soft reset and wait 30 ms; poll the chip ID; set and clear bits
of its eight configuration registers by read-modify-write, then read every one back;
reset the FIFO (write 0 to FIFO_CONFIG_0 and FIFO_CONFIG_1, then restore them); on each
FIFO watermark interrupt on INT3 (falling edge: INT3 push-pull, active low) read
FIFO_STATUS, reset the FIFO on overrun, else burst-read the counted frames from FIFO_DATA
(leaving one if exactly one more than expected arrived); every 100 ms read one
configuration register back and reset the chip if it changed. ArduPilot's BMI088 gyro
start-up and FIFO polling (the last test) is a second, independent client.
"""

from __future__ import annotations

import math
import statistics
import struct
from dataclasses import dataclass, field

from bmg160_emu.bus.spi import FakeSpiDev
from bmg160_emu.device.parts import make_chip

READ = 0x80  # SPI read bit (BMI088 DS 6.1)
CHIP_ID, FIFO_STATUS, RANGE, BANDWIDTH = 0x00, 0x0E, 0x0F, 0x10
SOFTRESET, INT_CTRL, IO_CONF, IO_MAP, FIFO_WM_ENABLE = 0x14, 0x15, 0x16, 0x18, 0x1E
FIFO_CONFIG_0, FIFO_CONFIG_1, FIFO_DATA = 0x3D, 0x3E, 0x3F
ODR_HZ = 2000  # PX4 runs the gyro at 2 kHz, 532 Hz filter (bandwidth code 0)
FIFO_SAMPLE_DT_S = 1.0 / ODR_HZ
PUBLISH_RATE_HZ = 400  # PX4's default IMU rate: 5 samples per watermark interrupt
FIFO_MAX_SAMPLES = 32  # min(100 frames, samples per sensor_gyro_fifo message)
TRUE_RATE_DPS = (30.0, -20.0, 10.0)


@dataclass
class Px4Bmi088Gyro:
    """The driver's state and its register traffic, one SPI frame per register access."""

    spi: FakeSpiDev
    fifo_samples: int = 0
    config: list[tuple[int, int, int]] = field(default_factory=list)
    scale_rad: float = 0.0
    published: list[tuple[int, int, int]] = field(default_factory=list)
    overflows: int = 0
    empties: int = 0
    fifo_resets: int = 0
    bad_registers: int = 0
    checked: int = 0

    def __post_init__(self) -> None:
        # ConfigureSampleRate: interval rounded to whole FIFO samples, samples per interrupt
        interval_s = round((1.0 / PUBLISH_RATE_HZ) / FIFO_SAMPLE_DT_S) * FIFO_SAMPLE_DT_S
        self.fifo_samples = min(round(interval_s * ODR_HZ), FIFO_MAX_SAMPLES)
        self.config = [  # (register, set bits, clear bits), INT3 variant
            (RANGE, 0x00, 0x00),  # +-2000 deg/s
            (BANDWIDTH, 0x00, 0x07),  # code 0: ODR 2000 Hz
            (INT_CTRL, 0x40, 0x00),  # fifo_en
            (FIFO_WM_ENABLE, 0x88, 0x00),  # watermark interrupt on (bit 3 as PX4 writes it)
            (FIFO_CONFIG_0, self.fifo_samples, ~self.fifo_samples & 0xFF),  # watermark
            (FIFO_CONFIG_1, 0x40, 0x00),  # FIFO (stop-at-full) mode
            (IO_CONF, 0x00, 0x03),  # INT3 push-pull, active low
            (IO_MAP, 0x04, 0x00),  # FIFO interrupt on INT3
        ]

    def read(self, reg: int) -> int:
        return self.spi.xfer2([reg | READ, 0])[1]

    def write(self, reg: int, value: int) -> None:
        self.spi.xfer2([reg, value])

    def set_and_clear(self, reg: int, set_bits: int, clear_bits: int) -> None:
        old = self.read(reg)
        new = (old & ~clear_bits & 0xFF) | set_bits
        if new != old:
            self.write(reg, new)

    def check(self, reg: int, set_bits: int, clear_bits: int) -> bool:
        value = self.read(reg)
        return (value & set_bits) == set_bits and not value & clear_bits

    def probe(self) -> bool:
        return self.read(CHIP_ID) == 0x0F

    def configure(self) -> bool:
        for entry in self.config:
            self.set_and_clear(*entry)
        ok = all(self.check(*entry) for entry in self.config)
        full_scale = {0: 2000.0, 1: 1000.0, 2: 500.0, 4: 250.0, 5: 125.0}  # PX4's table
        self.scale_rad = math.radians(full_scale[self.read(RANGE) & 0x0F] / 32768.0)
        return ok

    def fifo_reset(self) -> None:
        self.fifo_resets += 1
        self.write(FIFO_CONFIG_0, 0)  # clears the buffer (DS 5.5.15)
        self.write(FIFO_CONFIG_1, 0)  # clears the overrun flag (DS 5.5.4)
        for reg, set_bits, clear_bits in self.config:
            if reg in (FIFO_CONFIG_0, FIFO_CONFIG_1):
                self.set_and_clear(reg, set_bits, clear_bits)

    def fifo_read_cycle(self) -> None:
        status = self.read(FIFO_STATUS)
        if status & 0x80:
            self.fifo_reset()
            self.overflows += 1
            return
        count = status & 0x7F
        if count > FIFO_MAX_SAMPLES:
            self.fifo_reset()
            self.overflows += 1
            return
        if count == 0:
            self.empties += 1
            return
        if count == self.fifo_samples + 1:
            count -= 1  # tolerate jitter: the newest one waits for the next cycle
        data = bytes(self.spi.xfer2([FIFO_DATA | READ] + [0] * (6 * count)))[1:]
        for i in range(count):
            x, y, z = struct.unpack_from("<3h", data, 6 * i)
            # sensor frame x forward, y left, z up -> published with y, z flipped
            self.published.append((x, 32767 if y == -32768 else -y, 32767 if z == -32768 else -z))

    def register_check(self) -> bool:
        entry = self.config[self.checked]
        if not self.check(*entry):
            self.bad_registers += 1
            return False
        self.checked = (self.checked + 1) % len(self.config)
        return True


def _start(seed: int = 11):
    chip = make_chip("bmi088_gyro", seed=seed, true_rate=TRUE_RATE_DPS)
    driver = Px4Bmi088Gyro(FakeSpiDev(chip))
    assert driver.probe()
    driver.write(SOFTRESET, 0xB6)
    chip.advance(0.030)  # ScheduleDelayed(30 ms)
    assert driver.read(CHIP_ID) == 0x0F
    chip.advance(0.010)
    assert driver.configure(), "every configuration register reads back as written"
    chip.advance(0.010)
    driver.fifo_reset()
    return chip, driver


def _run(chip, driver, seconds: float, stall: tuple[float, float] | None = None) -> None:
    """Interrupt-driven FIFO reads: a falling edge on INT3 schedules a read cycle; each
    cycle pushes a backup schedule two intervals on, which runs one if no edge came."""
    step = FIFO_SAMPLE_DT_S / 4
    backup_s = 2 * driver.fifo_samples * FIFO_SAMPLE_DT_S
    level = chip.int_pin_level(1)
    t0 = chip.time
    last_check = last_cycle = t0
    while chip.time - t0 < seconds:
        chip.advance(step)
        now = chip.time - t0
        new_level = chip.int_pin_level(1)
        stalled = stall is not None and stall[0] <= now < stall[1]
        edge = level == 1 and new_level == 0
        if not stalled and (edge or chip.time - last_cycle >= backup_s):
            driver.fifo_read_cycle()
            last_cycle = chip.time
            new_level = chip.int_pin_level(1)
        level = new_level
        if chip.time - last_check > 0.100:
            last_check = chip.time
            assert driver.register_check()


def test_px4_configures_the_bmi088_and_every_register_check_passes():
    chip, driver = _start()
    assert driver.fifo_samples == 5
    assert [chip.read(r)[0] for r in (INT_CTRL, FIFO_WM_ENABLE, FIFO_CONFIG_0, FIFO_CONFIG_1,
                                     IO_CONF, IO_MAP)] == [0x40, 0x88, 0x05, 0x40, 0x0C, 0x04]
    assert driver.scale_rad == math.radians(2000.0 / 32768.0)
    assert chip.odr_hz == ODR_HZ and driver.fifo_resets == 1


def test_px4_fifo_reads_deliver_every_sample_in_order_and_the_rate():
    chip, driver = _start()
    _run(chip, driver, 1.0)
    # one watermark interrupt per 5 frames: 2000 samples in 1 s, minus the few left in the
    # FIFO at the end (below the watermark)
    assert ODR_HZ - driver.fifo_samples <= len(driver.published) <= ODR_HZ
    assert driver.overflows == 0 and driver.empties == 0 and driver.bad_registers == 0
    for axis, sign in ((0, 1), (1, -1), (2, -1)):
        values = [s[axis] for s in driver.published[100:]]  # past the filter's start
        mean_dps = statistics.fmean(values) * math.degrees(driver.scale_rad)
        # noise 0.014 deg/s/sqrt(Hz) (DS table 5) at 523 Hz: ~0.4 deg/s per sample, the mean
        # of ~1900 within 0.03 (3 sigma), plus a bias-instability draw of a few mdeg/s
        assert abs(mean_dps - sign * TRUE_RATE_DPS[axis]) < 0.1, axis


def test_px4_resets_the_fifo_after_an_overrun_and_reads_on():
    chip, driver = _start()
    _run(chip, driver, 0.3, stall=(0.1, 0.2))  # the driver misses 100 ms: 200 samples > 100
    assert driver.overflows == 1 and driver.fifo_resets == 2
    # before the stall ~200 samples, after the reset another ~200 (frames in between lost)
    assert 350 <= len(driver.published) <= 410
    assert driver.bad_registers == 0


def test_ardupilot_bmi088_gyro_init_checks_and_stream_reads_pass():
    # ArduPilot AP_InertialSensor_BMI088.cpp (read to learn): chip ID, soft reset, 30 ms,
    # then five "checked" writes it reads back while running, stream mode, FIFO reads of at
    # most 8 frames. It writes 0 to RATE_HBW (0x13), which the BMI088 map reserves: the
    # read-back still matches, as a reserved register reads 0.
    chip = make_chip("bmi088_gyro", seed=3, true_rate=TRUE_RATE_DPS)
    spi = FakeSpiDev(chip)
    assert spi.xfer2([CHIP_ID | READ, 0])[1] == 0x0F
    spi.xfer2([SOFTRESET, 0xB6])
    chip.advance(0.030)
    checked = {RANGE: 0x00, BANDWIDTH: 0x81, 0x11: 0x00, 0x13: 0x00, FIFO_CONFIG_1: 0x80}
    for reg, value in checked.items():
        spi.xfer2([reg, value])
    frames = []
    for _ in range(400):  # its 2 kHz periodic callback, for 0.2 s
        chip.advance(FIFO_SAMPLE_DT_S)
        count = min(spi.xfer2([FIFO_STATUS | READ, 0])[1] & 0x7F, 8)
        if count:
            data = bytes(spi.xfer2([FIFO_DATA | READ] + [0] * (6 * count)))[1:]
            frames += [struct.unpack_from("<3h", data, 6 * i) for i in range(count)]
    assert all(spi.xfer2([reg | READ, 0])[1] == value for reg, value in checked.items())
    assert 390 <= len(frames) <= 400 and chip.read(FIFO_STATUS)[0] & 0x80 == 0
    mean_x = statistics.fmean(f[0] for f in frames[100:]) * 2000.0 / 32768
    assert abs(mean_x - TRUE_RATE_DPS[0]) < 0.3  # ~300 samples at 230 Hz: noise of the mean ~0.02
