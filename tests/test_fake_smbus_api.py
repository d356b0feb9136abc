"""FakeSMBus is smbus2.SMBus name for name: signatures, defaults, return types, limits, errors."""

from __future__ import annotations

import errno
import inspect

import pytest
import smbus2
from _standin_chip import RegisterFileChip

from bmg160_emu.bus.patching import patch_smbus
from bmg160_emu.bus.smbus import FakeSMBus

PUBLIC = sorted(
    name
    for name, value in vars(smbus2.SMBus).items()
    if not name.startswith("_") and callable(value)
)


@pytest.fixture
def chip() -> RegisterFileChip:
    return RegisterFileChip()


@pytest.fixture
def bus(chip):
    with FakeSMBus(1, devices={0x68: chip}) as fake:
        yield fake


@pytest.mark.parametrize("name", PUBLIC)
def test_every_public_method_has_smbus2s_parameters_and_defaults(name):
    ours = inspect.signature(getattr(FakeSMBus, name))
    theirs = inspect.signature(getattr(smbus2.SMBus, name))
    strip = [p for p in ours.parameters.values() if p.kind is not p.KEYWORD_ONLY]
    assert [(p.name, p.kind, p.default) for p in strip] == [
        (p.name, p.kind, p.default) for p in theirs.parameters.values()
    ]


def test_pec_is_a_property_like_smbus2s():
    assert isinstance(FakeSMBus.pec, property) and isinstance(smbus2.SMBus.pec, property)


@pytest.mark.parametrize(
    ("method", "args"),
    [
        ("read_i2c_block_data", (0x68, 0, 33)),
        ("write_i2c_block_data", (0x68, 0, [0] * 33)),
        ("write_block_data", (0x68, 0, [0] * 33)),
        ("block_process_call", (0x68, 0, [0] * 33)),
    ],
)
def test_32_byte_limits_raise_smbus2s_valueerror(bus, method, args):
    # smbus2 checks these before touching the device, so an unopened SMBus shows its message.
    with pytest.raises(ValueError) as theirs:
        getattr(smbus2.SMBus(), method)(*args)
    with pytest.raises(ValueError) as ours:
        getattr(bus, method)(*args)
    assert str(ours.value) == str(theirs.value)


def test_reads_return_smbus2s_types(bus):
    assert isinstance(bus.read_byte_data(0x68, 0), int)
    assert isinstance(bus.read_word_data(0x68, 2), int)
    block = bus.read_i2c_block_data(0x68, 2, 6)
    assert isinstance(block, list) and all(isinstance(v, int) for v in block)


def test_no_device_at_the_address_raises_oserror_121(bus):
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x50, 0)
    assert info.value.errno == 121


def test_opening_a_bus_number_without_emulated_bus_raises_filenotfounderror():
    with pytest.raises(FileNotFoundError) as info:
        FakeSMBus(7)
    assert info.value.errno == errno.ENOENT
    assert info.value.filename == "/dev/i2c-7"


def test_bus_of_the_wrong_type_raises_typeerror_as_smbus2():
    with pytest.raises(TypeError, match="Unexpected type"):
        FakeSMBus(1.0)


def test_closed_bus_raises_the_typeerror_smbus2_gets_from_ioctl(chip):
    fake = FakeSMBus(1, devices={0x68: chip})
    fake.close()
    assert fake.fd is None
    with pytest.raises(TypeError):
        fake.read_byte_data(0x68, 0)


def test_context_manager_closes_and_fd_is_an_int(chip):
    with FakeSMBus(1, devices={0x68: chip}) as fake:
        assert isinstance(fake.fd, int) and fake.fd > 0
    assert fake.fd is None


def test_funcs_report_i2c_and_smbus_support_and_pec(bus):
    funcs = smbus2.I2cFunc(bus.funcs)
    for flag in (smbus2.I2cFunc.I2C, smbus2.I2cFunc.SMBUS_PEC, smbus2.I2cFunc.SMBUS_READ_I2C_BLOCK):
        assert funcs & flag


def test_pec_setter_turns_pec_on_and_close_turns_it_off(chip):
    fake = FakeSMBus(1, devices={0x68: chip})
    fake.pec = 1
    assert fake.pec == 1
    fake.close()
    assert fake.pec == 0


def test_register_and_value_are_truncated_to_8_bits_as_ctypes_does(bus, chip):
    bus.write_byte_data(0x68, 0x120, 0x1AB)  # -> register 0x20, value 0xAB
    assert chip.regs[0x20] == 0xAB


def test_float_arguments_raise_typeerror(bus):
    with pytest.raises(TypeError):
        bus.read_byte_data(0x68, 2.0)
    with pytest.raises(TypeError):
        bus.write_byte_data(0x68, 2, 1.5)


