"""Benchmark: the vhost-user back end's own CPU per register read, without QEMU.

The in-process fake front end of the tests (tests/_vhost_front_end.py: real vhost-user
messages, guest RAM in a memfd, split rings with indirect descriptors and EVENT_IDX, as
the Linux i2c-virtio driver lays them out) queues the driver's register read (write [0x02]
with FAIL_NEXT, read 6) and the device is kicked. Two measures:

- ``kick()`` alone, in this process: the thread CPU time of the ring and device code (a
  host busy with other work does not count);
- served: the back end as a guest meets it, a separate process (``bmg160-emu
  vhost-user-i2c``, with ``--gpio-socket`` as the kernel harness runs it) on its socket; the
  front end kicks the eventfd, waits for the call, and takes the used entries (it writes
  ``used_event`` as Linux does). The back end process's CPU (user + system, from
  /proc/PID/schedstat) per read is what it adds to every guest round trip: the event loop,
  the eventfd system calls, the after-transfer work (GPIO lines, pacing) and ``kick()``.

Compared in the same run: the full virtio-i2c device on I2CBus and a chip; a bare device on
the same vhost-user code answering zeros (tools/bench_virtio_i2c.py's reference, served the
same way); the chip read alone through I2CBus (``read_i2c_block_data``), the model's share.

    python tools/bench_virtio_backend.py [--count 20000] [--served-count 20000]
"""

from __future__ import annotations

import argparse
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from _vhost_front_end import FakeFrontEnd

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.clock import RealTimeClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.vhost_user import VhostUserDevice, VirtQueue  # (as older trees have it)
from bmg160_emu.linux.vhost_user_server import Connection, Server
from bmg160_emu.linux.virtio_i2c import FLAG_FAIL_NEXT, FLAG_M_RD, VirtioI2CDevice


class Bare(VhostUserDevice):
    """Every read answered with zeros, every request OK: the protocol alone."""

    num_queues = 1
    device_features = 1  # VIRTIO_I2C_F_ZERO_LENGTH_REQUEST

    def process(self, queue: VirtQueue) -> None:
        while (chain := queue.pop()) is not None:
            room = 0
            for addr, length in chain.writable:
                self.memory.write(addr, bytes(length))
                room += length
            queue.push(chain.head, room)


def serve_bare(socket_path: str, ready: str) -> int:
    """Serve :class:`Bare` on ``socket_path`` until SIGTERM."""
    server = Server()
    server.add(socket_path, Bare())
    signal.signal(signal.SIGTERM, lambda *_: server.stop())
    Path(ready).write_text("ready\n")
    try:
        server.run()
    finally:
        server.close()
    return 0


def _header(address: int, flags: int) -> bytes:
    return struct.pack("<HHI", address << 1, 0, flags)


def kick_cpu_us(device: VhostUserDevice, count: int) -> float:
    """Thread CPU (us) of ``device.kick`` per register read, after a warm-up."""
    front, back = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake()
    write = [_header(0x68, FLAG_FAIL_NEXT), b"\x02"]
    read = [_header(0x68, FLAG_M_RD)]
    total = 0.0
    try:
        for i in range(count + 2000):
            fe.add(0, write, [1])
            fe.add(0, read, [6, 1])
            t0 = time.thread_time()
            device.kick(0)
            if i >= 2000:
                total += time.thread_time() - t0
            assert len(fe.used(0)) == 2, "a read was not answered"
            fe.called(0)
    finally:
        connection.close()
        fe.close()
    return total / count * 1e6


