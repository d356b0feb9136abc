"""Every "unconfirmed" behaviour of the register specification, chosen in one place.

Each constant names the spec section it answers. docs/unconfirmed-choices.md lists them
with their reasons; change a behaviour here, not in the model. The one exception is the
output filter of each BW code (5.3), which a noise profile names too: it is chosen in
``bmg160_emu.noise.bandwidths``.
"""

from __future__ import annotations

from bmg160_emu.device.registers import address_of, field_of
from bmg160_emu.noise import bandwidths

# 2.1: the I2C address is 0x68 with SDO low, 0x69 with SDO high; the chip answers nowhere else.
VALID_ADDRESSES = (0x68, 0x69)
DEFAULT_ADDRESS = 0x68
DEFAULT_PART = "bmg160"  # the part of a chip when none is named (device.parts.PART_NAMES)
# 4.8: full scale of RANGE codes 0..4 in deg/s (codes 5..7 are reserved: RESERVED_RANGE_AS_CODE).
RANGE_FULL_SCALE_DPS = (2000, 1000, 500, 250, 125)
RANGE_CODE_BY_DPS = {dps: code for code, dps in enumerate(RANGE_FULL_SCALE_DPS)}

# 5.1: per-range sensitivity in LSB per deg/s, indexed by RANGE code 0..4.
SENSITIVITY_BINARY = (16.384, 32.768, 65.536, 131.072, 262.144)  # 32768 / full scale
SENSITIVITY_NOMINAL = (16.4, 32.8, 65.6, 131.2, 262.4)  # data-sheet typical figures
SENSITIVITY_TABLES = {"binary": SENSITIVITY_BINARY, "nominal": SENSITIVITY_NOMINAL}
DEFAULT_SENSITIVITY = "binary"
RESERVED_RANGE_AS_CODE = 0  # 4.8: codes 5..7 produce data as +-2000 deg/s

_RANGE_CODE = field_of("RANGE", "range")
_BW_CODE = field_of("BW", "bw")


def range_code(range_reg: int) -> int:
    """The RANGE code the data is scaled for: reserved codes as RESERVED_RANGE_AS_CODE (4.8)."""
    code = _RANGE_CODE.extract(range_reg)
    return code if code < len(SENSITIVITY_BINARY) else RESERVED_RANGE_AS_CODE


def bw_code(bw: int) -> int:
    """The BW code a BW byte behaves as: codes 8..15 as code & 7 (4.9, unconfirmed)."""
    return _BW_CODE.extract(bw) % len(bandwidths.BW_CODES)


def bandwidth(bw: int) -> tuple[int, float]:
    """(ODR Hz, filter bandwidth Hz) of a BW byte: its code's filter (5.3, the table of
    noise.bandwidths, where a profile's BW code finds it too)."""
    return bandwidths.BANDWIDTHS[bw_code(bw)]


# 6.9: offset resolution, one LSB of the +-2000 deg/s range of the sensitivity table.
OFFSET_LSB_RANGE_CODE = 0

# 5.2: temperature encoding raw = round((T - 23) / 0.5); raw 0 (23 deg C) before the first
# conversion; one conversion per rate sample, frozen when not sampling.
TEMP_ZERO_C = 23.0
TEMP_LSB_K = 0.5

# 6.6 / 6.7: times in nanoseconds.
STARTUP_TIME_NS = 30_000_000  # soft reset, power-on, wake from (deep) suspend (DS)
FAST_POWER_UP_WAKE_NS = 10_000_000  # wake from fast power-up (DS)
# A chip built by BMG160(...) has been powered long enough: sample 0 is at t = 0.
POWERED_UP_AT_CONSTRUCTION = True

# 6.7: registers writable in each low-power mode (others ignored).
WRITABLE_IN_SUSPEND = frozenset(address_of(n) for n in ("LPM1", "LPM2", "BGW_SOFTRESET"))
WRITABLE_IN_DEEP_SUSPEND = frozenset(address_of(n) for n in ("LPM1", "BGW_SOFTRESET"))
LEAVING_DEEP_SUSPEND_RESETS = True  # behaves like a soft reset, then stores the LPM1 write

# 6.3: data_int is a pulse after each new sample (B088: 280..400 us on the sister part).
DATA_READY_PULSE_NS = 300_000
# 6.3: latch_status_bits = 1 keeps status bits set until reset_int.
# 6.3: fast_offset_int is an event: set when FOC completes, cleared by reset_int, by a new
# FOC trigger or by reset (in every latch mode).

# 4.6: sign bit polarity of any_sign / high_sign: 1 = negative slope / rate.
SIGN_BIT_MEANS_NEGATIVE = True

# 6.4: any-motion slope evaluated at min(ODR, 400 Hz) (every ceil(ODR/400)-th sample),
# set and cleared after N = 4 * (any_dursample + 1) consecutive slope points.
ANY_MOTION_MAX_RATE_HZ = 400

# 6.5 FIFO.
FIFO_CAPACITY_FRAMES = 100  # whatever the frame size; also in stream mode
FIFO_EMPTY_WORD = b"\x00\x80"  # -32768 for every 16-bit word read past the last frame
FIFO_EMPTY_TAG = 0x00
# A transaction that stops inside a frame leaves the rest of that frame for the next read.
FIFO_KEEP_PARTIAL_FRAME = True
# Mode 3 (reserved) behaves as bypass.
FIFO_RESERVED_MODE_AS = 0
# With fifo_wm_en = 0 the FIFO interrupt asserts at 100 frames; with a watermark of 0 the
# watermark interrupt asserts from 1 frame.


def fifo_tag_bytes(int1_active: bool, int2_active: bool) -> bytes:
    """The 2 tag bytes of a FIFO frame (6.5, encoding unconfirmed): INT1, INT2 states."""
    return bytes((int(int1_active), int(int2_active)))


# 6.8 self-test: finishes this long after the trigger; passes unless a failure is injected.
BIST_TIME_NS = 5_000_000

# 6.10 NVM: default image (OFC1..4, GP0, GP1 all 0), cycles left, programming time.
NVM_DEFAULT_IMAGE = bytes(6)
NVM_DEFAULT_REMAIN = 0xF
NVM_PROG_TIME_NS = 5_000_000

# 2.4: the register address byte's bit 7 is not decoded: bits 6..0 are the address on both
# buses (bit 7 is SPI's read flag). Over I2C, Zephyr's bmi08x driver sends ``reg | 0x80``
# on every read, and that driver, unmodified, reads a real BMI088 (this die) over I2C: a
# Crazyflie 2.1 Brushless application checks GYRO_CHIP_ID through it and calibrates on its
# rates. Sources and the rest of the evidence: docs/unconfirmed-choices.md.
REGISTER_ADDRESS_BITS = 7  # decoded address bits: 0x00..0x7F on I2C as on SPI
REGISTER_ADDRESS_MASK = (1 << REGISTER_ADDRESS_BITS) - 1

# 2.4: a burst starting at 0x40 or above reads 0x00 for every byte; writes there are
# ignored. A burst that runs into 0x3F stays there and reads the FIFO.
