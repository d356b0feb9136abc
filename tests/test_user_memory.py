"""The in-process /dev/i2c-N reads a caller's memory directly only where it is the caller's.

bmg160_emu.bus.user_memory reads the ctypes objects an ioctl argument keeps alive directly
(no system call) and every other address through the kernel's own checked copy. A ctypes
object kept alive is not always memory of its own: ``from_address`` views anybody's address,
``pointer.contents`` and ``pointer[i]`` view where the pointer points. Given a message buffer
or SMBus data union of that kind at an unmapped address, the kernel answers EFAULT; a direct
read there would crash the process. Each bad case runs in a forked child, so that a crash is
reported as this test's failure (with its signal) instead of ending the test run, and after
good calls of the same argument type: what was learnt about an argument's layout
(``_SHAPES``) must not carry trust from one call to the next.
"""

from __future__ import annotations

import array
import ast
import ctypes
import errno
import fcntl
import os
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.kernel_abi import (
    I2C_M_RD,
    I2C_RDWR,
    I2C_SLAVE,
    I2C_SMBUS,
    I2C_SMBUS_I2C_BLOCK_DATA,
    I2C_SMBUS_READ,
    i2c_msg,
    i2c_rdwr_ioctl_data,
    i2c_smbus_data,
    i2c_smbus_ioctl_data,
)
from bmg160_emu.bus.patching import patch_i2c_dev
from bmg160_emu.bus.user_memory import owned_range

GUEST_FILES = Path(__file__).resolve().parent / "kernel_guest"

UNMAPPED = 0x10  # below vm.mmap_min_addr: never mapped, the parity suite's bad pointer
REGISTERS = bytes(range(0x40))  # RegisterFileChip's content: register r holds r
Buffer = ctypes.c_uint8 * 6


def unmapped_buffer() -> Any:
    return Buffer.from_address(UNMAPPED)


def contents_at_unmapped() -> Any:
    return ctypes.cast(UNMAPPED, ctypes.POINTER(Buffer)).contents


class Framed(ctypes.Structure):
    _fields_ = [("header", ctypes.c_uint8 * 2), ("payload", Buffer)]


def field_of_element_at_unmapped() -> Any:
    return ctypes.cast(UNMAPPED, ctypes.POINTER(Framed))[0].payload  # base chain: the pointer


BAD_BUFFERS: dict[str, Callable[[], Any]] = {
    "from_address": unmapped_buffer,
    "pointer contents": contents_at_unmapped,
    "field of a pointer's element": field_of_element_at_unmapped,
}


def rdwr_read(fd: int, buffer: Any) -> int:
    """I2C_RDWR: write the register 0x02, read 6 bytes into ``buffer`` (kept alive by the
    request through its message table, as the libraries build it)."""
    register = (ctypes.c_uint8 * 1)(0x02)
    table = (i2c_msg * 2)(i2c_msg(0x68, 0, 1, register), i2c_msg(0x68, I2C_M_RD, 6, None))
    table[1].buf = buffer  # the array is kept in the table's _objects
    return fcntl.ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data(table, 2))


def smbus_read(fd: int, union: Any) -> bytes:
    """I2C_SMBUS: an I2C block read from 0x02 into ``union``, of the count its first byte
    holds (the kernel copies the union in first: a bad one faults there)."""
    request = i2c_smbus_ioctl_data(I2C_SMBUS_READ, 0x02, I2C_SMBUS_I2C_BLOCK_DATA,
                                   ctypes.pointer(union))
    fcntl.ioctl(fd, I2C_SMBUS, request)
    return bytes(union.block[1:7])


def errno_of(call: Callable[[], Any]) -> int | None:
    try:
        call()
    except OSError as exc:
        return exc.errno
    return None


def in_child(work: Callable[[], dict[str, Any]]) -> dict[str, Any]:
    """``work()`` in a forked child: its answers, or a failure naming the signal that
    ended it (a crash is a failure here, not the end of the test run)."""
    reader, writer = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: answer through the pipe, leave without pytest's handlers
        code = 0
        try:
            os.write(writer, repr(work()).encode())
        except BaseException as exc:  # noqa: BLE001 - any failure is reported to the parent
            os.write(writer, repr({"child raised": repr(exc)}).encode())
            code = 1
        finally:
            os._exit(code)
    os.close(writer)
    with os.fdopen(reader, "rb") as pipe:
        text = pipe.read().decode()
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        pytest.fail(f"the child crashed: {signal.Signals(os.WTERMSIG(status)).name}")
    answers: dict[str, Any] = ast.literal_eval(text)  # plain data: bytes, ints, None
    return answers


def with_node(work: Callable[[int], dict[str, Any]]) -> dict[str, Any]:
    with patch_i2c_dev({1: I2CBus(1, {0x68: RegisterFileChip(REGISTERS)})}):
        fd = os.open("/dev/i2c-1", os.O_RDWR)
        try:
            fcntl.ioctl(fd, I2C_SLAVE, 0x68)
            return work(fd)
        finally:
            os.close(fd)


