"""The i2c-dev emulation (bmg160_emu.bus.i2c_dev) answers ioctls as drivers/i2c/i2c-dev.c does.

Requests are built with the kernel's own structures (ctypes, as a C program lays them out)
and issued through ``fcntl.ioctl`` as smbus2 calls it under ``patch_smbus``: the marshalling
layer patch_smbus uses, over the same I2CDevFile the umockdev node uses (whose C client
checks the same cases in test_umockdev_programs.py).
"""

from __future__ import annotations

import ctypes
import errno

import pytest
import smbus2
import smbus2.smbus2 as smbus2_impl
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.kernel_abi import (
    I2C_FUNCS,
    I2C_M_RD,
    I2C_M_RECV_LEN,
    I2C_M_TEN,
    I2C_PEC,
    I2C_RDWR,
    I2C_RETRIES,
    I2C_SLAVE,
    I2C_SLAVE_FORCE,
    I2C_SMBUS,
    I2C_SMBUS_BLOCK_DATA,
    I2C_SMBUS_BYTE,
    I2C_SMBUS_BYTE_DATA,
    I2C_SMBUS_I2C_BLOCK_BROKEN,
    I2C_SMBUS_I2C_BLOCK_DATA,
    I2C_SMBUS_QUICK,
    I2C_SMBUS_READ,
    I2C_SMBUS_WRITE,
    I2C_TENBIT,
    I2C_TIMEOUT,
    i2c_msg,
    i2c_rdwr_ioctl_data,
    i2c_smbus_data,
    i2c_smbus_ioctl_data,
)
from bmg160_emu.bus.patching import patch_smbus


@pytest.fixture
def node():
    """An emulated /dev/i2c-1 opened as smbus2 opens it; yields (fd, ioctl, chip, bus)."""
    chip = RegisterFileChip()
    bus = I2CBus(1, {0x68: chip})
    with patch_smbus({1: bus}), smbus2.SMBus(1) as handle:
        yield handle.fd, smbus2_impl.ioctl, chip, bus


def errno_of(call, *args) -> int:
    try:
        call(*args)
    except OSError as exc:
        return exc.errno
    return 0


def smbus_request(read_write, command, size, data):
    pointer = ctypes.pointer(data) if data is not None else None
    return i2c_smbus_ioctl_data(read_write, command, size, pointer)


def test_null_data_pointer_is_einval_as_in_i2c_dev(node):
    fd, ioctl, _, _ = node
    ioctl(fd, I2C_SLAVE, 0x68)
    request = smbus_request(I2C_SMBUS_READ, 0x00, I2C_SMBUS_BYTE_DATA, None)
    assert errno_of(ioctl, fd, I2C_SMBUS, request) == errno.EINVAL


def test_quick_and_send_byte_need_no_data(node):
    fd, ioctl, _, bus = node
    ioctl(fd, I2C_SLAVE, 0x68)
    assert ioctl(fd, I2C_SMBUS, smbus_request(I2C_SMBUS_WRITE, 0, I2C_SMBUS_QUICK, None)) == 0
    assert ioctl(fd, I2C_SMBUS, smbus_request(I2C_SMBUS_WRITE, 0x21, I2C_SMBUS_BYTE, None)) == 0
    assert bus.log.kinds() == ["write_quick", "write_byte"]


@pytest.mark.parametrize(
    ("read_write", "size"), [(I2C_SMBUS_READ, 9), (2, I2C_SMBUS_BYTE_DATA)]
)
def test_unknown_size_or_direction_is_einval(node, read_write, size):
    fd, ioctl, _, bus = node
    request = smbus_request(read_write, 0, size, i2c_smbus_data())
    assert errno_of(ioctl, fd, I2C_SMBUS, request) == errno.EINVAL
    assert len(bus.log) == 0


def test_i2c_block_count_over_32_is_einval(node):
    fd, ioctl, _, _ = node
    ioctl(fd, I2C_SLAVE, 0x68)
    data = i2c_smbus_data()
    data.block[0] = 33
    request = smbus_request(I2C_SMBUS_READ, 0, I2C_SMBUS_I2C_BLOCK_DATA, data)
    assert errno_of(ioctl, fd, I2C_SMBUS, request) == errno.EINVAL


