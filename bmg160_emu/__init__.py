"""bmg160-emu: a register-level emulator of the Bosch BMG160 gyroscope.

Public names are imported lazily (PEP 562) so that ``import bmg160_emu`` stays cheap and a
command that needs only one part of the package does not pay for the others.
"""

from __future__ import annotations

# First: SIGINT and SIGTERM held as the command, ignored by its workers (bmg160_emu.startup)
try:
    from bmg160_emu import startup as _startup

    _startup.hold_signals()
except KeyboardInterrupt:  # a ^C while that first module loads, before its handler is in
    from bmg160_emu import startup as _startup

    _startup.interrupted_while_loading()  # the command's one line (a library import: raise)
    raise

import importlib
from typing import Any

__version__ = "0.3.0"

# public name -> module that defines it
_EXPORTS = {
    "BMG160": "bmg160_emu.device.chip",
    "make_chip": "bmg160_emu.device.parts",
    "PART_NAMES": "bmg160_emu.device.parts",
    "VirtualClock": "bmg160_emu.clock",
    "RealTimeClock": "bmg160_emu.clock",
    "virtual_sleep": "bmg160_emu.clock",
    "I2CBus": "bmg160_emu.bus.i2c",
    "FakeSMBus": "bmg160_emu.bus.smbus",
    "patch_smbus": "bmg160_emu.bus.patching",
    "patch_i2c_dev": "bmg160_emu.bus.i2c_dev_node",
    "patch_spidev": "bmg160_emu.bus.patching",
    "FakeSpiDev": "bmg160_emu.bus.spi",
    "micropython_machine": "bmg160_emu.bus.machine",
    "circuitpython_board": "bmg160_emu.bus.board",
    "Transaction": "bmg160_emu.traffic.transaction",
    "TransactionLog": "bmg160_emu.traffic.transaction",
    "NoiseGenerator": "bmg160_emu.noise",
    "load_profile": "bmg160_emu.noise",
}

__all__ = [
    "BMG160",
    "PART_NAMES",
    "FakeSMBus",
    "FakeSpiDev",
    "I2CBus",
    "NoiseGenerator",
    "RealTimeClock",
    "Transaction",
    "TransactionLog",
    "VirtualClock",
    "__version__",
    "circuitpython_board",
    "load_profile",
    "make_chip",
    "micropython_machine",
    "patch_i2c_dev",
    "patch_smbus",
    "patch_spidev",
    "virtual_sleep",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'bmg160_emu' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return list(__all__)
