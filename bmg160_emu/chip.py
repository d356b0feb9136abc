"""Deprecated: moved to ``bmg160_emu.device.chip``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.device.chip as _moved

warnings.warn("bmg160_emu.chip moved to bmg160_emu.device.chip", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
