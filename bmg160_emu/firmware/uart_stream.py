"""Reader of the firmware's UART sample stream (line format in docs/firmware.md).

The reader lives in :mod:`bmg160_emu.io.uart_stream`, beside the other file formats, so that
``identify`` (through the rate-file reader) can read a stream; this module keeps the names
the firmware tools import.
"""

from __future__ import annotations

from bmg160_emu.io.uart_stream import (
    MDPS_PER_DPS,
    UartStream,
    UartStreamError,
    parse_uart_stream,
    read_uart_stream,
)

__all__ = ["MDPS_PER_DPS", "UartStream", "UartStreamError", "parse_uart_stream",
           "read_uart_stream"]
