"""Fixtures that give the same driver-level tests a Python BMG160 and the simulated firmware."""

from __future__ import annotations

import pytest

from bmg160_emu.firmware.build import (
    AVR_PACKAGES,
    SIM_PACKAGES,
    FirmwareToolError,
    build_firmware,
    missing_avr_tools,
    simavr_available,
)


def firmware_skip_reason() -> str | None:
    """Why the firmware cannot be built and simulated here, or None."""
    missing = missing_avr_tools()
    if missing:
        return f"{', '.join(missing)} not installed (Debian packages {AVR_PACKAGES})"
    if not simavr_available():
        return f"simavr development files not installed (Debian packages {SIM_PACKAGES})"
    return None


def require_firmware_build(**kwargs):
    """Build the firmware (cached by configuration) or skip the test with the reason."""
    reason = firmware_skip_reason()
    if reason:
        pytest.skip(reason)
    try:
        return build_firmware(**kwargs)
    except FirmwareToolError as exc:  # a broken toolchain is a failure, not a skip
        pytest.fail(str(exc))
