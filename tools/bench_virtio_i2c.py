"""Benchmark: 6-byte register reads per second from a guest program through virtio-i2c.

One QEMU guest (TCG, one vCPU) boots with two vhost-user-i2c adapters: one served by
``bmg160-emu vhost-user-i2c`` (the full model), one by a bare back end (this file with
``--serve-bare``: the same vhost-user code answering every read with zeros, no I2CBus and no
chip; the reference for "what the model costs"). i2c-stub and ``bmg160-emu stub`` come up
after. The same C program (tests/kernel_guest/i2c_read_loop.c: I2C_RDWR write [0x02] + read 6,
timed one by one) runs

- in the guest on the full virtio-i2c adapter: every read reaches the model as it is made;
- in the guest on the bare adapter, same run (three rounds of each, interleaved; the best
  round of each is compared, as the host's load changes within a minute);
- in the guest on the i2c-stub adapter: reads of kernel memory, which the stub adapter
  refreshes from the model at most once per output period (its refresh rate is printed;
  i2c-stub is SMBus only, so the loop uses the SMBus I2C block read there);
- on the host under umockdev (``bmg160-emu run``): the other route where every read
  reaches the model.

While each guest loop runs, the CPU time of QEMU's threads (the vCPU runs the guest, the
main loop delivers the back end's interrupts) and of the back end is taken from /proc: the
CPU per read says where a read's time goes; what the wall time adds is waiting for a core.

    python tools/bench_virtio_i2c.py [--count 20000] [--trace]
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
GUEST_FILES = REPO / "tests" / "kernel_guest"

GUEST_SCRIPT = r"""
set -u
cd /run
[ -n "${GUEST_I2C_BUS:-}" ] || insmod "$KMOD/i2c-virtio.ko"  # (the engine loads it)
modprobe -d "$GUEST_ROOT" i2c-dev
modprobe -d "$GUEST_ROOT" i2c-stub chip_addr=0x68
sleep 1
VBUS=; BBUS=; SBUS=
for d in /sys/bus/i2c/devices/i2c-*; do
    b=${d##*/i2c-}
    case "$(cat "$d/name")" in
        *virtio*) if [ "$(i2cget -y "$b" 0x68 0x00 2>/dev/null)" = 0x0f ]; then VBUS=$b; else BBUS=$b; fi ;;
        *stub*) SBUS=$b ;;
    esac
done
timed() {  # $1 name, then the loop's arguments
    name=$1; shift
    echo > "$GUEST_OUT/$name.start"; sleep 0.2
    "$LOOP" "$@" > "$GUEST_OUT/$name.txt" 2>&1
    echo > "$GUEST_OUT/$name.end"; sleep 0.2
}
for r in 1 2 3; do  # interleaved: the host's load changes within a minute
    timed "full$r" "$VBUS" 0x68 0x02 6 "$COUNT"
    timed "bare$r" "$BBUS" 0x68 0x02 6 "$COUNT"
done
"$PY" -m bmg160_emu stub --bus "$SBUS" --address 0x68 --bandwidth 6 --seed 7 \
    --stats "$GUEST_OUT/stub_stats.json" --ready-file /run/stub.ready > /dev/null 2>&1 &
