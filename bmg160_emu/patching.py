"""Deprecated: moved to ``bmg160_emu.bus.patching``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.patching as _moved

warnings.warn("bmg160_emu.patching moved to bmg160_emu.bus.patching", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
