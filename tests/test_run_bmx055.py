"""A 6-axis BMX055 under `bmg160-emu run`: the gyro part and the accelerometer and
magnetometer stand-ins on one virtual /dev/i2c-N, read by the real i2c-tools (umockdev)."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from bmg160_emu.device.parts import PART_NAMES

pytestmark = pytest.mark.umockdev


def _umockdev_missing() -> str | None:
    try:
        from bmg160_emu.linux.umockdev import UMockdevUnavailable, load_umockdev, preload_available

        load_umockdev()
    except UMockdevUnavailable as exc:
        return str(exc)
    if not preload_available():
        return "umockdev's preload library is missing (apt-get install libumockdev0)"
    if shutil.which("i2cdetect") is None or shutil.which("i2cget") is None:
        return "i2c-tools is missing (apt-get install i2c-tools)"
    return None


_MISSING = _umockdev_missing()
if _MISSING:
    pytest.skip(f"umockdev route unavailable: {_MISSING}", allow_module_level=True)

# What each step prints goes into one file per step, read back after the session.
SESSION = """\
set -u
cd "$1"
i2cdetect -y {bus} > detect.txt 2>&1
i2cget -y {bus} 0x68 0x00 > gyro_id.txt 2>&1
i2cget -y {bus} 0x18 0x00 > accel_id.txt 2>&1
i2cget -y {bus} 0x10 0x40 > mag_id_suspended.txt 2>&1
i2cset -y {bus} 0x10 0x4b 0x01
i2cget -y {bus} 0x10 0x40 > mag_id.txt 2>&1
i2cset -y {bus} 0x18 0x0f 0x05
i2cget -y {bus} 0x18 0x0f > accel_range.txt 2>&1
"""


def run_session(tmp_path, devices: list[str], bus: int) -> None:
    script = tmp_path / "session.sh"
    script.write_text(SESSION.format(bus=bus))
    argv = [sys.executable, "-m", "bmg160_emu", "run", "--bus", str(bus), "--seed", "5"]
    for device in devices:
        argv += ["--device", device]
    done = subprocess.run([*argv, "--", "sh", str(script), str(tmp_path)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr


def detected(path) -> set[int]:
    """The addresses an i2cdetect table shows as present."""
    found = set()
    for row in path.read_text().splitlines()[1:]:
        base = int(row[:2], 16)
        cells = row[4:].split()
        first = 3 if base == 0 else 0  # the 00 row starts at 0x03
        for i, cell in enumerate(cells):
            if cell not in ("--", "UU"):
                assert int(cell, 16) == base + first + i
                found.add(base + first + i)
    return found


def test_i2c_tools_see_the_three_chips_of_a_bmx055(tmp_path):
    assert "bmx055_gyro" in PART_NAMES
    run_session(tmp_path, ["bmx055_gyro@0x68", "bma2x2_accel@0x18", "bmm150@0x10"], bus=1)
    assert detected(tmp_path / "detect.txt") == {0x10, 0x18, 0x68}
    assert (tmp_path / "gyro_id.txt").read_text().strip() == "0x0f"
    assert (tmp_path / "accel_id.txt").read_text().strip() == "0xfa"
    # BMM150: the chip ID reads 0x00 until the power control bit is set (data sheet 5.3)
    assert (tmp_path / "mag_id_suspended.txt").read_text().strip() == "0x00"
    assert (tmp_path / "mag_id.txt").read_text().strip() == "0x32"
    assert (tmp_path / "accel_range.txt").read_text().strip() == "0x05"


def test_devices_on_two_buses_each_get_their_own_dev_i2c(tmp_path):
    # a BMG160 on bus 3 and the companions on bus 4: two /dev/i2c-N in one session
    script = tmp_path / "buses.sh"
    script.write_text('set -u\ncd "$1"\ni2cdetect -y 3 > three.txt 2>&1\n'
                      'i2cdetect -y 4 > four.txt 2>&1\ni2cget -y 4 0x19 0x00 > accel.txt\n')
    done = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "run", "--bus", "3", "--seed", "5",
         "--device", "bmg160@0x69", "--device", "bmi088_accel@0x19:4",
         "--device", "bmm150@0x12:4", "--", "sh", str(script), str(tmp_path)],
        capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert detected(tmp_path / "three.txt") == {0x69}
    assert detected(tmp_path / "four.txt") == {0x12, 0x19}
    assert (tmp_path / "accel.txt").read_text().strip() == "0x1e"
