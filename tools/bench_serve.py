"""Benchmark: what one transfer through ``bmg160-emu serve`` costs, against a bare FakeSMBus read.

The transfer measured is the one a polling Zephyr driver makes at each output sample: a
register read of the six rate bytes (write [RATE_X_LSB], repeated start, read 6), stamped
one output period after the last (so every transfer makes the chip produce a sample).

- reference: the same read on FakeSMBus in this process, after ``chip.advance(period)``
  (the model's work with no socket and no protocol);
- served, Python client: the request from this process to a server in a child process,
  round trip timed here, the server's CPU taken from /proc for the same loops (their mean:
  /proc counts whole clock ticks);
- served, C client: the module's host half (zephyr/src/bmg160_emu_link.c, the code
  native_sim links), a loop of the same requests in one process (built with cc if found).

Rounds of every loop are interleaved and the best round of each is kept (the least
disturbed on a shared host); the ratios are served / reference from the same run.

    python tools/bench_serve.py [--loop 2000] [--rounds 7]
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bmg160_emu.bus.smbus import FakeSMBus
from bmg160_emu.device.chip import BMG160
from bmg160_emu.device.registers import address_of
from bmg160_emu.serve.client import ServeClient
from bmg160_emu.serve.zephyr_app import MODULE_ROOT, serve_process

RATE_X_LSB, BW = address_of("RATE_X_LSB"), address_of("BW")
BW_CODE = 5  # ODR 100 Hz (spec 5.3)
PERIOD_NS = 10_000_000


def cpu_s(pid: int) -> float:
    """utime + stime of a process, seconds (/proc/PID/stat fields 14 and 15)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def build_c_client(folder: Path) -> Path | None:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:
        return None
    out = folder / "client"
    subprocess.run([compiler, "-O2", "-std=c11", "-D_DEFAULT_SOURCE", "-o", str(out),
                    str(MODULE_ROOT / "zephyr" / "host" / "bmg160_emu_client.c"),
                    str(MODULE_ROOT / "zephyr" / "src" / "bmg160_emu_link.c"),
                    f"-I{MODULE_ROOT / 'zephyr' / 'src'}"], check=True)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--loop", type=int, default=2000, help="transfers per timed loop")
    parser.add_argument("--rounds", type=int, default=7, help="interleaved rounds, best kept")
    args = parser.parse_args()
    n = args.loop

    chip = BMG160(seed=7)
    bus = FakeSMBus(1, devices={0x68: chip})
    bus.write_byte_data(0x68, BW, BW_CODE)
    advance, read = chip.advance, bus.read_i2c_block_data

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        proc, socket = serve_process(folder / "srv", "--seed", "7", "--bandwidth", str(BW_CODE))
        c_client = build_c_client(folder)
        client = ServeClient(socket, "bench")
        client.greet()
        stamp = [0]

        def reference() -> float:
            started = time.perf_counter()
            for _ in range(n):
                advance(0.01)
                read(0x68, RATE_X_LSB, 6)
            return (time.perf_counter() - started) / n

        def served() -> tuple[float, float]:
            before = cpu_s(proc.pid)
            started = time.perf_counter()
            for _ in range(n):
                stamp[0] += PERIOD_NS
                client.write_read(0x68, RATE_X_LSB, 6, stamp[0])
            wall = (time.perf_counter() - started) / n
            return wall, (cpu_s(proc.pid) - before) / n

        def served_c() -> float:
            assert c_client is not None
            lines = []
            for _ in range(n):
                stamp[0] += PERIOD_NS
                lines.append(f"i2c {stamp[0]} 68 0:{RATE_X_LSB:02x} 1:6")
            script = "\n".join(lines) + "\n"
            started = time.perf_counter()
            done = subprocess.run([str(c_client), socket], input=script, capture_output=True,
                                  text=True, check=True)
            wall = time.perf_counter() - started
            assert done.stdout.count("rc=0 ") == n, done.stdout[-300:]
            return wall / n  # (one process start, ~1 ms, spread over the loop)

        best: dict[str, float] = {}
        server_cpu = 0.0  # summed over the rounds: /proc counts in clock ticks (10 ms)
        for _ in range(args.rounds):
            wall, cpu = served()
            server_cpu += cpu / args.rounds
            for name, value in [("reference", reference()), ("served", wall),
                                *((("served_c", served_c()),) if c_client else ())]:
                best[name] = min(best.get(name, float("inf")), value)
        best["server_cpu"] = server_cpu
        client.close()
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)

    load = os.getloadavg()[0]
    print(f"per transfer (a 6-byte register read at a new sample), best of {args.rounds} "
          f"rounds of {n}; load {load:.1f}")
    print(f"  reference, FakeSMBus in process : {best['reference'] * 1e6:7.1f} us")
    print(f"  served, Python client round trip: {best['served'] * 1e6:7.1f} us  "
          f"({best['served'] / best['reference']:.1f}x the reference)")
    print(f"  served, server CPU per transfer : {best['server_cpu'] * 1e6:7.1f} us  "
          "(mean of the rounds) "
          f"({best['server_cpu'] / best['reference']:.1f}x)")
    if "served_c" in best:
        print(f"  served, C client (the module's) : {best['served_c'] * 1e6:7.1f} us  "
              f"({best['served_c'] / best['reference']:.1f}x)")
    else:
        print("  served, C client: no C compiler", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
