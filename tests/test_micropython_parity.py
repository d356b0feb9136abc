"""The MicroPython and CircuitPython drop-ins answer every method and bad argument as the
ports do.

Each case is one call and the port's answer, read from the port's own source (cited per
case): MicroPython's extmod/machine_i2c.c, extmod/modmachine.c, extmod/modtime.c,
py/obj.c, py/objstr.c and the ESP32 port (ports/esp32/machine_i2c.c, modmachine.c), the
port the drop-in stands for; CircuitPython's shared-bindings/busio/I2C.c,
shared/runtime/buffer_helper.c, py/argcheck.c and the RP2040 port's common-hal. An answer
is a value, or an exception's type and (a part of) its message or its errno.
"""

from __future__ import annotations

import array
import errno
import time
from typing import Any

import pytest

ADDRESS = 0x68
NOT_SUPPORTED = (OSError, "I2C operation not supported")


def answer(call: Any) -> Any:
    try:
        return call()
    except Exception as exc:  # noqa: BLE001 - the exception is the answer compared
        return exc


def _into(call: Any, buffer: Any) -> Any:
    """``call(buffer)``, then the buffer it filled."""
    call(buffer)
    return buffer


def check(got: Any, expected: Any) -> None:
    if isinstance(expected, tuple) and expected and isinstance(expected[0], type) \
            and issubclass(expected[0], BaseException):
        kind, detail = expected
        assert isinstance(got, kind), f"{got!r} is not {kind.__name__}"
        if isinstance(detail, int):
            assert got.errno == detail, got
        else:
            assert detail in str(got), got
    else:
        assert got == expected


