"""The emulated MicroPython board: what a test or ``bmg160-emu micropython`` wired to it.

The drop-in ``machine`` stands for the ESP32 port (the common MicroPython target): a CPU at
160 MHz (the port's default, ``machine.freq()``), two hardware I2C controllers I2C(0) and
I2C(1) of which the wired ones exist, ENODEV for an address nobody acknowledges. The heap
is unlimited unless ``heap_bytes`` says otherwise (an ESP32 without PSRAM has about 110 KB
for Python; a buffer past it is a MemoryError, as on the board).
"""

from __future__ import annotations

from typing import Any

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.registry import emulated_bus

CPU_HZ = 160_000_000  # the ESP32 port's default CPU frequency (machine.freq())
CPU_MHZ_CHOICES = (20, 40, 80, 160, 240)  # ports/esp32/modmachine.c mp_machine_set_freq
# machine.unique_id(): the ESP32's 6-byte base MAC (esp_efuse_mac_get_default); this board's
# is Espressif's OUI 24:0A:C4 with a fixed device part, the same on every run
UNIQUE_ID = bytes((0x24, 0x0A, 0xC4, 0x16, 0x01, 0x60))


class Board:
    """What is wired: the bus every SoftI2C reaches, chip selects and pin levels, the CPU
    frequency, the heap, and a sentence saying where the chips are (for a bus that is not
    there)."""

    def __init__(self) -> None:
        self.soft_i2c: int | None = None
        self.chip_selects: dict[Any, tuple[Any, Any]] = {}  # pin id -> (SPI id, chip)
        self.frames: dict[Any, Any] = {}  # pin id -> the SPI frame while CS is low
        self.levels: dict[Any, int] = {}
        self.cpu_hz = CPU_HZ
        self.heap_bytes: int | None = None
        # where the chips are, for the error of a bus not wired; {id} is the one asked for
        self.where = ""

    def i2c_bus(self, number: int) -> I2CBus:
        """The wired bus ``number``; ValueError ``I2C(n) doesn't exist`` (with where the
        chips are) for any other."""
        bus = emulated_bus(number)
        if bus is None:
            where = self.where.format(id=number)
            raise ValueError(f"I2C({number}) doesn't exist" + (f": {where}" if where else ""))
        return bus

    def reset(self) -> None:
        self.__init__()  # type: ignore[misc]


board = Board()