def test_a_kept_alive_buffer_that_is_not_its_own_memory_is_efault():
    def work(fd: int) -> dict[str, Any]:
        answers: dict[str, Any] = {}
        for name, make in BAD_BUFFERS.items():
            good = Buffer()
            rdwr_read(fd, good)  # the same argument type, well formed, first
            answers[f"good before {name}"] = bytes(good)
            answers[name] = errno_of(lambda make=make: rdwr_read(fd, make()))
        union_type = i2c_smbus_data
        six = union_type()
        six.block[0] = 6
        smbus_read(fd, six)
        answers["smbus union from_address"] = errno_of(
            lambda: smbus_read(fd, union_type.from_address(UNMAPPED)))
        answers["smbus union as pointer contents"] = errno_of(
            lambda: smbus_read(fd, ctypes.cast(UNMAPPED, ctypes.POINTER(union_type)).contents))
        answers["good after"] = smbus_read(fd, six)
        return answers

    answers = in_child(lambda: with_node(work))
    expected_data = REGISTERS[2:8]
    assert answers == {
        **{f"good before {name}": expected_data for name in BAD_BUFFERS},
        **dict.fromkeys(BAD_BUFFERS, errno.EFAULT),
        "smbus union from_address": errno.EFAULT,
        "smbus union as pointer contents": errno.EFAULT,
        "good after": expected_data,
    }


def test_a_read_into_a_read_only_view_faults_after_the_transfer():
    # copy_to_user into a read-only page: EFAULT (the kernel's), never a crash of ours
    sys.path.insert(0, str(GUEST_FILES))
    try:
        from guest_i2c_dev_parity import read_only_page  # the parity suite's own page
    finally:
        sys.path.remove(str(GUEST_FILES))

    def work(fd: int) -> dict[str, Any]:
        page = read_only_page()
        return {"rdwr": errno_of(lambda: rdwr_read(fd, Buffer.from_address(page))),
                "unchanged": bytes(Buffer.from_address(page))}

    assert in_child(lambda: with_node(work)) == {"rdwr": errno.EFAULT, "unchanged": bytes(6)}


def test_memory_that_is_the_caller_s_is_read_and_written_whatever_object_holds_it():
    # each of these is the caller's mapped memory: the kernel copies into it, so must we
    # (directly where the object's memory is its own, through the checked copy otherwise)
    expected = REGISTERS[2:8]
    backing = bytearray(8)
    framed = Framed()
    owner = Buffer()
    stale_owner = Framed()
    stale = stale_owner.payload
    ctypes.resize(stale_owner, 4096)  # the field now views the old, still mapped, memory

    def work(fd: int) -> dict[str, Any]:
        answers = {}
        for name, buffer, view in (
                ("from_buffer", Buffer.from_buffer(backing, 2), lambda: bytes(backing[2:])),
                ("a structure's field", framed.payload, lambda: bytes(framed.payload)),
                ("from_address of owned memory", Buffer.from_address(ctypes.addressof(owner)),
                 lambda: bytes(owner)),
                ("pointer contents of owned memory", ctypes.pointer(owner).contents,
                 lambda: bytes(owner)),
                ("a field left by resize", stale, lambda: bytes(stale))):
            assert rdwr_read(fd, buffer) == 2
            answers[name] = view()
        return answers

    answers = with_node(work)
    assert answers == dict.fromkeys(answers, expected) and len(answers) == 5


def test_owned_range_is_the_memory_an_object_keeps_alive_itself():
    owner = Framed()
    start = ctypes.addressof(owner)
    assert owned_range(owner) == (start, start + ctypes.sizeof(owner), owner)
    field = owner.payload
    assert owned_range(field)[:2] == (start + 2, start + 8)  # inside its root
    backing = bytearray(6)
    assert owned_range(Buffer.from_buffer(backing)) is not None
    assert owned_range(Buffer.from_address(start)) is None  # anybody's address
    assert owned_range(ctypes.pointer(owner).contents) is None  # where a pointer points
    assert owned_range(ctypes.cast(ctypes.pointer(owner), ctypes.POINTER(Buffer))[0]) is None


def test_a_request_in_a_plain_buffer_is_followed_with_checks_only():
    # a bytearray or array.array argument keeps nothing alive: every pointer in it is
    # copied with the kernel's checks (the table and buffers are the caller's: they work;
    # a buffer at 0x10 is EFAULT)
    def work(fd: int) -> dict[str, Any]:
        register = (ctypes.c_uint8 * 1)(0x02)
        out = Buffer()
        table = (i2c_msg * 2)(i2c_msg(0x68, 0, 1, register), i2c_msg(0x68, I2C_M_RD, 6, out))
        raw = bytes(i2c_rdwr_ioctl_data(table, 2))
        answers: dict[str, Any] = {}
        for name, argument in (("bytearray", bytearray(raw)), ("array", array.array("B", raw))):
            out[:] = bytes(6)
            answers[name] = (fcntl.ioctl(fd, I2C_RDWR, argument), bytes(out))
        table[1].buf = ctypes.cast(UNMAPPED, ctypes.POINTER(ctypes.c_uint8))
        answers["buffer at 0x10"] = errno_of(
            lambda: fcntl.ioctl(fd, I2C_RDWR, bytearray(bytes(i2c_rdwr_ioctl_data(table, 2)))))
        return answers

    assert in_child(lambda: with_node(work)) == {
        "bytearray": (2, REGISTERS[2:8]), "array": (2, REGISTERS[2:8]),
        "buffer at 0x10": errno.EFAULT}
