"""bmg160-emu: a register-level emulator of the Bosch BMG160 gyroscope.

Public names are imported lazily (PEP 562) so that ``import bmg160_emu`` stays cheap and a
command that needs only one part of the package does not pay for the others.
"""

from __future__ import annotations

import signal as _signal
import sys as _sys


def _stopped_while_starting(number: int, frame: object) -> None:
    # os._exit, not SystemExit: the handler may run inside a finaliser during an import,
    # where an exception is printed and ignored (a traceback, and the command ran on); and
    # before the command runs there is nothing to finish or clean up
    _sys.stderr.write(f"bmg160-emu: interrupted by {_signal.Signals(number).name} while "
                      "starting; nothing written\n")
    _sys.stderr.flush()
    import os

    os._exit(128 + number)


# Run as the command (console script, python -m bmg160_emu), SIGINT and SIGTERM stop it with
# one line and their exit status from the package's first line on, never a KeyboardInterrupt
# traceback out of an import (issue 24); bmg160_emu.cli takes over when the command starts.
# (the console script's own file is __main__: a Dask worker spawned from it gets its
# sys.argv, not its __main__, and keeps Python's handlers)
_MAIN_FILE = str(getattr(_sys.modules.get("__main__"), "__file__", None) or "")
if (_sys.argv[0].endswith("bmg160-emu") and _MAIN_FILE.endswith("bmg160-emu")) \
        or _sys.orig_argv[1:3] == ["-m", "bmg160_emu"]:
    for _number in (_signal.SIGINT, _signal.SIGTERM):
        if _signal.getsignal(_number) is not _signal.SIG_IGN:  # nohup, a background job
            _signal.signal(_number, _stopped_while_starting)

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