# (name, call on (machine, i2c), answer, source)
MACHINE_CASES = [
    # fill_memaddr_buf: addrsize is a uint8_t, a multiple of 8 up to 32
    ("readfrom_mem addrsize=12", lambda m, i: i.readfrom_mem(ADDRESS, 0x10, 1, addrsize=12),
     (ValueError, "invalid addrsize"), "extmod/machine_i2c.c fill_memaddr_buf"),
    *[(f"readfrom_mem addrsize={size}", lambda m, i, s=size: i.readfrom_mem(
        ADDRESS, 0x10, 1, addrsize=s), (ValueError, "invalid addrsize"),
       "extmod/machine_i2c.c fill_memaddr_buf") for size in (7, 33, 40, 64, -8)],
    *[(f"writeto_mem addrsize={size}", lambda m, i, s=size: i.writeto_mem(
        ADDRESS, 0x10, b"\x00", addrsize=s), (ValueError, "invalid addrsize"),
       "extmod/machine_i2c.c fill_memaddr_buf") for size in (12, 7, 33, 40, 64, -8)],
    ("readfrom_mem addrsize=264 is 8 as a byte",
     lambda m, i: i.readfrom_mem(ADDRESS, 0x00, 1, addrsize=264), b"\x0f",
     "uint8_t addrsize"),
    ("readfrom_mem addrsize=0 reads from the pointer",
     lambda m, i: (i.writeto(ADDRESS, b"\x00"), i.readfrom_mem(ADDRESS, 0x10, 1, addrsize=0))[1],
     b"\x0f", "fill_memaddr_buf: no address byte"),
    ("readfrom_mem memaddr as a float", lambda m, i: i.readfrom_mem(ADDRESS, 1.0, 1),
     (TypeError, "can't convert float to int"), "MP_ARG_INT"),
    # readfrom: nbytes through mp_obj_get_int, then vstr_init_len
    ("readfrom 1.5 bytes", lambda m, i: i.readfrom(ADDRESS, 1.5),
     (TypeError, "can't convert float to int"), "py/obj.c mp_obj_get_int"),
    ("readfrom '1' bytes", lambda m, i: i.readfrom(ADDRESS, "1"),
     (TypeError, "can't convert str to int"), "py/obj.c mp_obj_get_int"),
    ("readfrom True bytes", lambda m, i: len(i.readfrom(ADDRESS, True)), 1,
     "mp_obj_get_int: a bool is an int"),
    ("readfrom 2**31 bytes", lambda m, i: i.readfrom(ADDRESS, 2**31),
     (OverflowError, "overflow converting long int to machine word"), "py/objint_mpz.c"),
    ("readfrom -1 bytes", lambda m, i: i.readfrom(ADDRESS, -1),
     (ValueError, "wraps to 4294967295 bytes"), "py/vstr.c vstr_init_len"),
    ("readfrom 10**6 bytes", lambda m, i: len(i.readfrom(ADDRESS, 10**6)), 10**6,
     "no heap limit unless the board has one (see the heap case)"),
    ("readfrom 0 bytes", lambda m, i: i.readfrom(ADDRESS, 0), b"",
     "ports/esp32/machine_i2c.c: nothing sent for an empty read"),
    ("readfrom an address beyond 7 bits", lambda m, i: i.readfrom(0x168, 1),
     (OSError, errno.ENODEV), "ports/esp32/machine_i2c.c: change_address fails, ENODEV"),
    ("readfrom an address as a float", lambda m, i: i.readfrom(104.0, 1),
     (TypeError, "can't convert float to int"), "mp_obj_get_int(args[1])"),
    ("readfrom a missing device", lambda m, i: i.readfrom(0x50, 1), (OSError, errno.ENODEV),
     "ports/esp32/machine_i2c.c: ESP_FAIL is ENODEV"),
    # buffers through mp_get_buffer_raise
    ("writeto a str", lambda m, i: i.writeto(ADDRESS, "\x0f\x02"), 2,
     "py/objstr.c mp_obj_str_get_buffer: a str reads as its bytes"),
    ("writeto an int", lambda m, i: i.writeto(ADDRESS, 5),
     (TypeError, "object with buffer protocol required"), "py/obj.c mp_get_buffer_raise"),
    ("writeto returns the bytes acknowledged", lambda m, i: i.writeto(ADDRESS, b"\x10\x07"), 2,
     "machine_i2c_writeto: number of acks"),
    ("readfrom_into a str", lambda m, i: i.readfrom_into(ADDRESS, "ab"),
     (TypeError, "object with buffer protocol required"), "mp_obj_str_get_buffer: not writable"),
    ("readfrom_into bytes", lambda m, i: i.readfrom_into(ADDRESS, b"ab"),
     (TypeError, "object with buffer protocol required"), "a read-only buffer"),
    ("writevto a list", lambda m, i: i.writevto(ADDRESS, [b"\x10", b"\x07"]), 2,
     "machine_i2c_writevto"),
    ("writevto bytes", lambda m, i: i.writevto(ADDRESS, b"\x10\x07"),
     (TypeError, "object 'bytes' isn't a tuple or list"), "mp_obj_get_array"),
    ("readfrom_mem_into", lambda m, i: _into(lambda b: i.readfrom_mem_into(ADDRESS, 0, b),
                                             bytearray(1)),
     bytearray(b"\x0f"), "machine_i2c_readfrom_mem_into"),
    # the hardware I2C has no primitive operations (ESP32 protocol: start/stop/read/write NULL)
    ("start", lambda m, i: i.start(), NOT_SUPPORTED, "machine_i2c_start"),
    ("stop", lambda m, i: i.stop(), NOT_SUPPORTED, "machine_i2c_stop"),
    ("readinto", lambda m, i: i.readinto(bytearray(1)), NOT_SUPPORTED, "machine_i2c_readinto"),
    ("write", lambda m, i: i.write(b"\x00"), NOT_SUPPORTED, "machine_i2c_write"),
    ("scan", lambda m, i: i.scan(), [ADDRESS], "machine_i2c_scan: 0x08..0x77"),
    # constructor and module functions
    ("I2C(0) where only I2C(1) is wired", lambda m, i: m.I2C(0),
     (ValueError, ("I2C(0) doesn't exist: the chip is on I2C(1); to reach it as I2C(0), mark "
                   "the test @pytest.mark.bmg160(bus=0)")),
     "machine_hw_i2c_make_new, and where the chip is"),
    ("I2C(1.5)", lambda m, i: m.I2C(1.5), (TypeError, "can't convert float to int"),
     "MP_ARG_INT id"),
    ("I2C(-1, ...) is a SoftI2C", lambda m, i: type(m.I2C(-1, scl=m.Pin(5), sda=m.Pin(4))).__name__,
     "SoftI2C", "MP_MACHINE_I2C_CHECK_FOR_LEGACY_SOFTI2C_CONSTRUCTION"),
    ("SoftI2C without pins", lambda m, i: m.SoftI2C(), (TypeError, "'scl' argument required"),
     "mp_arg_parse_all: MP_ARG_REQUIRED"),
    ("freq()", lambda m, i: m.freq(), 160_000_000, "ESP32 default CPU frequency"),
    ("freq(240 MHz)", lambda m, i: (m.freq(240_000_000), m.freq())[1], 240_000_000,
     "ports/esp32/modmachine.c mp_machine_set_freq"),
    ("freq(100 MHz)", lambda m, i: m.freq(100_000_000),
     (ValueError, "frequency must be 20MHz, 40MHz, 80Mhz, 160MHz or 240MHz"),
     "ports/esp32/modmachine.c mp_machine_set_freq"),
    ("freq with 2 arguments", lambda m, i: m.freq(1, 2), (TypeError, "at most 1 arguments"),
     "MICROPY_PY_MACHINE_FREQ_NUM_ARGS_MAX"),
    ("unique_id", lambda m, i: len(m.unique_id()), 6, "esp_efuse_mac_get_default: 6 bytes"),
    ("idle", lambda m, i: m.idle(), None, "mp_machine_idle: taskYIELD"),
]


