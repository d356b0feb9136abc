"""One gyro driver routine written once per Python I2C stack: probe, configure, read rates.

Each ``<stack>_session(bus_number)`` does what a driver of that stack does on a BMG160 at
0x68 (CHIP_ID, soft reset and the start-up wait, RANGE and BW written and read back, a few
rate bursts at the output data rate) with the stack's own calls, and returns what it saw.
The same functions run in process (tests/test_stacks_in_process.py, under patch_i2c_dev)
and as a program under ``bmg160-emu run`` (umockdev), where this file is the program:

    python tests/_stack_drivers.py smbus3 1     # prints the session as JSON

Registers and values: spec 4.1 (CHIP_ID 0x0F), 4.8 (RANGE: 0x01 = +-1000 deg/s), 4.9 (BW:
0x07 = ODR 100 Hz, 32 Hz filter), 4.12 (BGW_SOFTRESET 0xB6), 6.6 (30 ms start-up).
"""

from __future__ import annotations

import contextlib
import json
import os
import struct
import sys
import time
from collections.abc import Callable, Iterator

ADDRESS = 0x68
CHIP_ID, RATE_X_LSB, RANGE, BW, BGW_SOFTRESET = 0x00, 0x02, 0x0F, 0x10, 0x14
RANGE_1000, BW_32HZ, SOFTRESET = 0x01, 0x07, 0xB6
FULL_SCALE_DPS = 1000.0
STARTUP_S, SETTLE_S, PERIOD_S = 0.030, 0.25, 0.010  # 100 Hz ODR at BW 7
READS = 8

# platformdetect's own overrides (Adafruit_PlatformDetect board.py and chip.py read them
# first): a Raspberry Pi 4B, whose board module maps SCL/SDA to /dev/i2c-1. Blinka then
# asks for the Pi's pin library, gpiod, at import; BLINKA_SKIP_DEPENDENCY_CHECK keeps it
# from offering to pip-install the Pi's other extras.
BLINKA_ENVIRONMENT = {"BLINKA_FORCECHIP": "BCM2XXX", "BLINKA_FORCEBOARD": "RASPBERRY_PI_4B",
                      "BLINKA_SKIP_DEPENDENCY_CHECK": "1"}
_BLINKA_MODULES = ("board", "busio", "digitalio", "microcontroller", "adafruit_blinka",
                   "adafruit_platformdetect", "adafruit_bus_device", "micropython")


def _counts(raw: bytes | bytearray | list[int]) -> list[int]:
    return list(struct.unpack("<3h", bytes(raw)))


def _session(write: Callable[[int, int], None], read: Callable[[int, int], bytes]) -> dict:
    """The routine every stack runs, given its register write and burst read."""
    chip_id = read(CHIP_ID, 1)[0]
    write(BGW_SOFTRESET, SOFTRESET)
    time.sleep(STARTUP_S)
    write(RANGE, RANGE_1000)
    write(BW, BW_32HZ)
    configured = [read(RANGE, 1)[0], read(BW, 1)[0]]
    time.sleep(SETTLE_S)  # the 32 Hz filter settles on the true rate
    rates = []
    for _ in range(READS):
        time.sleep(PERIOD_S)
        rates.append([c * FULL_SCALE_DPS / 32768 for c in _counts(read(RATE_X_LSB, 6))])
    return {"chip_id": chip_id, "configured": configured, "rates_dps": rates}


def smbus2_session(bus_number: int) -> dict:
    import smbus2

    with smbus2.SMBus(bus_number) as bus:
        return _session(lambda r, v: bus.write_byte_data(ADDRESS, r, v),
                        lambda r, n: bytes(bus.read_i2c_block_data(ADDRESS, r, n)))


def smbus3_session(bus_number: int) -> dict:
    import smbus3

    with smbus3.SMBus(bus_number) as bus:
        return _session(lambda r, v: bus.write_byte_data(ADDRESS, r, v),
                        lambda r, n: bytes(bus.read_i2c_block_data(ADDRESS, r, n)))


