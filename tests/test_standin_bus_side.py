"""A stand-in's bus side: the register-address width it decodes on I2C and how it frames SPI.

The BMI088 accelerometer is read by Zephyr's bmi08x driver with bit 7 of the register byte
set on I2C (``reg | BIT(7)``), and on SPI it shifts out a dummy byte before the data and
starts in I2C mode (its data sheet 6.1). The frames here are the ones Zephyr's driver, the
Linux bmi088-accel-spi regmap and Bosch's SensorAPI send (transcribed as byte lists, in our
words), through FakeSMBus, FakeSpiDev and the serve protocol.
"""

from __future__ import annotations

import pytest

from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.bus.spi import UNDRIVEN_BYTE, FakeSpiDev, SpiFrame
from bmg160_emu.device.standin import StandinConfig, StandinDevice
from bmg160_emu.io.standin_file import StandinFormatError, load_standin, spec_from_toml
from bmg160_emu.serve.client import ServeClient
from bmg160_emu.session.session_trace import session_header
from bmg160_emu.session.trace_replay import replay_trace
from tests._serve_harness import gyro, serving

READ = 0x80
ACC_CHIP_ID, ACC_X_LSB, ACC_CONF, ACC_RANGE = 0x00, 0x12, 0x40, 0x41
ACC_PWR_CONF, ACC_PWR_CTRL, ACC_SOFTRESET = 0x7C, 0x7D, 0x7E


def device(name: str, address: int | None = None) -> StandinDevice:
    return StandinDevice(load_standin(name), address)


def spi_to(chip: StandinDevice) -> FakeSpiDev:
    spi = FakeSpiDev(chip)
    spi.log.enabled = True
    return spi


# --------------------------------------------------------------------------- I2C: 7 bits


@pytest.mark.parametrize("name, reg, value", [
    ("bmi088_accel", 0x00, 0x1E), ("bma2x2_accel", 0x00, 0xFA), ("bmm150", 0x40, 0x32)])
def test_bit_7_of_the_i2c_register_byte_is_not_decoded(name, reg, value):
    chip = device(name)
    if name == "bmm150":
        chip.write(0x4B, b"\x01")  # out of suspend (data sheet 5.3)
    with FakeSMBus(1, devices={chip.address: chip}) as bus:
        assert bus.read_byte_data(chip.address, reg | READ) == value
        # a write with bit 7 set reaches the register too, and a burst continues from there
        writable = {"bmi088_accel": ACC_RANGE, "bma2x2_accel": 0x0F, "bmm150": 0x4F}[name]
        bus.write_byte_data(chip.address, writable | READ, 0x02)
        assert bus.read_byte_data(chip.address, writable) == 0x02
        assert bus.read_i2c_block_data(chip.address, (writable - 1) | READ, 2)[1] == 0x02
    # what an i2cdump of the chip shows: the upper half repeats the lower half
    image = chip.dump()
    assert image[0x80:] == image[:0x80]


def test_zephyrs_bmi08x_accel_i2c_probe_finds_the_chip():
    # bmi08x_accel_init over I2C: soft reset (reg & 0x7F), chip ID read with bit 7 set,
    # power on, range, then ACC_CONF's ODR field read-modify-written
    chip = device("bmi088_accel", 0x18)
    with FakeSMBus(1, devices={0x18: chip}) as bus:
        bus.write_byte_data(0x18, ACC_SOFTRESET, 0xB6)
        assert bus.read_i2c_block_data(0x18, ACC_CHIP_ID | READ, 1) == [0x1E]
        bus.write_byte_data(0x18, ACC_PWR_CONF, 0x00)
        bus.write_byte_data(0x18, ACC_PWR_CTRL, 0x04)
        bus.write_byte_data(0x18, ACC_RANGE, 0x01)
        conf = bus.read_i2c_block_data(0x18, ACC_CONF | READ, 1)[0]
        bus.write_byte_data(0x18, ACC_CONF, (conf & 0xF0) | 0x08)
        assert bus.read_i2c_block_data(0x18, ACC_CONF | READ, 2) == [0xA8, 0x01]
        assert bus.read_i2c_block_data(0x18, ACC_PWR_CONF | READ, 2) == [0x00, 0x04]