def _cpu_ns(pid: int) -> int:
    """CPU time (ns) a process has run: /proc/PID/schedstat's first field, for each thread."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        total += int((task / "schedstat").read_text().split()[0])
    return total


def served_us(command: list[str], count: int, gpio: bool) -> tuple[float, float]:
    """(back end CPU us, round-trip wall us) per register read, ``command`` serving
    ``--socket`` (and ``--gpio-socket``, a front end connected and idle, when ``gpio``)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        p for p in (os.environ.get("PYTHONPATH"), str(REPO)) if p)}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        sockets = work / "sockets"  # the back end creates it 0700
        argv = [*command, "--socket", str(sockets / "i2c.sock"),
                "--ready-file", str(work / "ready")]
        if gpio:
            argv += ["--gpio-socket", str(sockets / "gpio.sock")]
        back = subprocess.Popen(argv, env=env)
        fronts: list[FakeFrontEnd] = []
        try:
            while not (work / "ready").exists():
                if back.poll() is not None:
                    raise SystemExit(f"the back end did not start: {' '.join(argv)}")
                time.sleep(0.02)
            for name, queues in (("gpio.sock", 2), ("i2c.sock", 1))[0 if gpio else 1:]:
                sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
                sock.connect(str(sockets / name))
                fronts.append(fe := FakeFrontEnd(sock, lambda: None))
                # as UML's virtio_uml: it also hands over the back end's request channel
                fe.handshake(num_queues=queues, backend_channel=True)
            fe = fronts[-1]
            kick, call = fe.queues[0]["kick"], fe.queues[0]["call"]
            write = [_header(0x68, FLAG_FAIL_NEXT), b"\x02"]
            read = [_header(0x68, FLAG_M_RD)]
            poller = select.poll()
            poller.register(call, select.POLLIN)
            for i in range(count + 2000):
                if i == 2000:
                    cpu0, wall0 = _cpu_ns(back.pid), time.perf_counter()
                fe.add(0, write, [1])
                fe.add(0, read, [6, 1])
                os.eventfd_write(kick, 1)  # one kick for both, as i2c-virtio does
                if not poller.poll(5000):
                    raise SystemExit("the back end did not call within 5 s")
                os.eventfd_read(call)
                if len(fe.used(0)) != 2:
                    raise SystemExit("a read was not answered")
                fe.set_used_event(0, fe.queues[0]["used_seen"])  # interrupt me on the next
            cpu = (_cpu_ns(back.pid) - cpu0) / count / 1e3
            wall = (time.perf_counter() - wall0) / count * 1e6
        finally:
            for fe in fronts:
                fe.close()
            back.send_signal(signal.SIGTERM)
            back.wait(30)
    return cpu, wall


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20000,
                        help="register reads per device, kick() alone")
    parser.add_argument("--served-count", type=int, default=20000,
                        help="register reads per served back end (0: skip those)")
    # the bare back end served on its own (this file runs it as a process)
    parser.add_argument("--serve-bare", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--socket", help=argparse.SUPPRESS)
    parser.add_argument("--ready-file", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve_bare:
        return serve_bare(args.socket, args.ready_file)
    chip = BMG160(seed=3, true_rate=(20.0, -10.0, 5.0), clock=RealTimeClock())
    bus = I2CBus(0, {0x68: chip})
    full = kick_cpu_us(VirtioI2CDevice(bus), args.count)
    bare = kick_cpu_us(Bare(), args.count)
    t0 = time.thread_time()
    for _ in range(args.count):
        bus.read_i2c_block_data(0x68, 0x02, 6)
    model = (time.thread_time() - t0) / args.count * 1e6
    print("kick() alone, CPU per register read:")
    print(f"  bare back end:  {bare:6.1f} us (reference)")
    print(f"  full back end:  {full:6.1f} us, {full / bare:.2f}x bare")
    print(f"    of which the chip read through I2CBus: {model:.1f} us; the virtio-i2c layer "
          f"over bare: {full - bare - model:.1f} us")
    if args.served_count <= 0:
        return 0
    python = [sys.executable]
    command = [*python, "-m", "bmg160_emu", "vhost-user-i2c", "--seed", "3",
               "--true-rate", "20", "-10", "5"]
    rows = [("bare back end (reference)",
             [*python, str(Path(__file__).resolve()), "--serve-bare"], False),
            ("full, virtio-i2c only", command, False),
            ("full, with --gpio-socket (the kernel harness's)", command, True)]
    print("served by a back end process (kick eventfd -> call eventfd), per register read:")
    reference = None
    for name, cmd, gpio in rows:
        cpu, wall = served_us(cmd, args.served_count, gpio)
        reference = reference or cpu
        print(f"  {name:48s} {cpu:6.1f} us CPU ({cpu / reference:.2f}x bare), "
              f"round trip {wall:6.1f} us wall")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
