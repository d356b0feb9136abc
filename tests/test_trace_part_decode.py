"""`trace` decodes each device with its own register table: a BMI088 gyroscope's registers by
the BMI088's names and fields, and a stand-in's pointer sets by the stand-in's names.

A BMI088 gyroscope's 0x16 is INT3_INT4_IO_CONF (the BMG160's INT_EN_1 at that address),
its LPM1 has no sleep_dur field and its FIFO_CONFIG_0 no tag bit (docs/parts.md); a
BMI088 accelerometer stand-in's 0x7C is ACC_PWR_CONF, named so whether it is written or
only pointed at (an SMBus send byte sets the pointer a following receive byte reads).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.device.config import ChipConfig
from bmg160_emu.device.standin import StandinConfig
from bmg160_emu.io.standin_file import load_standin
from bmg160_emu.io.trace import TraceHeader, TraceWriter
from bmg160_emu.session.decode import describe_transaction

REPO = Path(__file__).resolve().parents[1]


def _session(path: Path) -> None:
    gyro = ChipConfig(address=0x69, part="bmi088_gyro", noise=False)
    accel = StandinConfig(load_standin("bmi088_accel"), 0x19)
    header = TraceHeader(1)
    for config in (gyro, accel):
        header.add_config(config)
    bus = I2CBus(1, {0x69: gyro.build(seed=1), 0x19: accel.build()})
    with TraceWriter(path, header) as trace:
        bus.log.sinks.append(trace)
        bus.write_byte_data(0x69, 0x16, 0x05)  # INT3_INT4_IO_CONF
        bus.read_byte_data(0x69, 0x11)  # GYRO_LPM1, 0x00
        bus.write_byte_data(0x69, 0x3D, 0x88)  # FIFO_CONFIG_0
        bus.write_byte(0x19, 0x7C)  # the accelerometer's pointer to ACC_PWR_CONF
        bus.read_byte(0x19)
        bus.write_byte_data(0x19, 0x7C, 0x00)


def test_a_bmi088_session_is_told_in_the_parts_own_words(tmp_path):
    path = tmp_path / "bmi088.jsonl"
    _session(path)
    shown = subprocess.run([sys.executable, "-m", "bmg160_emu", "trace", str(path)],
                           capture_output=True, text=True, check=False,
                           env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert shown.returncode == 0, shown.stderr
    lines = shown.stdout.splitlines()
    assert "write 0x16 INT3_INT4_IO_CONF <- 0x05" in lines[0] and "INT_EN_1" not in lines[0]
    assert lines[1].split("  [")[0].endswith("read 0x11 GYRO_LPM1 -> 0x00")  # no sleep_dur
    assert "FIFO_CONFIG_0 <- 0x88" in lines[2] and "tag" not in lines[2]
    assert "set pointer 0x7C ACC_PWR_CONF" in lines[3]
    assert "write 0x7C ACC_PWR_CONF <- 0x00" in lines[5]


def test_without_the_part_the_same_bytes_read_as_a_bmg160():
    # what the command printed before it knew the part: the BMG160's names and fields
    record = {"time": 0.0, "bus": 1, "address": 0x69, "kind": "read_byte_data",
              "register": 0x11, "read": [0x00]}
    assert "LPM1 -> 0x00 (sleep_dur" in describe_transaction(record)
