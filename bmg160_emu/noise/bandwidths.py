"""The BMG160 family's output filter per BW code (register spec 5.3): each code's output
data rate and the -3 dB bandwidth of its low-pass, and the filter's order.

Why in noise/: a profile's ``[output]`` table may name its filter as a BW code, and
``generate --bandwidth`` filters noise through a code's filter, with no chip in sight. The
chip (device/) translates a BW register byte into a code (``spec_choices.bw_code``: codes
8..15 behave as code & 7, 4.9) and takes the code's filter from here. The figures are
unconfirmed choices of the spec (docs/unconfirmed-choices.md), chosen here and nowhere else.
"""

from __future__ import annotations

# 5.3: BW code -> (ODR Hz, -3 dB low-pass bandwidth Hz).
BANDWIDTHS = {
    0: (2000, 523.0),  # QC figure; BMI088 sources say 532 Hz
    1: (2000, 230.0),
    2: (1000, 116.0),
    3: (400, 47.0),
    4: (200, 23.0),
    5: (100, 12.0),
    6: (200, 64.0),
    7: (100, 32.0),
}
BW_CODES = range(len(BANDWIDTHS))  # the BW field's eight codes (4.9)

# The chip's filter is not documented: a Butterworth low-pass of this order at the table's
# bandwidth, unity DC gain (5.3, unconfirmed).
LOWPASS_ORDER = 2


def code_filter(code: object) -> tuple[int, float]:
    """(ODR Hz, bandwidth Hz) of a BW code 0..7; ValueError naming the codes otherwise."""
    if isinstance(code, bool) or code not in BANDWIDTHS:
        codes = ", ".join(f"{c} ({o} Hz ODR, {b:g} Hz)" for c, (o, b) in BANDWIDTHS.items())
        raise ValueError(f"unknown BW code {code!r}: use one of {codes}")
    return BANDWIDTHS[code]  # type: ignore[index]