def test_a_declaration_without_a_width_decodes_8_bits(tmp_path):
    spec = spec_from_toml('name = "w"\nchip_id_register = 0x00\nchip_id = 0x42\naddresses = []\n'
                          '[registers]\n0x80 = { name = "HIGH", reset = 0x55 }\n', "w.toml")
    chip = StandinDevice(spec, 0x30)
    assert spec.register_address_bits == 8
    assert chip.read(0x80, 1) == b"\x55" and chip.read(0x00, 1) == b"\x42"
    assert chip.dump()[0x80] == 0x55 and chip.dump()[0x00] == 0x42


@pytest.mark.parametrize("text, message", [
    ("register_address_bits = 9\n", "register_address_bits must be 7 or 8, not 9"),
    ("register_address_bits = true\n", "register_address_bits must be 7 or 8, not True"),
    ("register_address_bits = 7\n[registers]\n0x80 = { reset = 1 }\n",
     "[registers] 0x80: register 0x80 is beyond a 7-bit register address"),
    ("[spi]\ndummy_bytes = 9\n", "[spi]: dummy_bytes must be an integer 0..4, not 9"),
    ("[spi]\nstarts_in_i2c = 1\n", "[spi]: starts_in_i2c must be true or false, not 1"),
    ("[spi]\nthree_wire_mask = 1\n", "[spi]: three_wire_mask needs three_wire_register"),
    ("[spi]\nthree_wire_register = 0x20\n", "[spi]: three_wire_register 0x20 must be declared"),
    ("[spi]\nclock = 1\n", "[spi]: unknown keys ['clock']"),
])
def test_bus_side_mistakes_are_one_line_errors_naming_the_place(text, message):
    head = 'name = "w"\nchip_id_register = 0x00\nchip_id = 0x42\naddresses = []\n'
    if "[registers]" not in text:
        text = text + '[registers]\n0x10 = { reset = 0 }\n' if "[spi]" not in text else (
            '[registers]\n0x10 = { reset = 0 }\n' + text)
    with pytest.raises(StandinFormatError) as caught:
        spec_from_toml(head + text, "w.toml")
    assert str(caught.value).startswith("w.toml: ") and message in str(caught.value)
    assert "\n" not in str(caught.value)


def test_the_declaration_round_trips_with_its_bus_side():
    from bmg160_emu.io.standin_file import spec_from_dict

    for name in ("bmi088_accel", "bma2x2_accel", "bmm150"):
        spec = load_standin(name)
        again = spec_from_dict(spec.to_dict(), "header", spec.source)
        assert (again.register_address_bits, again.spi) == (spec.register_address_bits, spec.spi)


# --------------------------------------------------------------------------- SPI


def test_the_bmi088_accel_ignores_spi_until_chip_select_rises_once():
    chip = device("bmi088_accel")
    spi = spi_to(chip)
    # the first frame after power-on: the chip is in I2C mode and drives nothing
    assert spi.xfer2([READ | ACC_CHIP_ID, 0, 0]) == [UNDRIVEN_BYTE] * 3
    spi.xfer2([ACC_PWR_CTRL, 0x04])  # now in SPI mode: this write lands
    assert chip.peek(ACC_PWR_CTRL) == 0x04


