"""The ``fault:<kind>`` log entry: written by the fault engine, read by trace decoding and
replay, in one place below both.

A fault that changed the chip, its samples or the bytes the host read (anything but a
failed transaction, which is its own record) adds one entry to the bus's log at its onset.
Its ``written`` bytes are UTF-8 text: the fault's description for a person, then one JSON
line with what a replay needs (docs/trace-format.md, "Fault entries")::

    {"fault": {kind, effect parameters}, "activation": {start_s, end_s, first_sample_s,
     held_dps}, "base_temperature_c": ...}

``activation`` comes with sample faults only, ``base_temperature_c`` with a temperature
ramp. Entries written before the JSON line was added carry the description alone.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from bmg160_emu.traffic.kinds import FAULT_KIND_PREFIX


def fault_kind(kind: str) -> str | None:
    """The fault kind of a log entry's kind (``"fault:spike"`` -> ``"spike"``), or None."""
    return kind[len(FAULT_KIND_PREFIX):] if kind.startswith(FAULT_KIND_PREFIX) else None


def fault_entry_text(detail: str, effect: Mapping[str, Any] | None = None, *,
                     start_s: float | None = None, end_s: float | None = None,
                     first_sample_s: float | None = None,
                     held_dps: Sequence[float] | None = None, activation: bool = False,
                     base_temperature_c: float | None = None) -> str:
    """The written bytes of a ``fault:<kind>`` entry: ``detail``, then (with ``effect``, the
    fault's kind and the effect parameters that differ from their defaults) the JSON line.
    ``activation``: the fault acts on samples, and ``start_s`` .. ``end_s`` (None: for
    ever), the first sample it touched and the value a stuck axis holds (deg/s) say when
    and how."""
    if effect is None:
        return detail
    entry: dict[str, Any] = {"fault": dict(effect)}
    if activation:
        entry["activation"] = {
            "start_s": start_s,
            "end_s": end_s,
            "first_sample_s": first_sample_s,
            "held_dps": None if held_dps is None else [float(v) for v in held_dps],
        }
    if base_temperature_c is not None:
        entry["base_temperature_c"] = float(base_temperature_c)
    return detail + "\n" + json.dumps(entry, sort_keys=True)


def parse_fault_entry(written: bytes | str) -> tuple[str, dict[str, Any] | None]:
    """(description, parameters or None) of a ``fault:<kind>`` entry's written bytes.

    Entries written before the parameters were added carry only the description (None)."""
    text = written.decode("utf-8", "replace") if isinstance(written, (bytes, bytearray)) else written
    detail, _, rest = text.partition("\n")
    if not rest.strip():
        return detail, None
    try:
        entry = json.loads(rest)
    except json.JSONDecodeError:
        return detail, None
    if not isinstance(entry, dict) or not isinstance(entry.get("fault"), dict):
        return detail, None
    return detail, entry
