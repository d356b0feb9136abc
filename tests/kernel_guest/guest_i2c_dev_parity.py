"""The i2c-dev parity checks: every ioctl argument shape, bad pointers, the descriptor and
the node, through fcntl and through smbus2, smbus3, Adafruit_PureIO and periphery.

Runs twice with the same code (tests/test_i2c_dev_parity.py): INSIDE the kernel guest,
against the real kernel's /dev/i2c-BUS (drivers/i2c/i2c-dev.c over the virtio adapter, the
chips at 0x68 and 0x69 served by bmg160-emu), and in the host's process under
patch_i2c_dev. ``run_checks(bus)`` gives {check: outcome}, where an outcome is the value a
call returned (bytes as hex) or the exception's type and errno name; the two worlds must
give the same dictionary. Usage in the guest: python guest_i2c_dev_parity.py BUS; prints
the JSON object.

Only what i2c-dev and the VFS decide is compared: adapter-specific answers (a NACK's
errno, zero-length messages, 10-bit transfers, SMBus block reads and quick commands that
virtio-i2c lacks) are left to tests/test_i2c_dev_ioctls.py, and noise values to the chip's
own tests (rate registers are compared by length).
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import glob
import io
import json
import os
import select
import stat
import sys
from collections.abc import Callable
from typing import Any

I2C_SLAVE, I2C_SLAVE_FORCE, I2C_TENBIT, I2C_FUNCS = 0x0703, 0x0706, 0x0704, 0x0705
I2C_RETRIES, I2C_TIMEOUT, I2C_RDWR, I2C_PEC, I2C_SMBUS = 0x0701, 0x0702, 0x0707, 0x0708, 0x0720
I2C_M_RD, I2C_M_RECV_LEN = 0x0001, 0x0400
SMBUS_READ, SMBUS_WRITE = 1, 0
SMBUS_BYTE, SMBUS_BYTE_DATA, SMBUS_WORD_DATA, SMBUS_BLOCK_DATA = 1, 2, 3, 5
SMBUS_I2C_BLOCK_BROKEN, SMBUS_I2C_BLOCK_DATA = 6, 8
CHIP_ID, BW, BGW_SOFTRESET = 0x00, 0x10, 0x14
INT_MAX = 0x7FFFFFFF


class i2c_msg(ctypes.Structure):
    _fields_ = [("addr", ctypes.c_uint16), ("flags", ctypes.c_uint16),
                ("len", ctypes.c_uint16), ("buf", ctypes.c_void_p)]


class i2c_rdwr_ioctl_data(ctypes.Structure):
    _fields_ = [("msgs", ctypes.c_void_p), ("nmsgs", ctypes.c_uint32)]


class i2c_smbus_ioctl_data(ctypes.Structure):
    _fields_ = [("read_write", ctypes.c_uint8), ("command", ctypes.c_uint8),
                ("size", ctypes.c_uint32), ("data", ctypes.c_void_p)]


def outcome(call: Callable[[], Any]) -> Any:
    """What a call gave: its value (bytes as hex text), or its exception's type and errno."""
    try:
        value = call()
    except Exception as exc:  # noqa: BLE001 - the exception is the outcome compared
        code = getattr(exc, "errno", None)
        return {"error": type(exc).__name__,
                "errno": errno.errorcode.get(code, code) if isinstance(code, int) else None}
    return plain(value)


def plain(value: Any) -> Any:
    """A value as JSON carries it: bytes as hex text, sequences as lists, other objects by
    their type's name."""
    if isinstance(value, (bytes, bytearray, memoryview)):
        return bytes(value).hex()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if value is None or isinstance(value, (bool, int, float, str, dict)):
        return value
    return type(value).__name__


TASK_SIZE_MAX = (1 << 47) - 4096  # x86-64's first address access_ok refuses (4-level paging)
VSYSCALL_PAGE = 0xFFFFFFFFFF600000  # x86-64's legacy vsyscall page, in the kernel's half