@pytest.mark.bmg160(noise=False)
@pytest.mark.parametrize(("name", "call", "expected", "source"), MACHINE_CASES,
                         ids=[c[0] for c in MACHINE_CASES])
def test_machine_answers_as_the_esp32_port(name, call, expected, source, bmg160_machine,
                                           capsys):
    check(answer(lambda: call(bmg160_machine, bmg160_machine.I2C(1))), expected)


def test_i2c_minus_one_warns_as_the_port_does(bmg160_machine, capsys):
    bmg160_machine.I2C(-1, scl=bmg160_machine.Pin(5), sda=bmg160_machine.Pin(4))
    assert "Warning: I2C(-1, ...) is deprecated, use SoftI2C(...) instead" in capsys.readouterr().out


@pytest.mark.bmg160(noise=False)
def test_a_write_without_a_stop_and_the_read_after_it_are_one_transfer(bmg160_machine,
                                                                      bmg160_smbus):
    i2c = bmg160_machine.I2C(1)
    assert i2c.writeto(ADDRESS, b"\x10", False) == 1
    assert i2c.readfrom(ADDRESS, 1) == b"\x80"  # BW after reset
    [entry] = bmg160_smbus.log
    assert (entry.kind, entry.register, entry.read) == ("i2c_read", 0x10, b"\x80")


def test_a_board_heap_makes_a_large_buffer_a_memory_error(bmg160_chip):
    from bmg160_emu.bus.machine import micropython_machine

    with micropython_machine({1: {ADDRESS: bmg160_chip}}, heap_bytes=100_000) as machine:
        i2c = machine.I2C(1)
        with pytest.raises(MemoryError, match="memory allocation failed, allocating 1000001"):
            i2c.readfrom(ADDRESS, 10**6)
        assert len(i2c.readfrom(ADDRESS, 1000)) == 1000


@pytest.mark.bmg160(noise=False)
def test_softi2c_primitives_build_one_register_read(bmg160_machine, bmg160_smbus):
    m = bmg160_machine
    i2c = m.SoftI2C(m.Pin(5), m.Pin(4))
    i2c.start()
    assert i2c.write(bytes([ADDRESS << 1, 0x00])) == 2  # address byte and register acked
    i2c.start()  # repeated start
    assert i2c.write(bytes([ADDRESS << 1 | 1])) == 1
    buf = bytearray(1)
    i2c.readinto(buf)
    i2c.stop()
    assert buf == bytearray(b"\x0f")
    [entry] = bmg160_smbus.log
    assert (entry.kind, entry.register, entry.read) == ("i2c_read", 0x00, b"\x0f")
    i2c.start()
    assert i2c.write(bytes([0x50 << 1, 0x00])) == 0  # nobody acks 0x50: writing stops
    i2c.stop()
    unread = bytearray(2)
    i2c.readinto(unread)  # no start, no address: SDA floats high
    assert unread == bytearray(b"\xff\xff")


@pytest.mark.bmg160(noise=False)
def test_softi2c_sends_the_address_as_one_byte(bmg160_machine):
    m = bmg160_machine
    i2c = m.SoftI2C(m.Pin(5), m.Pin(4))
    # (0x168 << 1) & 0xFF is 0x68 << 1: the bit-banged address byte keeps 7 bits
    assert i2c.readfrom_mem(0x168, 0x00, 1) == b"\x0f"
    with pytest.raises(OSError) as info:  # an empty read still sends the address byte
        i2c.readfrom(0x50, 0)
    assert info.value.errno == errno.ENODEV


def test_time_functions_as_modtime(bmg160_machine, bmg160_virtual_time):
    start = time.ticks_us()
    cycles = time.ticks_cpu()
    time.sleep_ms(-5)  # a negative sleep returns at once
    time.sleep_us(0)
    assert time.ticks_diff(time.ticks_us(), start) == 0
    time.sleep_ms(2)
    assert time.ticks_diff(time.ticks_us(), start) == 2000
    assert time.ticks_diff(time.ticks_cpu(), cycles) == 2000 * 160  # cycles at 160 MHz
    with pytest.raises(TypeError, match="can't convert float to int"):
        time.sleep_ms(1.5)
    with pytest.raises(OverflowError, match="ticks interval overflow"):
        time.ticks_add(0, 2**29)
    assert time.ticks_add(2**30 - 1, 1) == 0 and time.ticks_diff(0, 2**30 - 1) == 1


