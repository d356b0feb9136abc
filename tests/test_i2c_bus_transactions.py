"""I2CBus: each SMBus / I2C transaction kind reaches the chip as the spec's mapping says (2.1),
with the errors a Linux adapter gives. Uses a plain register file, so only the bus is tested."""

from __future__ import annotations

import errno

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.i2c import DEFAULT_FUNCS, I2CBus, I2CMessage, smbus_pec
from bmg160_emu.traffic.kinds import I2C_FUNC_SMBUS_QUICK


@pytest.fixture
def chip() -> RegisterFileChip:
    return RegisterFileChip()


@pytest.fixture
def bus(chip: RegisterFileChip) -> I2CBus:
    return I2CBus(1, {0x68: chip})


def test_read_byte_data_is_a_one_byte_read_at_the_register(bus, chip):
    assert bus.read_byte_data(0x68, 0x05) == 0x05
    assert chip.reads == [(0x05, 1)]


def test_read_word_data_is_lsb_first(bus, chip):
    chip.regs[0x02:0x04] = bytes([0x34, 0x12])
    assert bus.read_word_data(0x68, 0x02) == 0x1234


def test_i2c_block_read_is_one_burst(bus, chip):
    assert bus.read_i2c_block_data(0x68, 0x02, 6) == bytes(range(2, 8))
    assert chip.reads == [(0x02, 6)]


def test_i2c_block_read_longer_than_32_is_einval_and_never_reaches_the_chip(bus, chip):
    with pytest.raises(OSError) as info:
        bus.read_i2c_block_data(0x68, 0x02, 33)
    assert info.value.errno == errno.EINVAL
    assert chip.reads == []


def test_write_word_data_writes_lsb_then_msb_from_the_register(bus, chip):
    bus.write_word_data(0x68, 0x36, 0xBEEF)
    assert chip.writes == [(0x36, bytes([0xEF, 0xBE]))]


def test_smbus_block_read_takes_the_first_byte_as_count(bus, chip):
    chip.regs[0x10] = 3
    assert bus.read_block_data(0x68, 0x10) == bytes([0x11, 0x12, 0x13])


def test_smbus_block_read_with_count_above_32_is_eproto(bus, chip):
    chip.regs[0x10] = 33
    with pytest.raises(OSError) as info:
        bus.read_block_data(0x68, 0x10)
    assert info.value.errno == errno.EPROTO
    assert bus.log[-1].error == "EPROTO"


def test_smbus_block_write_sends_count_then_data_as_register_bytes(bus, chip):
    bus.write_block_data(0x68, 0x20, bytes([7, 8]))
    assert chip.regs[0x20:0x23] == bytes([2, 7, 8])


def test_process_call_reads_back_from_where_the_pointer_went(bus, chip):
    # write 0x0201 at 0x30..0x31, then the word read continues at 0x32
    assert bus.process_call(0x68, 0x30, 0x0201) == 0x32 | 0x33 << 8
    assert chip.regs[0x30:0x32] == bytes([1, 2])


def test_send_byte_sets_the_pointer_and_receive_byte_reads_from_it(bus, chip):
    bus.write_byte(0x68, 0x0A)
    assert bus.read_byte(0x68) == 0x0A
    assert bus.read_byte(0x68) == 0x0B  # auto-increment goes on


def test_address_without_device_is_eremoteio_and_logged(bus):
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x50, 0x00)
    assert info.value.errno == errno.EREMOTEIO == 121
    assert info.value.strerror == "Remote I/O error"
    assert bus.log[-1].address == 0x50 and bus.log[-1].error == "EREMOTEIO"


def test_quick_write_acks_only_when_a_device_answers(bus):
    bus.write_quick(0x68)
    with pytest.raises(OSError):
        bus.write_quick(0x69)


def test_claimed_address_is_ebusy_unless_forced(bus):
    bus.claimed.add(0x68)
    with pytest.raises(OSError) as info:
        bus.check_address(0x68)
    assert info.value.errno == errno.EBUSY
    bus.check_address(0x68, force=True)


def test_address_above_7_bits_is_einval(bus):
    with pytest.raises(OSError) as info:
        bus.check_address(0x80)
    assert info.value.errno == errno.EINVAL


def test_kind_missing_from_funcs_is_eopnotsupp(chip):
    bus = I2CBus(1, {0x68: chip}, funcs=DEFAULT_FUNCS & ~I2C_FUNC_SMBUS_QUICK)
    with pytest.raises(OSError) as info:
        bus.write_quick(0x68)
    assert info.value.errno == errno.EOPNOTSUPP


