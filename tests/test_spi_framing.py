"""The chip's SPI framing (spec 2.2-2.4) as seen through FakeSpiDev."""

from __future__ import annotations

import pytest
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.spi import UNDRIVEN_BYTE, FakeSpiDev, spi_frame
from bmg160_emu.device.chip import BMG160

READ = 0x80  # R/W bit (spec 2.2)
U = UNDRIVEN_BYTE


@pytest.fixture
def chip() -> RegisterFileChip:
    return RegisterFileChip()


@pytest.fixture
def spi(chip):
    with FakeSpiDev(chip) as dev:
        yield dev


def test_read_frame_returns_registers_after_the_command_byte(spi):
    assert spi.xfer2([READ | 0x02, 0, 0, 0]) == [U, 2, 3, 4]


def test_write_frame_writes_the_byte_after_the_command(spi, chip):
    spi.xfer2([0x0F, 0x03])
    assert chip.regs[0x0F] == 0x03


def test_further_bytes_of_a_write_frame_are_address_data_pairs(spi, chip):
    spi.writebytes([0x0F, 0x01, 0x10, 0x05, 0x11, 0x80])
    assert (chip.regs[0x0F], chip.regs[0x10], chip.regs[0x11]) == (1, 5, 0x80)


def test_burst_read_stops_advancing_at_fifo_data(chip):
    chip.regs[0x3E], chip.regs[0x3F] = 0xAA, 0xBB
    assert spi_frame(chip, [READ | 0x3E, 0, 0, 0]) == bytes([U, 0xAA, 0xBB, 0xBB])


def test_addresses_0x40_to_0x7f_read_zero_and_ignore_writes(spi, chip):
    before = chip.dump()
    spi.xfer2([0x45, 0x99])
    assert chip.dump() == before
    assert spi.xfer2([READ | 0x45, 0, 0]) == [U, 0, 0]


def test_each_call_is_its_own_frame_so_a_new_command_byte_starts_it(spi, chip):
    spi.xfer2([READ | 0x02, 0])
    assert spi.xfer2([READ | 0x05, 0]) == [U, 5]


def test_with_no_cs_the_frame_goes_on_across_calls(spi, chip):
    spi.no_cs = True
    spi.writebytes([READ | 0x02])
    assert spi.readbytes(3) == [2, 3, 4]
    spi.no_cs = False  # chip select driven again: the next call starts a new frame
    assert spi.xfer2([READ | 0x08, 0]) == [U, 8]


def test_lsb_first_host_is_seen_bit_reversed_by_the_chip(spi):
    spi.lsbfirst = True
    # 0x41 reversed is 0x82 (read 0x02); the chip's 0x02 comes back reversed as 0x40
    assert spi.xfer2([0x41, 0x00]) == [U, 0x40]


def test_16_bit_words_go_msb_first_on_the_wire(spi):
    spi.bits_per_word = 16
    # host words 0x8202, 0x0000 (little-endian in memory) go out as 0x82 0x02 0x00 0x00:
    # a read of 0x02; the wire answer U, 2, 3, 4 lands in memory word-swapped
    assert spi.xfer2([0x02, 0x82, 0x00, 0x00]) == [0x02, U, 0x04, 0x03]


def test_16_bit_transfer_of_odd_length_is_einval(spi):
    spi.bits_per_word = 16
    with pytest.raises(OSError) as info:
        spi.xfer2([0x82, 0, 0])
    assert info.value.errno == 22


@pytest.mark.parametrize("mode", [1, 2])
def test_modes_1_and_2_do_not_reach_the_chip(spi, chip, mode):
    spi.mode = mode
    assert spi.xfer2([READ | 0x02, 0]) == [U, U]
    spi.xfer2([0x20, 0x55])
    assert chip.regs[0x20] == 0x20


def test_active_high_chip_select_never_selects_the_chip(spi, chip):
    spi.cshigh = True
    assert spi.xfer2([READ | 0x02, 0]) == [U, U]


def test_loopback_returns_what_was_sent(spi):
    spi.loop = True
    assert spi.xfer2([READ | 0x02, 0x12]) == [READ | 0x02, 0x12]


def test_chip_in_3_wire_mode_answers_a_3_wire_host_only():
    chip = BMG160(seed=1, noise=False)
    with FakeSpiDev(chip) as spi:
        spi.xfer2([0x34, 0x01])  # spi3 = 1 (spec 4.23)
        assert spi.xfer2([READ | 0x00, 0]) == [U, U]  # 4-wire host listens on the wrong line
        spi.threewire = True
        spi.no_cs = True  # one frame: command out, then turn the line around and listen
        spi.writebytes([READ | 0x00])
        assert spi.readbytes(1) == [0x0F]


def test_3_wire_host_cannot_do_full_duplex_transfers(spi):
    spi.threewire = True
    with pytest.raises(OSError) as info:
        spi.xfer2([READ, 0])
    assert info.value.errno == 22


def test_split_two_byte_frames_still_get_a_shadowed_pair():
    # spec 2.2/6.2: LeOSW42 reads LSB and MSB in separate frames; shadowing works across them
    chip = BMG160(seed=1, noise=False)
    chip.set_true_rate((300.0, 0.0, 0.0))
    chip.advance(0.1)
    with FakeSpiDev(chip) as spi:
        lsb = spi.xfer2([READ | 0x02, 0])[1]
        chip.set_true_rate((-300.0, 0.0, 0.0))
        chip.advance(0.1)  # many new samples, opposite sign
        msb = spi.xfer2([READ | 0x03, 0])[1]
    value = lsb | msb << 8
    assert value < 0x8000  # the MSB latched with the positive sample's LSB


def test_spi_burst_gives_the_same_bytes_as_an_i2c_burst():
    chip = BMG160(seed=3)
    chip.advance(0.05)
    expected = chip.dump()[0x02:0x08]
    with FakeSpiDev(chip) as spi:
        assert bytes(spi.xfer2([READ | 0x02] + [0] * 6)[1:]) == expected
