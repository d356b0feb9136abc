"""The kernel's i2c-dev character device (drivers/i2c/i2c-dev.c), emulated once for every
front end that stands in for ``/dev/i2c-N``.

Why one module: ``patch_smbus`` (smbus2's ``ioctl`` calls, in-process) and the umockdev node
(a program's ``ioctl``/``read``/``write``, across a socket) must answer each request the same
way, errors included. Both only marshal memory: they hand :class:`I2CDevFile` an
:class:`IoctlArgument` whose :class:`UserMemory` blocks behave like the calling program's
memory (``copy_from_user``, ``copy_to_user``, following a pointer stored in a structure),
and the order of checks, copies and transfers here is the kernel's:

- ``I2C_SLAVE``/``I2C_SLAVE_FORCE``: EINVAL above 0x7f (0x3ff after ``I2C_TENBIT``), EBUSY
  for an address a driver holds unless forced; ``I2C_PEC``, ``I2C_TENBIT`` per open file;
  ``I2C_RETRIES`` EINVAL above INT_MAX, ``I2C_TIMEOUT`` above INT_MAX / 10; ``I2C_FUNCS``
  the adapter's mask, put where the argument points (EFAULT if it points nowhere).
- ``I2C_SMBUS``: size and direction checked (EINVAL), quick and send-byte need no data, any
  other kind with a NULL data pointer is EINVAL; the union is copied in and out with the
  kernel's sizes (1, 2 or 34 bytes) and only for the kinds i2cdev_ioctl_smbus copies; size 6
  (I2C_SMBUS_I2C_BLOCK_BROKEN) becomes an I2C block read of 32 bytes. The i2c core
  (``__i2c_smbus_xfer``) refuses a block count of 0 or over 32 for an I2C block transfer
  (either way), a block write and a block process call with EINVAL before any transfer:
  Debian 12's kernel since 6.1.190 ("i2c: smbus: reject oversized block transfers in the
  common path"); older 6.1 kernels passed a count of 0 on to the adapter.
- ``I2C_RDWR``: 1..42 messages, each at most 8192 bytes, every buffer copied in first; after
  the transfer the read buffers are copied back, last first, until one faults (EFAULT).
- Every copy of the caller's memory may fault (``UserMemory``): EFAULT, never a crash, at
  the place the kernel's copy would fault (for an SMBus read, after the transfer).
- ``read()``/``write()``: plain I2C at the open file's address, 8192 bytes at most.

The transaction itself is a call into :class:`~bmg160_emu.bus.i2c.I2CBus`. The emulated
adapter has no 10-bit addressing (I2C_FUNC_10BIT_ADDR clear): a transfer to a 10-bit address
fails with ENXIO, and ``I2C_M_RECV_LEN`` reads, which an adapter must resize mid-transfer,
with EOPNOTSUPP after i2c-dev's own checks.
"""

from __future__ import annotations

import errno
import struct
from typing import Protocol

from bmg160_emu.bus.i2c import I2CBus, I2CMessage, os_error
from bmg160_emu.bus.kernel_abi import (
    I2C_DEV_MAX_TRANSFER,
    I2C_FUNCS,
    I2C_M_RD,
    I2C_M_RECV_LEN,
    I2C_M_TEN,
    I2C_MSG_BUF_OFFSET,
    I2C_MSG_SIZE,
    I2C_PEC,
    I2C_RDWR,
    I2C_RDWR_IOCTL_MAX_MSGS,
    I2C_RETRIES,
    I2C_SLAVE,
    I2C_SLAVE_FORCE,
    I2C_SMBUS,
    I2C_SMBUS_BLOCK_DATA,
    I2C_SMBUS_BLOCK_MAX,
    I2C_SMBUS_BLOCK_PROC_CALL,
    I2C_SMBUS_BYTE,
    I2C_SMBUS_BYTE_DATA,
    I2C_SMBUS_I2C_BLOCK_BROKEN,
    I2C_SMBUS_I2C_BLOCK_DATA,
    I2C_SMBUS_PROC_CALL,
    I2C_SMBUS_QUICK,
    I2C_SMBUS_READ,
    I2C_SMBUS_WORD_DATA,
    I2C_SMBUS_WRITE,
    I2C_TENBIT,
    I2C_TIMEOUT,
    RDWR_IOCTL_DATA_SIZE,
    SMBUS_DATA_OFFSET,
    SMBUS_DATA_SIZE,
    SMBUS_IOCTL_DATA_SIZE,
    SMBUS_SIZE_NAMES,
)
from bmg160_emu.traffic.kinds import I2C_FUNC_I2C

