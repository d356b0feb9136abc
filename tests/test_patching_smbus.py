"""patch_smbus: unmodified code that builds smbus2.SMBus / smbus.SMBus reaches the chip."""

from __future__ import annotations

import builtins
import fcntl
import importlib
import io
import os
import sys

import pytest
import smbus2
import smbus2.smbus2 as smbus2_impl
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.bus.smbus import FakeSMBus

# A "driver module" that imported the class by name before any patch existed.
DRIVER_SOURCE = """
from smbus2 import SMBus

def chip_id(bus_number):
    with SMBus(bus_number) as bus:
        return bus.read_byte_data(0x68, 0x00)
"""


@pytest.fixture
def driver_module(tmp_path, monkeypatch):
    (tmp_path / "fake_driver_for_test.py").write_text(DRIVER_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    module = importlib.import_module("fake_driver_for_test")  # imported before any patch
    yield module
    sys.modules.pop("fake_driver_for_test", None)


def test_module_that_did_from_smbus2_import_smbus_reaches_the_chip(driver_module):
    chip = RegisterFileChip(bytes([0x0F]) + bytes(63))
    with patch_smbus({1: {0x68: chip}}) as buses:
        assert driver_module.chip_id(1) == 0x0F
    assert buses[1].log.kinds() == ["read_byte_data"]


def test_smbus2_class_is_untouched_so_subclasses_and_isinstance_work():
    class MyBus(smbus2.SMBus):
        def chip_id(self):
            return self.read_byte_data(0x68, 0)

    chip = RegisterFileChip(bytes([0x0F]) + bytes(63))
    with patch_smbus({2: {0x68: chip}}):
        bus = MyBus(2)
        assert isinstance(bus, smbus2.SMBus)
        assert bus.chip_id() == 0x0F
        bus.close()


def test_device_path_string_opens_the_emulated_bus():
    chip = RegisterFileChip()
    with patch_smbus({1: {0x68: chip}}), smbus2.SMBus("/dev/i2c-1") as bus:
        assert bus.read_byte_data(0x68, 5) == 5


def test_bus_numbers_not_in_the_patch_still_reach_the_real_kernel():
    if os.path.exists("/dev/i2c-9"):
        pytest.skip("this machine has a real /dev/i2c-9")
    with patch_smbus({1: {0x68: RegisterFileChip()}}), pytest.raises(FileNotFoundError):
        smbus2.SMBus(9)


def test_missing_device_gives_oserror_121_through_real_smbus2():
    with patch_smbus({1: {0x68: RegisterFileChip()}}), smbus2.SMBus(1) as bus:
        with pytest.raises(OSError) as info:
            bus.read_byte_data(0x69, 0)
        assert info.value.errno == 121


REAL_CALLS = (os.open, os.close, os.read, os.write, fcntl.ioctl, builtins.open, io.open)


def _calls_now():
    return (os.open, os.close, os.read, os.write, fcntl.ioctl, builtins.open, io.open)


def test_everything_is_restored_on_exit():
    with patch_smbus({1: {0x68: RegisterFileChip()}}):
        assert all(now is not real for now, real in zip(_calls_now(), REAL_CALLS))
        assert smbus2_impl.ioctl is fcntl.ioctl  # its `from fcntl import ioctl` follows
    assert _calls_now() == REAL_CALLS
    assert smbus2_impl.ioctl is REAL_CALLS[4]
    with pytest.raises(FileNotFoundError):
        FakeSMBus(1)


def test_nested_patches_stack_and_unwind():
    outer, inner = RegisterFileChip(), RegisterFileChip()
    inner.regs[0] = 0xAA
    with patch_smbus({1: {0x68: outer}}):
        with patch_smbus({1: {0x68: inner}}), smbus2.SMBus(1) as bus:
            assert bus.read_byte_data(0x68, 0) == 0xAA
        with smbus2.SMBus(1) as bus:
            assert bus.read_byte_data(0x68, 0) == 0x00
        assert os.open is not REAL_CALLS[0]  # the inner exit leaves the outer patch on
    assert _calls_now() == REAL_CALLS


def test_works_as_a_decorator():
    chip = RegisterFileChip()

    @patch_smbus({4: {0x69: chip}})
    def read():
        with smbus2.SMBus(4) as bus:
            return bus.read_word_data(0x69, 2)

    assert read() == 0x0302


def test_an_i2cbus_can_be_given_and_keeps_its_hooks():
    bus = I2CBus(1, {0x68: RegisterFileChip()})
    calls = []
    bus.transaction_hooks.append(lambda b, i, a, k: calls.append(k))
    with patch_smbus({1: bus}), smbus2.SMBus(1) as handle:
        handle.write_byte_data(0x68, 0x20, 1)
    assert calls == ["write_byte_data"]


def test_legacy_smbus_module_is_injected_and_removed():
    had_smbus = "smbus" in sys.modules
    chip = RegisterFileChip()
    with patch_smbus({1: {0x68: chip}}):
        import smbus

        bus = smbus.SMBus(1)
        assert bus.read_byte_data(0x68, 3) == 3
        assert len(bus.read_i2c_block_data(0x68, 0)) == 32  # python-smbus default length
        bus.close()
    if not had_smbus:
        assert "smbus" not in sys.modules


def test_i2c_rdwr_through_real_smbus2():
    with patch_smbus({1: {0x68: RegisterFileChip()}}), smbus2.SMBus(1) as bus:
        write, read = smbus2.i2c_msg.write(0x68, [0x10]), smbus2.i2c_msg.read(0x68, 3)
        bus.i2c_rdwr(write, read)
        assert list(read) == [0x10, 0x11, 0x12]


def test_bad_arguments_are_refused_clearly():
    with pytest.raises(TypeError):
        patch_smbus([1, 2])
    with pytest.raises(TypeError):
        patch_smbus({1: 42})


def test_a_bus_left_open_after_the_patch_no_longer_reaches_the_chip():
    chip = RegisterFileChip()
    with patch_smbus({1: {0x68: chip}}):
        bus = smbus2.SMBus(1)
    with pytest.raises(OSError):  # now a plain descriptor: the kernel knows no such ioctl
        bus.read_byte_data(0x68, 0)
    bus.close()
    assert chip.reads == []


def test_legacy_smbus_follows_python_smbus_rules():
    chip = RegisterFileChip()
    with patch_smbus({1: {0x68: chip}}):
        import smbus

        bus = smbus.SMBus()
        bus.open(1)
        assert bus.read_i2c_block_data(0x68, 0x02, 3) == [2, 3, 4]
        with pytest.raises(OSError) as info:
            bus.read_i2c_block_data(0x68, 0x02, 33)  # the kernel refuses it (EINVAL)
        assert info.value.errno == 22
        with pytest.raises(TypeError, match="must be a list"):
            bus.write_i2c_block_data(0x68, 0x20, (1, 2))
        with pytest.raises(OverflowError):
            bus.write_block_data(0x68, 0x20, [0] * 33)
        bus.write_i2c_block_data(0x68, 0x20, [0x1AA])
        assert chip.regs[0x20] == 0xAA
        bus.pec = 1
        assert bus.pec is True
        bus.close()


@pytest.mark.parametrize("address", [b"h", "h", bytearray(b"h"), 1.5, None])
def test_an_address_of_the_wrong_type_fails_as_it_does_over_the_kernel(address):
    # smbus2 hands the address to fcntl.ioctl: a buffer (bytes, bytearray, str) is passed as
    # a pointer, which i2c-dev refuses with EINVAL; anything else is fcntl's TypeError
    from bmg160_emu.device.chip import BMG160

    def outcome(bus):
        try:
            bus.read_byte_data(address, 0)
        except OSError as exc:
            return ("OSError", exc.errno)
        except TypeError as exc:
            return ("TypeError", str(exc))
        return ("no error", None)

    with patch_smbus({1: {0x68: BMG160(seed=1)}}):
        real = outcome(smbus2.SMBus(1))
    fake = outcome(FakeSMBus(1, devices={0x68: BMG160(seed=1)}))
    assert fake == real
    assert real[0] == ("OSError" if isinstance(address, (bytes, bytearray, str)) else "TypeError")
