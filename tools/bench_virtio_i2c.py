"""Benchmark: 6-byte register reads per second from a guest program through virtio-i2c.

One QEMU guest (TCG) boots with ``bmg160-emu vhost-user-i2c`` serving a chip, and with
i2c-stub and ``bmg160-emu stub`` beside it. The same C program (tools/qemu/i2c_read_loop.c:
I2C_RDWR write [0x02] + read 6, timed one by one) runs

- in the guest on the virtio-i2c adapter: every read reaches the model as it is made;
- in the guest on the i2c-stub adapter: reads of kernel memory, which the stub adapter
  refreshes from the model at most once per output period (its refresh rate is printed;
  i2c-stub is SMBus only, so the loop uses the SMBus I2C block read there);
- on the host under umockdev (``bmg160-emu run``): the other route where every read
  reaches the model, measured in the same run as the reference.

    python tools/bench_virtio_i2c.py [--count 20000]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
QEMU = REPO / "tools" / "qemu"

GUEST_SCRIPT = r"""
set -u
cd /run
insmod "$KMOD/i2c-virtio.ko"
modprobe -d "$GUEST_ROOT" i2c-dev
modprobe -d "$GUEST_ROOT" i2c-stub chip_addr=0x68
sleep 1
VBUS=; SBUS=
for d in /sys/bus/i2c/devices/i2c-*; do
    case "$(cat "$d/name")" in *virtio*) VBUS=${d##*/i2c-} ;; *stub*) SBUS=${d##*/i2c-} ;; esac
done
"$PY" -m bmg160_emu stub --bus "$SBUS" --address 0x68 --bandwidth 6 --seed 7 \
    --stats "$GUEST_OUT/stub_stats.json" --ready-file /run/stub.ready > /dev/null 2>&1 &
STUB=$!
i=0; while [ ! -e /run/stub.ready ] && [ $i -lt 600 ]; do sleep 0.1; i=$((i + 1)); done
"$LOOP" "$VBUS" 0x68 0x02 6 "$COUNT" > "$GUEST_OUT/virtio.txt" 2>&1
"$LOOP" "$SBUS" 0x68 0x02 6 "$COUNT" smbus > "$GUEST_OUT/stub.txt" 2>&1
kill -TERM $STUB; wait $STUB
echo done > "$GUEST_OUT/done.txt"
"""


def _load(name: str, path: Path):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _fields(text: str) -> dict[str, float]:
    """The ``key=value`` figures of one i2c_read_loop line (its error text if it failed)."""
    try:
        return {k: float(v) for k, v in (item.split("=") for item in text.split())}
    except ValueError:
        raise SystemExit(f"read loop failed: {text.strip()}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20000, help="reads per client")
    args = parser.parse_args(argv)
    guest = _load("bmg160_guest", QEMU / "guest.py")
    reason = guest.missing_requirements()
    if reason:
        print(f"cannot boot a guest: {reason}", file=sys.stderr)
        return 2
    kmod = _load("bmg160_guest_modules", QEMU / "modules.py").build_modules()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        loop = work / "i2c_read_loop"
        subprocess.run(["gcc", "-O2", "-o", str(loop), str(QEMU / "i2c_read_loop.c")], check=True)
        # the reference: the same program on the host, on umockdev's /dev/i2c-1
        umockdev = subprocess.run(
            [sys.executable, "-m", "bmg160_emu", "run", "--seed", "7", "--bandwidth", "6", "--",
             str(loop), "1", "0x68", "0x02", "6", str(args.count)],
            capture_output=True, text=True, env=env, check=False)
        if umockdev.returncode:
            print(f"umockdev route failed: {umockdev.stderr.strip()}", file=sys.stderr)
            return 1
        reference = _fields(umockdev.stdout)
        sockets = work / "sockets"
        backend = subprocess.Popen(
            [sys.executable, "-m", "bmg160_emu", "vhost-user-i2c", "--socket",
             str(sockets / "i2c.sock"), "--seed", "7", "--bandwidth", "6",
             "--stats", str(work / "vu_stats.json"), "--ready-file", str(work / "ready")],
            env=env)
        while not (work / "ready").exists() and backend.poll() is None:
            time.sleep(0.05)
        out = work / "out"
        script = work / "run.sh"
        script.write_text(
            f"export PY={shlex.quote(sys.executable)} PYTHONPATH={shlex.quote(str(REPO))}\n"
            f"export KMOD={shlex.quote(str(kmod))} LOOP={shlex.quote(str(loop))}\n"
            f"export COUNT={args.count}\n" + GUEST_SCRIPT)
        result = guest.run_guest(script, out, timeout_s=600,
                                 qemu_args=guest.vhost_user_args(sockets / "i2c.sock"))
        backend.send_signal(signal.SIGTERM)
        backend.wait(30)
        if not (out / "done.txt").exists():
            sys.stdout.write(result.console)
            print("the guest did not finish", file=sys.stderr)
            return 1
        virtio = _fields((out / "virtio.txt").read_text())
        stub = _fields((out / "stub.txt").read_text())
        refresh = json.loads((out / "stub_stats.json").read_text())["summary"]
        served = json.loads((work / "vu_stats.json").read_text())["i2c"]
    print(f"umockdev (host, reference): {reference['per_s']:8.0f} reads/s  "
          f"p50 {reference['p50_us']:.0f} us  p99 {reference['p99_us']:.0f} us")
    print(f"virtio-i2c (guest):         {virtio['per_s']:8.0f} reads/s  "
          f"p50 {virtio['p50_us']:.0f} us  p99 {virtio['p99_us']:.0f} us  "
          f"= {virtio['per_s'] / reference['per_s']:.2f}x umockdev; back end "
          f"{served['us_per_request']:.1f} us per request")
    period = refresh.get("period_mean_s") or float("nan")
    print(f"i2c-stub (guest, memory):   {stub['per_s']:8.0f} reads/s of a register map the "
          f"adapter refreshed every {period * 1e3:.2f} ms ({1 / period:.0f} model samples/s, "
          f"ODR 200 Hz): {virtio['per_s'] * period:.0f} virtio reads per stub refresh")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