def test_address_above_0x7f_raises_einval(bus):
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x80, 0)
    assert info.value.errno == errno.EINVAL


def test_i2c_rdwr_fills_real_smbus2_read_messages(bus):
    write = smbus2.i2c_msg.write(0x68, [0x02])
    read = smbus2.i2c_msg.read(0x68, 6)
    assert bus.i2c_rdwr(write, read) is None
    assert list(read) == [2, 3, 4, 5, 6, 7]


def test_force_true_reaches_an_address_a_kernel_driver_holds(bus):
    bus.i2c_bus.claimed.add(0x68)
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x68, 0)
    assert info.value.errno == errno.EBUSY
    assert bus.read_byte_data(0x68, 0, force=True) == 0


@pytest.mark.parametrize(
    ("method", "args"),
    [
        ("read_byte_data", (0x68, 0x102)),
        ("read_word_data", (0x68, 0x02)),
        ("read_i2c_block_data", (0x68, 0x02, 6)),
        ("read_i2c_block_data", (0x68, 0x02, 0)),
        ("read_i2c_block_data", (0x68, 0x02, -224)),
        ("read_i2c_block_data", (0x68, 0x02, -1)),
        ("read_block_data", (0x68, 0x05)),
        ("process_call", (0x68, 0x30, 0x10203)),
        ("block_process_call", (0x68, 0x03, [1, 2])),
        ("write_word_data", (0x68, 0x30, -1)),
        ("write_block_data", (0x68, 0x30, b"\x01\x02")),
        ("write_i2c_block_data", (0x68, 0x30, [1, 300])),
        ("write_i2c_block_data", (0x68, 0x30, [])),  # a count of 0: EINVAL (Linux 6.1.190)
        ("write_block_data", (0x68, 0x30, [])),
        ("block_process_call", (0x68, 0x03, [])),
        ("read_i2c_block_data", (0x68, 0x02, -256)),  # ctypes makes it 0
        ("read_byte", (0x68,)),
        ("write_byte", (0x68, 0x11)),
        ("write_quick", (0x68,)),
        ("read_byte_data", (0x69, 0)),
    ],
)
def test_same_result_or_error_as_real_smbus2_over_the_emulated_kernel(method, args):
    results = []
    for front_end in ("fake", "smbus2"):
        chip = RegisterFileChip()
        with patch_smbus({1: {0x68: chip}}):
            bus = FakeSMBus(1) if front_end == "fake" else smbus2.SMBus(1)
            try:
                outcome = ("ok", getattr(bus, method)(*args))
            except OSError as exc:
                outcome = ("OSError", exc.errno)
            bus.close()
        results.append((outcome, chip.dump()))
    assert results[0] == results[1]


def _address_sequence(bus, kernel) -> list:
    """Block reads around hand-set ``address`` and ``force`` attributes: smbus2 decides on
    its ioctl by comparing them, so a stale fast path would reach the wrong device or skip
    the EBUSY of an unforced ioctl."""
    out = []

    def read(address, **force):
        try:
            out.append(bus.read_i2c_block_data(address, 0x00, 2, **force))
        except OSError as exc:
            out.append(exc.errno)

    read(0x68)
    bus.address = 0x69  # by hand: no ioctl, the kernel's client is still 0x68
    read(0x69)  # smbus2: no ioctl, reads 0x68
    read(0x68)  # the address differs: ioctl, 0x68
    read(0x69)  # ioctl to 0x69
    bus.force = True
    read(0x68)  # force differs: a forced ioctl
    kernel.claimed.add(0x68)  # a kernel driver binds 0x68
    read(0x68)  # same address and force: no ioctl, the read goes through
    bus.force = False
    read(0x68)  # force differs: an unforced ioctl, EBUSY
    read(0x68, force=True)
    return out


def test_hand_set_address_and_force_route_reads_as_real_smbus2():
    results = []
    for front_end in ("fake", "smbus2"):
        low, high = RegisterFileChip(), RegisterFileChip()
        high.write(0x00, bytes([0xAA, 0xBB]))
        with patch_smbus({1: {0x68: low, 0x69: high}}) as buses:
            bus = FakeSMBus(1) if front_end == "fake" else smbus2.SMBus(1)
            out = _address_sequence(bus, buses[1])
            bus.close()
            kinds = [(t.address, t.kind) for t in buses[1].log]
        results.append((out, kinds))
    assert results[0] == results[1]
    out = results[0][0]
    assert out[1] == out[0] != out[3]  # the stale-address read really hit 0x68
    assert out[6] == errno.EBUSY
