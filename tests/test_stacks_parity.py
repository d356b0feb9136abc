"""Argument errors are the same through the emulator as through the real OS, per stack.

Each stack's call sequence runs twice: against the real OS, where /dev/i2c-N does not exist
(nothing patched), and against the emulator (patch_i2c_dev with bus N emulated). Every
step is an argument error or the open of a node missing in both worlds, so each must give
the same exception type and errno in both: the library's own checks, and the conversions
CPython's ``os``, ``fcntl`` and ``io`` make before the system call, which the emulated node
must make the same way (the smbus2 parity of tests/test_fake_smbus_api.py, for every stack).
The descriptor-level sequence compares an emulated descriptor with a closed one: CPython
converts the arguments before the system call, so the closed descriptor's EBADF never
hides a conversion error.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Callable

import pytest
from _stack_drivers import blinka_environment

from bmg160_emu.bus.i2c_dev_node import patch_i2c_dev
from bmg160_emu.device.chip import BMG160

N = 96  # the bus under test: missing on this machine, emulated in the second world
MISSING = 95  # missing in both worlds
I2C_SLAVE, I2C_SMBUS = 0x0703, 0x0720

Step = tuple[str, Callable[[], object]]


def outcome(call: Callable[[], object]) -> tuple[str, int | None]:
    try:
        call()
    except Exception as exc:  # noqa: BLE001 - the type is what is compared
        return type(exc).__name__, getattr(exc, "errno", None)
    return "no error", None


def both_worlds(steps: Callable[[], list[Step]]) -> tuple[list, list]:
    for path in (f"/dev/i2c-{N}", f"/dev/i2c-{MISSING}"):
        if os.path.exists(path):
            pytest.skip(f"this machine has a real {path}")
    real = [(name, outcome(call)) for name, call in steps()]
    with patch_i2c_dev({N: {0x68: BMG160(seed=1)}}):
        emulated = [(name, outcome(call)) for name, call in steps()]
    return real, emulated


def assert_parity(steps: Callable[[], list[Step]]) -> None:
    real, emulated = both_worlds(steps)
    assert emulated == real
    assert all(result[0] != "no error" for _, result in real)  # every step is an error


def smbus_steps(module) -> Callable[[], list[Step]]:
    """smbus2 and smbus3 share smbus2's layout and checks."""
    def steps() -> list[Step]:
        unopened = module.SMBus()
        return [
            ("missing node", lambda: module.SMBus(MISSING)),
            ("missing path", lambda: module.SMBus(f"/dev/i2c-{MISSING}")),
            ("bus of the wrong type", lambda: module.SMBus(1.5)),
            ("block read of 33", lambda: unopened.read_i2c_block_data(0x68, 0, 33)),
            ("block write of 33", lambda: unopened.write_i2c_block_data(0x68, 0, [0] * 33)),
            ("SMBus block write of 33", lambda: unopened.write_block_data(0x68, 0, [0] * 33)),
            ("ioctl on a closed bus", lambda: unopened.read_byte_data(0x68, 0)),
            ("i2c_rdwr of a non-message", lambda: unopened.i2c_rdwr(object())),
        ]
    return steps


def test_smbus2_argument_errors_match_the_real_os():
    import smbus2

    assert_parity(smbus_steps(smbus2))


def test_smbus3_argument_errors_match_the_real_os():
    import smbus3

    assert_parity(smbus_steps(smbus3))


def test_pureio_argument_errors_match_the_real_os():
    from Adafruit_PureIO.smbus import SMBus

    def steps() -> list[Step]:
        unopened = SMBus()
        return [
            ("missing node", lambda: SMBus(MISSING)),
            ("bus of the wrong type", lambda: SMBus(1.5)),  # opens "/dev/i2c-1.5"
            ("read on a closed bus", lambda: unopened.read_byte(0x68)),
            ("write on a closed bus", lambda: unopened.write_byte(0x68, 0)),
        ]

    assert_parity(steps)


def test_periphery_argument_errors_match_the_real_os():
    from periphery import I2C

    def steps() -> list[Step]:
        return [
            ("missing node", lambda: I2C(f"/dev/i2c-{MISSING}")),
            ("path of the wrong type", lambda: I2C(N)),
            ("message of the wrong type", lambda: I2C.Message("abc")),
            ("read flag of the wrong type", lambda: I2C.Message([1], read="yes")),
        ]

    assert_parity(steps)


def test_blinka_and_busdevice_argument_errors_match_the_real_os():
    with blinka_environment():
        import board
        import busio
        from adafruit_blinka.microcontroller.generic_linux.i2c import I2C as LinuxI2C

        def steps() -> list[Step]:
            return [
                ("missing bus", lambda: LinuxI2C(MISSING)),
                ("pins of no I2C port", lambda: busio.I2C(board.D4, board.D5)),
                ("not a master", lambda: LinuxI2C(N, mode=LinuxI2C.SLAVE)),
            ]

        assert_parity(steps)


def test_descriptor_calls_convert_their_arguments_as_cpython_does(tmp_path):
    """The calls every stack ends in, on an emulated descriptor and on a closed one."""
    closed = os.open(tmp_path / "gone", os.O_CREAT | os.O_RDWR)
    os.close(closed)

    def steps() -> list[Step]:
        node = f"/dev/i2c-{N}"
        try:
            fd = os.open(node, os.O_RDWR)
        except FileNotFoundError:
            fd = closed
        return [
            ("read of a negative count", lambda: os.read(fd, -1)),
            ("read of a str count", lambda: os.read(fd, "1")),
            ("read of a huge count", lambda: os.read(fd, 2**70)),
            ("write of a str", lambda: os.write(fd, "x")),
            ("ioctl request of the wrong type", lambda: fcntl.ioctl(fd, "r", 0)),
            ("ioctl float argument", lambda: fcntl.ioctl(fd, I2C_SLAVE, 1.5)),
            ("ioctl argument beyond a C int", lambda: fcntl.ioctl(fd, I2C_SLAVE, 2**40)),
            ("ioctl argument None", lambda: fcntl.ioctl(fd, I2C_SLAVE, None)),
            ("ioctl buffer over 1024 bytes", lambda: fcntl.ioctl(fd, I2C_SMBUS, b"x" * 2000)),
            ("ioctl on None", lambda: fcntl.ioctl(None, I2C_SLAVE, 0x68)),
            ("os.open flags of the wrong type", lambda: os.open(node, "x")),
            ("open mode rw", lambda: open(node, "rw")),  # noqa: PLW1501 - the error is the point
            ("binary open with an encoding", lambda: open(node, "rb", encoding="utf-8")),
            ("missing node", lambda: os.open(f"/dev/i2c-{MISSING}", os.O_RDWR)),
        ]

    assert_parity(steps)
