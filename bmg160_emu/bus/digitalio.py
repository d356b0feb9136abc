"""CircuitPython's ``digitalio`` module (``DigitalInOut``, ``Direction``, ``Pull``,
``DriveMode``) for the emulated board: what a CircuitPython SPI driver drives its chip-select
pin with (``adafruit_bus_device.spi_device.SPIDevice`` included).

A pin wired as a chip's chip select (:class:`~bmg160_emu.bus.board.circuitpython_board`)
frames SPI transfers while it is driven low (:func:`bmg160_emu.bus.busio.chip_select`); other
pins only keep their level.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from bmg160_emu.bus.busio import chip_select

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["DigitalInOut", "Direction", "DriveMode", "Pull"]


class _Named:
    def __init__(self, name: str) -> None:
        self.name = name

    def __repr__(self) -> str:
        return f"digitalio.{type(self).__name__}.{self.name}"


class Direction(_Named):
    INPUT: Direction
    OUTPUT: Direction


class Pull(_Named):
    UP: Pull
    DOWN: Pull


class DriveMode(_Named):
    PUSH_PULL: DriveMode
    OPEN_DRAIN: DriveMode


Direction.INPUT, Direction.OUTPUT = Direction("INPUT"), Direction("OUTPUT")
Pull.UP, Pull.DOWN = Pull("UP"), Pull("DOWN")
DriveMode.PUSH_PULL, DriveMode.OPEN_DRAIN = DriveMode("PUSH_PULL"), DriveMode("OPEN_DRAIN")


class DigitalInOut:
    """``digitalio.DigitalInOut(pin)``: an input until switched to an output."""

    def __init__(self, pin: Any) -> None:
        self.pin = pin
        self._direction = Direction.INPUT
        self._value = False
        self.pull: Pull | None = None
        self.drive_mode = DriveMode.PUSH_PULL

    @property
    def direction(self) -> Direction:
        return self._direction

    @direction.setter
    def direction(self, value: Direction) -> None:
        self._direction = value
        if value is Direction.OUTPUT:
            self.value = False  # CircuitPython: an output starts low

    def switch_to_output(self, value: bool = False, drive_mode: DriveMode = DriveMode.PUSH_PULL) -> None:
        self._direction, self.drive_mode = Direction.OUTPUT, drive_mode
        self.value = value

    def switch_to_input(self, pull: Pull | None = None) -> None:
        self._direction, self.pull = Direction.INPUT, pull

    @property
    def value(self) -> bool:
        if self._direction is Direction.INPUT:
            return self.pull is Pull.UP
        return self._value

    @value.setter
    def value(self, level: bool) -> None:
        if self._direction is not Direction.OUTPUT:
            raise AttributeError("Cannot set value when direction is input.")
        self._value = bool(level)
        chip_select(self.pin, self._value)

    def deinit(self) -> None:
        """Nothing to release on the emulated board."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.deinit()
