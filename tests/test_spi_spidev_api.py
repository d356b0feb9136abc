"""FakeSpiDev follows spidev.SpiDev: attributes, argument rules, limits and errors."""

from __future__ import annotations

import errno

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.spi import MAX_SPEED_HZ, SPIDEV_BUFSIZ, FakeSpiDev


@pytest.fixture
def spi():
    with FakeSpiDev(RegisterFileChip()) as dev:
        yield dev


def test_open_device_reports_mode_0_8_bits_and_the_chips_10_mhz(spi):
    assert (spi.mode, spi.bits_per_word, spi.max_speed_hz) == (0, 8, MAX_SPEED_HZ)
    assert isinstance(spi.fileno(), int) and spi.fileno() > 0


def test_unopened_device_has_fd_minus_1_and_transfers_fail_with_ebadf():
    dev = FakeSpiDev()
    assert dev.fileno() == -1
    with pytest.raises(OSError) as info:
        dev.xfer2([0x80, 0])
    assert info.value.errno == errno.EBADF
    with pytest.raises(OSError):
        dev.mode = 3


def test_missing_device_node_is_filenotfounderror():
    with pytest.raises(FileNotFoundError):
        FakeSpiDev(5, 1)


def test_xfer_writes_the_answer_into_the_callers_list(spi):
    values = [0x82, 0, 0]
    result = spi.xfer(values)
    assert result is values and values == [0, 2, 3]


def test_xfer2_of_a_tuple_returns_a_tuple_and_xfer3_always_a_tuple(spi):
    assert spi.xfer2((0x82, 0)) == (0, 2)
    assert spi.xfer3([0x82, 0]) == (0, 2)


@pytest.mark.parametrize("method", ["xfer", "xfer2", "writebytes"])
def test_empty_list_is_a_typeerror(spi, method):
    with pytest.raises(TypeError, match="Empty argument list"):
        getattr(spi, method)([])


@pytest.mark.parametrize("method", ["xfer", "xfer2", "writebytes"])
def test_more_than_bufsiz_bytes_is_an_overflowerror(spi, method):
    with pytest.raises(OverflowError, match=f"exceeds {SPIDEV_BUFSIZ} bytes"):
        getattr(spi, method)([0] * (SPIDEV_BUFSIZ + 1))


def test_xfer3_and_writebytes2_take_any_length(spi):
    assert len(spi.xfer3([0x82] + [0] * SPIDEV_BUFSIZ)) == SPIDEV_BUFSIZ + 1
    spi.writebytes2(bytes(SPIDEV_BUFSIZ * 2 + 1))


def test_non_int_values_are_a_typeerror(spi):
    with pytest.raises(TypeError, match="Non-Int/Long"):
        spi.xfer2([0x82, 1.0])


def test_values_are_truncated_to_8_bits(spi):
    assert spi.xfer2([0x182, 0]) == [0, 2]


def test_readbytes_length_is_clamped_to_1_and_bufsiz(spi):
    assert len(spi.readbytes(0)) == 1
    assert len(spi.readbytes(SPIDEV_BUFSIZ + 10)) == SPIDEV_BUFSIZ


@pytest.mark.parametrize("value", [4, -1, 1.0])
def test_mode_outside_0_to_3_is_a_typeerror(spi, value):
    with pytest.raises(TypeError):
        spi.mode = value


@pytest.mark.parametrize("name", ["cshigh", "lsbfirst", "threewire", "loop", "no_cs", "read0"])
def test_flag_attributes_take_booleans_only(spi, name):
    with pytest.raises(TypeError, match="boolean"):
        setattr(spi, name, 1)
    setattr(spi, name, True)
    assert getattr(spi, name) is True


def test_bits_per_word_range_and_controller_support(spi):
    with pytest.raises(TypeError, match="8 to 32"):
        spi.bits_per_word = 7
    with pytest.raises(OSError) as info:
        spi.bits_per_word = 12  # in spidev's range, not one the emulated controller does
    assert info.value.errno == errno.EINVAL
    spi.bits_per_word = 16
    assert spi.bits_per_word == 16


def test_close_resets_the_attributes(spi):
    spi.mode = 3
    spi.close()
    assert (spi.fileno(), spi.mode, spi.bits_per_word, spi.max_speed_hz) == (-1, 0, 0, 0)


def test_each_frame_is_logged_in_register_terms(spi):
    spi.xfer2([0x82, 0, 0])  # read from 0x02
    spi.writebytes([0x0F, 0x03])  # write 0x03 to 0x0F
    read, write = spi.log[-2], spi.log[-1]
    assert (read.kind, read.register, read.written, read.read) == (
        "spi_read",
        0x02,
        b"",
        b"\x02\x03",
    )
    assert (write.kind, write.register, write.written, write.read) == (
        "spi_write",
        0x0F,
        b"\x03",
        b"",
    )


def test_a_frame_continued_without_cs_is_logged_from_where_it_stands(spi):
    spi.no_cs = True
    spi.writebytes([0x84])
    spi.readbytes(2)
    assert (spi.log[-1].kind, spi.log[-1].register, spi.log[-1].read) == (
        "spi_read",
        0x04,
        b"\x04\x05",
    )


def test_spi_log_reads_like_an_i2c_trace():
    from bmg160_emu.session.decode import describe_transaction

    with FakeSpiDev(RegisterFileChip()) as dev:
        dev.xfer2([0x82] + [0] * 6)
        text = describe_transaction(dev.log[-1].to_dict())
    assert "burst read 0x02..0x07" in text


def test_a_transaction_hook_can_fail_a_frame_before_it_reaches_the_chip():
    chip = RegisterFileChip()
    with FakeSpiDev(chip) as dev:

        def fail_second(d, index, address, kind):
            if index == 1:
                raise OSError(errno.EIO, "injected")

        dev.transaction_hooks.append(fail_second)
        dev.writebytes([0x20, 0x11])
        with pytest.raises(OSError) as info:
            dev.writebytes([0x21, 0x22])
        assert info.value.errno == errno.EIO
    assert (chip.regs[0x20], chip.regs[0x21]) == (0x11, 0x21)
