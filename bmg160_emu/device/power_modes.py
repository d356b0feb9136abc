"""The power modes (spec 6.7): normal, deep suspend, suspend, fast power-up and advanced
power saving, from the LPM1 and LPM2 bits by the physical priority rule (unconfirmed)."""

from __future__ import annotations

from bmg160_emu.device.registers import field_of

NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE = (
    "normal", "deep suspend", "suspend", "fast power-up", "advanced power saving")
MODES = (NORMAL, DEEP_SUSPEND, SUSPEND, FAST_POWER_UP, POWER_SAVE)
SAMPLING_MODES = (NORMAL, POWER_SAVE)  # 6.7: power saving samples as normal (unconfirmed)

_SUSPEND = field_of("LPM1", "suspend").mask
_DEEP_SUSPEND = field_of("LPM1", "deep_suspend").mask
_FAST_POWER_UP = field_of("LPM2", "fast_power_up").mask
_POWER_SAVE = field_of("LPM2", "power_save_mode").mask


def power_mode(lpm1: int, lpm2: int) -> str:
    """Power mode from LPM1/LPM2 by the physical priority rule of spec 6.7 (unconfirmed)."""
    if lpm1 & _DEEP_SUSPEND:
        return DEEP_SUSPEND
    if lpm1 & _SUSPEND:
        return FAST_POWER_UP if lpm2 & _FAST_POWER_UP else SUSPEND
    if lpm2 & _POWER_SAVE:
        return POWER_SAVE
    return NORMAL
