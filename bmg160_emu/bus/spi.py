"""The BMG160's SPI framing and FakeSpiDev, a drop-in for ``spidev.SpiDev``.

Framing (spec 2.2-2.4): after chip select falls, the first byte is bit 7 = R/W (1 = read) and
bits 6..0 = register address. A read frame shifts out the addressed register and the following
ones (auto-increment, the pointer stays on 0x3F FIFO_DATA) for as long as CS stays low. A write
frame writes the next byte to the addressed register, and further bytes in the same frame are
taken as (address, data) pairs (spec 2.2, recommended behaviour). Addresses 0x40..0x7F read 0x00
and ignore writes (spec 2.4). With ``spi3`` (0x34 bit 0) set, the chip answers on its one data
line (3-wire, spec 2.3), so a host must be in 3-wire mode too to hear it.

Emulator choices (one place each): an undriven data line reads as ``UNDRIVEN_BYTE``; in SPI
modes 1 and 2 (wrong clock edge for this chip, which supports modes 0 and 3) and with an
active-high chip select the chip does not take part in the transfer.
"""

from __future__ import annotations

import contextlib
import errno
import itertools
import os
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, Any, Literal

from bmg160_emu.bus.i2c import os_error
from bmg160_emu.device.contract import SpiFramedDevice
from bmg160_emu.device.registers import FIRST_OUTSIDE_MAP, address_of, field_of
from bmg160_emu.traffic.transaction import TransactionLog

if TYPE_CHECKING:
    from typing_extensions import Self

UNDRIVEN_BYTE = 0x00  # what a host reads from a data line nobody drives (emulator choice)
FIFO_DATA = address_of("FIFO_DATA")  # the address pointer does not advance here (spec 2.4)
USER_MAP_END = FIRST_OUTSIDE_MAP  # 0x40..0x7F: outside the register map (spec 2.4)
SPI3_ADDRESS = address_of("BGW_SPI3_WDT")
SPI3_BIT = field_of("BGW_SPI3_WDT", "spi3").mask  # 1: 3-wire SPI (spec 4.23)
MAX_SPEED_HZ = 10_000_000  # maximum SPI clock of the chip (spec 2.2); the fake node's default
SPIDEV_BUFSIZ = 4096  # spidev's default bufsiz (/sys/module/spidev/parameters/bufsiz)
SUPPORTED_BITS_PER_WORD = (8, 16, 32)  # word sizes the emulated controller accepts

# struct spi_device mode bits (linux/spi/spi.h)
SPI_CPHA = 0x01
SPI_CPOL = 0x02
SPI_CS_HIGH = 0x04
SPI_LSB_FIRST = 0x08
SPI_3WIRE = 0x10
SPI_LOOP = 0x20
SPI_NO_CS = 0x40

_REVERSED = bytes(int(f"{b:08b}"[::-1], 2) for b in range(256))

_COMMAND, _READ, _WRITE_DATA, _WRITE_ADDRESS = range(4)


def next_address(address: int, count: int) -> int:
    """Where the chip's address pointer is after ``count`` bytes from ``address`` (spec 2.4)."""
    if address <= FIFO_DATA:
        return min(address + count, FIFO_DATA)
    return min(address + count, 0x7F)


_OWN_FRAMING: dict[type, bool] = {}  # device type -> decodes its own SPI frames


def _frames_itself(chip: Any) -> bool:
    kind = type(chip)
    known = _OWN_FRAMING.get(kind)
    if known is None:
        known = _OWN_FRAMING[kind] = isinstance(chip, SpiFramedDevice)
    return known


