"""Benchmark: one guest boot per engine (uml, and qemu for reference, same run) against the
vhost-user back end (`bmg160-emu vhost-user-i2c`, two chips, INT lines on virtio-gpio).

Each boot runs one guest script that prints marker lines on the console; the host stamps
each marker as it arrives (host clock, from the engine's start with the back end already
listening):

- ``init``: the script starts (virtio-i2c and -gpio up, i2c-virtio loaded);
- ``chipid``: ``i2cget`` of CHIP_ID (0x0F) on 0x68 through the model;
- ``first``: the kernel's bmg160 driver bound (bmg160-board gives it its IRQ) and its first
  ``in_anglvel_x_raw`` read: "boot to the driver's first read";
- ``loop``: 6-byte register reads from a C program through /dev/i2c-N (reads/s, p50, p99);
- ``capture``: the driver's data-ready trigger at 100 Hz feeding a triggered buffer for
  CAPTURE seconds: records read and the GPIO interrupt count (interrupts working).

Prints one row per engine and the uml/qemu ratios.

    python tools/bench_uml.py [--engines uml,qemu] [--reads 20000] [--capture 2]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bmg160_emu.linux.guest.engine import Boot, EngineError, choose

READ_LOOP_SOURCE = REPO / "tests" / "kernel_guest" / "i2c_read_loop.c"
CAPTURE_SOURCE = REPO / "tests" / "kernel_guest" / "guest_iio_capture.py"

SCRIPT = r"""
set -u
B=$GUEST_I2C_BUS
echo "MARK init bus=$B gpio=$GUEST_GPIO_BASE"
echo "MARK chipid $(i2cget -y "$B" 0x68 0x00)"
modprobe -d "$GUEST_ROOT" bmg160_i2c || echo "modprobe bmg160_i2c failed"
insmod "$BOARD" bus="$B" gpio_base="$GUEST_GPIO_BASE" addr=0x68 line=0 || echo "board failed"
for i in $(seq 200); do
    D=$(ls -d /sys/bus/iio/devices/iio:device* 2>/dev/null | head -1)
    [ -n "$D" ] && break; sleep 0.01
done
echo "MARK first $(cat "$D/in_anglvel_x_raw")"
echo "MARK loop $("$READ_LOOP" "$B" 0x68 0x02 6 "$READS")"
kw() { sh -c 'echo "$1" > "$2"' kw "$1" "$2"; }
kw 100 "$D/in_anglvel_sampling_frequency"
for e in "$D"/scan_elements/*_en; do echo 1 > "$e"; done
cat /sys/bus/iio/devices/trigger*/name | head -1 > "$D/trigger/current_trigger"
echo 4096 > "$D/buffer/length"; echo 32 > "$D/buffer/watermark"
before=$(grep -i gpio /proc/interrupts | awk '{print $2}')
kw 1 "$D/buffer/enable"
"$PY" "$CAPTURE" "$CAPTURE_S" "/dev/${D##*/}" "$BMG160_RESULTS/capture.bin"
kw 0 "$D/buffer/enable"
after=$(grep -i gpio /proc/interrupts | awk '{print $2}')
echo "MARK capture bytes=$(stat -c %s "$BMG160_RESULTS/capture.bin") irqs=$((after - before))"
"""


def run_engine(name: str, reads: int, capture_s: float, work: Path) -> dict[str, float]:
    engine = choose(name)
    board = getattr(engine, "board_module", None)
    if board is None:
        raise EngineError(f"engine {name} does not say where its bmg160-board.ko is")
    loop = work / "i2c_read_loop"
    if not loop.exists():
        subprocess.run(["gcc", "-O2", "-o", str(loop), str(READ_LOOP_SOURCE)], check=True)
    results = work / f"results-{name}"
    results.mkdir()
    script = work / f"script-{name}.sh"
    script.write_text(SCRIPT)
    i2c, gpio, ready = work / f"{name}-i2c.sock", work / f"{name}-gpio.sock", work / f"{name}.ready"
    backend = subprocess.Popen(
        [sys.executable, "-m", "bmg160_emu", "vhost-user-i2c", "--socket", str(i2c),
         "--gpio-socket", str(gpio), "--ready-file", str(ready), "--address", "0x68",
         "--seed", "1"],
        env=dict(os.environ, PYTHONPATH=str(REPO)))
    while not ready.exists():
        if backend.poll() is not None:
            raise RuntimeError("the back end ended before it listened")
        time.sleep(0.01)
    env = {"BOARD": str(board()), "READ_LOOP": str(loop), "READS": str(reads),
           "PY": sys.executable, "CAPTURE": str(CAPTURE_SOURCE), "CAPTURE_S": str(capture_s)}
    start = time.monotonic()
    guest = engine.start(Boot(script=script, results=results, i2c_socket=i2c,
                              gpio_socket=gpio, environment=env))
    row: dict[str, float] = {}
    assert guest.stdout is not None
    console = []
    for raw in guest.stdout:
        line = raw.decode(errors="replace").rstrip()
        console.append(line)
        match = re.search(r"MARK (\w+) ?(.*)", line)
        if match is None:
            continue
        key, rest = match.groups()
        row[f"{key}_s"] = time.monotonic() - start
        for word, value in re.findall(r"(\w+)=([-\d.]+)", rest):
            row[f"{key}_{word}"] = float(value)
        if key == "chipid":
            row["chip_id"] = int(rest.split()[0], 16)
    guest.wait()
    row["total_s"] = time.monotonic() - start
    backend.terminate()
    backend.wait()
    Path(f"/tmp/bench-uml-{name}.console").write_text("\n".join(console) + "\n")
    if "capture_bytes" not in row:
        sys.stderr.write("\n".join(console[-40:]) + "\n")
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", default="uml,qemu")
    parser.add_argument("--reads", type=int, default=20000)
    parser.add_argument("--capture", type=float, default=2.0, help="seconds of capture")
    args = parser.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory(prefix="bench-uml-") as tmp:
        for name in args.engines.split(","):
            rows[name] = run_engine(name, args.reads, args.capture, Path(tmp))
    keys = ["init_s", "chipid_s", "first_s", "loop_per_s", "loop_p50_us", "loop_p99_us",
            "capture_bytes", "capture_irqs", "total_s"]
    print(f"{'':14}" + "".join(f"{name:>12}" for name in rows))
    for key in keys:
        print(f"{key:14}" + "".join(f"{row.get(key, float('nan')):12.3f}"
                                    for row in rows.values()))
    if "uml" in rows and "qemu" in rows:
        for key in ("init_s", "first_s", "loop_per_s", "total_s"):
            u, q = rows["uml"].get(key), rows["qemu"].get(key)
            if u and q:
                print(f"uml/qemu {key}: {u / q:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