def read_only_page(first: int = 0) -> int:
    """The address of one page mapped read-only, its first byte ``first`` (the rest 0):
    copy_from_user from it works, copy_to_user into it faults."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mmap.restype = ctypes.c_void_p
    libc.mmap.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int, ctypes.c_int,
                          ctypes.c_int, ctypes.c_long]
    libc.mprotect.argtypes = [ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int]
    address = libc.mmap(None, 4096, 0x3, 0x22, -1, 0)  # PROT_READ|PROT_WRITE, MAP_PRIVATE|
    assert address not in (None, ctypes.c_void_p(-1).value)  # MAP_ANONYMOUS
    ctypes.c_uint8.from_address(address).value = first
    assert libc.mprotect(address, 4096, 0x1) == 0  # PROT_READ
    return address


class Checks:
    """The checks on one bus; ``self.results`` collects them in order."""

    def __init__(self, bus: int) -> None:
        self.bus = bus
        self.path = f"/dev/i2c-{bus}"
        self.results: dict[str, Any] = {}
        self.keep: list[Any] = []  # ctypes objects whose addresses are in flight
        self.read_only = read_only_page()
        self.read_only_count_4 = read_only_page(4)  # an I2C block request of 4 bytes

    def check(self, name: str, call: Callable[[], Any]) -> None:
        self.results[name] = outcome(call)

    def fd(self, flags: int = os.O_RDWR, address: int | None = 0x68) -> int:
        fd = os.open(self.path, flags)
        if address is not None:
            fcntl.ioctl(fd, I2C_SLAVE, address)
        return fd

    # --------------------------------------------------------------- requests

    def rdwr(self, *messages: tuple[int, int, int, int | None]) -> i2c_rdwr_ioctl_data:
        """An I2C_RDWR request of (address, flags, length, buffer address or None: a fresh
        buffer of that length) messages."""
        table = (i2c_msg * len(messages))()
        for slot, (address, flags, length, buffer) in zip(table, messages):
            if buffer is None:
                data = (ctypes.c_uint8 * max(length, 1))()
                self.keep.append(data)
                buffer = ctypes.addressof(data)
            slot.addr, slot.flags, slot.len, slot.buf = address, flags, length, buffer
        self.keep.append(table)
        return i2c_rdwr_ioctl_data(ctypes.addressof(table), len(messages))

    def smbus(self, read_write: int, command: int, size: int,
              data: int | None | bytes = b"") -> i2c_smbus_ioctl_data:
        """An I2C_SMBUS request; ``data``: an address, None (NULL) or the union's bytes."""
        if isinstance(data, bytes):
            union = (ctypes.c_uint8 * 34)(*data.ljust(34, b"\0"))
            self.keep.append(union)
            data = ctypes.addressof(union)
        return i2c_smbus_ioctl_data(read_write, command, size, data)

    def message_bytes(self, request: i2c_rdwr_ioctl_data, index: int) -> bytes:
        table = (i2c_msg * request.nmsgs).from_address(request.msgs)
        return ctypes.string_at(table[index].buf, table[index].len)

    def smbus_data(self, request: i2c_smbus_ioctl_data, count: int) -> bytes:
        return ctypes.string_at(request.data, count)

    # --------------------------------------------------------------- the checks

    def run(self) -> dict[str, Any]:
        fd = self.fd()
        for register, value in ((BGW_SOFTRESET, 0xB6),):  # both chips from their reset state
            for address in (0x68, 0x69):
                fcntl.ioctl(fd, I2C_SLAVE, address)
                os.write(fd, bytes([register, value]))
        fcntl.ioctl(fd, I2C_SLAVE, 0x68)
        os.close(fd)
        self.scalar_requests()
        self.rdwr_requests(fcntl.ioctl, "fcntl")
        self.smbus_requests(fcntl.ioctl, "fcntl")
        self.libraries()
        self.descriptors()
        self.node()
        return self.results

    def scalar_requests(self) -> None:
        fd = self.fd(address=None)
        ioctl = fcntl.ioctl
        for arg in (8, 1, 0, -1):
            self.check(f"I2C_FUNCS arg {arg}", lambda a=arg: ioctl(fd, I2C_FUNCS, a))
        self.check("I2C_FUNCS bytes(8) has I2C", lambda: ioctl(fd, I2C_FUNCS, bytes(8))[0] & 1)
        self.check("I2C_FUNCS bytearray(8) length",
                   lambda: (ioctl(fd, I2C_FUNCS, bytearray(8)), 0)[1])
        for request, name in ((I2C_SLAVE, "I2C_SLAVE"), (I2C_SLAVE_FORCE, "I2C_SLAVE_FORCE")):
            for address in (0x68, 0x7F, 0x80, 0x3FF, 0x400, -1):
                self.check(f"{name} {address:#x}", lambda r=request, a=address: ioctl(fd, r, a))
        self.check("I2C_TENBIT 1", lambda: ioctl(fd, I2C_TENBIT, 1))
        self.check("I2C_SLAVE 0x100 ten-bit", lambda: ioctl(fd, I2C_SLAVE, 0x100))
        self.check("I2C_SLAVE 0x400 ten-bit", lambda: ioctl(fd, I2C_SLAVE, 0x400))
        self.check("I2C_TENBIT 0", lambda: ioctl(fd, I2C_TENBIT, 0))
        self.check("I2C_SLAVE 0x100 seven-bit", lambda: ioctl(fd, I2C_SLAVE, 0x100))
        for value in (1, 0, -1):
            self.check(f"I2C_PEC {value}", lambda v=value: ioctl(fd, I2C_PEC, v))
        ioctl(fd, I2C_PEC, 0)
        for value in (3, INT_MAX, -1):
            self.check(f"I2C_RETRIES {value}", lambda v=value: ioctl(fd, I2C_RETRIES, v))
        for value in (10, INT_MAX // 10, INT_MAX // 10 + 1, -1):
            self.check(f"I2C_TIMEOUT {value}", lambda v=value: ioctl(fd, I2C_TIMEOUT, v))
        self.check("unknown request", lambda: ioctl(fd, 0x0799, 0))
        self.check("I2C_SLAVE as a buffer", lambda: ioctl(fd, I2C_SLAVE, bytes(8)))
        os.close(fd)

    def rdwr_requests(self, ioctl: Callable[..., Any], via: str) -> None:
        fd = self.fd()
        rd = I2C_M_RD
        self.check(f"{via} I2C_RDWR arg 16", lambda: ioctl(fd, I2C_RDWR, 16))
        self.check(f"{via} I2C_RDWR arg 0", lambda: ioctl(fd, I2C_RDWR, 0))
        self.check(f"{via} I2C_RDWR msgs NULL",
                   lambda: ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data(None, 1)))
        self.check(f"{via} I2C_RDWR msgs at 0x10",
                   lambda: ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data(0x10, 1)))
        good = self.rdwr((0x68, 0, 1, None), (0x68, rd, 1, None))
        self.check(f"{via} I2C_RDWR 0 messages",
                   lambda: ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data(good.msgs, 0)))
        self.check(f"{via} I2C_RDWR 43 messages",
                   lambda: ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data(good.msgs, 43)))
        self.check(f"{via} I2C_RDWR write buffer at 0x10",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, 0, 1, 0x10))))
        self.check(f"{via} I2C_RDWR read buffer at 0x10",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, rd, 1, 0x10))))
        self.check(f"{via} I2C_RDWR read buffer NULL",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, rd, 1, 0))))
        self.check(f"{via} I2C_RDWR message of 8193",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, rd, 8193, None))))
        for first, length in ((0, 40), (9, 40), (1, 32)):
            def recv_len(first: int = first, length: int = length) -> Any:
                request = self.rdwr((0x68, rd | I2C_M_RECV_LEN, length, None))
                table = (i2c_msg * 1).from_address(request.msgs)
                ctypes.c_uint8.from_address(table[0].buf).value = first
                return ioctl(fd, I2C_RDWR, request)
            self.check(f"{via} I2C_RDWR receive-length first {first} length {length}", recv_len)
        self.check(f"{via} I2C_RDWR receive-length write",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, I2C_M_RECV_LEN, 40, None))))

        def register_read(address: int = 0x68) -> Any:
            request = self.rdwr((address, 0, 1, None), (address, rd, 1, None))
            return [ioctl(fd, I2C_RDWR, request), self.message_bytes(request, 1).hex()]
        self.check(f"{via} I2C_RDWR CHIP_ID of 0x68", register_read)
        self.check(f"{via} I2C_RDWR CHIP_ID of 0x69", lambda: register_read(0x69))

        def into_read_only() -> Any:  # the transfer happens; the copy back faults
            return ioctl(fd, I2C_RDWR, self.rdwr((0x68, 0, 1, None),
                                                  (0x68, rd, 1, self.read_only)))
        self.check(f"{via} I2C_RDWR read into a read-only page", into_read_only)

        def one_good_one_bad() -> Any:
            request = self.rdwr((0x68, 0, 1, None), (0x68, rd, 1, None),
                                (0x68, rd, 1, self.read_only))
            result = outcome(lambda: ioctl(fd, I2C_RDWR, request))
            return [result, self.message_bytes(request, 1).hex()]  # still copied back
        self.check(f"{via} I2C_RDWR one buffer copied, one faulting", one_good_one_bad)
        self.check(f"{via} I2C_RDWR 6 rate bytes",
                   lambda: ioctl(fd, I2C_RDWR, self.rdwr((0x68, 0, 1, None),
                                                         (0x68, rd, 6, None))))
        os.close(fd)

    def smbus_requests(self, ioctl: Callable[..., Any], via: str) -> None:
        fd = self.fd()
        self.check(f"{via} I2C_SMBUS arg 16", lambda: ioctl(fd, I2C_SMBUS, 16))
        self.check(f"{via} I2C_SMBUS arg 0", lambda: ioctl(fd, I2C_SMBUS, 0))
        self.check(f"{via} I2C_SMBUS size 99",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_READ, 0, 99)))
        self.check(f"{via} I2C_SMBUS read_write 2",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(2, 0, SMBUS_BYTE_DATA)))
        self.check(f"{via} I2C_SMBUS data NULL",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_READ, 0, SMBUS_BYTE_DATA, None)))
        for size, name in ((SMBUS_BYTE_DATA, "byte"), (SMBUS_WORD_DATA, "word"),
                           (SMBUS_I2C_BLOCK_DATA, "i2c block")):
            self.check(f"{via} I2C_SMBUS read {name}, data at 8",
                       lambda s=size: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_READ, 0, s, 8)))
            self.check(f"{via} I2C_SMBUS write {name}, data at 8",
                       lambda s=size: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_WRITE, BW, s, 8)))
            # the I2C block's count is read from the page (4): the transfer happens, the
            # copy back faults
            page = self.read_only_count_4 if size == SMBUS_I2C_BLOCK_DATA else self.read_only
            self.check(f"{via} I2C_SMBUS read {name} into a read-only page",
                       lambda s=size, p=page: ioctl(fd, I2C_SMBUS,
                                                    self.smbus(SMBUS_READ, 0, s, p)))
        for where, address in (("at TASK_SIZE_MAX", TASK_SIZE_MAX),
                               ("in the vsyscall page", VSYSCALL_PAGE)):  # access_ok refuses
            self.check(f"{via} I2C_SMBUS read byte, data {where}",
                       lambda a=address: ioctl(fd, I2C_SMBUS,
                                               self.smbus(SMBUS_READ, 0, SMBUS_BYTE_DATA, a)))
        # a block count of 0: EINVAL in the i2c core since 6.1.190, before any transfer
        self.check(f"{via} I2C_SMBUS i2c block read of 0",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_READ, 0, SMBUS_I2C_BLOCK_DATA,
                                                            bytes([0]))))
        self.check(f"{via} I2C_SMBUS i2c block write of 0",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_WRITE, BW, SMBUS_I2C_BLOCK_DATA,
                                                            bytes([0]))))
        self.check(f"{via} I2C_SMBUS block write of 0",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_WRITE, BW, SMBUS_BLOCK_DATA,
                                                            bytes([0]))))
        self.check(f"{via} I2C_SMBUS send byte, data at 8 (not used)",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_WRITE, 0, SMBUS_BYTE, 8)))
        self.check(f"{via} I2C_SMBUS receive byte, data at 8",
                   lambda: ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_READ, 0, SMBUS_BYTE, 8)))

        def read(size: int, command: int, count: int, block: int = 0) -> Any:
            request = self.smbus(SMBUS_READ, command, size, bytes([block]))
            return [ioctl(fd, I2C_SMBUS, request), self.smbus_data(request, count).hex()]
        self.check(f"{via} I2C_SMBUS read byte CHIP_ID", lambda: read(SMBUS_BYTE_DATA, 0, 1))
        self.check(f"{via} I2C_SMBUS read word CHIP_ID", lambda: read(SMBUS_WORD_DATA, 0, 2))
        self.check(f"{via} I2C_SMBUS i2c block of 4 from 0x0F",
                   lambda: read(SMBUS_I2C_BLOCK_DATA, 0x0F, 5, 4))
        self.check(f"{via} I2C_SMBUS i2c block of 33",
                   lambda: read(SMBUS_I2C_BLOCK_DATA, 0x0F, 1, 33))
        self.check(f"{via} I2C_SMBUS broken i2c block from 0x00 (count)",
                   lambda: read(SMBUS_I2C_BLOCK_BROKEN, 0, 1))

        def write_then_read(value: int) -> Any:
            ioctl(fd, I2C_SMBUS, self.smbus(SMBUS_WRITE, BW, SMBUS_BYTE_DATA, bytes([value])))
            return read(SMBUS_BYTE_DATA, BW, 1)
        self.check(f"{via} I2C_SMBUS write then read BW", lambda: write_then_read(0x03))
        write_then_read(0x00)
        os.close(fd)

    def libraries(self) -> None:
        import periphery
        import smbus2
        import smbus3
        from Adafruit_PureIO import smbus as pureio

        modules = {"smbus2": sys.modules["smbus2.smbus2"], "smbus3": sys.modules["smbus3.smbus3"],
                   "PureIO": pureio, "periphery": sys.modules["periphery.i2c"]}
        for via, module in modules.items():  # each library's own bound ioctl name
            bound = module.ioctl if hasattr(module, "ioctl") else module.fcntl.ioctl
            fd = self.fd()
            self.check(f"{via} ioctl I2C_FUNCS arg 8",
                       lambda b=bound, f=fd: b(f, I2C_FUNCS, 8))
            self.check(f"{via} ioctl I2C_RDWR arg 16", lambda b=bound, f=fd: b(f, I2C_RDWR, 16))
            self.check(f"{via} ioctl I2C_SMBUS data at 8",
                       lambda b=bound, f=fd: b(f, I2C_SMBUS,
                                               self.smbus(SMBUS_READ, 0, SMBUS_BYTE_DATA, 8)))
            os.close(fd)
        self.rdwr_requests(sys.modules["smbus2.smbus2"].ioctl, "smbus2")
        self.smbus_requests(sys.modules["smbus3.smbus3"].ioctl, "smbus3")
        for via, module in (("smbus2", smbus2), ("smbus3", smbus3)):
            with module.SMBus(self.bus) as bus:
                self.check(f"{via} read_byte_data", lambda b=bus: b.read_byte_data(0x68, CHIP_ID))
                self.check(f"{via} read_i2c_block_data length",
                           lambda b=bus: len(b.read_i2c_block_data(0x68, 0x02, 6)))
                write = module.i2c_msg.write(0x68, [CHIP_ID])
                get = module.i2c_msg.read(0x68, 1)
                self.check(f"{via} i2c_rdwr", lambda b=bus, w=write, g=get: (
                    b.i2c_rdwr(w, g), bytes(g).hex())[1])
                bad = module.i2c_msg.read(0x68, 1)
                bad.buf = ctypes.cast(0x10, type(bad.buf))
                self.check(f"{via} i2c_rdwr buffer at 0x10", lambda b=bus, m=bad: b.i2c_rdwr(m))
                self.check(f"{via} fstat of its fd is 89:N", lambda b=bus: self.node_of(b.fd))
                self.check(f"{via} lseek of its fd", lambda b=bus: os.lseek(b.fd, 0, os.SEEK_SET))
        bus = pureio.SMBus(self.bus)
        self.check("PureIO read_byte_data", lambda: bus.read_byte_data(0x68, CHIP_ID))
        self.check("PureIO read_i2c_block_data length",
                   lambda: len(bus.read_i2c_block_data(0x68, 0x02, 6)))
        self.check("PureIO write_byte_data then read",
                   lambda: (bus.write_byte_data(0x68, BW, 2), bus.read_byte_data(0x68, BW))[1])
        bus.write_byte_data(0x68, BW, 0)
        self.check("PureIO read_bytes", lambda: bytes(bus.read_bytes(0x68, 1)).hex())
        self.check("PureIO its file", lambda: [isinstance(bus._device, io.FileIO),
                                                bus._device.mode, bus._device.seekable()])
        bus.close()
        i2c = periphery.I2C(self.path)
        messages = [periphery.I2C.Message([CHIP_ID]), periphery.I2C.Message([0], read=True)]
        self.check("periphery transfer", lambda: (i2c.transfer(0x68, messages),
                                                  bytes(messages[1].data).hex())[1])
        self.check("periphery message of 8193", lambda: i2c.transfer(
            0x68, [periphery.I2C.Message(bytearray(8193), read=True)]))
        self.check("periphery fstat of its fd", lambda: self.node_of(i2c.fd))
        i2c.close()

    def node_of(self, fd: int) -> Any:
        st = os.fstat(fd)
        return [stat.S_ISCHR(st.st_mode), os.major(st.st_rdev), os.minor(st.st_rdev) == self.bus]

    def descriptors(self) -> None:
        fd = self.fd()
        self.check("write then read", lambda: (os.write(fd, bytes([CHIP_ID])), os.read(fd, 1)))
        self.check("read 9000 is 8192 bytes",
                   lambda: (os.write(fd, bytes([CHIP_ID])), len(os.read(fd, 9000)))[1])
        # to FIFO_DATA, whose pointer stays put and which takes no data (spec 2.4)
        self.check("write of 9000 bytes", lambda: os.write(fd, bytes([0x3F]) + bytes(8999)))
        self.check("read a negative count", lambda: os.read(fd, -1))
        self.check("lseek SEEK_SET", lambda: os.lseek(fd, 0, os.SEEK_SET))
        self.check("lseek SEEK_CUR", lambda: os.lseek(fd, 0, os.SEEK_CUR))
        self.check("lseek SEEK_END", lambda: os.lseek(fd, 10, os.SEEK_END))
        self.check("pread at 0", lambda: (os.write(fd, bytes([CHIP_ID])), os.pread(fd, 1, 0))[1])
        self.check("pread at 1000", lambda: (os.write(fd, bytes([CHIP_ID])),
                                             os.pread(fd, 1, 1000))[1])
        self.check("pread at -1", lambda: os.pread(fd, 1, -1))
        self.check("pwrite at 5", lambda: os.pwrite(fd, bytes([CHIP_ID]), 5))
        self.check("isatty", lambda: os.isatty(fd))
        self.check("F_GETFL access mode", lambda: fcntl.fcntl(fd, fcntl.F_GETFL) & os.O_ACCMODE)
        self.check("select", lambda: [len(r) for r in select.select([fd], [fd], [], 0)])

        def dup_shares_the_address() -> Any:
            os.write(fd, bytes([BW, 0x03]))  # 0x68's BW = 3
            other = os.dup(fd)
            fcntl.ioctl(other, I2C_SLAVE, 0x69)  # the dup's address is the file's
            os.write(other, bytes([BW, 0x05]))  # 0x69's BW = 5
            os.write(fd, bytes([BW]))
            seen = os.read(fd, 1)  # through the first descriptor: 0x69's
            fcntl.ioctl(other, I2C_SLAVE, 0x68)
            os.write(other, bytes([BW]))
            back = os.read(fd, 1)
            os.close(other)
            os.write(fd, bytes([BW]))
            after = os.read(fd, 1)  # still open after the dup's close
            return [seen.hex(), back.hex(), after.hex()]
        self.check("dup shares the address", dup_shares_the_address)

        def dup2_is_the_same_file() -> Any:
            spare = os.open("/dev/null", os.O_RDONLY)
            os.dup2(fd, spare)
            os.write(spare, bytes([CHIP_ID]))
            data = os.read(spare, 1)
            st = os.fstat(spare)
            os.close(spare)
            return [data.hex(), stat.S_ISCHR(st.st_mode)]
        self.check("dup2 onto another descriptor", dup2_is_the_same_file)

        def file_io(mode: str) -> Any:
            handle = io.FileIO(fd, mode, closefd=False)
            out = [handle.mode, handle.name == fd, handle.seekable(), handle.readable(),
                   handle.writable()]
            out.append(outcome(lambda: handle.write(bytes([CHIP_ID]))))
            out.append(outcome(lambda: handle.read(1)))
            out.append(outcome(handle.tell))
            out.append(outcome(lambda: handle.seek(0)))
            handle.close()
            return out
        for mode in ("rb", "r+b", "wb", "rb+", "ab"):
            self.check(f"FileIO(fd, {mode!r})", lambda m=mode: file_io(m))
        self.check("FileIO(fd, 'rt')", lambda: io.FileIO(fd, "rt", closefd=False))
        self.check("FileIO(path, 'r+b')",
                   lambda: self.path_file(lambda: io.FileIO(self.path, "r+b")))
        self.check("open(path, 'r+b', buffering=0)",
                   lambda: self.path_file(lambda: open(self.path, "r+b", buffering=0)))  # noqa: SIM115
        self.check("open(path, 'rb')",
                   lambda: self.path_file(lambda: open(self.path, "rb")))  # noqa: SIM115
        self.check("open(path, 'r+b') buffered", lambda: open(self.path, "r+b"))  # noqa: SIM115
        self.check("os.fdopen(dup, 'wb', 0)",
                   lambda: self.path_file(lambda: os.fdopen(os.dup(fd), "wb", 0)))
        os.close(fd)
        ro = self.fd(os.O_RDONLY)
        self.check("write on O_RDONLY", lambda: os.write(ro, bytes([CHIP_ID])))
        self.check("read on O_RDONLY after its I2C_SLAVE", lambda: len(os.read(ro, 1)))
        os.close(ro)
        wo = self.fd(os.O_WRONLY)
        self.check("read on O_WRONLY", lambda: os.read(wo, 1))
        self.check("write on O_WRONLY", lambda: os.write(wo, bytes([CHIP_ID])))
        os.close(wo)
        self.check("open O_CREAT|O_EXCL", lambda: os.open(self.path, os.O_RDWR | os.O_CREAT
                                                          | os.O_EXCL))
        self.check("open O_DIRECTORY", lambda: os.open(self.path, os.O_RDONLY | os.O_DIRECTORY))

    def path_file(self, make: Callable[[], Any]) -> Any:
        handle = make()
        try:
            raw = getattr(handle, "raw", handle)
            fcntl.ioctl(handle.fileno(), I2C_SLAVE, 0x68)
            kind = [type(handle).__name__ if handle is not raw else "FileIO",
                    getattr(handle, "mode", None), raw.mode, isinstance(raw, io.FileIO),
                    outcome(handle.seekable)]
            if handle.writable():
                kind.append(outcome(lambda: (handle.write(bytes([CHIP_ID])), handle.flush())[0]))
            if handle.readable():
                kind.append(outcome(lambda: handle.read(1)))
            return kind
        finally:
            handle.close()

    def node(self) -> None:
        name = os.path.basename(self.path)
        self.check("stat", lambda: self.describe_stat(os.stat(self.path)))
        self.check("lstat", lambda: self.describe_stat(os.lstat(self.path)))
        self.check("os.path.exists", lambda: os.path.exists(self.path))
        self.check("os.path.isfile", lambda: os.path.isfile(self.path))
        self.check("os.path.isdir", lambda: os.path.isdir(self.path))
        self.check("access R|W", lambda: os.access(self.path, os.R_OK | os.W_OK))
        self.check("access X", lambda: os.access(self.path, os.X_OK))
        self.check("glob", lambda: self.path in glob.glob("/dev/i2c-*"))
        self.check("listdir", lambda: name in os.listdir("/dev"))
        self.check("listdir bytes", lambda: os.fsencode(name) in os.listdir(b"/dev"))
        self.check("scandir entry", lambda: [[e.is_dir(), e.is_file(), e.is_symlink(),
                                              stat.S_ISCHR(e.stat().st_mode)]
                                             for e in os.scandir("/dev") if e.name == name])
        from pathlib import Path

        self.check("Path.is_char_device", lambda: Path(self.path).is_char_device())
        self.check("Path('/dev').glob", lambda: Path(self.path) in Path("/dev").glob("i2c-*"))
        fd = self.fd()
        self.check("fstat", lambda: self.describe_stat(os.fstat(fd)))
        self.check("fstat equals stat",
                   lambda: os.fstat(fd).st_rdev == os.stat(self.path).st_rdev)
        os.close(fd)

    def describe_stat(self, st: os.stat_result) -> Any:
        return [stat.S_ISCHR(st.st_mode), oct(stat.S_IMODE(st.st_mode)), os.major(st.st_rdev),
                os.minor(st.st_rdev) == self.bus, st.st_size, st.st_nlink, st.st_blksize]


def run_checks(bus: int) -> dict[str, Any]:
    """Every check on /dev/i2c-``bus`` (the chips at 0x68 and 0x69): {name: outcome}."""
    return Checks(bus).run()


if __name__ == "__main__":
    print(json.dumps(run_checks(int(sys.argv[1]))))