class SpiFrame:
    """One chip-select-low frame as the chip decodes it; ``clock`` may be called several times
    while CS stays low (the frame goes on). Created when chip select falls. A device that
    decodes its own frames (``contract.SpiFramedDevice``: a register-file stand-in with its
    dummy byte or I2C start) is handed the frame; any other is framed as the BMG160
    (spec 2.2-2.4)."""

    def __init__(self, chip: Any) -> None:
        self.chip = chip
        self.state = _COMMAND
        self.address = 0
        self.command: int | None = None
        self.own = chip.spi_frame() if _frames_itself(chip) else None
        self._start = (_COMMAND, 0)
        self._mosi = self._driven = b""

    def clock(self, mosi: bytes) -> bytes:
        """Shift ``mosi`` into the chip; returns what the chip drives (UNDRIVEN_BYTE where it
        does not drive its output)."""
        if self.own is not None:
            return bytes(self.own.clock(mosi))
        self._start, self._mosi = (self.state, self.address), mosi
        out = bytearray()
        count = len(mosi)
        chip = self.chip
        i = 0
        while i < count:
            state = self.state
            if state == _READ:
                n = count - i
                address = self.address
                if address < USER_MAP_END:
                    out += chip.read(address, n)
                else:
                    out += bytes(n)  # outside the map: reads 0x00 (spec 2.4)
                self.address = next_address(address, n)
                break
            byte = mosi[i]
            if state == _COMMAND:
                self.command = byte
                self.address = byte & 0x7F
                self.state = _READ if byte & 0x80 else _WRITE_DATA
            elif state == _WRITE_DATA:
                if self.address < USER_MAP_END:
                    chip.write(self.address, bytes([byte]))
                self.state = _WRITE_ADDRESS
            else:  # _WRITE_ADDRESS: the next (address, data) pair; bit 7 is not looked at
                self.address = byte & 0x7F
                self.state = _WRITE_DATA
            out.append(UNDRIVEN_BYTE)
            i += 1
        self._driven = bytes(out)
        return self._driven

    def access(self) -> tuple[str, int | None, bytes, bytes]:
        """The last ``clock`` in register terms for a log: (kind, register, written, read):
        ``spi_read``/``spi_write`` from the frame's register, the data bytes after the
        command byte (as for I2C transactions)."""
        if self.own is not None:
            return self.own.access()
        (state, address), mosi, driven = self._start, self._mosi, self._driven
        offset = 0
        if state == _COMMAND and mosi:
            state = _READ if mosi[0] & 0x80 else _WRITE_DATA
            address = mosi[0] & 0x7F
            offset = 1
        if state == _READ:
            return ("spi_read", address, b"", driven[offset:])
        return ("spi_write", address, mosi[offset:], b"")

    def three_wire(self) -> bool:
        """Whether the chip answers on its one data line (spi3, spec 4.23)."""
        if self.own is not None:
            return bool(self.own.three_wire())
        return bool(self.chip.peek(SPI3_ADDRESS) & SPI3_BIT)

    @property
    def dummy_bytes(self) -> int:
        """Bytes a read shifts out between the command byte and the data (0 on the BMG160)."""
        return int(self.own.dummy_bytes) if self.own is not None else 0


def chip_select_of(name: Any) -> int | None:
    """The chip select of a logged SPI device name ``spi<bus>.<cs>`` (FakeSpiDev's, serve's),
    or None for any other name. Where a session has several devices, chip select i is the
    i-th in address order (serve's board)."""
    if not isinstance(name, str) or not name.startswith("spi"):
        return None
    _, dot, cs = name[3:].partition(".")
    return int(cs) if dot and cs.isdigit() else None


def read_dummy_bytes(chip: Any) -> int:
    """Bytes ``chip`` shifts out between a read's command byte and its data (without
    starting a frame): what a replayed read must clock besides its data."""
    return int(chip.spec.spi.dummy_bytes) if _frames_itself(chip) else 0


def spi_frame(chip: Any, mosi: bytes | Sequence[int]) -> bytes:
    """One complete 4-wire frame: the bytes the chip drives on SDO while ``mosi`` is sent."""
    with chip.lock:
        return SpiFrame(chip).clock(bytes(mosi))


def _swap_words(data: bytes, size: int) -> bytes:
    """Host memory (little-endian words) <-> wire order (each word MSB first)."""
    if size == 1:
        return data
    out = bytearray(len(data))
    for i in range(0, len(data), size):
        out[i : i + size] = data[i : i + size][::-1]
    return bytes(out)


def _as_tx(values: Any, limit: int | None) -> bytes:
    """spidev's argument rules: a non-empty sequence of ints, truncated to 8 bits."""
    try:
        items = list(values)
    except TypeError:
        raise TypeError("Empty argument list.") from None
    if not items:
        raise TypeError("Empty argument list.")
    if limit is not None and len(items) > limit:
        raise OverflowError(f"Argument list size exceeds {limit} bytes.")
    out = bytearray(len(items))
    for i, value in enumerate(items):
        if not isinstance(value, int):
            raise TypeError(f"Non-Int/Long value in arguments: {id(value):x}.")
        out[i] = value & 0xFF
    return bytes(out)