def test_a_read_shifts_out_a_dummy_byte_before_the_data():
    chip = device("bmi088_accel")
    spi = spi_to(chip)
    spi.xfer2([READ | 0x7F, 0, 0])  # Zephyr's and Bosch's dummy read: selects SPI
    got = spi.xfer2([READ | ACC_CHIP_ID, 0, 0])
    assert got[2] == 0x1E  # command, dummy, then the chip ID
    # a 6-byte burst from ACC_CONF reaches the registers above 0x40 (the BMG160 frame's map
    # ends there) and continues with the stand-in's own pointer
    burst = spi.xfer2([READ | ACC_CONF, 0, 0, 0])
    assert burst[2:] == [0xA8, 0x01]


def test_a_driver_that_takes_the_dummy_byte_for_data_sees_a_stale_byte():
    # the Bosch forum's "reading any register gives the value of the previous read request":
    # the dummy repeats the last byte shifted out
    chip = device("bmi088_accel")
    spi = spi_to(chip)
    spi.xfer2([READ | 0x7F, 0, 0])
    assert spi.xfer2([READ | ACC_CHIP_ID, 0])[1] == 0x00  # before any data: 0x00
    assert spi.xfer2([READ | ACC_CHIP_ID, 0, 0])[2] == 0x1E
    assert spi.xfer2([READ | ACC_CONF, 0])[1] == 0x1E  # the wrong chip ID... of the last read


def test_a_soft_reset_over_spi_puts_the_accelerometer_back_in_i2c_mode():
    chip = device("bmi088_accel")
    spi = spi_to(chip)
    spi.xfer2([READ | 0x7F, 0, 0])
    spi.xfer2([ACC_RANGE, 0x03])
    spi.xfer2([ACC_SOFTRESET, 0xB6])
    assert chip.peek(ACC_RANGE) == 0x01  # reset value back
    assert spi.xfer2([READ | ACC_CHIP_ID, 0, 0]) == [UNDRIVEN_BYTE] * 3  # ignored
    assert spi.xfer2([READ | ACC_CHIP_ID, 0, 0])[2] == 0x1E


def test_zephyrs_bmi08x_accel_spi_init_as_its_buffers_make_the_frames():
    # bmi08x_accel_init on SPI: the soft reset write (reg & 0x7F, one frame), 1 ms, the dummy
    # read of 0x7F, then every read as tx {reg | 0x80} and rx {2 bytes it discards, data}
    chip = device("bmi088_accel")
    spi = spi_to(chip)

    def read(reg: int, n: int) -> list[int]:
        rx = spi.xfer2([reg | READ] + [0] * (1 + n))
        return rx[2:]

    spi.xfer2([ACC_SOFTRESET, 0xB6])  # at power-on, in I2C mode: ignored, selects SPI
    read(0x7F, 1)
    assert read(ACC_CHIP_ID, 1) == [0x1E]
    spi.xfer2([ACC_PWR_CONF, 0x00])
    spi.xfer2([ACC_PWR_CTRL, 0x04])
    spi.xfer2([ACC_RANGE, 0x01])
    conf = read(ACC_CONF, 1)[0]
    spi.xfer2([ACC_CONF, (conf & 0xF0) | 0x08])
    assert read(ACC_CONF, 2) == [0xA8, 0x01] and read(ACC_PWR_CONF, 2) == [0x00, 0x04]
    assert read(ACC_X_LSB, 6) == [0] * 6  # registers only: no acceleration data
    # the log is in register terms, the dummy bytes left out
    reads = [(t.register, t.read) for t in spi.log if t.kind == "spi_read"]
    assert reads[1] == (ACC_CHIP_ID, b"\x1e")


def test_linux_bmi088_accel_spi_regmap_read():
    # drivers/iio/accel/bmi088-accel-spi.c: spi_write_then_read of {reg | 0x80, 0} then
    # val_size bytes, one frame
    chip = device("bmi088_accel")
    spi = spi_to(chip)
    spi.xfer2([READ | ACC_CHIP_ID, 0])  # its probe's first access selects SPI
    rx = spi.xfer2([READ | ACC_CHIP_ID, 0, 0, 0])
    assert rx[2:] == [0x1E, 0x00]


