"""Bounded numbers: every number a person or a file gives the project, checked in one place.

Why: a number that parses is not yet a number the emulator can use. ``1e308`` seconds
overflows the nanosecond clock, ``nan`` deg C reaches LAPACK, ``1e23`` runs allocate for ever
and ``-1`` writes ``TC_G-1_`` parameters. A :class:`Bounded` names the quantity, its unit and
its range (with the reason, listed in docs/limits.md) and turns text or a file's value into a
finite number in that range, or raises :class:`LimitError` with one line naming the option
or the file and place. The command line reads every numeric option through it
(``commands._common.bounded_option``), the file readers every numeric value they take.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

# an integer as people type it: decimal, or 0x/0o/0b; no exponent (1e23 is not an integer count)
_INTEGER = re.compile(r"^[+-]?(0[xX][0-9a-fA-F]+|0[oO][0-7]+|0[bB][01]+|\d+)$")
_MAX_DIGITS = 40  # longer integer text is refused before int() parses it (it is out of range)


def _shown(bound: float) -> str:
    """A range end as people read it: 1,000,000 rather than 1e+06; 0.001 and 1e+13 as %g."""
    if float(bound).is_integer() and abs(bound) < 1e12:
        return f"{int(bound):,}"
    if isinstance(bound, int) and (bound + 1) & bound == 0:  # 2**64 - 1 and the like
        return f"2**{(bound + 1).bit_length() - 1} - 1"
    return f"{bound:g}"


def finite_number(value: Any) -> float | None:
    """``value`` as a finite float, or None: a bool, a non-number, an integer beyond a
    double's range (TOML and JSON hold them: 1e400 written out in digits; math.isfinite and
    float() raise OverflowError on it) or inf/nan."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    try:
        number = float(value)
    except OverflowError:
        return None
    return number if math.isfinite(number) else None


class LimitError(ValueError):
    """A number that is not finite, not of the right kind, or outside its stated range; the
    message is one line and starts with where the number came from."""


@dataclass(frozen=True)
class Bounded:
    """A quantity ``name`` in ``unit``, accepted from ``low`` to ``high`` inclusive;
    ``integer`` for counts, seeds and indices. ``reason`` is where the range comes from."""

    name: str
    low: float
    high: float
    unit: str = ""
    integer: bool = False
    reason: str = ""

    def describe(self) -> str:
        """The accepted range in words: ``an integer from 0 to 3``, ``a number from ... deg C``."""
        kind = "an integer" if self.integer else "a number"
        unit = f" {self.unit}" if self.unit else ""
        return f"{kind} from {_shown(self.low)} to {_shown(self.high)}{unit}"

    def parse(self, text: str, where: str = "") -> Any:
        """``text`` (an option's value, a token of a text file) -> the checked number."""
        stripped = text.strip() if isinstance(text, str) else text
        if not isinstance(stripped, str):
            return self.check(stripped, where)
        if "_" in stripped:  # float() and int() take 1_000; a file or a person means a typo
            raise self._error(text, where)
        if self.integer:
            if len(stripped) > _MAX_DIGITS or not _INTEGER.match(stripped):
                raise self._error(text, where)
            value: Any = int(stripped, 0) if not stripped.lstrip("+-").isdigit() \
                else int(stripped)
        else:
            try:
                value = float(stripped)
            except ValueError:
                raise self._error(text, where) from None
        return self.check(value, where, shown=text)

    def check(self, value: Any, where: str = "", *, shown: Any = None) -> Any:
        """A number already read (TOML, JSON, an array element) -> the same number, checked:
        an ``int`` for an integer quantity, else a ``float``."""
        shown = value if shown is None else shown
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            try:  # numpy scalars
                import numbers

                if isinstance(value, bool) or not isinstance(value, numbers.Real):
                    raise TypeError
                value = int(value) if isinstance(value, numbers.Integral) else float(value)
            except (TypeError, ValueError, OverflowError):
                raise self._error(shown, where) from None
        if self.integer:
            if isinstance(value, float):
                if not (math.isfinite(value) and value.is_integer()):
                    raise self._error(shown, where)
                value = int(value)
            if not self.low <= value <= self.high:
                raise self._error(shown, where)
            return value
        try:
            value = float(value)  # an int of 400 digits overflows
        except OverflowError:
            raise self._error(shown, where) from None
        if not (math.isfinite(value) and self.low <= value <= self.high):
            raise self._error(shown, where)
        return value + 0.0  # -0.0 reads as 0.0

    def _error(self, shown: Any, where: str) -> LimitError:
        if isinstance(shown, int) and shown.bit_length() > 4000:  # repr() refuses 4300 digits
            text = f"an integer of {shown.bit_length()} bits"
        else:
            text = repr(shown)
        if len(text) > 60:
            text = text[:40] + "..." + text[-10:]
        prefix = f"{where}: " if where else ""
        return LimitError(f"{prefix}{self.name} must be {self.describe()}, not {text}")


# ---------------------------------------------------------------------------- the limits
# Each names its source; docs/limits.md lists them (tests/test_limits.py checks it does).

SEED = Bounded("seed", 0, 2**64 - 1, integer=True,
               reason="numpy's SeedSequence takes non-negative integers; 64 bits is what the "
                      "CSV headers and traces record")
FIRMWARE_SEED = Bounded("seed", 0, 2**32 - 1, integer=True,
                        reason="the firmware's generator state is a uint32 (BMG_SEED ...UL)")