_devices: dict[tuple[int, int], list[Any]] = {}


def register_spi_device(bus: int, device: int, chip: Any) -> None:
    """Make ``chip`` answer at /dev/spidev<bus>.<device> (used by ``patch_spidev``)."""
    _devices.setdefault((bus, device), []).append(chip)


def unregister_spi_device(bus: int, device: int, chip: Any) -> None:
    stack = _devices.get((bus, device), [])
    for i in range(len(stack) - 1, -1, -1):
        if stack[i] is chip:
            del stack[i]
            break
    if not stack:
        _devices.pop((bus, device), None)


def emulated_spi_device(bus: int, device: int) -> Any | None:
    stack = _devices.get((bus, device))
    return stack[-1] if stack else None


def _is_chip(obj: Any) -> bool:
    return all(hasattr(obj, name) for name in ("read", "write", "lock"))


class FakeSpiDev:
    """SpiDev([bus],[client]) -> SPI, with the emulated chip at the other end.

    ``FakeSpiDev(chip)`` is already open on that chip; ``FakeSpiDev(bus, client)`` and
    ``open(bus, device)`` reach the chip ``patch_spidev`` put at /dev/spidev<bus>.<device>.
    """

    def __init__(self, bus: Any = -1, client: int = -1) -> None:
        self._fd = -1
        self._mode = 0
        self._bits_per_word = 0
        self._max_speed_hz = 0
        self._read0 = False
        self.chip: Any = None
        self.name = ""
        self.log = TransactionLog()
        # hook(dev, index, None, "spi") before each frame; an OSError it raises fails the
        # transfer as a failing SPI_IOC_MESSAGE ioctl would (fault injection, as on I2CBus)
        self.transaction_hooks: list[Any] = []
        self._frames = itertools.count()
        self._frame: SpiFrame | None = None
        if _is_chip(bus):
            self._attach(bus, "spi0.0")
        elif bus >= 0:
            self.open(bus, client)

    # ------------------------------------------------------------------ open/close

    def _attach(self, chip: Any, name: str) -> None:
        if self._fd != -1:
            os.close(self._fd)
        self._fd = os.open(os.devnull, os.O_RDWR)
        self.chip = chip
        self.name = name
        self._mode = 0
        self._bits_per_word = 8
        self._max_speed_hz = MAX_SPEED_HZ
        self._frame = None

    def open(self, bus: int, device: int) -> None:
        """Connects the object to the specified SPI device. open(X,Y) will open
        /dev/spidev<X>.<Y>."""
        if not isinstance(bus, int) or not isinstance(device, int):
            raise TypeError("an integer is required")
        chip = emulated_spi_device(bus, device)
        if chip is None:
            path = f"/dev/spidev{bus}.{device}"
            raise OSError(errno.ENOENT, os.strerror(errno.ENOENT), path)
        self._attach(chip, f"spi{bus}.{device}")

    def close(self) -> None:
        """Disconnects the object from the interface."""
        if self._fd != -1:
            os.close(self._fd)
        self._fd = -1
        self._mode = 0
        self._bits_per_word = 0
        self._max_speed_hz = 0
        self._frame = None

    def __del__(self) -> None:  # spidev closes its descriptor when the object goes away
        fd = getattr(self, "_fd", -1)
        if fd != -1:
            with contextlib.suppress(OSError):
                os.close(fd)

    def fileno(self) -> int:
        return self._fd

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: object, exc_value: object, traceback: object) -> Literal[False]:
        self.close()
        return False

    # ------------------------------------------------------------------ attributes

    def _set_mode_bits(self, mode: int) -> None:
        if self._fd == -1:
            raise os_error(errno.EBADF)
        if not mode & SPI_NO_CS:
            self._frame = None  # chip select goes back to being driven: the frame ends
        self._mode = mode

    def _flag(self, bit: int) -> bool:
        return bool(self._mode & bit)

    def _set_flag(self, bit: int, name: str, value: Any) -> None:
        if not isinstance(value, bool):
            raise TypeError(f"The {name} attribute must be boolean")
        self._set_mode_bits(self._mode | bit if value else self._mode & ~bit)

    @property
    def mode(self) -> int:
        """SPI mode as two bit pattern of Clock Polarity and Phase [CPOL|CPHA]."""
        return self._mode & (SPI_CPHA | SPI_CPOL)

    @mode.setter
    def mode(self, value: Any) -> None:
        if not isinstance(value, int):
            raise TypeError("The mode attribute must be an integer")
        if value & 0xFF > 3:
            raise TypeError("The mode attribute must be an integerbetween 0 and 3.")
        self._set_mode_bits((self._mode & ~(SPI_CPHA | SPI_CPOL)) | (value & 0xFF))

    cshigh = property(
        lambda self: self._flag(SPI_CS_HIGH),
        lambda self, v: self._set_flag(SPI_CS_HIGH, "cshigh", v),
    )
    lsbfirst = property(
        lambda self: self._flag(SPI_LSB_FIRST),
        lambda self, v: self._set_flag(SPI_LSB_FIRST, "lsbfirst", v),
    )
    threewire = property(
        lambda self: self._flag(SPI_3WIRE), lambda self, v: self._set_flag(SPI_3WIRE, "3wire", v)
    )
    loop = property(
        lambda self: self._flag(SPI_LOOP), lambda self, v: self._set_flag(SPI_LOOP, "loop", v)
    )
    no_cs = property(
        lambda self: self._flag(SPI_NO_CS), lambda self, v: self._set_flag(SPI_NO_CS, "no_cs", v)
    )

    @property
    def read0(self) -> bool:
        return self._read0

    @read0.setter
    def read0(self, value: Any) -> None:
        if not isinstance(value, bool):
            raise TypeError("The read0 attribute must be boolean")
        self._read0 = value

    @property
    def bits_per_word(self) -> int:
        return self._bits_per_word

    @bits_per_word.setter
    def bits_per_word(self, value: Any) -> None:
        if not isinstance(value, int):
            raise TypeError("The bits_per_word attribute must be an integer")
        bits = value & 0xFF
        if bits < 8 or bits > 32:
            raise TypeError("invalid bits_per_word (8 to 32)")
        if bits != self._bits_per_word:
            if self._fd == -1:
                raise os_error(errno.EBADF)
            if bits not in SUPPORTED_BITS_PER_WORD:
                raise os_error(errno.EINVAL)  # spi_setup(): the controller cannot do it
            self._bits_per_word = bits

    @property
    def max_speed_hz(self) -> int:
        return self._max_speed_hz

    @max_speed_hz.setter
    def max_speed_hz(self, value: Any) -> None:
        if not isinstance(value, int):
            raise TypeError("The max_speed_hz attribute must be an integer")
        speed = value & 0xFFFFFFFF
        if speed != self._max_speed_hz:
            if self._fd == -1:
                raise os_error(errno.EBADF)
            self._max_speed_hz = speed

    # ------------------------------------------------------------------ transfers

    def _transfer(self, tx: bytes | None, count: int, bits_per_word: int = 0) -> bytes:
        """One spidev message: tx (None for a read-only transfer) and ``count`` bytes back."""
        if self._fd == -1:
            raise os_error(errno.EBADF)
        bits = bits_per_word or self._bits_per_word
        if bits not in SUPPORTED_BITS_PER_WORD:
            raise os_error(errno.EINVAL)
        size = bits // 8
        if count % size:
            raise os_error(errno.EINVAL)  # a transfer is a whole number of words
        if self.transaction_hooks:
            index = next(self._frames)
            for hook in list(self.transaction_hooks):
                hook(self, index, None, "spi")
        mode = self._mode
        host_3wire = bool(mode & SPI_3WIRE)
        wire_tx = _swap_words(tx, size) if tx is not None else bytes(count)  # undriven MOSI: 0
        if mode & SPI_LSB_FIRST:
            wire_tx = wire_tx.translate(_REVERSED)
        chip = self.chip
        heard = True  # whether the host hears what the chip drives
        with chip.lock:
            selected = not (mode & SPI_CS_HIGH) and (mode & (SPI_CPHA | SPI_CPOL)) in (0, 3)
            if selected:
                frame = self._frame if self._frame is not None else SpiFrame(chip)
                driven = frame.clock(wire_tx)
                self._frame = frame if mode & SPI_NO_CS else None
                heard = host_3wire == frame.three_wire()
                if not heard:
                    driven = bytes([UNDRIVEN_BYTE]) * count  # the chip answers on the other line
            else:
                driven = bytes([UNDRIVEN_BYTE]) * count
            time = float(chip.time)
        wire_rx = wire_tx if mode & SPI_LOOP else driven
        if mode & SPI_LSB_FIRST:
            wire_rx = wire_rx.translate(_REVERSED)
        rx = _swap_words(wire_rx, size)
        if self.log.enabled:
            if not selected:  # the chip took no part: log the raw frame
                self.log.record(time, self.name, None, "spi_frame", None, tx or b"", rx)
            else:  # what the chip saw, in register terms
                kind, register, written, read = frame.access()
                if not heard:
                    read = bytes([UNDRIVEN_BYTE]) * len(read)
                self.log.record(time, self.name, None, kind, register, written, read)
        return rx

    def readbytes(self, length: int) -> list[int]:
        """Read len bytes from SPI device (1..4096; other lengths are clamped, as spidev does)."""
        if not isinstance(length, int):
            raise TypeError("an integer is required")
        length = max(1, min(length, SPIDEV_BUFSIZ))
        return list(self._transfer(None, length))

    def writebytes(self, values: Sequence[int]) -> None:
        """Write bytes to SPI device (at most 4096 in one frame)."""
        tx = _as_tx(values, SPIDEV_BUFSIZ)
        self._transfer(tx, len(tx))

    def writebytes2(self, values: Any) -> None:
        """Write bytes to SPI device; any length, sent as frames of at most 4096 bytes."""
        if isinstance(values, (bytes, bytearray, memoryview)):
            tx = bytes(values)
            if not tx:
                return
        else:
            tx = _as_tx(values, None)
        for start in range(0, len(tx), SPIDEV_BUFSIZ):
            chunk = tx[start : start + SPIDEV_BUFSIZ]
            self._transfer(chunk, len(chunk))

    def _xfer(self, values: Any, speed_hz: int, delay_usecs: int, bits_per_word: int) -> Any:
        for name, value in (
            ("speed_hz", speed_hz),
            ("delay_usecs", delay_usecs),
            ("bits_per_word", bits_per_word),
        ):
            if not isinstance(value, int):
                raise TypeError(f"{name} must be an integer")
        tx = _as_tx(values, SPIDEV_BUFSIZ)
        if self._mode & SPI_3WIRE:
            if self._fd == -1:
                raise os_error(errno.EBADF)
            raise os_error(errno.EINVAL)  # full duplex on a 3-wire link (spi core __spi_validate)
        rx = self._transfer(tx, len(tx), bits_per_word & 0xFF)
        if isinstance(values, tuple):
            return tuple(rx)
        if isinstance(values, list):
            values[:] = list(rx)  # spidev writes the answer into the caller's list
            return values
        return list(rx)

    def xfer(
        self, values: Any, speed_hz: int = 0, delay_usecs: int = 0, bits_per_word: int = 0
    ) -> Any:
        """Perform SPI transaction (one frame; the answer replaces the list's items)."""
        return self._xfer(values, speed_hz, delay_usecs, bits_per_word)

    def xfer2(
        self, values: Any, speed_hz: int = 0, delay_usecs: int = 0, bits_per_word: int = 0
    ) -> Any:
        """Perform SPI transaction. CS will be held active between blocks."""
        return self._xfer(values, speed_hz, delay_usecs, bits_per_word)

    def xfer3(
        self, values: Any, speed_hz: int = 0, delay_usecs: int = 0, bits_per_word: int = 0
    ) -> tuple:
        """Perform SPI transaction of any size; blocks of 4096 bytes are separate frames.
        Returns a tuple."""
        tx = _as_tx(values, None)
        if self._mode & SPI_3WIRE:
            raise os_error(errno.EBADF if self._fd == -1 else errno.EINVAL)
        rx = bytearray()
        for start in range(0, len(tx), SPIDEV_BUFSIZ):
            chunk = tx[start : start + SPIDEV_BUFSIZ]
            rx += self._transfer(chunk, len(chunk), bits_per_word & 0xFF)
        return tuple(rx)

    def __repr__(self) -> str:
        state = self.name if self._fd != -1 else "closed"
        return f"<FakeSpiDev {state}>"


def iter_rate_words(data: Iterable[int]) -> list[int]:
    """Signed 16-bit words from LSB-first byte pairs (spec 4.2), for SPI burst reads."""
    raw = list(data)
    words = []
    for i in range(0, len(raw) - 1, 2):
        value = raw[i] | raw[i + 1] << 8
        words.append(value - 0x10000 if value & 0x8000 else value)
    return words