def test_hook_sees_index_address_and_kind_and_its_oserror_fails_the_transaction(bus, chip):
    seen = []

    def hook(b, index, address, kind):
        seen.append((index, address, kind))
        if index == 1:
            raise OSError(errno.ETIMEDOUT, "timeout")

    bus.transaction_hooks.append(hook)
    bus.read_byte_data(0x68, 0)
    with pytest.raises(TimeoutError):
        bus.write_byte_data(0x68, 0x0F, 3)
    assert seen == [(0, 0x68, "read_byte_data"), (1, 0x68, "write_byte_data")]
    assert chip.regs[0x0F] == 0x0F  # the failed write never reached the chip
    assert bus.log[-1].error == "ETIMEDOUT"


def test_pec_write_appends_the_crc_which_the_chip_takes_as_data(bus, chip):
    bus.write_byte_data(0x68, 0x20, 0x55, pec=True)
    expected = smbus_pec([0x68 << 1, 0x20, 0x55])
    assert chip.regs[0x20:0x22] == bytes([0x55, expected])


def test_pec_read_fails_with_ebadmsg_when_the_next_register_is_not_the_crc(bus, chip):
    chip.regs[0x21] = smbus_pec([0x68 << 1, 0x20, 0x69 << 1 | 1, 0x20]) ^ 0xFF
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x68, 0x20, pec=True)
    assert info.value.errno == errno.EBADMSG


def test_pec_read_succeeds_when_the_next_byte_happens_to_be_the_crc(bus, chip):
    chip.regs[0x20] = 0x42
    chip.regs[0x21] = smbus_pec([0x68 << 1, 0x20, 0x68 << 1 | 1, 0x42])
    assert bus.read_byte_data(0x68, 0x20, pec=True) == 0x42


def test_smbus_pec_matches_the_crc8_check_value():
    # CRC-8 (poly 0x07, init 0) of "123456789" is 0xF4 (catalogue check value).
    assert smbus_pec(b"123456789") == 0xF4


def test_i2c_transfer_write_then_read_is_one_register_read(bus):
    indices = []
    bus.transaction_hooks.append(lambda b, index, a, kind: indices.append((index, kind)))
    messages = bus.i2c_transfer([I2CMessage.write(0x68, [0x02]), I2CMessage.read_message(0x68, 4)])
    assert messages[1].data == bytes([2, 3, 4, 5])
    # one transaction, as the same bytes on the wire are from smbus2's read_i2c_block_data
    assert indices == [(0, "i2c_read")]
    [entry] = bus.log
    assert (entry.kind, entry.register, entry.written, entry.read) == (
        "i2c_read", 0x02, b"", bytes([2, 3, 4, 5]))


def test_i2c_transfer_splits_into_register_reads_and_lone_messages(bus):
    bus.i2c_transfer([I2CMessage.write(0x68, [0x20, 0x99]),  # a write: its own transaction
                      I2CMessage.write(0x68, [0x02, 0x07]),  # a write then a read: one,
                      I2CMessage.read_message(0x68, 2),      # written bytes kept
                      I2CMessage.read_message(0x68, 1)])     # a read from the pointer
    assert [(t.kind, t.register, t.written.hex(), len(t.read)) for t in bus.log] == [
        ("i2c_write", 0x20, "99", 0), ("i2c_read", 0x02, "07", 2), ("i2c_read", None, "", 1)]


def test_i2c_transfer_stops_at_a_missing_device_after_earlier_messages_took_effect(bus, chip):
    with pytest.raises(OSError) as info:
        bus.i2c_transfer([I2CMessage.write(0x68, [0x20, 0x99]), I2CMessage.read_message(0x69, 1)])
    assert info.value.errno == errno.EREMOTEIO
    assert chip.regs[0x20] == 0x99


@pytest.mark.parametrize("count", [0, 43])
def test_i2c_transfer_with_0_or_more_than_42_messages_is_einval(bus, count):
    with pytest.raises(OSError) as info:
        bus.i2c_transfer([I2CMessage.read_message(0x68, 1)] * count)
    assert info.value.errno == errno.EINVAL


def test_two_chips_on_one_bus_are_independent():
    a, b = RegisterFileChip(), RegisterFileChip()
    bus = I2CBus(1, {0x68: a, 0x69: b})
    bus.write_byte_data(0x69, 0x20, 0xAA)
    assert a.regs[0x20] == 0x20 and b.regs[0x20] == 0xAA


def test_attach_refuses_addresses_beyond_7_bits_and_non_chips():
    bus = I2CBus(1)
    with pytest.raises(ValueError):
        bus.attach(0x80, RegisterFileChip())
    with pytest.raises(TypeError):
        bus.attach(0x68, object())


def test_nack_errno_can_match_an_adapter_that_answers_enxio(bus):
    bus.nack_errno = errno.ENXIO
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x50, 0)
    assert info.value.errno == errno.ENXIO
