"""Deprecated: moved to ``bmg160_emu.bus.i2c``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.i2c as _moved

warnings.warn("bmg160_emu.i2c_bus moved to bmg160_emu.bus.i2c", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
