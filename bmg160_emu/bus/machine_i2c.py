"""MicroPython's ``machine.I2C`` and ``machine.SoftI2C`` over the emulated buses.

The methods, their arguments and their errors are those of extmod/machine_i2c.c and the
ESP32 port's hardware I2C (ports/esp32/machine_i2c.c), with the argument rules of
:mod:`.micropython_rules`:

- ``readfrom_mem``/``readfrom_mem_into``: the memory address (``addrsize // 8`` bytes, most
  significant first; ``addrsize`` taken as a byte, a multiple of 8 up to 32, else
  ``ValueError: invalid addrsize``), a repeated start, the read: one transfer;
  ``writeto_mem`` writes address and data in one message.
- ``writeto`` returns the number of bytes acknowledged; ``stop=False`` leaves the bus held,
  so the next transfer follows with a repeated start (one combined transfer on the bus).
- An address outside 0..0x7f is ENODEV on the hardware I2C (the ESP32 driver refuses it);
  SoftI2C sends ``addr << 1 | rw`` as one byte, as the bit-banged code does.
- ``scan()`` probes 0x08..0x77 with writes of no data.
- The primitive operations ``start``, ``stop``, ``readinto``, ``write`` exist on SoftI2C;
  the hardware I2C answers ``OSError: I2C operation not supported``.
"""

from __future__ import annotations

import sys
from typing import Any

from bmg160_emu.bus.i2c import I2CBus, I2CMessage
from bmg160_emu.bus.micropython_board import board
from bmg160_emu.bus.micropython_rules import (
    allocate,
    get_int,
    micropython_error,
    read_buffer,
    write_buffer,
)

__all__ = ["I2C", "SoftI2C"]

_UNSET: Any = object()


def _memaddr(memaddr: Any, addrsize: Any) -> bytes:
    """fill_memaddr_buf: ``addrsize`` (as a byte) a multiple of 8 up to 32, the address's
    bytes most significant first."""
    size = get_int(addrsize) & 0xFF  # uint8_t addrsize
    address = get_int(memaddr) & 0xFFFFFFFF  # uint32_t memaddr
    if size & 7 or size > 32:
        raise ValueError("invalid addrsize")
    return bytes((address >> shift) & 0xFF for shift in range(size - 8, -1, -8))