def test_the_bma2x2_takes_address_data_pairs_in_one_spi_write_frame():
    # Bosch's bma2x2_support.c BMA2x2_SPI_bus_write: (reg++ & 0x7F, data) per byte
    chip = device("bma2x2_accel")
    spi = spi_to(chip)
    spi.xfer2([0x0F, 0x05, 0x10, 0x0C])  # PMU_RANGE 0x05, PMU_BW 0x0C
    assert (chip.peek(0x0F), chip.peek(0x10)) == (0x05, 0x0C)
    assert spi.xfer2([READ | 0x00, 0, 0])[1:] == [0xFA, 0x00]  # no dummy byte on the BMA2x2


@pytest.mark.parametrize("name, register, bit", [("bma2x2_accel", 0x34, 0x01),
                                                 ("bmm150", 0x4B, 0x04)])
def test_the_three_wire_bit_is_the_chips_own(name, register, bit):
    chip = device(name)
    if name == "bmm150":
        chip.write(0x4B, b"\x01")
    spi = spi_to(chip)
    chip_id_reg = load_standin(name).chip_id_register
    assert spi.xfer2([READ | chip_id_reg, 0])[1] == load_standin(name).chip_id
    chip.write(register, bytes([chip.peek(register) | bit]))
    # the chip now answers on its one data line: a 4-wire host hears nothing
    assert spi.xfer2([READ | chip_id_reg, 0])[1] == UNDRIVEN_BYTE


def test_every_front_end_frames_a_stand_in_as_the_stand_in():
    # machine.SPI and busio build their frames with SpiFrame as FakeSpiDev does
    chip = device("bmi088_accel")
    with chip.lock:
        SpiFrame(chip).clock(bytes([READ | 0x7F, 0, 0]))
        assert SpiFrame(chip).clock(bytes([READ | ACC_CHIP_ID, 0, 0]))[2] == 0x1E
        assert SpiFrame(chip).dummy_bytes == 1


# --------------------------------------------------------------------------- serve


def test_served_over_the_protocol_on_i2c_and_spi(tmp_path):
    accel = StandinConfig(load_standin("bmi088_accel"), 0x18)
    with serving(tmp_path, [gyro(0x68, part="bmi088_gyro"), accel]) as (path, server):
        with ServeClient(path, "test", timeout_s=10) as c:
            c.greet()
            # I2C: Zephyr's i2c_write_read_dt of reg | BIT(7)
            assert c.write_read(0x18, ACC_CHIP_ID | READ, 1, 1000).data == b"\x1e"
            assert c.write_read(0x68, 0x00 | READ, 1, 2000).data == b"\x0f"
            # SPI on chip select 0 (the accelerometer, first in address order)
            assert c.spi(0, bytes([READ | 0x7F, 0, 0]), 3000).status == 0  # selects SPI
            got = c.spi(0, bytes([READ | ACC_CHIP_ID, 0, 0]), 4000)
            assert (got.status, got.data[2]) == (0, 0x1E)
            # a read split over two transfers with chip select held keeps the frame
            first = c.spi(0, bytes([READ | ACC_CONF, 0]), 5000, keep_cs=True)
            rest = c.spi(0, bytes([0, 0]), 6000)
            assert first.data[1] == 0x1E  # the dummy: the last byte shifted out
            assert rest.data == bytes([0xA8, 0x01])
            c.bye(7000)
        log = list(server.sessions[0].log)
    spi_reads = [(t.register, t.read) for t in log if t.kind == "spi_read"]
    assert (ACC_CHIP_ID, b"\x1e") in spi_reads


