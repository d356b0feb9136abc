"""Benchmark: a guest of each engine from its start to the driver's first read, and 6-byte
reads/s through the model, in virtual time (uml's time travel) and against wall time.

Per engine and time mode, one fresh guest beside the in-process back ends (two chips, INT
lines on virtio-gpio, the agent on two more lines), host clock from the engine's start:

- ``agent``: the agent (the guest's init) is serving;
- ``first read``: the kernel's bmg160 driver bound through bmg160-board with its IRQ and its
  ``in_anglvel_x_raw`` read, by the agent (one request batch, no program started);
- ``reads/s``: ``tests/kernel_guest/i2c_read_loop.c`` (I2C_RDWR write [0x02] + read 6, no
  clock read per read) timed on the host around the agent's run of it, less an empty run.

Beside each wall time: the CPU seconds of this process (the back ends) plus the guest's
processes (UML's process group, or QEMU's), and the host's load average.

    python tools/bench_uml.py [--engines uml,qemu] [--reads 20000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

READ_LOOP_SOURCE = REPO / "tests" / "kernel_guest" / "i2c_read_loop.c"
TICK_S = 1.0 / os.sysconf("SC_CLK_TCK")


def group_cpu_s(process: subprocess.Popen[bytes] | None) -> float:
    """CPU seconds (user + system) of the guest: every process in the process group the
    orphan guard gave it (its leader is the guard's child), read from /proc while alive."""
    if process is None:
        return 0.0
    total = 0.0
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        # fields[0] is state: ppid 1, pgrp 2, ... utime 11, stime 12, and the reaped
        # children's 13, 14 (proc(5), counted from field 3)
        if int(fields[1]) == process.pid or int(fields[2]) in _groups(process):
            total += sum(int(v) for v in fields[11:15]) * TICK_S
    return total


def _groups(process: subprocess.Popen[bytes]) -> set[int]:
    groups = set()
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                fields = Path(f"/proc/{entry}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == process.pid:
                groups.add(int(fields[2]))
    return groups


_SCANS_CPU_S = [0.0]  # what reading /proc cost this process: not the back ends' work


def own_cpu_s() -> float:
    """This process's CPU seconds (the back ends' thread and the harness), less the scans."""
    t = os.times()
    return t.user + t.system - _SCANS_CPU_S[0]


def guest_cpu_s(process: subprocess.Popen[bytes] | None) -> float:
    t = os.times()
    before = t.user + t.system
    found = group_cpu_s(process)
    t = os.times()
    _SCANS_CPU_S[0] += t.user + t.system - before
    return found


def one_guest(engine_name: str, virtual: bool, reads: int, loop: Path) -> dict[str, float]:
    from bmg160_emu.clock import VirtualClock
    from bmg160_emu.device.chip import BMG160
    from bmg160_emu.linux.guest import agent
    from bmg160_emu.linux.guest.drivers import bind_failure, bind_ops
    from bmg160_emu.linux.guest.engine import choose
    from bmg160_emu.linux.guest.harness import Backend, Guest, temporary_work
    from bmg160_emu.linux.guest_pace import GuestPacedClock

    engine = choose(engine_name)
    clock = VirtualClock() if virtual else GuestPacedClock()
    chips = {a: BMG160(seed=7 + i, clock=clock, address=a) for i, a in enumerate((0x68, 0x69))}
    work = temporary_work()
    backend = Backend(chips, work / "s", gpio=True, clock=clock, time_travel=virtual)
    guest = Guest(engine, work, backend)
    row: dict[str, float] = {}
    cpu0, wall0 = own_cpu_s(), time.monotonic()
    try:
        guest.start(timeout_s=300)
        row["agent_s"] = time.monotonic() - wall0
        row["agent_cpu_s"] = own_cpu_s() - cpu0 + guest_cpu_s(guest.process)
        wall0 += time.monotonic() - wall0 - row["agent_s"]  # (the /proc scan is not the guest's)
        board = engine.board_module()  # type: ignore[attr-defined]
        ops = bind_ops("bmg160", [0x68], guest.i2c_bus, [backend.line_of(0x68)], board,
                       int(guest.facts["gpio_base"]), kernel_driver=True)
        ops.append(agent.read(f"/sys/bus/i2c/devices/{guest.i2c_bus}-0068/iio:device0/"
                              "in_anglvel_x_raw", check=True))
        replies = guest.call(ops)
        row["first_read_s"] = time.monotonic() - wall0
        row["first_read_cpu_s"] = own_cpu_s() - cpu0 + guest_cpu_s(guest.process)
        # (the first guest of a run also built the agent: not the boot's cost)
        failure = bind_failure(replies, ops)
        if failure or not replies[-1].text.strip().lstrip("-").isdigit():
            raise RuntimeError(f"no first read: {failure or replies[-1].error()}")
        empty = guest.call([agent.run("/", "true", guest.agent_dir / "e.out",
                                      guest.agent_dir / "e.err")])  # warm: sh is cached
        started, cpu1, guest_cpu1 = time.monotonic(), own_cpu_s(), guest_cpu_s(guest.process)
        empty = guest.call([agent.run("/", "true", guest.agent_dir / "e.out",
                                      guest.agent_dir / "e.err")])
        empty_s = time.monotonic() - started
        started = time.monotonic()
        done = guest.call([agent.run("/", f"{loop} {guest.i2c_bus} 0x68 0x02 6 {reads} nolat",
                                     guest.agent_dir / "l.out", guest.agent_dir / "l.err")],
                          timeout_s=600)
        loop_s = time.monotonic() - started - empty_s
        assert not empty[0].status and done[0].text == "0", (guest.agent_dir / "l.err")
        row["reads_per_s"] = reads / loop_s
        row["us_back_end_per_read"] = (own_cpu_s() - cpu1) / reads * 1e6
        row["us_guest_per_read"] = (guest_cpu_s(guest.process) - guest_cpu1) / reads * 1e6
        row["us_cpu_per_read"] = row["us_back_end_per_read"] + row["us_guest_per_read"]
    finally:
        guest.close()
        backend.close()
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", default="uml", help="comma-separated: uml,qemu")
    parser.add_argument("--reads", type=int, default=20000)
    parser.add_argument("--repeat", type=int, default=3, help="guests per engine and mode")
    args = parser.parse_args()
    from bmg160_emu.linux.guest.engine import choose

    with tempfile.TemporaryDirectory(prefix="bench-uml-") as tmp:
        loop = Path(tmp) / "i2c_read_loop"
        subprocess.run(["gcc", "-O2", "-o", str(loop), str(READ_LOOP_SOURCE)], check=True)
        rows: dict[str, list[dict[str, float]]] = {}
        for name in args.engines.split(","):
            modes = [True, False] if getattr(choose(name), "time_travel", False) else [False]
            for virtual in modes:
                key = f"{name} {'virtual' if virtual else 'real-time'}"
                rows[key] = [one_guest(name, virtual, args.reads, loop)
                             for _ in range(args.repeat)]
                print(f"{key}: done (load average {os.getloadavg()[0]:.1f})", file=sys.stderr)
    print(f"median of {args.repeat} guests each; {args.reads} reads; load average "
          f"{os.getloadavg()[0]:.1f} / {os.getloadavg()[1]:.1f} (1 / 5 min) at the end")
    keys = [("agent serving", "agent_s", "agent_cpu_s"),
            ("driver's first read", "first_read_s", "first_read_cpu_s")]
    for key, runs in rows.items():
        print(key)
        for label, wall, cpu in keys:
            print(f"  {label:<22} {statistics.median(r[wall] for r in runs):7.3f} s wall, "
                  f"{statistics.median(r[cpu] for r in runs):6.3f} s CPU")
        print(f"  {'6-byte reads/s':<22} {statistics.median(r['reads_per_s'] for r in runs):7.0f}"
              f"      ({statistics.median(r['us_cpu_per_read'] for r in runs):.0f} us CPU per "
              f"read: {statistics.median(r['us_guest_per_read'] for r in runs):.0f} the guest's, "
              f"{statistics.median(r['us_back_end_per_read'] for r in runs):.0f} the back "
              "end's)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
