"""The stand-in i2c-stub adapter against a Python copy of i2c-stub's memory model.

No kernel needed: `StubMemory` (tests/test_kernel_stub_adapter_logic.py) answers the smbus2
calls the way drivers/i2c/i2c-stub.c does. tests/test_kernel_parts.py binds the kernel's
bmc150-accel driver to the same adapter in a QEMU guest.
"""

from __future__ import annotations

from test_kernel_stub_adapter_logic import StubMemory

from bmg160_emu.device.standin import StandinDevice
from bmg160_emu.io.standin_file import load_standin
from bmg160_emu.linux.i2c_stub_standin import StandinStubAdapter


def _rig(name: str, address: int):
    device = StandinDevice(load_standin(name), address)
    stub = StubMemory(address)
    adapter = StandinStubAdapter(device, bus=0, address=address, smbus=stub)
    adapter.preload()
    return device, stub, adapter


def test_preload_puts_the_whole_map_in_place_with_word_slots():
    device, stub, _ = _rig("bma2x2_accel", 0x18)
    image = device.dump()
    assert stub.client_block(0x00, 32) == image[:32] and image[0] == 0xFA
    assert all(stub.words[r] == image[r] | image[r + 1] << 8 for r in range(255))


def test_a_write_to_read_only_bits_is_undone_and_a_writable_one_kept():
    device, stub, adapter = _rig("bma2x2_accel", 0x18)
    stub.client_write(0x00, 0x12)          # BGW_CHIPID is read-only
    stub.client_write(0x0F, 0xF5)          # PMU_RANGE: only bits 3..0 are writable
    adapter.refresh()
    assert stub.client_block(0x00, 1) == b"\xfa"
    assert stub.client_block(0x0F, 1) == bytes([device.peek(0x0F)]) == bytes([0xF5 & 0x0F])
    assert stub.words[0x0E] >> 8 == device.peek(0x0F)  # the slot below's high byte follows


def test_soft_reset_through_the_stub_restores_reset_values():
    _, stub, adapter = _rig("bma2x2_accel", 0x18)
    stub.client_write(0x0F, 0x05)
    adapter.refresh()
    stub.client_write(0x14, 0xB6)          # BGW_SOFTRESET
    adapter.refresh()
    assert stub.client_block(0x0F, 1) == b"\x03" and stub.client_block(0x14, 1) == b"\x00"


def test_bmm150_chip_id_appears_only_after_its_power_bit():
    _, stub, adapter = _rig("bmm150", 0x10)
    assert stub.client_block(0x40, 1) == b"\x00"   # suspended: reads 0
    stub.client_write(0x4B, 0x01)
    adapter.refresh()
    assert stub.client_block(0x40, 1) == b"\x32"
    assert adapter.events and adapter.events[-1]["writes"] == {"0x4b": "0x01"}


def test_a_poll_without_client_writes_writes_nothing():
    _, stub, adapter = _rig("bmi088_accel", 0x18)
    stub.operations.clear()
    adapter.refresh()
    assert set(stub.operations) == {"read_i2c_block_data"} and len(stub.operations) == 8


def test_a_reset_and_a_configuration_seen_in_one_poll_keep_the_configuration():
    # a driver writes BGW_SOFTRESET, then PMU_RANGE; a poll that sees both must not let the
    # reset undo the range (in register order 0x0F would come before 0x14)
    device, stub, adapter = _rig("bma2x2_accel", 0x18)
    stub.client_write(0x14, 0xB6)
    stub.client_write(0x0F, 0x05)
    adapter.refresh()
    assert device.peek(0x0F) == 0x05 and stub.client_block(0x0F, 1) == b"\x05"