def pureio_session(bus_number: int) -> dict:
    from Adafruit_PureIO.smbus import SMBus

    with SMBus(bus_number) as bus:  # plain read()/write() on the node, and I2C_RDWR
        return _session(lambda r, v: bus.write_byte_data(ADDRESS, r, v),
                        lambda r, n: bytes(bus.read_i2c_block_data(ADDRESS, r, n)))


def periphery_session(bus_number: int) -> dict:
    from periphery import I2C

    i2c = I2C(f"/dev/i2c-{bus_number}")

    def write(register: int, value: int) -> None:
        i2c.transfer(ADDRESS, [I2C.Message([register, value])])

    def read(register: int, count: int) -> bytes:
        messages = [I2C.Message([register]), I2C.Message(bytearray(count), read=True)]
        i2c.transfer(ADDRESS, messages)
        return bytes(messages[1].data)

    try:
        return _session(write, read)
    finally:
        i2c.close()


def fcntl_session(bus_number: int) -> dict:
    """Hand-written os/fcntl code: I2C_SLAVE, then write() and read() on the descriptor."""
    import fcntl

    fd = os.open(f"/dev/i2c-{bus_number}", os.O_RDWR)
    try:
        fcntl.ioctl(fd, 0x0703, ADDRESS)  # I2C_SLAVE

        def read(register: int, count: int) -> bytes:
            os.write(fd, bytes([register]))
            return os.read(fd, count)

        return _session(lambda r, v: os.write(fd, bytes([r, v])) and None, read)
    finally:
        os.close(fd)


@contextlib.contextmanager
def blinka_environment() -> Iterator[None]:
    """Blinka imported afresh on the forced board, and forgotten after (its board detection
    runs once, at import)."""
    saved_env = {k: os.environ.get(k) for k in BLINKA_ENVIRONMENT}
    saved_modules = {name: module for name, module in sys.modules.items()
                     if name.split(".")[0] in _BLINKA_MODULES}
    for name in saved_modules:
        del sys.modules[name]
    os.environ.update(BLINKA_ENVIRONMENT)
    try:
        yield
    finally:
        for name in [n for n in sys.modules if n.split(".")[0] in _BLINKA_MODULES]:
            del sys.modules[name]
        sys.modules.update(saved_modules)
        for key, value in saved_env.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


def blinka_session(bus_number: int) -> dict:
    """Blinka's busio.I2C on board.SCL/SDA (/dev/i2c-1 on the forced board), by hand."""
    with blinka_environment():
        import board
        import busio

        i2c = busio.I2C(board.SCL, board.SDA)
        while not i2c.try_lock():
            pass

        def read(register: int, count: int) -> bytes:
            data = bytearray(count)
            i2c.writeto_then_readfrom(ADDRESS, bytes([register]), data)
            return bytes(data)

        try:
            return _session(lambda r, v: i2c.writeto(ADDRESS, bytes([r, v])), read)
        finally:
            i2c.unlock()
            i2c.deinit()


def busdevice_session(bus_number: int) -> dict:
    """adafruit_bus_device's I2CDevice over Blinka's busio, as CircuitPython drivers use it."""
    with blinka_environment():
        import board
        from adafruit_bus_device.i2c_device import I2CDevice

        device = I2CDevice(board.I2C(), ADDRESS)

        def write(register: int, value: int) -> None:
            with device as i2c:
                i2c.write(bytes([register, value]))

        def read(register: int, count: int) -> bytes:
            data = bytearray(count)
            with device as i2c:
                i2c.write_then_readinto(bytes([register]), data)
            return bytes(data)

        return _session(write, read)


SESSIONS: dict[str, Callable[[int], dict]] = {
    "smbus2": smbus2_session, "smbus3": smbus3_session, "pureio": pureio_session,
    "blinka": blinka_session, "busdevice": busdevice_session,
    "periphery": periphery_session, "fcntl": fcntl_session,
}

if __name__ == "__main__":
    print(json.dumps(SESSIONS[sys.argv[1]](int(sys.argv[2]))))
