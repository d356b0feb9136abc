"""One parser for the durations people type: ``10s``, ``5min``, ``2h``, ``1d``, ``250ms``, ``100us``,
and the text durations are written back as (``duration_text``, ``exact_duration_text``).

Every command-line option and the register-script language read durations through
:func:`parse_duration`, so the same text means the same time everywhere. Callers choose
only whether a bare number (seconds) is accepted and whether zero is a valid duration.

Every duration, and every simulated time a file gives (scenarios, trace records, replay
spans), is at most :data:`MAX_SIMULATED_S` and, when positive, at least the chip clock's
1 ns step (:data:`MIN_STEP_S`): a script interval that rounds to 0 ns would never advance.
"""

from __future__ import annotations

import math

# Unit suffix -> seconds. Suffixes are read case-insensitively ("10MS" is 10 ms).
UNIT_SECONDS: dict[str, float] = {
    "us": 1e-6,
    "ms": 1e-3,
    "s": 1.0,
    "min": 60.0,
    "h": 3600.0,
    "d": 86400.0,
}
UNIT_NAMES = "us, ms, s, min, h or d"
# The one cap on simulated time: 30 days. Longer than any Allan-variance or mission run the
# project serves (the long runs in docs/noise-engine.md are 24 h), and what the emulator
# simulates in about 15-25 min at 2000 Hz (about 1 s per simulated hour, measured with
# `script` and `advance 1h`); a longer request is refused, not left to run for hours.
MAX_SIMULATED_S = 30 * 86400.0
MIN_STEP_S = 1e-9  # the chip clock's step (bmg160_emu.clock counts integer nanoseconds)
MAX_TEXT = "30 days (2592000 s)"
EXAMPLES = "e.g. 10s, 5min, 2h, 1d, 250ms"


def parse_duration(text: str, *, unit_required: bool = False, allow_zero: bool = False) -> float:
    """``text`` -> seconds, finite and positive (or zero when ``allow_zero``).

    A bare number is seconds unless ``unit_required`` (the script language asks for a unit
    because simulated time is exact and "10" alone is ambiguous). Raises ``ValueError`` with
    a message that names the text and says what is expected.
    """
    if not isinstance(text, str):
        raise TypeError(f"a duration is text such as '10s', not {type(text).__name__}")
    stripped = text.strip().lower()
    if "_" in stripped:  # float() takes 1_000; a person typing a duration means a typo
        raise ValueError(f"not a duration: {text!r} ({EXAMPLES})")
    number = stripped.rstrip("abcdefghijklmnopqrstuvwxyz")
    unit = stripped[len(number):]
    try:
        value = float(number)
    except ValueError:
        raise ValueError(f"not a duration: {text!r} ({EXAMPLES})") from None
    if unit == "" and unit_required:
        raise ValueError(f"duration {text.strip()!r} needs a unit: {UNIT_NAMES}")
    if unit and unit not in UNIT_SECONDS:
        raise ValueError(f"not a duration: {text!r} (unknown time unit {unit!r}; use {UNIT_NAMES})")
    seconds = value * UNIT_SECONDS.get(unit, 1.0)
    if not math.isfinite(seconds) or seconds < 0 or (seconds == 0 and not allow_zero):
        qualifier = "zero or positive" if allow_zero else "positive"
        raise ValueError(f"duration must be {qualifier}: {text!r}")
    check_simulated_time(seconds, repr(text.strip()))
    return seconds + 0.0  # -0.0 (from '-0s') reads as 0.0


def check_simulated_time(seconds: float, shown: str, what: str = "duration") -> float:
    """``seconds`` unchanged if it is 0 or from 1 ns to :data:`MAX_SIMULATED_S`; else a
    ``ValueError`` naming ``what`` and ``shown`` (the text or value as given)."""
    if not math.isfinite(seconds) or seconds > MAX_SIMULATED_S:
        raise ValueError(f"{what} {shown} is longer than the cap on simulated time, {MAX_TEXT}")
    if 0 < seconds < MIN_STEP_S:
        raise ValueError(f"{what} {shown} is shorter than the chip clock's 1 ns step")
    return seconds


def duration_text(seconds: float, gap: str = " ") -> str:
    """A duration for a report, to 3 significant digits in h, min or s (``1.5 h``,
    ``20 min``, ``0.25 s``), in the units :func:`parse_duration` reads back; ``gap=""``
    writes it as an option's value (``--skip 15min``)."""
    if seconds >= 3600:
        return f"{seconds / 3600:.3g}{gap}h"
    if seconds >= 60:
        return f"{seconds / 60:.3g}{gap}min"
    return f"{seconds:.3g}{gap}s"


def exact_duration_text(seconds: float) -> str:
    """A duration as given, every digit kept, in s, ms or us (``2 s``, ``250 ms``,
    ``100 us``): what a register script says it advanced."""
    if seconds >= 1 or seconds == 0:
        return f"{seconds:g} s"
    if seconds >= 1e-3:
        return f"{seconds * 1e3:g} ms"
    return f"{seconds * 1e6:g} us"