STUB=$!
i=0; while [ ! -e /run/stub.ready ] && [ $i -lt 600 ]; do sleep 0.1; i=$((i + 1)); done
"$LOOP" "$SBUS" 0x68 0x02 6 "$COUNT" smbus > "$GUEST_OUT/stub.txt" 2>&1
kill -TERM $STUB; wait $STUB
echo done > "$GUEST_OUT/done.txt"
"""


def serve_bare(socket_path: str, ready: str) -> int:
    """A virtio-i2c back end with no model: every read is zeros, every request OK."""
    from bmg160_emu.linux.vhost_user import VhostUserDevice, VirtQueue
    from bmg160_emu.linux.vhost_user_server import Server

    class Bare(VhostUserDevice):
        num_queues = 1
        device_features = 1  # VIRTIO_I2C_F_ZERO_LENGTH_REQUEST
        name = "bare virtio-i2c"

        def process(self, queue: VirtQueue) -> None:
            while (chain := queue.pop()) is not None:
                room = 0
                for addr, length in chain.writable:  # read data (zeros), then the status 0
                    self.memory.write(addr, bytes(length))
                    room += length
                queue.push(chain.head, room)

    server = Server()
    server.add(socket_path, Bare())
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    Path(ready).write_text("ready\n")
    try:
        server.run()
    finally:
        server.close()
    return 0


def _cpu_s(pid: int) -> dict[str, float]:
    """CPU seconds (user + system) of each thread of ``pid``, by thread name."""
    tick = os.sysconf("SC_CLK_TCK")
    out: dict[str, float] = {}
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            name = (task / "comm").read_text().strip()
            fields = (task / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # the thread ended meanwhile
        # fields 14 and 15 of stat (utime, stime), counted after the ")" of the name
        out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / tick
    return out


def _qemu_pid(marker: str) -> int | None:
    """The QEMU process whose command line holds ``marker`` (our socket path)."""
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes()
            except OSError:
                continue
            if b"qemu-system" in cmdline and marker.encode() in cmdline:
                return int(entry.name)
    return None


class _CpuWatch(threading.Thread):
    """CPU seconds of QEMU's threads and of each back end between the guest loop's marker
    files ``NAME.start`` and ``NAME.end``, for each name."""

    def __init__(self, out: Path, marker: str, names: list[str], back_ends: dict[str, int]):
        super().__init__(daemon=True)
        self.out, self.marker, self.names, self.back_ends = out, marker, names, back_ends
        self.results: dict[str, dict[str, float]] = {}

    def _snapshot(self, pid: int) -> dict[str, float]:
        shot = {f"QEMU {k}": v for k, v in _cpu_s(pid).items()}
        for name, back_pid in self.back_ends.items():
            shot[name] = sum(_cpu_s(back_pid).values())
        return shot

    def run(self) -> None:
        deadline = time.monotonic() + 900
        pid = None
        for name in self.names:
            start = None
            while time.monotonic() < deadline:
                if start is None and (self.out / f"{name}.start").exists():
                    pid = pid or _qemu_pid(self.marker)
                    if pid is None:
                        return
                    start = (time.monotonic(), self._snapshot(pid))
                if start is not None and (self.out / f"{name}.end").exists():
                    t0, before = start
                    after = self._snapshot(pid)  # type: ignore[arg-type]
                    result = {k: v - before.get(k, 0.0) for k, v in after.items()}
                    result["wall_s"] = time.monotonic() - t0
                    self.results[name] = result
                    break
                time.sleep(0.005)


def _fields(text: str) -> dict[str, float]:
    """The ``key=value`` figures of one i2c_read_loop line (its error text if it failed)."""
    try:
        return {k: float(v) for k, v in (item.split("=") for item in text.split())}
    except ValueError:
        raise SystemExit(f"read loop failed: {text.strip()}") from None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20000, help="reads per client")
    parser.add_argument("--trace", action="store_true",
                        help="the full back end writes a --trace file (as the kernel test's)")
    parser.add_argument("--serve-bare", nargs=2, metavar=("SOCKET", "READY"),
                        help=argparse.SUPPRESS)  # the bare back end (run by this benchmark)
    args = parser.parse_args(argv)
    if args.serve_bare:
        return serve_bare(*args.serve_bare)
    from bmg160_emu.linux.guest.debian_modules import bundled_dir
    from bmg160_emu.linux.guest.engine import Boot
    from bmg160_emu.linux.guest.harness import run_script
    from bmg160_emu.linux.guest.qemu import QemuEngine

    missing = QemuEngine().missing()
    if missing:
        print(f"cannot boot a guest: {'; '.join(missing)}", file=sys.stderr)
        return 2
    kmod = bundled_dir()
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        loop = work / "i2c_read_loop"
        subprocess.run(["gcc", "-O2", "-o", str(loop), str(GUEST_FILES / "i2c_read_loop.c")], check=True)
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
             "--stats", str(work / "vu_stats.json"), "--ready-file", str(work / "ready"),
             *(["--trace", str(work / "trace.jsonl")] if args.trace else [])],
            env=env)
        bare = subprocess.Popen(
            [sys.executable, __file__, "--serve-bare", str(sockets / "bare.sock"),
             str(work / "bare.ready")], env=env)
        while not ((work / "ready").exists() and (work / "bare.ready").exists()):
            if backend.poll() is not None or bare.poll() is not None:
                print("a back end did not start", file=sys.stderr)
                return 1
            time.sleep(0.05)
        out = work / "out"
        script = work / "run.sh"
        script.write_text(
            f"export PY={shlex.quote(sys.executable)} PYTHONPATH={shlex.quote(str(REPO))}\n"
            f"export KMOD={shlex.quote(str(kmod))} LOOP={shlex.quote(str(loop))}\n"
            f"export COUNT={args.count}\n" + GUEST_SCRIPT)
        rounds = [f"{name}{r}" for r in (1, 2, 3) for name in ("full", "bare")]
        watch = _CpuWatch(out, str(sockets / "i2c.sock"), rounds,
                          {"back end": backend.pid, "bare back end": bare.pid})
        watch.start()
        engine = QemuEngine(extra_args=(
            "-chardev", f"socket,id=vbare,path={sockets / 'bare.sock'}",
            "-device", "vhost-user-i2c-pci,chardev=vbare",
            "-name", "bench,debug-threads=on"))  # QEMU names its threads
        result = run_script(engine, Boot(script=script, results=out, memory_mb=1024,
                                         i2c_socket=sockets / "i2c.sock"), timeout_s=900)
        watch.join(1)
        for process in (backend, bare):
            process.send_signal(signal.SIGTERM)
            process.wait(30)
        if not (out / "done.txt").exists():
            sys.stdout.write(result.console)
            print("the guest did not finish", file=sys.stderr)
            return 1
        loops = {name: _fields((out / f"{name}.txt").read_text()) for name in rounds}
        # the least disturbed of three interleaved rounds of each (the host is shared)
        best = {kind: max((n for n in rounds if n.startswith(kind)),
                          key=lambda n: loops[n]["per_s"]) for kind in ("full", "bare")}
        full, bare_loop = loops[best["full"]], loops[best["bare"]]
        stub = _fields((out / "stub.txt").read_text())
        refresh = json.loads((out / "stub_stats.json").read_text())["summary"]
        served = json.loads((work / "vu_stats.json").read_text())["i2c"]
    print(f"umockdev (host, reference):  {reference['per_s']:8.0f} reads/s  "
          f"p50 {reference['p50_us']:.0f} us  p99 {reference['p99_us']:.0f} us")
    print("virtio-i2c rounds (reads/s): " + ", ".join(
        f"{n} {loops[n]['per_s']:.0f}" for n in rounds) + "; best of each below")
    print(f"virtio-i2c, full model:      {full['per_s']:8.0f} reads/s  "
          f"p50 {full['p50_us']:.0f} us  p99 {full['p99_us']:.0f} us  "
          f"= {full['per_s'] / reference['per_s']:.2f}x umockdev, "
          f"{full['per_s'] / bare_loop['per_s']:.2f}x bare; in the model "
          f"{served['us_per_request']:.1f} us per request")
    print(f"virtio-i2c, bare back end:   {bare_loop['per_s']:8.0f} reads/s  "
          f"p50 {bare_loop['p50_us']:.0f} us  p99 {bare_loop['p99_us']:.0f} us")
    for name in (best["full"], best["bare"]):
        shares = watch.results.get(name)
        if not shares:
            continue
        wall = shares.pop("wall_s")
        used = {k: v for k, v in shares.items() if v > 0}
        print(f"  CPU per read, {name} ({wall:.1f} s wall): " + ", ".join(
            f"{k} {v / args.count * 1e6:.0f} us" for k, v in sorted(used.items()))
            + f"; sum {sum(used.values()) / args.count * 1e6:.0f} of "
              f"{wall / args.count * 1e6:.0f} us wall (the rest: waiting for a core)")
    period = refresh.get("period_mean_s") or float("nan")
    print(f"i2c-stub (guest, memory):    {stub['per_s']:8.0f} reads/s of a register map the "
          f"adapter refreshed every {period * 1e3:.2f} ms ({1 / period:.0f} model samples/s, "
          f"ODR 200 Hz): {full['per_s'] * period:.0f} virtio reads per stub refresh")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
