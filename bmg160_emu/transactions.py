"""Deprecated: moved to ``bmg160_emu.bus.transactions``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.transactions as _moved

warnings.warn("bmg160_emu.transactions moved to bmg160_emu.bus.transactions", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
