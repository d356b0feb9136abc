"""A fake vhost-user front end (QEMU's role) and virtio driver, in-process, for host tests.

It shares a memfd as guest RAM, sends real vhost-user messages over a socket, lays out split
virtqueues in that memory and adds requests as the Linux drivers do (one indirect table per
request), so the back-end code under test runs exactly as it does under QEMU, without QEMU.
"""

from __future__ import annotations

import mmap
import os
import socket
import struct

from bmg160_emu.linux import vhost_user as vu

RAM_SIZE = 1 << 20
GUEST_BASE = 0x0  # guest-physical address of the region
USER_BASE = 0x7F00_0000_0000  # the region's address in "QEMU": ring addresses use it
QUEUE_SIZE = 8
ARENA = 0x10000  # bytes of request buffers, reused round-robin
# Descriptor flags (virtio 1.x, 2.7.5): the driver's own copy, not the back end's
DESC_F_NEXT = 1
DESC_F_WRITE = 2
DESC_F_INDIRECT = 4
# vhost-user (QEMU docs/interop/vhost-user.rst): the front end's own copy as well
PROTOCOL_F_SLAVE_REQ = 5
SET_SLAVE_REQ_FD = 21


class FakeFrontEnd:
    """QEMU + guest driver for one device; ``pump`` lets the back end read what was sent."""

    def __init__(self, sock: socket.socket, pump) -> None:
        self.sock = sock
        self.pump = pump  # callable: the back end receives one message
        self.fd = os.memfd_create("guest-ram")
        os.ftruncate(self.fd, RAM_SIZE)
        self.ram = mmap.mmap(self.fd, RAM_SIZE)
        self.next_free = 0x40000
        self.queues: dict[int, dict] = {}
        self.event_idx = True
        self.backend_channel: socket.socket | None = None  # our end of SET_SLAVE_REQ_FD's

    # ---------------------------------------------------------------- messages

    def send(self, request: int, payload: bytes = b"", fds: list[int] = (), need_reply=False):
        flags = vu.VERSION | (vu.FLAG_NEED_REPLY if need_reply else 0)
        data = vu.HEADER.pack(request, flags, len(payload)) + payload
        if fds:
            socket.send_fds(self.sock, [data], list(fds))
        else:
            self.sock.sendall(data)
        self.pump()

    def reply(self) -> tuple[int, int, bytes]:
        head = self.sock.recv(vu.HEADER.size)
        request, flags, size = vu.HEADER.unpack(head)
        payload = self.sock.recv(size) if size else b""
        return request, flags, payload

    def call(self, request: int, payload: bytes = b"", fds=()) -> bytes:
        self.send(request, payload, fds)
        got, flags, body = self.reply()
        assert got == request and flags & vu.FLAG_REPLY
        return body

    def u64(self, request: int, value: int, fds=(), need_reply=False) -> None:
        self.send(request, struct.pack("<Q", value), fds, need_reply)

    def handshake(self, features: int | None = None, num_queues: int = 1,
                  backend_channel: bool = False) -> int:
        """QEMU's start-up sequence; ``backend_channel``: also hand over the back end's
        request socket (SET_SLAVE_REQ_FD) when SLAVE_REQ is offered, as UML's virtio_uml
        does (it gets the device's IRQ number from that step)."""
        offered = struct.unpack("<Q", self.call(vu.GET_FEATURES))[0]
        proto = struct.unpack("<Q", self.call(vu.GET_PROTOCOL_FEATURES))[0]
        self.u64(vu.SET_PROTOCOL_FEATURES, proto)
        if backend_channel and proto >> PROTOCOL_F_SLAVE_REQ & 1:
            assert self.set_backend_channel() == 0
        self.send(vu.SET_OWNER)
        chosen = offered if features is None else features
        self.event_idx = bool(chosen >> vu.VIRTIO_RING_F_EVENT_IDX & 1)
        self.u64(vu.SET_FEATURES, chosen)
        table = struct.pack("<II", 1, 0) + struct.pack("<QQQQ", GUEST_BASE, RAM_SIZE, USER_BASE, 0)
        self.send(vu.SET_MEM_TABLE, table, [self.fd], need_reply=True)  # the receiver gets a copy
        status = struct.unpack("<Q", self.reply()[2])[0]
        assert status == 0
        for index in range(num_queues):
            self.setup_queue(index)
        return offered

    def set_backend_channel(self) -> int:
        """SET_SLAVE_REQ_FD with a new socket pair (no payload, the fd in ancillary data,
        NEED_REPLY as with REPLY_ACK); keep our end in ``backend_channel``; the ack status."""
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            self.send(SET_SLAVE_REQ_FD, b"", [theirs.fileno()], need_reply=True)
        finally:
            theirs.close()  # the back end holds its own copy now
        if self.backend_channel is not None:
            self.backend_channel.close()
        self.backend_channel = ours
        return struct.unpack("<Q", self.reply()[2])[0]

    def setup_queue(self, index: int) -> None:
        base = 0x1000 + index * 0x4000
        desc, avail, used = base, base + 0x1000, base + 0x2000
        self.send(vu.SET_VRING_NUM, struct.pack("<II", index, QUEUE_SIZE))
        self.send(vu.SET_VRING_BASE, struct.pack("<II", index, 0))
        self.send(vu.SET_VRING_ADDR, struct.pack(
            "<IIQQQQ", index, 0, USER_BASE + desc, USER_BASE + used, USER_BASE + avail, 0))
        kick, call = os.eventfd(0, os.EFD_NONBLOCK), os.eventfd(0, os.EFD_NONBLOCK)
        self.u64(vu.SET_VRING_CALL, index, [call])
        self.u64(vu.SET_VRING_KICK, index, [kick])
        self.send(vu.SET_VRING_ENABLE, struct.pack("<II", index, 1))
        self.queues[index] = {"desc": desc, "avail": avail, "used": used, "kick": kick,
                              "call": call, "avail_idx": 0, "used_seen": 0, "free": 0,
                              "tokens": {}}

    # ---------------------------------------------------------------- memory

    def alloc(self, size: int) -> int:
        addr = self.next_free
        self.next_free += (size + 15) & ~15
        if self.next_free > 0x40000 + ARENA:  # reuse memory, as a guest's allocator does
            self.next_free = 0x40000
            return self.alloc(size)
        return addr

    def put(self, data: bytes) -> int:
        addr = self.alloc(max(len(data), 1))
        self.ram[addr:addr + len(data)] = data
        return addr

    # ---------------------------------------------------------------- driver side

    def add(self, index: int, readable: list[bytes], writable: list[int], indirect=True):
        """Add one request (device-readable buffers, device-writable sizes); its token."""
        q = self.queues[index]
        parts = [(self.put(b), len(b), 0) for b in readable]
        parts += [(self.alloc(n), n, DESC_F_WRITE) for n in writable]
        head = q["free"] % QUEUE_SIZE
        q["free"] += 1 if indirect else len(parts)
        if indirect:
            table = b"".join(
                struct.pack("<QIHH", a, n, f | (DESC_F_NEXT if i < len(parts) - 1
                                                  else 0), i + 1)
                for i, (a, n, f) in enumerate(parts))
            addr = self.put(table)
            self._desc(q, head, addr, len(table), DESC_F_INDIRECT, 0)
        else:
            for i, (a, n, f) in enumerate(parts):
                last = i == len(parts) - 1
                self._desc(q, (head + i) % QUEUE_SIZE, a, n,
                           f | (0 if last else DESC_F_NEXT), (head + i + 1) % QUEUE_SIZE)
        slot = q["avail"] + 4 + 2 * (q["avail_idx"] % QUEUE_SIZE)
        self.ram[slot:slot + 2] = struct.pack("<H", head)
        q["avail_idx"] = (q["avail_idx"] + 1) & 0xFFFF
        self.ram[q["avail"] + 2:q["avail"] + 4] = struct.pack("<H", q["avail_idx"])
        q["tokens"][head] = [a for a, _, f in parts if f & DESC_F_WRITE]
        return head

    def _desc(self, q, i: int, addr: int, length: int, flags: int, nxt: int) -> None:
        off = q["desc"] + 16 * i
        self.ram[off:off + 16] = struct.pack("<QIHH", addr, length, flags, nxt)

    def set_used_event(self, index: int, value: int) -> None:
        q = self.queues[index]
        off = q["avail"] + 4 + 2 * QUEUE_SIZE
        self.ram[off:off + 2] = struct.pack("<H", value)

    def avail_event(self, index: int) -> int:
        q = self.queues[index]
        off = q["used"] + 4 + 8 * QUEUE_SIZE
        return struct.unpack_from("<H", self.ram, off)[0]

    def used(self, index: int) -> list[tuple[int, int]]:
        """New used elements (head, length) since the last call."""
        q = self.queues[index]
        idx = struct.unpack_from("<H", self.ram, q["used"] + 2)[0]
        out = []
        while q["used_seen"] != idx:
            off = q["used"] + 4 + 8 * (q["used_seen"] % QUEUE_SIZE)
            out.append(struct.unpack_from("<II", self.ram, off))
            q["used_seen"] = (q["used_seen"] + 1) & 0xFFFF
        return out

    def called(self, index: int) -> int:
        """How many times the back end signalled the call eventfd since the last look."""
        try:
            return os.eventfd_read(self.queues[index]["call"])
        except BlockingIOError:
            return 0

    def read_back(self, index: int, head: int, sizes: list[int]) -> list[bytes]:
        addrs = self.queues[index]["tokens"][head]
        return [bytes(self.ram[a:a + n]) for a, n in zip(addrs, sizes)]

    def close(self) -> None:
        if self.backend_channel is not None:
            self.backend_channel.close()
        self.ram.close()
        os.close(self.fd)
        for q in self.queues.values():
            os.close(q["kick"])
            os.close(q["call"])
        self.sock.close()
