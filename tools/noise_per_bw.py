"""The plugin chip's noise at rest per BW code: the table docs/pytest-plugin.md shows.

A test writer picks a tolerance from it: the standard deviation of one output sample of a
chip at rest (true rate 0), per axis, in deg/s and in counts at the reset range (+-2000
deg/s, 16.384 LSB per deg/s). It is measured on the chip itself, the way a driver sees it
(a RATE_X_LSB..RATE_Z_MSB burst after each output period), so it follows the noise model
and the chip's filter as they are: regenerate the page's table after either changes.

    python tools/noise_per_bw.py            # prints the Markdown table
    python tools/noise_per_bw.py --check docs/pytest-plugin.md   # exit 1 if the page differs

``SAMPLES`` samples per code give a relative standard error of the std of about
1 / sqrt(2 * SAMPLES) = 1.1 % for white noise (more where the filter correlates successive
samples), so deg/s are shown to 0.01 and counts to 0.1. The plugin's defaults: seed 7, profile
"paper".
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import address_of

SAMPLES = 4000
RATE_X_LSB, BW = address_of("RATE_X_LSB"), address_of("BW")
FULL_SCALE_DPS = 2000.0  # RANGE reset value 0: +-2000 deg/s
BW_TEXT = {0: ("2000", "523"), 1: ("2000", "230"), 2: ("1000", "116"), 3: ("400", "47"),
           4: ("200", "23"), 5: ("100", "12"), 6: ("200", "64"), 7: ("100", "32")}  # spec 4.9
BEGIN, END = "<!-- noise-per-bw: begin -->", "<!-- noise-per-bw: end -->"


def noise_std(bw_code: int, seed: int = 7, samples: int = SAMPLES) -> np.ndarray:
    """Per-axis standard deviation of the output at rest, in counts."""
    chip = BMG160(seed=seed)
    chip.write(BW, bytes([bw_code]))
    period = 1.0 / chip.odr_hz
    chip.advance(0.5)  # past start-up and the filter's settling
    counts = np.empty((samples, 3))
    for i in range(samples):
        chip.advance(period)
        counts[i] = np.frombuffer(chip.read(RATE_X_LSB, 6), dtype="<i2")
    return counts.std(axis=0, ddof=1)


def table() -> str:
    lines = [BEGIN,
             "| BW | ODR, filter | std x, y, z (deg/s) | std x, y, z (counts at +-2000 deg/s) |",
             "| --- | --- | --- | --- |"]
    lsb_per_dps = 32768 / FULL_SCALE_DPS
    for code in range(8):
        std = noise_std(code)
        odr, filt = BW_TEXT[code]
        dps = ", ".join(f"{v / lsb_per_dps:.2f}" for v in std)
        counts = ", ".join(f"{v:.1f}" for v in std)
        lines.append(f"| {code} | {odr} Hz, {filt} Hz | {dps} | {counts} |")
    lines.append(END)
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", type=Path, metavar="PAGE",
                        help="compare with the table between the page's noise-per-bw markers")
    args = parser.parse_args()
    text = table()
    if args.check is None:
        print(text)
        return 0
    page = args.check.read_text(encoding="utf-8")
    if BEGIN not in page or END not in page:
        print(f"{args.check}: no {BEGIN} ... {END} block", file=sys.stderr)
        return 1
    shown = page[page.index(BEGIN):page.index(END) + len(END)]
    if shown != text:
        print(f"{args.check}: the noise table is stale; regenerate it with "
              f"python tools/noise_per_bw.py\n{text}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
