"""`trace` tells a stand-in's traffic with the stand-in's own register names.

A BMA2x2 accelerometer's 0x0F is PMU_RANGE, not the BMG160's RANGE: decoding it with the
gyro's table would print a wrong name and a wrong field meaning."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bmg160_emu", *args], check=False, cwd=cwd,
                          text=True,
                          capture_output=True, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})


def test_stand_in_reads_and_writes_use_its_names(tmp_path):
    (tmp_path / "s.script").write_text(
        "chip 0x18\nread 0x00 == 0xFA\nwrite 0x0F 0x05\nburst 0x00 3\nchip 0x68\nread CHIP_ID\n")
    made = _cli("script", "s.script", "--device", "bmg160@0x68", "--device", "bma2x2_accel@0x18",
                "--seed", "1", "--trace", "t.jsonl", "-q", cwd=tmp_path)
    assert made.returncode == 0, made.stderr
    shown = _cli("trace", "t.jsonl", cwd=tmp_path)
    assert shown.returncode == 0, shown.stderr
    lines = shown.stdout.splitlines()
    assert "0x18" in lines[0] and "read 0x00 BGW_CHIPID -> 0xfa" in lines[0]
    assert "write 0x0F PMU_RANGE <- 0x05" in lines[1] and "RANGE (" not in lines[1]
    assert "BGW_CHIPID=0xfa, 0x01 RESERVED=0x00, 0x02 ACCD_X_LSB=0x00" in lines[2]
    # the gyro at 0x68 keeps the BMG160's names and field text
    assert "0x68" in lines[3] and "CHIP_ID -> 0x0f" in lines[3]
