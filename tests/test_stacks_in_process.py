"""Every pure-Python I2C stack reaches the emulated chip in process (patch_i2c_dev), and the
same test runs unchanged on the umockdev route (`bmg160-emu run`).

The driver routine of each stack is tests/_stack_drivers.py (probe, soft reset, RANGE and
BW written and read back, rate bursts at the output data rate). The ``route`` fixture runs
it in process (virtual time, the chip at the true rate below) or as a program under
``bmg160-emu run`` (real time, the same seed and true rate); the assertions are one body.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from _stack_drivers import BLINKA_ENVIRONMENT, SESSIONS

from bmg160_emu.bus.i2c_dev_node import patch_i2c_dev
from bmg160_emu.clock import virtual_sleep
from bmg160_emu.device.chip import BMG160

TRUE_RATE_DPS = (20.0, -10.0, 5.0)
SEED = 3
# At BW 7 (32 Hz) the model's noise is ~0.2 deg/s rms and its bias ~0.1 deg/s per axis
# (docs/pytest-plugin.md, the noise table), so 1.5 deg/s is more than 5 sigma for one sample:
# a fixed seed makes the outcome repeatable, the margin keeps it so on a noise-model change.
TOLERANCE_DPS = 1.5
DRIVERS = Path(__file__).with_name("_stack_drivers.py")

pytest_plugins = ["pytester"]


def _umockdev_missing() -> str | None:
    try:
        from bmg160_emu.linux.umockdev import UMockdevUnavailable, load_umockdev, preload_available

        load_umockdev()
    except UMockdevUnavailable as exc:
        return str(exc)
    return None if preload_available() else "umockdev's preload library is missing"


def in_process(stack: str) -> dict:
    chip = BMG160(seed=SEED, true_rate=TRUE_RATE_DPS)
    with patch_i2c_dev({1: {0x68: chip}}) as buses, virtual_sleep(chip):
        session = SESSIONS[stack](1)
    session["transactions"] = len(buses[1].log)
    return session


def on_umockdev(stack: str) -> dict:
    missing = _umockdev_missing()
    if missing:
        pytest.skip(f"umockdev route unavailable: {missing}")
    env = {**os.environ, **BLINKA_ENVIRONMENT}
    result = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "run", "--seed", str(SEED), "--true-rate",
         *map(str, TRUE_RATE_DPS), "--", sys.executable, str(DRIVERS), stack, "1"],
        capture_output=True, text=True, timeout=180, check=False, env=env)
    assert result.returncode == 0, result.stderr
    session = json.loads(result.stdout.strip().splitlines()[-1])
    session["transactions"] = None  # counted in the emulator's process
    return session


@pytest.fixture(params=["in_process", pytest.param("umockdev", marks=pytest.mark.umockdev)])
def route(request):
    return in_process if request.param == "in_process" else on_umockdev


@pytest.mark.parametrize("stack", sorted(SESSIONS))
def test_a_driver_on_each_stack_probes_configures_and_reads_the_true_rate(route, stack):
    session = route(stack)
    assert session["chip_id"] == 0x0F
    assert session["configured"] == [0x01, 0x87]  # RANGE +-1000 deg/s; BW 32 Hz, bit 7 reads 1
    assert len(session["rates_dps"]) == 8
    for rates in session["rates_dps"]:
        for measured, true in zip(rates, TRUE_RATE_DPS):
            assert abs(measured - true) < TOLERANCE_DPS, session["rates_dps"]
    assert session["transactions"] is None or session["transactions"] >= 13  # it reached the chip


def test_the_emulated_node_is_the_only_path_the_patch_touches(tmp_path):
    chip = BMG160(seed=1)
    plain = tmp_path / "plain.bin"
    with patch_i2c_dev({1: {0x68: chip}}) as buses:
        fd = os.open(plain, os.O_RDWR | os.O_CREAT)
        assert os.write(fd, b"abc") == 3
        os.lseek(fd, 0, os.SEEK_SET)
        assert os.read(fd, 3) == b"abc"
        os.close(fd)
        with open(plain, "rb") as handle:
            assert handle.read() == b"abc"
        with pytest.raises(FileNotFoundError):
            os.open("/dev/i2c-97", os.O_RDWR)  # a bus number nobody emulates
    assert len(buses[1].log) == 0


def test_plain_read_and_write_on_the_descriptor_are_i2c_transfers():
    import fcntl

    chip = BMG160(seed=1)
    with patch_i2c_dev({1: {0x68: chip}}) as buses:
        fd = os.open("/dev/i2c-1", os.O_RDWR)
        fcntl.ioctl(fd, 0x0703, 0x68)  # I2C_SLAVE
        assert os.write(fd, bytes([0x00])) == 1
        assert os.read(fd, 1) == b"\x0f"
        os.close(fd)
        read_only = os.open("/dev/i2c-1", os.O_RDONLY)
        with pytest.raises(OSError) as info:
            os.write(read_only, b"\x00")  # the open file's access mode, as the VFS checks it
        assert info.value.errno == 9  # EBADF
        os.close(read_only)
    assert buses[1].log.kinds() == ["i2c_write", "i2c_read"]


def test_open_builds_file_objects_as_io_open_does_on_a_character_device():
    import io

    chip = BMG160(seed=1)
    with patch_i2c_dev({1: {0x68: chip}}):
        with open("/dev/i2c-1", "r+b", buffering=0) as raw:
            assert isinstance(raw, io.RawIOBase) and not raw.seekable()
        with pytest.raises(io.UnsupportedOperation):  # r+b buffered needs seek: not seekable
            open("/dev/i2c-1", "r+b")  # noqa: SIM115 - it raises
        with open("/dev/i2c-1", "rb") as reader:
            assert isinstance(reader, io.BufferedReader)
        with pytest.raises(ValueError, match="can't have unbuffered text I/O"):
            open("/dev/i2c-1", "r", buffering=0)  # noqa: SIM115 - it raises


def test_threads_see_one_bus_and_one_numbering_of_transactions():
    import threading

    import smbus2

    chip = BMG160(seed=1)
    with patch_i2c_dev({1: {0x68: chip}}) as buses:
        def worker():
            with smbus2.SMBus(1) as bus:
                for _ in range(50):
                    assert bus.read_byte_data(0x68, 0x00) == 0x0F

        threads = [threading.Thread(target=worker) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    assert len(buses[1].log) == 200
    assert next(buses[1].indices) == 200


def test_nothing_stays_patched_after_a_failing_test(pytester):
    pytester.makepyfile("""
        import fcntl, os
        import smbus3.smbus3 as impl

        REAL = (os.open, fcntl.ioctl, impl.ioctl, open)

        def test_fails(bmg160_i2c_dev):
            assert os.open is not REAL[0]
            assert impl.ioctl is not REAL[2]
            assert False

        def test_after():
            assert (os.open, fcntl.ioctl, impl.ioctl, open) == REAL
    """)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)


def test_a_module_imported_during_the_patch_is_restored_too(tmp_path, monkeypatch):
    import fcntl

    (tmp_path / "late_driver.py").write_text("from fcntl import ioctl\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    real = fcntl.ioctl
    with patch_i2c_dev({1: {0x68: BMG160(seed=1)}}):
        import late_driver

        assert late_driver.ioctl is not real  # bound to the replacement
    assert late_driver.ioctl is real  # and to the real call again after the patch
    sys.modules.pop("late_driver", None)