class _Bus:
    """What machine.I2C and SoftI2C share: the emulated bus, held between a transfer without
    a stop and the next, the transfers and the memory operations."""

    _bus: I2CBus

    def _open(self, bus: I2CBus, scl: Any, sda: Any, freq: Any, timeout: Any) -> None:
        self._bus = bus
        self._held: list[I2CMessage] = []  # sent without a stop: the next transfer goes on
        self.scl, self.sda = scl, sda
        self.freq, self.timeout = get_int(freq), get_int(timeout)

    def _address(self, addr: Any) -> int:
        """The 7-bit address a transfer goes to (hardware I2C: ENODEV beyond 0x7f)."""
        address = get_int(addr) & 0xFFFF  # uint16_t addr
        if address > 0x7F:
            raise micropython_error(OSError(19, "ENODEV"))
        return address

    def _transfer(self, messages: list[I2CMessage], stop: bool = True) -> list[I2CMessage]:
        """Send ``messages`` after those held; with ``stop`` the bus is released. A write
        without a stop is held (its address checked now, as the address byte is acked then)."""
        held = self._held + messages
        if not stop and messages and not messages[-1].read:
            if messages[-1].address not in self._bus.devices:
                self._held = []
                raise micropython_error(OSError(19, "ENODEV"))
            self._held = held
            return messages
        self._held = []
        try:
            self._bus.i2c_transfer(held, kernel_limits=False)
        except OSError as exc:
            raise micropython_error(exc) from None
        return messages

    def scan(self) -> list[int]:
        return self._bus.scan()

    def readfrom(self, addr: Any, nbytes: Any, stop: Any = True) -> bytes:
        address = self._address(addr)
        length = allocate(get_int(nbytes), board.heap_bytes, "readfrom")
        return self._read(address, length, bool(stop))

    def _read(self, address: int, length: int, stop: bool) -> bytes:
        if length == 0 and not self._held:
            return b""  # the ESP32 driver sends nothing for an empty read
        return self._transfer([I2CMessage.read_message(address, length)], stop)[0].data

    def readfrom_into(self, addr: Any, buf: Any, stop: Any = True) -> None:
        address = self._address(addr)
        view = write_buffer(buf)
        view[:] = self._read(address, len(view), bool(stop))

    def writeto(self, addr: Any, buf: Any, stop: Any = True) -> int:
        address = self._address(addr)
        data = read_buffer(buf)
        self._transfer([I2CMessage.write(address, data)], bool(stop))
        return len(data)  # the chip acknowledges every byte

    def writevto(self, addr: Any, vector: Any, stop: Any = True) -> int:
        address = self._address(addr)
        if not isinstance(vector, (list, tuple)):
            raise TypeError(f"object '{type(vector).__name__}' isn't a tuple or list")
        data = b"".join(read_buffer(b) for b in vector)
        self._transfer([I2CMessage.write(address, data)], bool(stop))
        return len(data)

    def readfrom_mem(self, addr: Any, memaddr: Any, nbytes: Any, *, addrsize: Any = 8) -> bytes:
        address = self._address(addr)
        prefix = _memaddr(memaddr, addrsize)
        length = allocate(get_int(nbytes), board.heap_bytes, "readfrom_mem")
        return self._read_mem(address, prefix, length)

    def _read_mem(self, address: int, prefix: bytes, length: int) -> bytes:
        messages = [I2CMessage.write(address, prefix), I2CMessage.read_message(address, length)]
        return self._transfer(messages)[1].data

    def readfrom_mem_into(self, addr: Any, memaddr: Any, buf: Any, *, addrsize: Any = 8) -> None:
        address = self._address(addr)
        prefix = _memaddr(memaddr, addrsize)
        view = write_buffer(buf)
        view[:] = self._read_mem(address, prefix, len(view))

    def writeto_mem(self, addr: Any, memaddr: Any, buf: Any, *, addrsize: Any = 8) -> None:
        address = self._address(addr)
        prefix = _memaddr(memaddr, addrsize)
        self._transfer([I2CMessage.write(address, prefix + read_buffer(buf))])

    def deinit(self) -> None:
        """Nothing to release on the emulated bus."""

    # the primitive operations: SoftI2C only
    def start(self) -> None:
        raise OSError("I2C operation not supported")

    def stop(self) -> None:
        raise OSError("I2C operation not supported")

    def readinto(self, buf: Any, nack: Any = True) -> None:
        raise OSError("I2C operation not supported")

    def write(self, buf: Any) -> int:
        raise OSError("I2C operation not supported")


class I2C(_Bus):
    """``machine.I2C(id=0, *, scl, sda, freq=400000, timeout=50000)``: the hardware I2C
    ``id`` is the emulated bus of that number. Without an id, or with -1, the port warns
    that this is deprecated and gives a SoftI2C."""

    def __new__(cls, id: Any = _UNSET, **kwargs: Any) -> Any:
        if cls is I2C and (id is _UNSET or (isinstance(id, int) and id == -1)):
            sys.stdout.write("Warning: I2C(-1, ...) is deprecated, use SoftI2C(...) instead\n")
            return SoftI2C(**kwargs)
        return super().__new__(cls)

    def __init__(self, id: Any = 0, *, scl: Any = None, sda: Any = None, freq: Any = 400000,
                 timeout: Any = 50000) -> None:
        number = get_int(id)
        self.id = number
        self._open(board.i2c_bus(number), scl, sda, freq, timeout)

    def init(self, *, scl: Any = None, sda: Any = None, freq: Any = 400000,
             timeout: Any = 50000) -> None:
        self.scl, self.sda = scl if scl is not None else self.scl, sda if sda is not None else self.sda
        self.freq, self.timeout = get_int(freq), get_int(timeout)

    def __repr__(self) -> str:
        return (f"I2C({self.id}, scl={self.scl}, sda={self.sda}, freq={self.freq}, "
                f"timeout={self.timeout})")