SAMPLE_RATE_HZ = Bounded("sample rate", 1e-3, 1e6, "Hz",
                         reason="one sample in 1000 s up to 1 MHz, beyond any MEMS gyro's output "
                                "rate (the BMG160's highest ODR is 2000 Hz, data sheet 5.3)")
TEMPERATURE_C = Bounded("temperature", -40.0, 85.0, "deg C",
                        reason="the BMG160's operating range (data sheet, table 1)")
REFERENCE_TEMPERATURE_C = Bounded(
    "reference temperature", -41.0, 86.5, "deg C",
    reason="what the TEMP register can show: 23 deg C + (-128..127) x 0.5 K (data sheet 7.2)")
RATE_DPS = Bounded("angular rate", -1e6, 1e6, "deg/s",
                   reason="far beyond the 2000 deg/s full scale (the chip saturates) and inside "
                          "a scenario's vectors (docs/scenarios.md)")
BANDWIDTH_CODE = Bounded("bandwidth code", 0, 7, integer=True, reason="BW register (data sheet 5.3)")
RUNS = Bounded("runs", 1, 1_000_000, integer=True,
               reason="a million Monte Carlo runs: past any percentile's need, and the table of "
                      "curves they keep fits in memory")
SEED_START = Bounded("seeds", 0, 2**63 - 1, integer=True,
                     reason="seeds START..START+runs-1 stay inside a signed 64-bit integer")
WORKERS = Bounded("workers", 1, 1024, integer=True, reason="local processes: more than any machine's "
                                                          "cores")
ROWS = Bounded("rows", 0, 100_000, integer=True, reason="a printed table a person reads")
PX4_INSTANCE = Bounded("PX4 gyro instance", 0, 3, integer=True,
                       reason="PX4 keeps at most four gyros (GYRO_COUNT_MAX): TC_G0 to TC_G3")
DEMO_SAMPLES = Bounded("samples", 1, 1_000_000, integer=True,
                       reason="a demonstration: 1e6 reads at 2000 Hz are 500 s of simulated time")
BOOTSTRAP = Bounded("bootstrap resamples", 0, 10_000, integer=True,
                    reason="10,000 resamples give percentiles to 0.01; each costs one fit")
CURVE_SAMPLES = Bounded("samples", 2, 1e13, integer=True,
                        reason="the record behind a curve: at least 2 samples, at most 1e13 "
                               "(2000 Hz for 158 years)")
GAP_FACTOR = Bounded("gap factor", 1.0, 1e6, reason="a gap is a step longer than the median step")
REFRESH_HZ = Bounded("refresh rate", 1.0, 1e5, "Hz", reason="1 Hz to 100 kHz: beyond the 2000 Hz ODR")
ODR_HZ = Bounded("output data rate", 100, 2000, "Hz", integer=True,
                 reason="the BMG160's output data rates (data sheet 5.3)")
TAU_S = Bounded("averaging time", 1e-6, 1e13, "s",
                reason="a correlation time's range in noise profiles (noise/profile.py)")
FULL_SCALE_DPS = Bounded("full-scale range", 125, 2000, "deg/s", integer=True,
                         reason="the RANGE register's 125 to 2000 deg/s (data sheet 5.2)")
POLYNOMIAL_ORDER = Bounded("polynomial order", 0, 3, integer=True,
                           reason="PX4's thermal compensation is a cubic (TC_G*_X3)")
RECORD_SAMPLES = Bounded("samples to record", 1, 100_000_000, integer=True,
                        reason="work and memory: 1e8 samples are 13.9 h at 2000 Hz, 11.6 days "
                               "at 100 Hz; record holds about 140 bytes a sample until it "
                               "writes them (14 GB for 1e8) and refuses, by that figure, what "
                               "this process cannot hold")
# What record (and replay -o) holds per sample until it writes the file: 56 bytes of arrays
# (time, counts, truth) and the writer's copies. Peak RSS less a 50 s run's, over 400,000
# samples at 2000 Hz (2026-12-06): 78 bytes a sample to CSV, 117 to NPZ, 131 to RESD.
RECORD_BYTES_PER_SAMPLE = 140
THERMAL_BLOCKS = Bounded("blocks", 1, 2_000, integer=True,
                         reason="the fit's covariance holds blocks x blocks numbers and its "
                                "Cholesky costs blocks^3: 2,000 blocks take about 9 s and "
                                "280 MB, 4,000 blocks 30 s and 890 MB (measured)")
GUEST_TIMEOUT_S = Bounded("timeout", 1.0, 86_400.0, "s",
                          reason="wall time for a command in a kernel guest: a second (a boot "
                                 "takes about that) to a day")
I2C_BUS = Bounded("bus", 0, 2**20 - 1, integer=True,
                  reason="Linux numbers /dev/i2c-N below I2C_MINORS, 2**20 (drivers/i2c/i2c-dev.c)")
ALLAN_DEVIATION_DPS = Bounded("Allan deviation", 1e-30, 1e6, "deg/s",
                             reason="the largest angular rate a file may hold (RATE_DPS): an "
                                    "Allan deviation is below the rates it is made of; the "
                                    "fit weighs each point by its variance squared, adev^-4, "
                                    "which overflows below 1e-77 (a 1e-320 point crashed it): "
                                    "1e-30 is 20 orders below any gyroscope's")
DIE_TEMPERATURE_C = Bounded("temperature", -50.0, 150.0, "deg C",
                           reason="what a die survives: the BMG160's storage range, -50 to "
                                  "150 deg C (data sheet, table 1: absolute maximum ratings)")
