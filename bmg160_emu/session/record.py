"""Recordings of what the chip outputs at its output data rate.

A recording holds, per output sample: the chip's sample time, the three rate words as the
driver reads them (raw counts from RATE_X/Y/Z), the same in deg/s with the range's
sensitivity, and the true body rate the chip was fed (from ``chip.truth_hooks``). It is
written as CSV, NPZ or RESD by :mod:`bmg160_emu.io.recording` (``docs/commands/record.md``).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bmg160_emu.device import spec_choices
from bmg160_emu.device.registers import address_of
from bmg160_emu.io.recording import Recording

RATE_X_LSB = address_of("RATE_X_LSB")  # a 6-byte burst from here gives x, y, z LSB first (4.2)
RANGE, BW = address_of("RANGE"), address_of("BW")


# --------------------------------------------------------------------------- recording


def chip_odr_hz(chip) -> float:
    """The chip's current output data rate, from its own attribute or BW (spec 5.3)."""
    for name in ("odr_hz", "output_data_rate_hz"):
        value = getattr(chip, name, None)
        if value is not None:
            return float(value() if callable(value) else value)
    return float(spec_choices.bandwidth(chip.peek(BW))[0])  # codes 8..15 as code & 7 (4.9)


def chip_lsb_per_dps(chip) -> float:
    """The chip's current sensitivity in LSB per deg/s (spec 5.1; binary or nominal table)."""
    for name in ("sensitivity", "lsb_per_dps"):
        value = getattr(chip, name, None)
        if value is not None:
            return float(value() if callable(value) else value)
    raise AttributeError("the chip exposes no sensitivity (lsb_per_dps)")


def chip_range_dps(chip) -> int:
    """Full scale of the chip's current RANGE code; reserved codes 5..7 act as 2000 (spec 4.8)."""
    return spec_choices.RANGE_FULL_SCALE_DPS[spec_choices.range_code(chip.peek(RANGE))]


def record(
    chip,
    duration_s: float,
    progress: Callable[[int, int], None] | None = None,
) -> Recording:
    """Read every output sample of ``chip`` for ``duration_s`` seconds of chip time.

    After each new sample the 6 rate bytes are read in one burst from RATE_X_LSB, as a
    polling driver would; the clock is advanced to the middle of each output period so every
    step holds exactly one sample whatever the rounding of the sample times.
    """
    if not (duration_s > 0 and math.isfinite(duration_s)):
        raise ValueError(f"duration must be positive, not {duration_s}")
    odr = chip_odr_hz(chip)
    period = 1.0 / odr
    n = round(duration_s * odr)
    if n < 1:
        raise ValueError(f"{duration_s} s is shorter than one output period ({period} s)")
    samples: list[tuple[float, np.ndarray]] = []

    def truth(_chip, t, true_rate) -> None:
        samples.append((float(t), np.array(true_rate, dtype=float, copy=True)))

    t_s = np.empty(n)
    counts = np.empty((n, 3), dtype=np.int64)
    truth_rows = np.empty((n, 3))
    chip.truth_hooks.append(truth)
    k = 0
    try:
        # Find the phase of the sample clock: advance one period at a time until one appears.
        for _ in range(3):
            if samples:
                break
            chip.advance(period)
        if not samples:
            raise RuntimeError("the chip produced no sample in three output periods (suspended?)")
        first_t = samples[-1][0]
        del samples[:-1]
        for k in range(n):
            if k > 0:
                chip.advance(first_t + (k + 0.5) * period - chip.time)
                if len(samples) != 1:
                    raise RuntimeError(
                        f"{len(samples)} samples in one output period at t={chip.time:.6f} s: "
                        "did the output data rate change?"
                    )
            data = chip.read(RATE_X_LSB, 6)
            raw = np.frombuffer(bytes(data), dtype="<i2")
            t_s[k], truth_rows[k] = samples[0]
            counts[k] = raw
            samples.clear()
            if progress is not None:
                progress(k + 1, n)
    except KeyboardInterrupt as exc:  # ^C, SIGTERM: the samples so far, as a shorter record
        done = k  # samples 0 .. k - 1 are complete
        metadata = {"odr_hz": odr, "range_dps": chip_range_dps(chip),
                    "seed": getattr(chip, "seed", None), "interrupted": True,
                    "samples_planned": n}
        partial = Recording(t_s[:done], counts[:done], chip_lsb_per_dps(chip),
                            truth_rows[:done], metadata)
        raise RecordingInterrupted(partial, exc) from None
    finally:
        chip.truth_hooks.remove(truth)
    metadata = {
        "odr_hz": odr,
        "range_dps": chip_range_dps(chip),
        "seed": getattr(chip, "seed", None),
    }
    return Recording(t_s, counts, chip_lsb_per_dps(chip), truth_rows, metadata)


class RecordingInterrupted(KeyboardInterrupt):
    """^C or SIGTERM during :func:`record`: ``recording`` holds the complete samples so far
    (its metadata says ``interrupted`` and ``samples_planned``)."""

    def __init__(self, recording: Recording, cause: BaseException) -> None:
        super().__init__()
        self.recording = recording
        self.signal_name = getattr(cause, "signal_name", "SIGINT")


# Output data rate -> the BW code the Linux driver writes for it (LNX bmg160_samp_freq_table;
# spec 5.3). Codes 0, 4 and 5 give the same rates with other filters: use --bandwidth for them.
BW_CODE_BY_ODR_HZ = {100: 0x07, 200: 0x06, 400: 0x03, 1000: 0x02, 2000: 0x01}