INT_MAX = 0x7FFFFFFF  # I2C_RETRIES and I2C_TIMEOUT refuse more (i2c-dev.c)
ULONG_MASK = 0xFFFFFFFFFFFFFFFF  # an ioctl argument is an unsigned long (LP64)

# i2cdev_ioctl_smbus: kinds whose data union is copied in even for a read
_COPIED_IN = frozenset((I2C_SMBUS_PROC_CALL, I2C_SMBUS_BLOCK_PROC_CALL, I2C_SMBUS_I2C_BLOCK_DATA))
_PROC_CALLS = frozenset((I2C_SMBUS_PROC_CALL, I2C_SMBUS_BLOCK_PROC_CALL))
# __i2c_smbus_xfer: kinds whose caller-supplied block count must be 1..32 (and a block write)
_COUNTED_BLOCKS = frozenset((I2C_SMBUS_I2C_BLOCK_DATA, I2C_SMBUS_BLOCK_PROC_CALL))


def smbus_data_size(size: int) -> int:
    """Bytes of ``union i2c_smbus_data`` i2c-dev copies for an SMBus kind (byte, word, block)."""
    if size in (I2C_SMBUS_BYTE, I2C_SMBUS_BYTE_DATA):
        return 1
    if size in (I2C_SMBUS_WORD_DATA, I2C_SMBUS_PROC_CALL):
        return 2
    return SMBUS_DATA_SIZE


_DATA_SIZES = {size: smbus_data_size(size) for size in SMBUS_SIZE_NAMES}
_SMBUS_IOCTL_DATA = struct.Struct("=BB2xIQ")  # read_write, command, size, data pointer


def unsigned_long(raw: bytes, offset: int = 0) -> int:
    """An unsigned long (a pointer or an ioctl argument) stored at ``offset``, LP64."""
    return int.from_bytes(raw[offset : offset + 8], "little")


class UserMemory(Protocol):
    """A block of the calling program's memory, as the kernel reaches it.

    Each method raises ``OSError(EFAULT)`` where the kernel's copy would fault."""

    def read(self) -> bytes:
        """copy_from_user of the whole block."""

    def write(self, data: bytes) -> None:
        """copy_to_user of ``data`` at the start of the block."""

    def follow(self, offset: int, size: int) -> UserMemory:
        """The ``size`` bytes the pointer stored at ``offset`` in this block points to."""


class IoctlArgument(Protocol):
    """The third argument of ``ioctl``: an unsigned long that may be a pointer."""

    @property
    def value(self) -> int:
        """The argument as an unsigned long."""

    def memory(self, size: int) -> UserMemory:
        """The ``size`` bytes the argument points to (EFAULT if it points nowhere)."""