def test_a_served_spi_session_of_the_accelerometer_replays(tmp_path):
    accel = StandinConfig(load_standin("bmi088_accel"), 0x18)
    with serving(tmp_path, [accel]) as (path, server):
        with ServeClient(path, "test", timeout_s=10) as c:
            c.greet()
            c.spi(0, bytes([ACC_SOFTRESET, 0xB6]), 1000)  # ignored: selects SPI
            c.spi(0, bytes([READ | 0x7F, 0, 0]), 2000)
            c.spi(0, bytes([ACC_RANGE, 0x02]), 3000)
            c.spi(0, bytes([READ | ACC_CHIP_ID, 0, 0, 0]), 4000)
            c.spi(0, bytes([ACC_SOFTRESET, 0xB6]), 5000)  # back to I2C mode
            c.spi(0, bytes([READ | ACC_RANGE, 0, 0]), 6000)  # ignored
            c.spi(0, bytes([READ | ACC_RANGE, 0, 0]), 7000)
            c.bye(8000)
        records = [t.to_dict() for t in server.sessions[0].log]
    result = replay_trace(session_header(7, [accel]).to_dict(), records)
    assert result.ok and result.transactions == len(records) == 7, result.divergence


def test_spi_records_are_the_device_on_their_chip_select_in_replay_and_in_trace(tmp_path):
    from bmg160_emu.device.parts import part_table
    from bmg160_emu.session.decode import describe_transaction

    accel, bmi_gyro = StandinConfig(load_standin("bmi088_accel"), 0x18), gyro(0x68, "bmi088_gyro")
    with serving(tmp_path, [bmi_gyro, accel]) as (path, server):
        with ServeClient(path, "test", timeout_s=10) as c:
            c.greet()
            c.spi(0, bytes([ACC_SOFTRESET, 0xB6]), 1000)  # chip select 0: the accelerometer
            c.spi(0, bytes([READ | ACC_CHIP_ID, 0, 0]), 2000)
            c.spi(1, bytes([READ | 0x00, 0]), 3000)  # chip select 1: the gyroscope
            c.spi(1, bytes([0x0F, 0x03]), 4000)  # its GYRO_RANGE
            c.bye(5000)
        records = [t.to_dict() for t in server.sessions[0].log]
    # replay sends each frame to the device on its chip select (the gyroscope's frames to
    # the accelerometer would read 0x00 where the trace has 0x0F)
    result = replay_trace(session_header(7, [bmi_gyro, accel]).to_dict(), records)
    assert result.ok and result.transactions == 4, result.divergence
    lines = [describe_transaction(r, {0x18: accel.spec}, {0x68: part_table("bmi088_gyro")
                                                          .registers}) for r in records]
    assert "spi0.0 0x18 write 0x7E ACC_SOFTRESET <- 0xb6" in lines[0]
    assert "spi0.1 0x68 read 0x00 GYRO_CHIP_ID -> 0x0f" in lines[2]
    assert "GYRO_RANGE <- 0x03" in lines[3]
    # without the devices' tables a write outside the BMG160's map is said, not a traceback
    assert "write 0x7E (outside the map) <- 0xb6 (outside the map, ignored)" in (
        describe_transaction(records[0]))


def test_a_micropython_driver_on_machine_spi_meets_the_dummy_byte_and_the_i2c_start():
    from bmg160_emu.bus.machine import micropython_machine

    chip = device("bmi088_accel")
    with micropython_machine(spi={1: {5: chip}}) as machine:
        cs = machine.Pin(5, machine.Pin.OUT, value=1)
        spi = machine.SPI(1, baudrate=1_000_000, polarity=0, phase=0)

        def read(reg: int, n: int) -> bytes:
            cs(0)
            spi.write(bytes([READ | reg]))
            data = spi.read(1 + n)  # the dummy byte, then the data
            cs(1)
            return data[1:]

        assert read(ACC_CHIP_ID, 1) == b"\x00"  # power-on: still in I2C mode, nothing driven
        assert read(ACC_CHIP_ID, 1) == b"\x1e"  # the first frame's rising CS selected SPI
        cs(0)
        spi.write(bytes([ACC_RANGE, 0x02]))
        cs(1)
        assert read(ACC_CONF, 2) == b"\xa8\x02"
