"""FakeSMBus: a drop-in for ``smbus2.SMBus`` whose bus is emulated.

Same methods, signatures, defaults, return types, limits and errors as smbus2 (0.4 .. 0.6),
with the argument handling smbus2 inherits from ctypes (integers are truncated to the field
width, non-integers raise TypeError) and the errors the kernel gives (see ``i2c_bus``).
Kept thin for speed: no ctypes structures, one call into ``I2CBus`` per transaction.

    bus = FakeSMBus(1, devices={0x68: chip})      # its own emulated bus 1
    bus = FakeSMBus(1)                            # the bus patch_smbus registered as 1
"""

from __future__ import annotations

import contextlib
import errno
import operator
import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

from smbus2 import I2cFunc, i2c_msg

from bmg160_emu.bus.i2c import I2C_SMBUS_BLOCK_MAX, I2CBus, I2CMessage, os_error
from bmg160_emu.bus.kernel_abi import I2C_M_RD
from bmg160_emu.bus.registry import emulated_bus, emulated_bus_for_path
from bmg160_emu.traffic.transaction import TransactionLog

if TYPE_CHECKING:
    from typing_extensions import Self

__all__ = ["FakeSMBus", "I2cFunc", "i2c_msg"]

def _u8(value: Any) -> int:
    """A ctypes c_uint8 field assignment: __index__ then truncation."""
    return operator.index(value) & 0xFF


def check_block_count(count: int) -> None:
    """A block count of 0 (I2C block read or write, block write, block process call) is
    EINVAL in the i2c core before any transfer (__i2c_smbus_xfer, Linux 6.1.190 on)."""
    if count == 0:
        raise os_error(errno.EINVAL)


def _block(data: Sequence[Any]) -> bytes:
    return bytes(operator.index(v) & 0xFF for v in data)


# the polling lane has its log drop what is beyond maxlen (TransactionLog.trim, which looks
# at the length) at every 1024th transaction index of the bus: at most 1024 entries more
_TRIM_EVERY_MASK = 1024 - 1
_NOT_HOT = object()  # FakeSMBus._hot when no address is set for the fast path


def _closed() -> TypeError:
    # What fcntl.ioctl(None, ...) raises on a closed smbus2.SMBus.
    return TypeError("argument must be an int, or have a fileno() method.")