class I2CDevFile:
    """One open ``/dev/i2c-N``: the kernel's ``struct i2c_client`` for that file (target
    address, PEC and 10-bit flags) over one :class:`I2CBus`. Every method answers as the
    system call would: a result, or ``OSError(errno)``."""

    __slots__ = ("address", "bus", "pec", "tenbit")

    def __init__(self, bus: I2CBus) -> None:
        self.bus = bus
        self.address = 0  # a new open(): address 0, no PEC, 7-bit
        self.pec = False
        self.tenbit = False

    # ------------------------------------------------------------------ ioctl

    def ioctl(self, request: int, arg: IoctlArgument) -> int:
        """``ioctl(fd, request, arg)`` on this file (i2cdev_ioctl)."""
        if request == I2C_SMBUS:
            return self._smbus_ioctl(arg)
        if request in (I2C_SLAVE, I2C_SLAVE_FORCE):
            self.set_address(arg.value, force=request == I2C_SLAVE_FORCE)
            return 0
        if request == I2C_RDWR:
            return self._rdwr_ioctl(arg)
        if request == I2C_FUNCS:  # put_user of an unsigned long
            arg.memory(8).write(struct.pack("=Q", self.bus.funcs))
            return 0
        if request == I2C_PEC:
            self.pec = bool(arg.value)
            return 0
        if request == I2C_TENBIT:
            self.tenbit = bool(arg.value)
            return 0
        if request == I2C_RETRIES:
            if arg.value > INT_MAX:
                raise os_error(errno.EINVAL)
            return 0  # the emulated adapter never retries
        if request == I2C_TIMEOUT:  # in units of 10 ms, so INT_MAX / 10 at most
            if arg.value > INT_MAX // 10:
                raise os_error(errno.EINVAL)
            return 0  # nor times out
        raise os_error(errno.ENOTTY)

    def set_address(self, address: int, force: bool = False) -> None:
        """``I2C_SLAVE`` (``force``: ``I2C_SLAVE_FORCE``)."""
        if address > (0x3FF if self.tenbit else 0x7F):
            raise os_error(errno.EINVAL)
        if address <= 0x7F:
            self.bus.check_address(address, force=force)
        self.address = address

    def _target(self) -> int:
        """The address a transfer goes to; a 10-bit one finds no device on this adapter."""
        if self.tenbit and self.address > 0x7F:
            raise os_error(errno.ENXIO)
        return self.address

    # ------------------------------------------------------------------ I2C_SMBUS

    def _smbus_ioctl(self, arg: IoctlArgument) -> int:
        """``I2C_SMBUS`` (i2cdev_ioctl_smbus): the request structure, then its data union."""
        block = arg.memory(SMBUS_IOCTL_DATA_SIZE)
        read_write, command, size, pointer = _SMBUS_IOCTL_DATA.unpack_from(block.read())
        return self.smbus(read_write, command, size, block if pointer else None)

    def smbus(self, read_write: int, command: int, size: int, request: UserMemory | None) -> int:
        """One ``I2C_SMBUS`` request. ``request`` is the caller's ``struct
        i2c_smbus_ioctl_data`` (its data pointer is followed only once the request is known
        to be well formed), or None when that pointer is NULL."""
        if size not in _DATA_SIZES:
            raise os_error(errno.EINVAL)
        if read_write not in (I2C_SMBUS_READ, I2C_SMBUS_WRITE):
            raise os_error(errno.EINVAL)
        reading = read_write == I2C_SMBUS_READ
        bus, pec = self.bus, self.pec
        if size == I2C_SMBUS_QUICK:  # these two carry no data
            bus.write_quick(self._target(), read=reading)
            return 0
        if size == I2C_SMBUS_BYTE and not reading:
            bus.write_byte(self._target(), command, pec)
            return 0
        if request is None:
            raise os_error(errno.EINVAL)
        datasize = _DATA_SIZES[size]
        user = request.follow(SMBUS_DATA_OFFSET, datasize)
        if not reading or size in _COPIED_IN:  # copy_from_user into the kernel's union
            temp = bytearray(user.read()[:datasize].ljust(SMBUS_DATA_SIZE, b"\0"))
        else:
            temp = bytearray(SMBUS_DATA_SIZE)
        if size == I2C_SMBUS_I2C_BLOCK_BROKEN:  # the old convention, converted
            size = I2C_SMBUS_I2C_BLOCK_DATA
            if reading:
                temp[0] = I2C_SMBUS_BLOCK_MAX
        self._smbus_transfer(reading, command, size, temp)
        if reading or size in _PROC_CALLS:
            user.write(bytes(temp) if datasize == SMBUS_DATA_SIZE else bytes(temp[:datasize]))
        return 0

    def _smbus_transfer(self, reading: bool, command: int, size: int, temp: bytearray) -> None:
        """i2c_smbus_xfer on the union ``temp`` (the kernel's copy)."""
        count = temp[0]
        if (size in _COUNTED_BLOCKS or (size == I2C_SMBUS_BLOCK_DATA and not reading)) \
                and not 1 <= count <= I2C_SMBUS_BLOCK_MAX:  # __i2c_smbus_xfer, before all
            raise os_error(errno.EINVAL)
        bus, pec, address = self.bus, self.pec, self._target()
        if size == I2C_SMBUS_BYTE:
            temp[0] = bus.read_byte(address, pec)
        elif size == I2C_SMBUS_BYTE_DATA:
            if reading:
                temp[0] = bus.read_byte_data(address, command, pec)
            else:
                bus.write_byte_data(address, command, temp[0], pec)
        elif size == I2C_SMBUS_WORD_DATA:
            if reading:
                temp[0:2] = bus.read_word_data(address, command, pec).to_bytes(2, "little")
            else:
                bus.write_word_data(address, command, temp[0] | temp[1] << 8, pec)
        elif size == I2C_SMBUS_PROC_CALL:
            word = bus.process_call(address, command, temp[0] | temp[1] << 8, pec)
            temp[0:2] = word.to_bytes(2, "little")
        elif size == I2C_SMBUS_BLOCK_DATA:
            if reading:
                _put_block(temp, bus.read_block_data(address, command, pec))
            else:
                bus.write_block_data(address, command, bytes(temp[1 : 1 + count]), pec)
        elif size == I2C_SMBUS_BLOCK_PROC_CALL:
            _put_block(temp, bus.block_process_call(address, command, bytes(temp[1 : 1 + count]), pec))
        elif reading:  # I2C_SMBUS_I2C_BLOCK_DATA: block[0] is the count both ways, no PEC
            temp[1 : 1 + count] = bus.read_i2c_block_data(address, command, count)
        else:
            bus.write_i2c_block_data(address, command, bytes(temp[1 : 1 + count]))

    # ------------------------------------------------------------------ I2C_RDWR

    def _rdwr_ioctl(self, arg: IoctlArgument) -> int:
        """``I2C_RDWR`` (i2cdev_ioctl_rdwr): returns the number of messages transferred."""
        block = arg.memory(RDWR_IOCTL_DATA_SIZE)
        raw = block.read()
        count = struct.unpack_from("=I", raw, 8)[0]
        if unsigned_long(raw) == 0 or count == 0 or count > I2C_RDWR_IOCTL_MAX_MSGS:
            raise os_error(errno.EINVAL)
        table = block.follow(0, count * I2C_MSG_SIZE)
        headers = table.read()
        messages: list[I2CMessage] = []
        buffers: list[UserMemory | None] = []
        ten_bit = recv_len = False
        for i in range(count):
            offset = i * I2C_MSG_SIZE
            address, flags, length = struct.unpack_from("=HHH", headers, offset)
            if length > I2C_DEV_MAX_TRANSFER:
                raise os_error(errno.EINVAL)
            buffer = None
            payload = b""
            if length:  # memdup_user of every buffer (EFAULT for a NULL one)
                if unsigned_long(headers, offset + I2C_MSG_BUF_OFFSET) == 0:
                    raise os_error(errno.EFAULT)
                buffer = table.follow(offset + I2C_MSG_BUF_OFFSET, length)
                payload = buffer.read()[:length]
            if flags & I2C_M_RECV_LEN:  # the first byte: the extra bytes after the count
                if (not flags & I2C_M_RD or not length or payload[0] < 1
                        or length < payload[0] + I2C_SMBUS_BLOCK_MAX):
                    raise os_error(errno.EINVAL)
                recv_len = True
            ten_bit = ten_bit or bool(flags & I2C_M_TEN)
            if flags & I2C_M_RD:
                messages.append(I2CMessage(address, True, b"", length))
            else:
                messages.append(I2CMessage(address, False, payload))
            buffers.append(buffer)
        if not self.bus.funcs & I2C_FUNC_I2C:  # i2c_transfer: no master_xfer, after the copies
            raise os_error(errno.EOPNOTSUPP)
        if ten_bit:
            raise os_error(errno.ENXIO)
        if recv_len:
            raise os_error(errno.EOPNOTSUPP)
        self.bus.i2c_transfer(messages)
        # the read buffers are copied back last message first; the first copy that faults
        # makes the result EFAULT and ends the copying (earlier messages keep no data)
        for message, buffer in reversed(list(zip(messages, buffers))):
            if message.read and buffer is not None and message.data:
                buffer.write(message.data)
        return count

    # ------------------------------------------------------------------ read, write

    def read(self, count: int) -> bytes:
        """``read(fd, buf, count)``: a plain I2C read, 8192 bytes at most."""
        if not self.bus.funcs & I2C_FUNC_I2C:
            raise os_error(errno.EOPNOTSUPP)
        count = min(count, I2C_DEV_MAX_TRANSFER)
        return self.bus.i2c_read(self._target(), count)

    def write(self, payload: bytes) -> int:
        """``write(fd, buf, count)``: a plain I2C write, 8192 bytes at most; returns the count."""
        if not self.bus.funcs & I2C_FUNC_I2C:
            raise os_error(errno.EOPNOTSUPP)
        payload = bytes(payload[:I2C_DEV_MAX_TRANSFER])
        self.bus.i2c_write(self._target(), payload)
        return len(payload)


def _put_block(temp: bytearray, block: bytes) -> None:
    temp[0] = len(block)
    temp[1 : 1 + len(block)] = block
