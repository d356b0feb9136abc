"""Deprecated: moved to ``bmg160_emu.bus.umockdev``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.umockdev as _moved

warnings.warn("bmg160_emu.linux.umockdev_node moved to bmg160_emu.bus.umockdev", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
