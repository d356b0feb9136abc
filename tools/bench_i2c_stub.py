"""Benchmark: the i2c-stub adapter's refresh period, jitter and CPU use in the QEMU guest.

Boots the guest (bmg160_emu.linux.guest, QEMU), loads i2c-stub and i2c-dev, and runs
``bmg160-emu stub`` at ODR 200 Hz (BW code 4) for --seconds, first alone, then with the
kernel's bmg160 driver bound and a reader polling in_anglvel_x_raw. The adapter reports its
refresh start times; the target period (1 / ODR) is the reference, so each line prints the
measured mean period as a ratio to it. Guest CPU is QEMU's software emulation: figures are
for that guest, not for hardware.

    python tools/bench_i2c_stub.py [--seconds 15]
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

GUEST_SCRIPT = """\
set -u
cd /run
modprobe -d "$GUEST_ROOT" i2c-stub chip_addr=0x68
modprobe -d "$GUEST_ROOT" i2c-dev
"$PY" -m bmg160_emu stub --bus 0 --bandwidth 4 --seed 1 --duration "$SECONDS_" \\
    --stats "$GUEST_OUT/alone.json" 2> "$GUEST_OUT/alone.log"
"$PY" -m bmg160_emu stub --bus 0 --bandwidth 4 --seed 1 --duration "$SECONDS_" \\
    --ready-file /run/ready --stats "$GUEST_OUT/driver.json" 2> "$GUEST_OUT/driver.log" &
STUB=$!
while [ ! -e /run/ready ] && kill -0 $STUB 2>/dev/null; do sleep 0.1; done
modprobe -d "$GUEST_ROOT" bmg160_i2c
echo bmg160 0x68 > /sys/bus/i2c/devices/i2c-0/new_device
sleep 0.5
echo 200 > /sys/bus/iio/devices/iio:device0/in_anglvel_sampling_frequency
n=0
while kill -0 $STUB 2>/dev/null; do
    cat /sys/bus/iio/devices/iio:device0/in_anglvel_x_raw > /dev/null; n=$((n + 1))
done
echo "$n" > "$GUEST_OUT/driver_reads.txt"
wait $STUB
"""


def describe(name: str, report: dict, odr_hz: float) -> str:
    group = report["summary"]["by_odr_hz"].get(f"{odr_hz:g}")
    if not group:
        return f"  {name}: no refreshes at {odr_hz:g} Hz"
    target = 1.0 / odr_hz
    return (
        f"  {name:<28} period mean {1e3 * group['period_mean_s']:.3f} ms "
        f"(ratio to 1/ODR {group['period_mean_s'] / target:.3f}), median "
        f"{1e3 * group['period_median_s']:.3f} ms, jitter (std) "
        f"{1e3 * group['period_jitter_s']:.3f} ms, CPU "
        f"{100 * report['summary']['cpu_fraction']:.1f} % of one guest CPU, "
        f"{group['refreshes']} refreshes"
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seconds", type=float, default=15.0)
    args = parser.parse_args()
    from bmg160_emu.linux.guest.engine import Boot
    from bmg160_emu.linux.guest.harness import run_script
    from bmg160_emu.linux.guest.qemu import QemuEngine

    engine = QemuEngine()
    if engine.missing():
        raise SystemExit("; ".join(engine.missing()))
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        script = work / "bench.sh"
        script.write_text(
            f"export PY={shlex.quote(sys.executable)} PYTHONPATH={shlex.quote(str(REPO))}\n"
            f"export SECONDS_={args.seconds:g}\n" + GUEST_SCRIPT
        )
        out = work / "out"
        result = run_script(engine, Boot(script=script, results=out, memory_mb=1024, cpus=2),
                            timeout_s=600 + 4 * args.seconds)
        if result.timed_out:
            raise SystemExit("the guest timed out:\n" + result.console[-3000:])
        try:
            alone = json.loads((out / "alone.json").read_text())
            driver = json.loads((out / "driver.json").read_text())
        except OSError:
            raise SystemExit("the guest wrote no statistics:\n" + result.console[-3000:]) from None
        reads = (out / "driver_reads.txt").read_text().strip()
    print(f"i2c-stub adapter at ODR 200 Hz, {args.seconds:g} s per run, QEMU TCG guest")
    print(describe("adapter alone", alone, 200.0))
    print(describe("with bmg160 driver + reader", driver, 200.0))
    print(f"  sysfs reads of in_anglvel_x_raw meanwhile: {reads}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
