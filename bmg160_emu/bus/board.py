"""CircuitPython's ``board`` module for the emulated board: its pins, ``board.I2C()`` and
``board.SPI()``, and :class:`circuitpython_board`, which wires chips to them and puts
``board``, ``busio`` and ``digitalio`` in ``sys.modules`` for a test.

The board is a generic one (the Feather's pin names): ``SCL``/``SDA`` carry the I2C bus the
test wires, ``SCK``/``MOSI``/``MISO`` the SPI bus, ``D0``..``D13`` and ``A0``..``A5`` are
plain pins (chip selects among them).
"""

from __future__ import annotations

import sys
import types
from collections.abc import Mapping
from contextlib import ContextDecorator
from typing import Any

from bmg160_emu.bus import busio, digitalio
from bmg160_emu.bus.i2c import I2CBus

__all__ = ["I2C", "SPI", "Pin", "circuitpython_board"]


class Pin:
    """``microcontroller.Pin``: a named pin of the board (compared by identity)."""

    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f"board.{self.name}"


SCL, SDA, SCK, MOSI, MISO = (Pin(n) for n in ("SCL", "SDA", "SCK", "MOSI", "MISO"))
D0, D1, D2, D3, D4, D5, D6, D7, D8, D9, D10, D11, D12, D13 = (Pin(f"D{i}") for i in range(14))
A0, A1, A2, A3, A4, A5 = (Pin(f"A{i}") for i in range(6))
PINS = {p.name: p for p in (SCL, SDA, SCK, MOSI, MISO, D0, D1, D2, D3, D4, D5, D6, D7, D8, D9,
                            D10, D11, D12, D13, A0, A1, A2, A3, A4, A5)}

_singletons: dict[str, Any] = {}


def I2C() -> busio.I2C:
    """The board's I2C bus on SCL/SDA, one object for every caller (``board.I2C()``)."""
    bus = _singletons.get("I2C")
    if bus is None or bus.deinitialized:
        bus = _singletons["I2C"] = busio.I2C(SCL, SDA)
    return bus


def SPI() -> busio.SPI:
    """The board's SPI bus on SCK/MOSI/MISO, one object for every caller (``board.SPI()``)."""
    bus = _singletons.get("SPI")
    if bus is None or bus.deinitialized:
        bus = _singletons["SPI"] = busio.SPI(SCK, MOSI, MISO)
    return bus


def _pin(name: Any) -> Pin:
    if isinstance(name, Pin):
        return name
    try:
        return PINS[str(name)]
    except KeyError:
        raise ValueError(f"the board has no pin {name!r}: one of {', '.join(PINS)}") from None


class circuitpython_board(ContextDecorator):
    """Context manager (and decorator): ``import board, busio, digitalio`` give the
    emulated board, with ``i2c`` (an I2CBus, or {address: chip} for bus ``i2c_number``) on
    SCL/SDA and ``spi`` ({chip-select pin or its name: chip}) on SCK/MOSI/MISO; yields the
    ``board`` module."""

    def __init__(self, i2c: I2CBus | Mapping[int, Any] | None = None, *,
                 spi: Mapping[Any, Any] | None = None, i2c_number: int = 1) -> None:
        self.i2c = i2c if isinstance(i2c, I2CBus) or i2c is None else I2CBus(i2c_number, i2c)
        self.spi = {_pin(pin): chip for pin, chip in (spi or {}).items()}
        self._saved: dict[str, Any] = {}

    def __enter__(self) -> types.ModuleType:
        busio.wiring.clear()
        _singletons.clear()
        if self.i2c is not None:
            busio.wiring.i2c[(SCL, SDA)] = self.i2c
        busio.wiring.spi_pins = (SCK, MOSI, MISO)
        busio.wiring.chip_selects.update(self.spi)
        module = sys.modules[__name__]
        for name, value in (("board", module), ("busio", busio), ("digitalio", digitalio)):
            self._saved[name] = sys.modules.get(name)
            sys.modules[name] = value
        return module

    def __exit__(self, *exc: object) -> None:
        for name, old in self._saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old
        self._saved = {}
        busio.wiring.clear()
        _singletons.clear()