class SoftI2C(_Bus):
    """``machine.SoftI2C(scl, sda, *, freq=400000, timeout=50000)``: bit-banged on any pins;
    it reaches the bus the test wired for SoftI2C. Its primitive operations build a transfer
    byte by byte: ``start()``, ``write(buf)`` (the address byte first, ``addr << 1 | rw``;
    returns the bytes acknowledged), ``readinto(buf, nack=True)``, ``stop()``."""

    def __init__(self, scl: Any = None, sda: Any = None, *, freq: Any = 400000,
                 timeout: Any = 50000) -> None:
        for name, pin in (("scl", scl), ("sda", sda)):
            if pin is None:
                raise TypeError(f"'{name}' argument required")
        if board.soft_i2c is None:
            where = board.where.format(id="-1")
            raise ValueError("no bus is wired for SoftI2C" + (f": {where}" if where else ""))
        self._open(board.i2c_bus(board.soft_i2c), scl, sda, freq, timeout)
        self._target: tuple[int, bool] | None = None  # (address, reading) after the address
        self._started = False
        self._messages: list[I2CMessage] = []

    def _address(self, addr: Any) -> int:
        return ((get_int(addr) << 1) & 0xFF) >> 1  # the address byte's upper 7 bits

    def _read(self, address: int, length: int, stop: bool) -> bytes:
        if length == 0:  # the address byte alone: ENODEV if nobody answers
            self._transfer([I2CMessage.write(address, b"")], stop)
            return b""
        return super()._read(address, length, stop)

    def init(self, *, scl: Any = None, sda: Any = None, freq: Any = 400000,
             timeout: Any = 50000) -> None:
        self.freq, self.timeout = get_int(freq), get_int(timeout)

    def start(self) -> None:
        self._started = True  # a repeated start: the messages so far and the next are one
        self._target = None   # transfer, sent when data must be read or at the stop

    def write(self, buf: Any) -> int:
        data = read_buffer(buf)
        acks = 0
        for byte in data:
            if not self._started:
                break  # no start condition: nobody listens
            if self._target is None:
                address, reading = byte >> 1, bool(byte & 1)
                if address not in self._bus.devices:
                    break  # the address is not acknowledged: writing stops
                self._target = (address, reading)
                if not reading:
                    self._messages.append(I2CMessage.write(address, b""))
            elif self._target[1]:
                break  # a write while reading: the device drives SDA, nobody acks
            else:
                last = self._messages[-1]
                self._messages[-1] = I2CMessage.write(last.address, last.data + bytes([byte]))
            acks += 1
        return acks

    def readinto(self, buf: Any, nack: Any = True) -> None:
        view = write_buffer(buf)
        if self._target is None or not self._target[1]:
            view[:] = b"\xff" * len(view)  # nobody drives SDA: it floats high
            return
        data = self._transfer_now([I2CMessage.read_message(self._target[0], len(view))])
        view[:] = data[-1].data

    def stop(self) -> None:
        self._flush()
        self._started = False
        self._target = None

    def _flush(self) -> None:
        if self._messages:
            self._transfer_now([])

    def _transfer_now(self, messages: list[I2CMessage]) -> list[I2CMessage]:
        pending, self._messages = self._messages + messages, []
        try:
            return self._bus.i2c_transfer(pending, kernel_limits=False)
        except OSError as exc:
            raise micropython_error(exc) from None

    def __repr__(self) -> str:
        return f"SoftI2C(scl={self.scl}, sda={self.sda}, freq={self.freq})"