def test_size_6_reads_32_bytes_whatever_the_count(node):
    fd, ioctl, _, _ = node
    ioctl(fd, I2C_SLAVE, 0x68)
    data = i2c_smbus_data()
    data.block[0] = 3
    ioctl(fd, I2C_SMBUS, smbus_request(I2C_SMBUS_READ, 0x10, I2C_SMBUS_I2C_BLOCK_BROKEN, data))
    assert data.block[0] == 32
    assert list(data.block[1:33]) == list(range(0x10, 0x30))  # RegisterFileChip: reg == value


def test_i2c_block_read_keeps_the_callers_bytes_after_the_count(node):
    fd, ioctl, _, _ = node
    ioctl(fd, I2C_SLAVE, 0x68)
    data = i2c_smbus_data()
    data.block[0], data.block[5] = 3, 0xEE
    ioctl(fd, I2C_SMBUS, smbus_request(I2C_SMBUS_READ, 0x20, I2C_SMBUS_I2C_BLOCK_DATA, data))
    assert list(data.block[:6]) == [3, 0x20, 0x21, 0x22, 0, 0xEE]


def test_smbus_block_read_returns_the_kernels_zeroed_union(node):
    """i2c-dev does not copy the union in for a block read: bytes after the block are 0."""
    fd, ioctl, chip, _ = node
    chip.regs[0x20] = 2  # the count byte
    ioctl(fd, I2C_SLAVE, 0x68)
    data = i2c_smbus_data()
    for i in range(34):
        data.block[i] = 0xEE
    ioctl(fd, I2C_SMBUS, smbus_request(I2C_SMBUS_READ, 0x20, I2C_SMBUS_BLOCK_DATA, data))
    assert list(data.block[:4]) == [2, 0x21, 0x22, 0]
    assert set(data.block[3:]) == {0}


def test_failed_read_leaves_the_callers_union_alone(node):
    fd, ioctl, _, _ = node
    ioctl(fd, I2C_SLAVE_FORCE, 0x50)  # nobody there
    data = i2c_smbus_data()
    data.byte = 0xAB
    request = smbus_request(I2C_SMBUS_READ, 0, I2C_SMBUS_BYTE_DATA, data)
    assert errno_of(ioctl, fd, I2C_SMBUS, request) == errno.EREMOTEIO
    assert data.byte == 0xAB


def test_address_checks(node):
    fd, ioctl, _, bus = node
    assert errno_of(ioctl, fd, I2C_SLAVE, 0x80) == errno.EINVAL
    bus.claimed.add(0x68)
    assert errno_of(ioctl, fd, I2C_SLAVE, 0x68) == errno.EBUSY
    assert errno_of(ioctl, fd, I2C_SLAVE_FORCE, 0x68) == 0
    ioctl(fd, I2C_TENBIT, 1)
    assert errno_of(ioctl, fd, I2C_SLAVE, 0x3FF) == 0
    assert errno_of(ioctl, fd, I2C_SLAVE, 0x400) == errno.EINVAL
    # the emulated adapter has no 10-bit addressing: nothing answers there
    data = i2c_smbus_data()
    request = smbus_request(I2C_SMBUS_READ, 0, I2C_SMBUS_BYTE_DATA, data)
    assert errno_of(ioctl, fd, I2C_SMBUS, request) == errno.ENXIO


