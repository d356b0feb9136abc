"""The i2c-stub adapter's bookkeeping, against a Python copy of i2c-stub's memory model.

No kernel needed (so no `kernel` marker): `StubMemory` answers the smbus2 calls the adapter
makes the way drivers/i2c/i2c-stub.c does: 256 slots of 16 bits per chip, byte and I2C
block transactions on the low bytes of consecutive slots, word transactions on whole slots.
The real kernel is exercised by tests/test_kernel_i2c_stub.py.
"""

from __future__ import annotations

import pytest

from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.i2c_stub import I2CStubAdapter


class StubMemory:
    """One i2c-stub chip: what a client (the kernel driver) and the adapter both reach."""

    def __init__(self, address: int = 0x68) -> None:
        self.address = address
        self.words = [0] * 256
        self.operations: list[str] = []
        self.after_each: list = []  # callables run after every adapter operation

    def _done(self, name: str) -> None:
        self.operations.append(name)
        for hook in list(self.after_each):
            hook(self)

    # the smbus2 methods the adapter uses
    def write_byte_data(self, address: int, register: int, value: int) -> None:
        self.words[register] = (self.words[register] & 0xFF00) | value
        self._done("write_byte_data")

    def read_byte_data(self, address: int, register: int) -> int:
        value = self.words[register] & 0xFF
        self._done("read_byte_data")
        return value

    def write_word_data(self, address: int, register: int, value: int) -> None:
        self.words[register] = value & 0xFFFF
        self._done("write_word_data")

    def write_i2c_block_data(self, address: int, register: int, data: list[int]) -> None:
        for i, value in enumerate(data[: 256 - register]):
            self.words[register + i] = (self.words[register + i] & 0xFF00) | value
        self._done("write_i2c_block_data")

    def read_i2c_block_data(self, address: int, register: int, length: int) -> list[int]:
        values = [self.words[register + i] & 0xFF for i in range(length)]
        self._done("read_i2c_block_data")
        return values

    # what a client does, without counting as an adapter operation
    def client_write(self, register: int, value: int) -> None:
        self.words[register] = (self.words[register] & 0xFF00) | value

    def client_block(self, register: int, length: int) -> bytes:
        return bytes(self.words[register + i] & 0xFF for i in range(length))


@pytest.fixture
def rig():
    chip = BMG160(seed=5, true_rate=(20.0, -10.0, 5.0))
    stub = StubMemory()
    adapter = I2CStubAdapter(chip, bus=0, address=0x68, smbus=stub)
    adapter.preload()
    return chip, stub, adapter


def test_preload_puts_the_reset_map_in_place(rig):
    chip, stub, _ = rig
    assert stub.client_block(0x00, 0x40) == chip.dump()
    assert stub.client_block(0x00, 1) == b"\x0f"


def test_word_byte_and_block_reads_of_a_slot_agree(rig):
    chip, stub, adapter = rig
    chip.advance(0.01)
    adapter.refresh()
    image = chip.dump()
    for register in range(0x0F):
        assert stub.words[register] == image[register] | image[register + 1] << 8
    assert stub.client_block(0x02, 6) == image[0x02:0x08]


def test_refresh_follows_new_samples(rig):
    chip, stub, adapter = rig
    seen = set()
    for _ in range(5):
        chip.advance(0.01)
        adapter.refresh()
        assert stub.client_block(0x02, 6) == chip.dump()[0x02:0x08]
        seen.add(stub.client_block(0x02, 6))
    assert len(seen) >= 4


def test_block_readers_never_see_half_of_two_samples(rig):
    chip, stub, adapter = rig
    chip.advance(0.01)
    adapter.refresh()
    old = stub.client_block(0x02, 6)
    chip.advance(0.01)
    new = chip.dump()[0x02:0x08]
    assert new != old
    seen = []
    stub.after_each.append(lambda s: seen.append(s.client_block(0x02, 6)))
    adapter.refresh()
    assert set(seen) <= {old, new}, seen
    assert seen[-1] == new


