"""Which emulated bus a bus number or a /dev/i2c-N path reaches in this process.

The in-process node (patch_i2c_dev), FakeSMBus(n), MicroPython's machine.I2C(n) and
CircuitPython's board all look the bus up here; patches nest, so each number keeps a stack
and the innermost bus wins.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from bmg160_emu.bus.i2c import I2CBus

__all__ = ["emulated_bus", "emulated_bus_for_path", "emulated_bus_numbers", "register_bus",
           "unregister_bus"]

_registry: dict[int, list[I2CBus]] = {}


def register_bus(bus: I2CBus) -> None:
    """Make ``bus`` the emulated bus for its number (what opening /dev/i2c-N reaches)."""
    _registry.setdefault(bus.number, []).append(bus)


def unregister_bus(bus: I2CBus) -> None:
    stack = _registry.get(bus.number, [])
    for i in range(len(stack) - 1, -1, -1):
        if stack[i] is bus:
            del stack[i]
            break
    if not stack:
        _registry.pop(bus.number, None)


def emulated_bus(number: int) -> I2CBus | None:
    """The innermost registered bus with this number, or None."""
    stack = _registry.get(number)
    return stack[-1] if stack else None


def emulated_bus_numbers() -> list[int]:
    """The numbers of the registered buses, lowest first (the /dev/i2c-N that exist)."""
    return sorted(_registry)


def emulated_bus_for_path(path: str) -> I2CBus | None:
    """The registered bus for a device path such as ``/dev/i2c-1``."""
    prefix = "/dev/i2c-"
    if not path.startswith(prefix) or not path[len(prefix) :].isdigit():
        return None
    return emulated_bus(int(path[len(prefix) :]))
