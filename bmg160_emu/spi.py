"""Deprecated: moved to ``bmg160_emu.bus.spi``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.spi as _moved

warnings.warn("bmg160_emu.spi moved to bmg160_emu.bus.spi", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