def test_scalar_requests(node):
    fd, ioctl, _, bus = node
    funcs = ctypes.c_uint64()
    assert ioctl(fd, I2C_FUNCS, funcs) == 0 and funcs.value == bus.funcs
    assert ioctl(fd, I2C_PEC, 1) == 0
    assert ioctl(fd, I2C_RETRIES, 3) == 0 and ioctl(fd, I2C_RETRIES, 0x7FFFFFFF) == 0
    # the timeout is in units of 10 ms: INT_MAX / 10 at most (drivers/i2c/i2c-dev.c, 6.1)
    assert ioctl(fd, I2C_TIMEOUT, 0x7FFFFFFF // 10) == 0
    assert errno_of(ioctl, fd, I2C_TIMEOUT, 0x7FFFFFFF // 10 + 1) == errno.EINVAL
    assert errno_of(ioctl, fd, I2C_RETRIES, -1) == errno.EINVAL  # above INT_MAX unsigned
    assert errno_of(ioctl, fd, 0x0799, 0) == errno.ENOTTY
    with pytest.raises(OverflowError):  # fcntl passes an integer argument as a C int
        ioctl(fd, I2C_SLAVE, 2**31)


def rdwr_request(*messages):
    table = (i2c_msg * max(len(messages), 1))(*messages)
    return rdwr_keepalive(table, i2c_rdwr_ioctl_data(table, len(messages)))


def rdwr_keepalive(table, request):
    request._table = table  # keep the message table alive with the request
    return request


def test_rdwr_combined_transfer_returns_the_message_count(node):
    fd, ioctl, _, _ = node
    reg = (ctypes.c_uint8 * 1)(0x30)
    out = (ctypes.c_uint8 * 4)()
    request = rdwr_request(i2c_msg(0x68, 0, 1, reg), i2c_msg(0x68, I2C_M_RD, 4, out))
    assert ioctl(fd, I2C_RDWR, request) == 2
    assert list(out) == [0x30, 0x31, 0x32, 0x33]


@pytest.mark.parametrize(
    ("count", "flags", "length", "first", "expected"),
    [
        (43, I2C_M_RD, 1, 0, errno.EINVAL),  # I2C_RDWR_IOCTL_MAX_MSGS is 42
        (0, I2C_M_RD, 1, 0, errno.EINVAL),
        (1, I2C_M_RD, 8193, 0, errno.EINVAL),  # messages are capped at 8192 bytes
        (1, I2C_M_RECV_LEN, 40, 1, errno.EINVAL),  # a receive-length message must be a read
        # its first byte counts the bytes after the length byte: at least 1, and the buffer
        # holds that many plus 32 (i2cdev_ioctl_rdwr, 6.1)
        (1, I2C_M_RD | I2C_M_RECV_LEN, 40, 0, errno.EINVAL),
        (1, I2C_M_RD | I2C_M_RECV_LEN, 40, 9, errno.EINVAL),
        (1, I2C_M_RD | I2C_M_RECV_LEN, 40, 1, errno.EOPNOTSUPP),  # well formed: adapter lacks it
        (1, I2C_M_RD | I2C_M_TEN, 1, 0, errno.ENXIO),
    ],
)
def test_rdwr_argument_checks(node, count, flags, length, first, expected):
    fd, ioctl, _, bus = node
    buffer = (ctypes.c_uint8 * 8200)(first)
    table = (i2c_msg * 43)(*[i2c_msg(0x68, flags, length, buffer) for _ in range(43)])
    request = rdwr_keepalive(table, i2c_rdwr_ioctl_data(table, count))
    assert errno_of(ioctl, fd, I2C_RDWR, request) == expected
    assert len(bus.log) == 0  # refused before any message reached the bus


def test_rdwr_null_buffer_faults(node):
    fd, ioctl, _, _ = node
    request = rdwr_request(i2c_msg(0x68, I2C_M_RD, 2, None))
    assert errno_of(ioctl, fd, I2C_RDWR, request) == errno.EFAULT


def test_immutable_buffer_argument_returns_the_result_as_bytes(node):
    """fcntl.ioctl works on a copy of a bytes argument and returns the copy."""
    fd, ioctl, _, bus = node
    out = ioctl(fd, I2C_FUNCS, bytes(8))
    assert int.from_bytes(out, "little") == bus.funcs


def test_read_and_write_are_plain_i2c_capped_at_8192_bytes():
    from bmg160_emu.bus.i2c_dev import I2CDevFile

    chip = RegisterFileChip()
    file = I2CDevFile(I2CBus(1, {0x68: chip}))
    file.set_address(0x68)
    assert file.write(bytes([0x10]) + bytes(9000)) == 8192  # i2c-dev truncates the write
    assert chip.writes[-1] == (0x10, bytes(8191))
    assert len(file.read(10_000)) == 8192


def test_adapter_without_plain_i2c_refuses_read_write_and_rdwr():
    from bmg160_emu.bus.i2c import DEFAULT_FUNCS
    from bmg160_emu.bus.i2c_dev import I2CDevFile
    from bmg160_emu.traffic.kinds import I2C_FUNC_I2C

    bus = I2CBus(1, {0x68: RegisterFileChip()}, funcs=DEFAULT_FUNCS & ~I2C_FUNC_I2C)
    file = I2CDevFile(bus)
    file.set_address(0x68)
    assert errno_of(file.read, 1) == errno.EOPNOTSUPP
    assert errno_of(file.write, b"\x00") == errno.EOPNOTSUPP
    with patch_smbus({1: bus}), smbus2.SMBus(1) as handle:
        out = (ctypes.c_uint8 * 1)()
        request = rdwr_request(i2c_msg(0x68, I2C_M_RD, 1, out))
        assert errno_of(smbus2_impl.ioctl, handle.fd, I2C_RDWR, request) == errno.EOPNOTSUPP
    assert len(bus.log) == 0