class FakeSMBus:
    """Main class for I2C and SMBus communication with emulated devices (smbus2 API)."""

    def __init__(
        self,
        bus: int | str | I2CBus | None = None,
        force: bool = False,
        *,
        devices: Mapping[int, Any] | None = None,
    ) -> None:
        self.fd: int | None = None
        self.funcs: int = I2cFunc(0)
        self._i2c: I2CBus | None = None
        self._own_bus: I2CBus | None = None
        if devices is not None:
            if bus is None or isinstance(bus, I2CBus):
                raise ValueError("devices= needs a bus number to build the emulated bus")
            number = bus if isinstance(bus, int) else _number_from_path(bus)
            self._own_bus = I2CBus(number, devices)
        if bus is not None:
            self.open(bus)
        self._hot: object = _NOT_HOT
        self._clocked: Any = _NOT_HOT  # the last device seen with a ``virtual_clock``
        self.address = None
        self.force = force
        self._force_last: bool | None = None
        self._pec = 0
        self._client = 0  # the kernel's client->addr for this open file (0 after open)

    # ------------------------------------------------------------------ open/close

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: object, exc_val: object, exc_tb: object) -> None:
        self.close()

    def open(self, bus: int | str | I2CBus) -> None:
        """Open an emulated bus: a number, a path such as '/dev/i2c-1', or an I2CBus.

        A number or path with no emulated bus raises FileNotFoundError, as opening a missing
        /dev/i2c-N does."""
        if isinstance(bus, I2CBus):
            target: I2CBus | None = bus
            filepath = bus.path
        elif isinstance(bus, int):
            filepath = f"/dev/i2c-{bus}"
            own = self._own_bus
            target = own if own is not None and own.number == bus else emulated_bus(bus)
        elif isinstance(bus, str):
            filepath = bus
            own = self._own_bus
            target = own if own is not None and own.path == bus else emulated_bus_for_path(bus)
        else:
            raise TypeError(f"Unexpected type(bus)={type(bus)}")
        if target is None:
            raise OSError(errno.ENOENT, os.strerror(errno.ENOENT), filepath)
        if self.fd is not None:
            os.close(self.fd)
        self.fd = os.open(os.devnull, os.O_RDWR)  # a real, unique descriptor number
        self._i2c = target
        self._client = 0
        self.funcs = target.funcs

    def close(self) -> None:
        """Close the i2c connection."""
        if self.fd:
            os.close(self.fd)
            self.fd = None
            self._pec = 0
            self.address = None
            self._force_last = None
            self._i2c = None

    def __del__(self) -> None:
        # smbus2 leaks the descriptor of an SMBus never closed; a fake used in long test runs
        # should not, so the placeholder descriptor is released with the object.
        fd = getattr(self, "fd", None)
        if fd:
            with contextlib.suppress(OSError):
                os.close(fd)

    # ------------------------------------------------------------------ emulator extras

    @property
    def i2c_bus(self) -> I2CBus:
        """The emulated adapter behind this handle (devices, hooks, log)."""
        if self._i2c is None:
            raise ValueError("bus is not open")
        return self._i2c

    @property
    def log(self) -> TransactionLog:
        """The transaction log of the emulated bus."""
        return self.i2c_bus.log

    # ------------------------------------------------------------------ pec, address

    def _get_pec(self) -> int:
        return self._pec

    def enable_pec(self, enable: bool = True) -> None:
        """Enable/Disable PEC (Packet Error Checking) - SMBus 1.1 and later."""
        if not (self.funcs & I2cFunc.SMBUS_PEC):
            raise OSError("SMBUS_PEC is not a feature")
        self._pec = int(enable)
        if self.fd is None:
            raise _closed()

    pec = property(_get_pec, enable_pec)

    @property
    def address(self) -> int | None:
        """The address of the last ``I2C_SLAVE`` ioctl, as in smbus2 (None when closed)."""
        return self._address

    @address.setter
    def address(self, value: int | None) -> None:
        self._address = value
        self._hot = _NOT_HOT  # assigned by hand: the next call compares it, as smbus2 does

    @property
    def force(self) -> bool:
        """Force the address by default (``I2C_SLAVE_FORCE``), as in smbus2."""
        return self._force

    @force.setter
    def force(self, value: bool) -> None:
        self._force = value
        self._hot = _NOT_HOT

    def _set_address(self, address: int, force: bool | None = None) -> None:
        force = force if force is not None else self.force
        if self.address != address or self._force_last != force:
            if self.fd is None:
                raise _closed()
            if isinstance(address, (bytes, bytearray, memoryview, str)):
                # smbus2 hands it to fcntl.ioctl as a buffer: the kernel takes the buffer's
                # pointer for the address, above 0x7F, and answers EINVAL
                raise OSError(errno.EINVAL, os.strerror(errno.EINVAL))
            address = operator.index(address)
            if not -(2**31) <= address < 2**31:  # fcntl.ioctl passes the address as a C int
                raise OverflowError("signed integer is greater than maximum")
            bus = self._i2c
            assert bus is not None
            if force is True:
                bus.check_address(address, force=True)
            else:
                bus.check_address(address, force=False)
            self._client = address
            self.address = address
            self._force_last = force
        if force == self._force:  # the next call with force=None needs no ioctl: fast path
            self._hot = address

    def _bus(self) -> I2CBus:
        bus = self._i2c
        if bus is None:
            raise _closed()
        return bus

    # ------------------------------------------------------------------ SMBus transactions

    def write_quick(self, i2c_addr: int, force: bool | None = None) -> None:
        """Perform quick transaction. Throws IOError if unsuccessful."""
        self._set_address(i2c_addr, force=force)
        self._bus().write_quick(self._client)

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        """Read a single byte from a device (from the chip's register pointer)."""
        self._set_address(i2c_addr, force=force)
        return self._bus().read_byte(self._client, bool(self._pec))

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        """Write a single byte to a device (the chip takes it as the register pointer)."""
        self._set_address(i2c_addr, force=force)
        self._bus().write_byte(self._client, _u8(value), bool(self._pec))

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """Read a single byte from a designated register."""
        self._set_address(i2c_addr, force=force)
        return self._bus().read_byte_data(self._client, _u8(register), bool(self._pec))

    def write_byte_data(
        self, i2c_addr: int, register: int, value: int, force: bool | None = None
    ) -> None:
        """Write a byte to a given register."""
        self._set_address(i2c_addr, force=force)
        self._bus().write_byte_data(self._client, _u8(register), _u8(value), bool(self._pec))

    def read_word_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """Read a single word (2 bytes, LSB first) from a given register."""
        self._set_address(i2c_addr, force=force)
        return self._bus().read_word_data(self._client, _u8(register), bool(self._pec))

    def write_word_data(
        self, i2c_addr: int, register: int, value: int, force: bool | None = None
    ) -> None:
        """Write a single word (2 bytes, LSB first) to a given register."""
        self._set_address(i2c_addr, force=force)
        word = operator.index(value) & 0xFFFF
        self._bus().write_word_data(self._client, _u8(register), word, bool(self._pec))

    def process_call(
        self, i2c_addr: int, register: int, value: int, force: bool | None = None
    ) -> int:
        """Executes a SMBus Process Call, sending a 16-bit value and receiving a 16-bit response."""
        self._set_address(i2c_addr, force=force)
        word = operator.index(value) & 0xFFFF
        return self._bus().process_call(self._client, _u8(register), word, bool(self._pec))

    def read_block_data(self, i2c_addr: int, register: int, force: bool | None = None) -> list[int]:
        """Read a block of up to 32-bytes from a given register."""
        self._set_address(i2c_addr, force=force)
        return list(self._bus().read_block_data(self._client, _u8(register), bool(self._pec)))

    def write_block_data(
        self, i2c_addr: int, register: int, data: Sequence[int], force: bool | None = None
    ) -> None:
        """Write a block of byte data to a given register."""
        length = len(data)
        if length > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes")
        self._set_address(i2c_addr, force=force)
        command = _u8(register)
        payload = _block(data)
        check_block_count(length)
        self._bus().write_block_data(self._client, command, payload, bool(self._pec))

    def block_process_call(
        self, i2c_addr: int, register: int, data: Sequence[int], force: bool | None = None
    ) -> list[int]:
        """Executes a SMBus Block Process Call, sending a variable-size data
        block and receiving another variable-size response."""
        length = len(data)
        if length > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes")
        self._set_address(i2c_addr, force=force)
        command = _u8(register)
        payload = _block(data)
        check_block_count(length)
        return list(self._bus().block_process_call(self._client, command, payload, bool(self._pec)))

    def read_i2c_block_data(
        self, i2c_addr: int, register: int, length: int, force: bool | None = None
    ) -> list[int]:
        """Read a block of byte data from a given register (burst, auto-increment)."""
        if (
            i2c_addr == self._hot  # the address set last, with the default force, bus open
            and force is None
            and register.__class__ is int
            and length.__class__ is int
            and 0 <= register <= 0xFF
            and 0 < length <= I2C_SMBUS_BLOCK_MAX
        ):  # the hot path of a polling driver: the same address again, plain ints in range
            # I2CBus.read_i2c_block_data and TransactionLog.add inlined (one Python call
            # fewer, 60-100 ns of a 1.5 us poll): no hook, no sink, every kind supported
            bus: Any = self._i2c
            chip = bus.devices.get(i2c_addr)
            if chip is not None and not bus.transaction_hooks and not bus.unsupported:
                index = next(bus.indices)
                data = chip.read(register, length)
                log = bus.log
                if log.enabled:
                    if log.sinks:
                        log.add((chip.time, bus.number, i2c_addr, "read_i2c_block_data",
                                 register, b"", data, None))
                    else:  # extended by a tuple it frees at once: nothing left for the GC;
                        # the chip's clock's ns object itself when it has one (no float made)
                        clock = (chip.virtual_clock if chip is self._clocked
                                 else self._virtual_clock_of(chip))
                        fields = log.fields
                        if clock is None:
                            fields += (chip.time, bus.number, i2c_addr, "read_i2c_block_data",
                                       register, b"", data, None, None)
                        else:
                            fields += (None, bus.number, i2c_addr, "read_i2c_block_data",
                                       register, b"", data, None, clock.ns)
                        if not index & _TRIM_EVERY_MASK:  # (cheaper than len(fields) each
                            log.trim()  # time: 25 ns of 950, tools/bench_fake_smbus.py)
                return [*data]
        return self._read_i2c_block_data(i2c_addr, register, length, force)

    def _virtual_clock_of(self, chip: Any) -> Any:
        """The device's ``virtual_clock`` (BMG160's: its time in ns, ``time`` without the
        float), None when it has none; a device that has one is remembered, so that the
        polling lane reads the attribute directly (50 ns less than getattr)."""
        if not hasattr(chip, "virtual_clock"):
            return None
        self._clocked = chip
        return chip.virtual_clock

    def _read_i2c_block_data(
        self, i2c_addr: int, register: int, length: int, force: bool | None
    ) -> list[int]:
        if length > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Desired block length over {I2C_SMBUS_BLOCK_MAX} bytes")
        if self.address != i2c_addr or self._force_last != (self.force if force is None else force):
            self._set_address(i2c_addr, force=force)
        bus = self._bus()
        count = operator.index(length) & 0xFF
        check_block_count(count)
        data = bus.read_i2c_block_data(self._client, operator.index(register) & 0xFF, count)
        if count == length:
            return list(data)
        # smbus2 slices the 34-byte ctypes block as block[1:length + 1] (negative lengths)
        return ([count] + list(data) + [0] * (I2C_SMBUS_BLOCK_MAX + 1 - count))[1 : length + 1]

    def write_i2c_block_data(
        self, i2c_addr: int, register: int, data: Sequence[int], force: bool | None = None
    ) -> None:
        """Write a block of byte data to a given register (burst, auto-increment)."""
        length = len(data)
        if length > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"Data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes")
        self._set_address(i2c_addr, force=force)
        command = _u8(register)
        payload = _block(data)
        check_block_count(length)
        self._bus().write_i2c_block_data(self._client, command, payload)

    def i2c_rdwr(self, *i2c_msgs: i2c_msg) -> None:
        """Combine a series of i2c read and write operations in a single transaction (with
        repeated start bits but no stop bits in between). Takes ``smbus2.i2c_msg`` objects;
        read messages are filled in place."""
        for m in i2c_msgs:
            if not isinstance(m, i2c_msg):
                raise TypeError(
                    f"incompatible types, {type(m).__name__} instance instead of i2c_msg instance"
                )
        bus = self._bus()
        messages = [
            I2CMessage(m.addr, True, b"", m.len)
            if m.flags & I2C_M_RD
            else I2CMessage(m.addr, False, bytes(m))
            for m in i2c_msgs
        ]
        bus.i2c_transfer(messages)
        for m, message in zip(i2c_msgs, messages):
            if message.read and message.data:
                _fill(m, message.data)


def _fill(m: i2c_msg, data: bytes) -> None:
    import ctypes

    ctypes.memmove(m.buf, data, len(data))


def _number_from_path(path: str) -> int:
    prefix = "/dev/i2c-"
    if path.startswith(prefix) and path[len(prefix) :].isdigit():
        return int(path[len(prefix) :])
    raise ValueError(f"not an I2C device path: {path!r} (expected /dev/i2c-N)")
