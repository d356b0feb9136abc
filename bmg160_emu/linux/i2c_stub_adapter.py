"""Deprecated: moved to ``bmg160_emu.bus.i2c_stub``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.i2c_stub as _moved

warnings.warn("bmg160_emu.linux.i2c_stub_adapter moved to bmg160_emu.bus.i2c_stub", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
