"""Deprecated: moved to ``bmg160_emu.bus.smbus``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.smbus as _moved

warnings.warn("bmg160_emu.smbus moved to bmg160_emu.bus.smbus", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