def test_client_write_reaches_the_model_and_read_only_bits_are_written_back(rig):
    chip, stub, adapter = rig
    stub.client_write(0x0F, 0x02)  # RANGE 500 deg/s
    stub.client_write(0x10, 0x07)  # BW: ODR 100 Hz
    adapter.refresh()
    assert chip.peek(0x0F) == 0x02
    assert chip.odr_hz == 100
    assert stub.client_block(0x0F, 2) == bytes([0x02, chip.peek(0x10)])
    assert chip.peek(0x10) == 0x87  # bit 7 reads 1 (spec 4.9)
    assert [(e["register"], e["value"]) for e in adapter.events] == [(0x0F, 0x02), (0x10, 0x07)]
    adapter.refresh()  # nothing new: no second application
    assert len(adapter.events) == 2


def test_word_reads_of_configuration_slots_follow_client_writes(rig):
    """A word read of RANGE (slot 0x0F) is RANGE | BW << 8 on the chip (a 2-byte burst);
    after the client changed BW the slot's high byte must be the model's BW, not the
    preloaded one."""
    chip, stub, adapter = rig
    stub.client_write(0x10, 0x07)  # BW: ODR 100 Hz
    stub.client_write(0x11, 0x80)  # LPM1: suspend
    adapter.refresh()
    image = chip.dump()
    for register in (0x0F, 0x10):
        assert stub.words[register] == image[register] | image[register + 1] << 8
    assert stub.words[0x0F] >> 8 == 0x87


def test_soft_reset_is_applied_first_and_cleared(rig):
    chip, stub, adapter = rig
    stub.client_write(0x0F, 0x02)
    adapter.refresh()
    # within one period: soft reset, then the driver's new configuration
    stub.client_write(0x14, 0xB6)
    stub.client_write(0x0F, 0x03)
    adapter.refresh()
    assert adapter.stats.resets == 1
    assert chip.peek(0x0F) == 0x03  # written after the reset, so kept
    assert stub.client_block(0x14, 1) == b"\x00"  # the command does not stay in memory
    assert stub.client_block(0x00, 0x40)[0x0F:0x3F] == chip.dump()[0x0F:0x3F]


def test_client_write_during_write_back_is_not_overwritten(rig):
    chip, stub, adapter = rig
    stub.client_write(0x10, 0x07)  # needs a write-back (0x87)

    def client_writes_again(s):
        # after the adapter polled the configuration (two block reads) and before its
        # write-back, the driver writes BW again
        if s.operations.count("read_i2c_block_data") == 2:
            s.client_write(0x10, 0x03)
            s.after_each.remove(client_writes_again)

    stub.operations.clear()
    stub.after_each.append(client_writes_again)
    adapter.refresh()
    assert stub.client_block(0x10, 1) == b"\x03"  # the client's newest value survived
    adapter.refresh()
    assert chip.odr_hz == 400  # ... and reached the model one period later
    assert stub.client_block(0x10, 1) == b"\x83"


def test_power_mode_writes_reach_the_model(rig):
    chip, stub, adapter = rig
    stub.client_write(0x11, 0x80)
    adapter.refresh()
    assert chip.power_mode == "suspend"
    stub.client_write(0x11, 0x00)
    adapter.refresh()
    assert chip.power_mode == "normal"


def test_refresh_period_follows_odr_with_a_cap(rig):
    _, stub, adapter = rig
    assert adapter.refresh_period_s() == pytest.approx(1 / 500)  # reset ODR 2000 Hz, capped
    stub.client_write(0x10, 0x04)  # ODR 200 Hz
    adapter.refresh()
    assert adapter.refresh_period_s() == pytest.approx(1 / 200)


