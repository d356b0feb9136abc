"""Benchmark: the kernel harness on each ready guest engine, as ratios against QEMU's figures
from the same run.

Per engine (``bmg160_emu.linux.guest.engine.engines()``, those with nothing missing):

- boot to the driver's first read: a fresh guest beside the in-process back ends, the
  kernel's bmg160 driver bound with its IRQ and ``in_anglvel_x_raw`` read once (wall time
  from the engine's start to that read's answer);
- 6-byte reads/s through the full model: ``tests/kernel_guest/i2c_read_loop.c`` (I2C_RDWR
  write [0x02] + read 6, one process) on the virtio adapter, --count reads, in that guest;
- a single kernel test including the session's boot: ``pytest`` on one test of
  tests/test_kernel_fixture.py, the whole process's wall time;
- with --suite, the kernel suite: ``pytest -m kernel`` (all kernel tests, both routes).

The host is shared (load average printed): compare engines within one run, not across runs.

    python tools/bench_kernel.py [--count 20000] [--suite]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
READ_LOOP = REPO / "tests" / "kernel_guest" / "i2c_read_loop.c"
SINGLE_TEST = "tests/test_kernel_fixture.py::test_each_test_starts_at_the_probe_state"


def guest_figures(engine, count: int, loop: Path) -> dict[str, float]:
    """Boot to the driver's first read, and reads/s of the C loop, on one fresh guest."""
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.linux.guest.drivers import bind_command
    from bmg160_emu.linux.guest.harness import Backend, Guest, temporary_work
    from bmg160_emu.linux.guest_pace import GuestPacedClock

    work = temporary_work()
    clock = GuestPacedClock()
    backend = Backend({0x68: BMG160(seed=7, clock=clock, address=0x68)}, work / "s",
                      clock=clock)
    guest = Guest(engine, work, backend)
    board = getattr(engine, "board_module", lambda: None)()
    lines = [backend.line_of(0x68)] if board is not None else None
    started = time.monotonic()
    try:
        boot_s = guest.start()
        first = guest.run(bind_command("bmg160", [0x68], lines, board, kernel_driver=True)
                          + "cat /sys/bus/i2c/devices/$GUEST_I2C_BUS-0068/iio:device*/"
                            "in_anglvel_x_raw", check=True)
        first_read_s = time.monotonic() - started
        loop_out = guest.run(f"{loop} $GUEST_I2C_BUS 0x68 0x02 6 {count}", timeout_s=600,
                             check=True).stdout
    finally:
        guest.close()
        backend.close()
    fields = dict(item.split("=") for item in loop_out.split())
    return {"boot_s": boot_s, "first_read_s": first_read_s, "bind_read_s": first.seconds,
            "reads_per_s": float(fields["per_s"]), "p50_us": float(fields["p50_us"]),
            "p99_us": float(fields["p99_us"])}


def pytest_wall_s(engine: str, *words: str) -> tuple[float, str]:
    env = {**os.environ, "PYTHONPATH": str(REPO), "BMG160_KERNEL_ENGINE": engine}
    started = time.monotonic()
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             *words], cwd=REPO, env=env, capture_output=True, text=True,
                            check=False)
    summary = (result.stdout.strip().splitlines() or ["?"])[-1]
    return time.monotonic() - started, summary


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20000, help="6-byte reads in the loop")
    parser.add_argument("--suite", action="store_true", help="also time pytest -m kernel")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO))
    from bmg160_emu.linux.guest.engine import engines

    ready = {name: e for name, e in engines().items() if not e.missing()}
    if "qemu" not in ready:
        print("QEMU (the reference) is not ready: bmg160-emu kernel prepare --engine qemu",
              file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        loop = Path(tmp) / "i2c_read_loop"
        subprocess.run(["gcc", "-O2", "-o", str(loop), str(READ_LOOP)], check=True)
        figures: dict[str, dict[str, float]] = {}
        for name, engine in ready.items():
            print(f"{name}: booting (load average {os.getloadavg()[0]:.1f})", file=sys.stderr)
            figures[name] = guest_figures(engine, args.count, loop)
            single_s, summary = pytest_wall_s(name, SINGLE_TEST)
            figures[name]["single_test_s"] = single_s
            print(f"{name}: single test: {summary}", file=sys.stderr)
            if args.suite:
                suite_s, summary = pytest_wall_s(name, "-m", "kernel", "tests")
                figures[name]["suite_s"] = suite_s
                print(f"{name}: suite: {summary}", file=sys.stderr)
    reference = figures["qemu"]
    print(f"kernel harness, {args.count} six-byte reads; load average "
          f"{os.getloadavg()[0]:.1f} at the end; ratio = engine / QEMU in this run")
    rows = [("boot (agent ready)", "boot_s", "s"), ("boot to driver's first read",
            "first_read_s", "s"), ("6-byte reads/s", "reads_per_s", "/s"),
            ("read p50", "p50_us", "us"), ("read p99", "p99_us", "us"),
            ("single kernel test incl. boot", "single_test_s", "s"),
            ("kernel suite", "suite_s", "s")]
    for label, key, unit in rows:
        for name, values in figures.items():
            if key in values:
                ratio = values[key] / reference[key] if reference.get(key) else float("nan")
                print(f"  {label:<30} {name:<5} {values[key]:>10.2f} {unit:<3} "
                      f"ratio {ratio:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
