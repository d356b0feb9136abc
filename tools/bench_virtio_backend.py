"""Benchmark: the vhost-user back end's own CPU per register read, without QEMU.

The in-process fake front end of the tests (tests/_vhost_front_end.py: real vhost-user
messages, guest RAM in a memfd, split rings with indirect descriptors and EVENT_IDX, as
the Linux i2c-virtio driver lays them out) queues the driver's register read (write [0x02]
with FAIL_NEXT, read 6) and the device is kicked; the thread CPU time of ``kick()`` is
summed (so a host busy with other work does not count). Compared in the same run:

- the full virtio-i2c device on I2CBus and a chip (what ``bmg160-emu vhost-user-i2c``
  serves);
- a bare device on the same vhost-user code answering zeros (tools/bench_virtio_i2c.py's
  reference);
- the chip read alone through I2CBus (``read_i2c_block_data``), the model's share.

    python tools/bench_virtio_backend.py [--count 20000]
"""

from __future__ import annotations

import argparse
import socket
import struct
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from _vhost_front_end import FakeFrontEnd

from bmg160_emu.bus.i2c import I2CBus
from bmg160_emu.clock import RealTimeClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux.vhost_user import VhostUserDevice, VirtQueue
from bmg160_emu.linux.vhost_user_server import Connection
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=20000, help="register reads per device")
    args = parser.parse_args(argv)
    chip = BMG160(seed=3, true_rate=(20.0, -10.0, 5.0), clock=RealTimeClock())
    bus = I2CBus(0, {0x68: chip})
    full = kick_cpu_us(VirtioI2CDevice(bus), args.count)
    bare = kick_cpu_us(Bare(), args.count)
    t0 = time.thread_time()
    for _ in range(args.count):
        bus.read_i2c_block_data(0x68, 0x02, 6)
    model = (time.thread_time() - t0) / args.count * 1e6
    print(f"bare back end:  {bare:6.1f} us CPU per register read (reference)")
    print(f"full back end:  {full:6.1f} us, {full / bare:.2f}x bare")
    print(f"  of which the chip read through I2CBus: {model:.1f} us; the virtio-i2c layer "
          f"over bare: {full - bare - model:.1f} us")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
