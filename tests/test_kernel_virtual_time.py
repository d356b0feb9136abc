"""Virtual time (UML time travel driven by the chips' clock): the same seed and the same guest
command give the same values, bit for bit, on a quiet host and on one with CPU hogs beside
the guest; against wall time (``--real-time``) they do not.

Each run is ``bmg160-emu kernel run`` (a fresh guest): the kernel's bmg160 driver bound with
its data-ready interrupt, 100 records of its triggered buffer (values and the driver's time
stamps) and five raw reads 13 ms apart, printed.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import bmg160_emu

pytestmark = pytest.mark.kernel

REPO = Path(bmg160_emu.__file__).resolve().parents[1]
RECORDS = 100
COMMAND = f"""
d=$IIO
for e in $d/scan_elements/*_en; do echo 1 > $e; done
grep -l -- "-dev${{d##*iio:device}}$" /sys/bus/iio/devices/trigger*/name | head -n 1 \\
    | xargs cat > $d/trigger/current_trigger
echo monotonic > $d/current_timestamp_clock
echo 1 > $d/buffer/enable
head -c {16 * RECORDS} /dev/iio:device${{d##*iio:device}} | od -An -tx1 -v
echo 0 > $d/buffer/enable
for i in 1 2 3 4 5; do sleep 0.013; cat $d/in_anglvel_x_raw; done
"""


def _ready() -> None:
    from bmg160_emu.linux.guest.engine import EngineError, choose

    try:
        engine = choose(os.environ.get("BMG160_KERNEL_ENGINE"))
    except EngineError as exc:
        pytest.skip(str(exc))
    if not getattr(engine, "time_travel", False):
        pytest.skip(f"the {engine.name} engine has no virtual time")


def kernel_run(*words: str) -> str:
    result = subprocess.run(
        [sys.executable, "-m", "bmg160_emu", "kernel", "run", "--seed", "7", "--true-rate",
         "20", "-10", "5", *words, "--", COMMAND], capture_output=True, text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)}, timeout=600, check=False)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.split("\n")
    assert len("".join(lines[:-6]).split()) == 16 * RECORDS, result.stdout[-500:]
    return result.stdout


def test_the_same_seed_gives_the_same_values_on_a_busy_host():
    _ready()
    quiet = kernel_run()
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        busy = kernel_run()
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
    assert busy == quiet


def test_against_wall_time_the_values_differ():
    """What makes the check above able to fail: the driver's time stamps and the samples it
    reads follow the host's speed in real time (paced, but not repeatable)."""
    _ready()
    assert kernel_run("--real-time") != kernel_run("--real-time")
