"""A register-file stand-in's SPI frame: how the declared chip decodes the bytes clocked while
its chip select is low (``StandinSpec.spi``).

The first byte is R/W (bit 7, 1 = read) and a 7-bit register address, as on every Bosch part
of the family. A read shifts out the declared dummy bytes, then the registers from the
address on with the stand-in's own auto-increment (the pointer stays on its FIFO data
register); a write writes every following byte from the address on, or, declared with
``write_pairs``, its first data byte and then (address, data) pairs. A chip that starts in
I2C mode (the BMI088 accelerometer after power-on or a soft reset) takes no part in a frame
until chip select has risen once: it drives nothing and ignores what it is sent.

What the chip drives where it does not send data (the command byte, an ignored frame) is
``UNDRIVEN_BYTE``, as for the gyroscope's frames (bus.spi). A dummy byte repeats the last
byte the chip shifted out (0x00 after a reset): a driver that takes it for data sees a stale
value, as reported on silicon (docs/unconfirmed-choices.md).
"""

from __future__ import annotations

from typing import Any

UNDRIVEN_BYTE = 0x00  # the host's reading of a line the chip does not drive (as bus.spi)
READ_FLAG = 0x80  # bit 7 of the command byte: 1 = read
SPI_ADDRESS_MASK = 0x7F  # the command byte's address bits

_COMMAND, _READ, _WRITE, _WRITE_ADDRESS = range(4)


class StandinSpiFrame:
    """One chip-select-low frame as a stand-in decodes it; ``clock`` may be called several
    times while chip select stays low (the frame goes on). Created when chip select falls."""

    def __init__(self, chip: Any) -> None:
        """``chip``: the ``standin.StandinDevice`` whose chip select fell."""
        self.chip = chip
        self.taking_part = chip.spi_mode
        # the rising edge that ends this frame puts a chip still in I2C mode into SPI mode
        chip.spi_mode = True
        self.state = _COMMAND
        self.address = 0
        self.dummy_left = 0
        self._access: tuple[str, int | None, bytes, bytes] = ("spi_frame", None, b"", b"")

    def clock(self, mosi: bytes) -> bytes:
        """Shift ``mosi`` into the chip; the bytes it drives meanwhile."""
        chip, count = self.chip, len(mosi)
        start_state, start_address, start_dummy = self.state, self.address, self.dummy_left
        out = bytearray()
        i = 0
        while i < count:
            if self.state == _COMMAND:
                command = mosi[i]
                self.address = command & SPI_ADDRESS_MASK
                self.state = _READ if command & READ_FLAG else _WRITE
                self.dummy_left = chip.spec.spi.dummy_bytes if self.state == _READ else 0
                out.append(UNDRIVEN_BYTE)
                i += 1
            elif not self.taking_part:
                out += bytes([UNDRIVEN_BYTE]) * (count - i)
                break
            elif self.state == _READ:
                if self.dummy_left:
                    out.append(chip.last_shifted_out)
                    self.dummy_left -= 1
                    i += 1
                    continue
                data = chip.read(self.address, count - i)
                self.address = chip.pointer
                chip.last_shifted_out = data[-1]
                out += data
                break
            elif not chip.spec.spi.write_pairs:
                chip.write(self.address, mosi[i:])
                self.address = chip.pointer
                out += bytes([UNDRIVEN_BYTE]) * (count - i)
                break
            elif self.state == _WRITE:
                chip.write(self.address, mosi[i:i + 1])
                self.state = _WRITE_ADDRESS
                out.append(UNDRIVEN_BYTE)
                i += 1
            else:  # the next (address, data) pair: bit 7 of its address byte is not looked at
                self.address = mosi[i] & SPI_ADDRESS_MASK
                self.state = _WRITE
                out.append(UNDRIVEN_BYTE)
                i += 1
        self._access = self._describe(start_state, start_address, start_dummy, mosi, bytes(out))
        return bytes(out)

    def _describe(self, state: int, address: int, dummy: int, mosi: bytes, driven: bytes
                  ) -> tuple[str, int | None, bytes, bytes]:
        offset = 0
        if state == _COMMAND and mosi:
            state = _READ if mosi[0] & READ_FLAG else _WRITE
            address = mosi[0] & SPI_ADDRESS_MASK
            dummy = self.chip.spec.spi.dummy_bytes if state == _READ else 0
            offset = 1
        if state == _READ:
            return ("spi_read", address, b"", driven[offset + dummy:])
        if state in (_WRITE, _WRITE_ADDRESS):
            return ("spi_write", address, mosi[offset:], b"")
        return ("spi_frame", None, mosi, driven)

    def access(self) -> tuple[str, int | None, bytes, bytes]:
        """The last ``clock`` in register terms for a log: (kind, register, written, read),
        the read data without the dummy bytes (so replaying the read gives them again)."""
        return self._access

    def three_wire(self) -> bool:
        """Whether the chip answers on its one data line."""
        return self.chip.spi_three_wire()

    @property
    def dummy_bytes(self) -> int:
        """Bytes a read shifts out before its data."""
        return self.chip.spec.spi.dummy_bytes