def test_stub_stats_to_an_unwritable_path_is_refused_before_the_adapter_runs(
    tmp_path, monkeypatch, capsys
):
    """`bmg160-emu stub --stats` writes at exit, possibly hours later: a bad path is a
    one-line error at start, before the bus is opened (the bus checks are stubbed here)."""
    from bmg160_emu.cli import main
    from bmg160_emu.linux import i2c_stub as i2c_stub_adapter

    monkeypatch.setattr(i2c_stub_adapter, "check_stub_bus", lambda bus, address: tmp_path)

    def no_adapter(*args, **kwargs):
        raise AssertionError("the adapter must not start")

    monkeypatch.setattr(i2c_stub_adapter, "I2CStubAdapter", no_adapter)
    stats = tmp_path / "no" / "such" / "stats.json"
    assert main(["stub", "--bus", "0", "--stats", str(stats)]) == 2
    assert f"cannot write {stats}" in capsys.readouterr().err


def test_probe_writes_survive_a_runtime_suspend_in_the_same_period(rig):
    # Seen on the real kernel in 5 of 7 boots: the driver's probe writes INT_EN_1 and
    # INT_RST_LATCH, then runtime PM suspends the chip (LPM1 = 0x80) before the adapter's
    # next refresh. Applied in address order, the suspended model ignored 0x16 and 0x21 and
    # the adapter wrote its stale values back over the driver's.
    chip, stub, adapter = rig
    stub.client_write(0x16, 0x0D)
    stub.client_write(0x21, 0x8F)
    stub.client_write(0x11, 0x80)
    adapter.refresh()
    assert chip.power_mode == "suspend"
    assert chip.peek(0x16) == 0x0D
    assert chip.peek(0x21) & 0x0F == 0x0F  # latch mode kept; bit 7 (reset_int) self-clears
    assert stub.client_block(0x16, 1) == b"\x0d"  # the driver's value, not written back over
    assert stub.client_block(0x11, 1) == b"\x80"


def test_writes_after_a_wake_up_in_the_same_period_reach_the_model(rig):
    chip, stub, adapter = rig
    stub.client_write(0x11, 0x80)
    adapter.refresh()
    assert chip.power_mode == "suspend"
    # the driver resumes (LPM1 = 0x00) and then changes the range, within one period
    stub.client_write(0x11, 0x00)
    stub.client_write(0x0F, 0x01)
    adapter.refresh()
    assert chip.power_mode == "normal"
    assert chip.peek(0x0F) & 0x07 == 1
    assert stub.client_block(0x0F, 1) == b"\x01"


def test_a_restarted_adapter_adopts_the_bound_drivers_configuration(rig):
    # Restarting `bmg160-emu stub` while the driver stays bound used to preload reset values
    # over the driver's configuration: it kept its +-500 scale while the model went back to
    # +-2000, and a true 30 deg/s read as 7.6 deg/s.
    _, stub, adapter = rig
    stub.client_write(0x0F, 0x02)  # the driver: +-500 deg/s
    stub.client_write(0x10, 0x07)  # ODR 100 Hz
    stub.client_write(0x16, 0x0D)
    adapter.refresh()
    restarted = BMG160(seed=6, true_rate=(30.0, 0.0, 0.0))
    second = I2CStubAdapter(restarted, bus=0, address=0x68, smbus=stub)
    adopted = second.adopt()
    second.preload()
    assert set(adopted) == {0x0F, 0x10, 0x16}
    assert restarted.peek(0x0F) & 0x07 == 2 and restarted.odr_hz == 100
    assert restarted.peek(0x16) == 0x0D
    restarted.advance(0.1)
    second.refresh()
    raw = int.from_bytes(stub.client_block(0x02, 2), "little", signed=True)
    assert abs(raw * 500 / 32768 - 30.0) < 3.0  # the driver's scale reads the true rate


def test_bound_driver_reads_the_sysfs_link(tmp_path):
    from bmg160_emu.linux.i2c_stub import bound_driver

    device = tmp_path / "bus" / "i2c" / "devices" / "0-0068"
    device.mkdir(parents=True)
    assert bound_driver(0, 0x68, sysfs=tmp_path) is None
    (tmp_path / "bmg160_i2c").mkdir()
    (device / "driver").symlink_to(tmp_path / "bmg160_i2c")
    assert bound_driver(0, 0x68, sysfs=tmp_path) == "bmg160_i2c"
