"""Deprecated: moved to ``bmg160_emu.bus.kernel_abi``; this name stays for one release (issue 10's layout)."""

import sys
import warnings

import bmg160_emu.bus.kernel_abi as _moved

warnings.warn("bmg160_emu.linux.i2c_dev_structs moved to bmg160_emu.bus.kernel_abi", DeprecationWarning, stacklevel=2)
sys.modules[__name__] = _moved
