"""A noise profile as the TOML text ``load_profile`` reads back: every name, comment and number
written as a literal TOML accepts.

Why its own module: profile.py reads and checks a profile; this writes one (identify's
``--profile-out``, and ``thermal --errors-out``'s ``[errors]`` table, which a user adds to a
profile). A name or a comment comes from a file name, and Linux allows any byte in one but
``/`` and NUL: TOML (1.0.0, "String" and "Comment") forbids the control characters U+0000 to
U+001F (tab aside) and U+007F in both, and UTF-8 cannot hold the undecodable bytes Python
keeps as lone surrogates (PEP 383). A name is escaped (``\\u0001``), a comment shows such a
character as ``\\x01``, an undecodable byte as ``\\xff`` (as ``ls -b`` does).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import fields
from pathlib import Path
from typing import Any

from bmg160_emu.noise.profile import (
    AXES,
    BAND_KEYS,
    GM_KEYS,
    SINE_KEYS,
    UNITS,
    AxisNoise,
    Profile,
    ProfileError,
)

# TOML 1.0.0: the characters a basic string must escape, and those a comment may not hold
_CONTROL = re.compile("[\x00-\x08\x0a-\x1f\x7f]")
_SHORT_ESCAPES = {"\b": "\\b", "\n": "\\n", "\f": "\\f", "\r": "\\r"}  # (tab is allowed as it is)
# an axis's lists of terms: what the comment says, and the keys of each inline table
_TERM_LISTS = {
    "gm": ("Gauss-Markov terms: B deg/s, T s", GM_KEYS),
    "sine": ("sinusoidal terms (IEEE 952): A deg/s, f Hz", SINE_KEYS),
    "band": ("resonant band: resonators f Hz, width Hz, B deg/s", BAND_KEYS),
    "slow_band": ("slow band (below the response): resonators f Hz, width Hz, B deg/s",
                  BAND_KEYS),
}


def format_profile(profile: Profile, header: str = "") -> str:
    """The profile as TOML text that load_profile reads back (units in comments)."""
    lines = toml_comment(header)
    lines.append(f"name = {toml_string(profile.name)}")
    lines.append(f"description = {toml_string(profile.description)}")
    for axis_name, axis in zip(AXES, profile.axes):
        lines.append("")
        lines.append(f"[{axis_name}]")
        for f in fields(AxisNoise):
            value = getattr(axis, f.name)
            if f.name in _TERM_LISTS:
                lines += _inline_tables(f.name, *_TERM_LISTS[f.name], value)
                continue
            if f.name == "response":
                if value:
                    lines.append("response = [            # the measured output response "
                                 "at [output] rate_hz: c0, c1, ... (cosine series of |H|^2)")
                    lines += [f"  {toml_float(c, 'response')}," for c in value] + ["]"]
                continue
            if value is None or (f.name in ("Q", "R") and value == 0.0):
                continue
            if f.name in GM_KEYS and axis.gm and axis.B == 0.0:
                continue  # every term is in the gm list
            lines.append(f"{f.name} = {toml_float(value, f.name):<24}# {UNITS[f.name]}")
    if profile.output is not None:
        lines += ["", "[output]                  # the sensor's output filter and "
                  + "quantization (generate applies them)"]
        for key, value in profile.output.to_dict().items():
            text = str(value) if isinstance(value, int) else toml_float(value, key)
            lines.append(f"{key} = {text:<22}# {UNITS[key]}" if key in UNITS
                         else f"{key} = {text}")
    if profile.errors:
        lines += [""] + errors_table_lines(profile.errors)
    return "\n".join(lines) + "\n"


def write_profile(profile: Profile, path: str | Path, header: str = "") -> None:
    """Write a profile file (TOML) that load_profile and NoiseGenerator accept."""
    Path(path).write_text(format_profile(profile, header), encoding="utf-8")


def errors_table_lines(errors: Mapping[str, Any]) -> list[str]:
    """A profile's ``[errors]`` table (the unit's error budget, sensor_errors.SensorErrors)."""
    lines = ["[errors]                  # the unit's error budget (docs/error-budget.md)"]
    return lines + [f"{key} = {_toml_value(value)}" for key, value in errors.items()]


def toml_float(value: Any, what: str = "value") -> str:
    """A TOML float literal for any real number (numpy scalars included), finite only.

    ``repr`` of a numpy scalar is ``np.float64(0.01)``, which TOML rejects: the value is
    converted to a Python float first, and repr of a float is a valid TOML float
    (``0.01``, ``1e-05``, ``5.0``) that reads back bit for bit.
    """
    number = float(value)
    if not math.isfinite(number):
        raise ProfileError(f"{what} must be finite to be written to a profile, got {number}")
    return repr(number)


def toml_string(text: str) -> str:
    """A TOML basic string that reads back as ``text``; an undecodable byte of a file name
    (a lone surrogate, which no UTF-8 file can hold) as the four characters ``\\xNN``."""
    text = _decodable(text).replace("\\", "\\\\").replace('"', '\\"')
    return '"' + _CONTROL.sub(lambda m: _SHORT_ESCAPES.get(m[0], f"\\u{ord(m[0]):04x}"),
                              text) + '"'


def toml_comment(text: str) -> list[str]:
    """``text`` as TOML comment lines, one per line of it; a character a comment may not hold
    shown as ``\\xNN``."""
    return [f"# {_shown(line)}" if line else "#" for line in _decodable(text).splitlines()]


def _decodable(text: str) -> str:
    """``text`` with each undecodable byte (PEP 383's lone surrogate) as ``\\xNN``, and any
    other lone surrogate as ``\\udNNN``."""
    if not any("\ud800" <= c <= "\udfff" for c in text):
        return text
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a surrogate no byte stands for
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def _shown(line: str) -> str:
    return _CONTROL.sub(lambda m: f"\\x{ord(m[0]):02x}", line)


def _toml_value(value: Any) -> str:
    """A number, a string or (nested) lists of numbers as TOML."""
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, (list, tuple)) or hasattr(value, "tolist"):
        items = value.tolist() if hasattr(value, "tolist") else value
        return "[" + ", ".join(_toml_value(v) for v in items) + "]"
    number = float(value)
    if not math.isfinite(number):
        raise ProfileError(f"errors: {number} cannot be written (TOML profile values are finite)")
    return repr(number)


def _inline_tables(key: str, what: str, keys: tuple[str, ...],
                   terms: tuple[tuple[float, ...], ...]) -> list[str]:
    """A list of inline tables (an axis's gm, sine, band or slow_band terms), one a line."""
    if not terms:
        return []
    lines = [f"{key} = [".ljust(24) + f"# {what}"]
    for term in terms:
        cells = ", ".join(f"{k} = {toml_float(v, k)}" for k, v in zip(keys, term))
        lines.append(f"  {{ {cells} }},")
    return lines + ["]"]