# (name, call on (board, busio.I2C locked), answer, source)
BUSIO_CASES = [
    ("writeto a str", lambda b, i: i.writeto(ADDRESS, "\x10\x07"), None,
     "mp_get_buffer_raise MP_BUFFER_READ"),
    ("readfrom_into a str", lambda b, i: i.readfrom_into(ADDRESS, "ab"),
     (TypeError, "object with buffer protocol required"), "MP_BUFFER_WRITE"),
    ("readfrom_into an empty buffer", lambda b, i: i.readfrom_into(ADDRESS, bytearray(0)),
     (ValueError, "buffer length must be >= 1"), "py/argcheck.c mp_arg_validate_length_min"),
    ("writeto_then_readfrom into an empty buffer",
     lambda b, i: i.writeto_then_readfrom(ADDRESS, b"\x00", bytearray(0)),
     (ValueError, "out_buffer length must be >= 1"), "shared-bindings/busio/I2C.c (sic)"),
    ("readfrom_into with start beyond the end",
     lambda b, i: i.readfrom_into(ADDRESS, bytearray(2), start=5),
     (ValueError, "buffer length must be >= 1"), "normalize_buffer_bounds: length 0"),
    ("writeto with end=-1", lambda b, i: _into(
        lambda back: (i.writeto(ADDRESS, b"\x10\x07\x05", end=-1),
                      i.writeto_then_readfrom(ADDRESS, b"\x10", back)), bytearray(2)),
     bytearray(b"\x87\x00"), "normalize_buffer_bounds: end from the end; LPM1 untouched"),
    ("start counts elements of an array('H')",
     lambda b, i: _into(lambda a: i.writeto_then_readfrom(ADDRESS, b"\x0f", a, in_start=1),
                        array.array("H", [0xAAAA, 0xAAAA, 0xAAAA])).tolist(),
     [0xAAAA, 0x8000, 0x0000],
     "mp_binary_get_size stride"),
    ("a slice outside the buffer", lambda b, i: i.readfrom_into(ADDRESS, bytearray(6), start=-10),
     (ValueError, "reach outside it"), "normalize_buffer_bounds: start not clipped"),
    ("an address as a float", lambda b, i: i.writeto(104.0, b"\x00"),
     (TypeError, "can't convert float to int"), "MP_ARG_INT address"),
    ("an address beyond 7 bits", lambda b, i: i.writeto(0x168, b"\x00"),
     (OSError, errno.ENODEV), "not acknowledged"),
    ("a missing device", lambda b, i: i.writeto(0x50, b"\x00"), (OSError, errno.ENODEV),
     "ports/raspberrypi/common-hal/busio/I2C.c: PICO_ERROR_GENERIC is ENODEV"),
    ("probe", lambda b, i: (i.probe(ADDRESS), i.probe(0x50)), (True, False), "busio_i2c_probe"),
    ("scan", lambda b, i: i.scan(), [ADDRESS], "busio_i2c_scan: 0x08..0x77"),
    ("pins of the wrong type", lambda b, i: __import__("busio").I2C(5, 6),
     (TypeError, "scl must be of type Pin, not int"), "validate_obj_is_pin"),
    ("a pin in use", lambda b, i: __import__("busio").I2C(b.SCL, b.SDA), (ValueError, "SCL in use"),
     "assert_pin_free: %q in use"),
    ("frequency", lambda b, i: i.frequency, 100000, "busio_i2c_make_new default"),
]


@pytest.mark.bmg160(noise=False)
@pytest.mark.parametrize(("name", "call", "expected", "source"), BUSIO_CASES,
                         ids=[c[0] for c in BUSIO_CASES])
def test_busio_answers_as_circuitpython(name, call, expected, source, bmg160_circuitpython):
    import busio

    i2c = busio.I2C(bmg160_circuitpython.SCL, bmg160_circuitpython.SDA)
    assert i2c.try_lock()
    check(answer(lambda: call(bmg160_circuitpython, i2c)), expected)


def test_busio_needs_its_lock_and_refuses_use_after_deinit(bmg160_circuitpython):
    import busio

    i2c = busio.I2C(bmg160_circuitpython.SCL, bmg160_circuitpython.SDA)
    with pytest.raises(RuntimeError, match="Function requires lock"):
        i2c.writeto(ADDRESS, b"\x00")
    i2c.deinit()
    with pytest.raises(ValueError, match="Object has been deinitialized and can no longer be "
                                         "used. Create a new object."):
        i2c.try_lock()
