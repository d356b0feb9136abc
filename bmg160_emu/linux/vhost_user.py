"""The vhost-user protocol (back-end side): a virtio device served from this process to QEMU.

Why: a virtio device whose queues are processed here lets a real guest kernel's drivers
(virtio-i2c, virtio-gpio) reach the model at the moment they make each transfer. QEMU
connects to a UNIX socket, shares the guest's RAM as file descriptors (a memfd memory
backend with share=on), and hands over one eventfd per queue for each direction: the guest
"kicks" when it adds buffers, the back end "calls" when it has used them.

Written from the vhost-user specification (QEMU docs/interop/vhost-user.rst). Only what the
two devices need is offered: protocol features REPLY_ACK, SLAVE_REQ (for UML) and CONFIG,
ring features INDIRECT_DESC and EVENT_IDX (QEMU negotiates both with the guest whatever the
back end offers; see linux-kernel-notes.md). The rings themselves, in the guest's RAM, are
virtqueue.py's.
"""

from __future__ import annotations

import errno
import logging
import os
import struct
from collections.abc import Callable

from bmg160_emu.linux.virtqueue import GuestMemory, VhostUserError, VirtQueue, Vring

log = logging.getLogger(__name__)

# Message types (vhost-user spec, "Front-end message types").
GET_FEATURES = 1
SET_FEATURES = 2
SET_OWNER = 3
RESET_OWNER = 4
SET_MEM_TABLE = 5
SET_LOG_BASE = 6
SET_LOG_FD = 7
SET_VRING_NUM = 8
SET_VRING_ADDR = 9
SET_VRING_BASE = 10
GET_VRING_BASE = 11
SET_VRING_KICK = 12
SET_VRING_CALL = 13
SET_VRING_ERR = 14
GET_PROTOCOL_FEATURES = 15
SET_PROTOCOL_FEATURES = 16
GET_QUEUE_NUM = 17
SET_VRING_ENABLE = 18
SET_SLAVE_REQ_FD = 21  # the spec now calls it SET_BACKEND_REQ_FD
SET_VRING_ENDIAN = 23
GET_CONFIG = 24
SET_CONFIG = 25
RESET_DEVICE = 34
VRING_KICK = 35  # in-band notifications: a kick as a message (no kick eventfd)

MESSAGE_NAMES = {
    value: name for name, value in list(globals().items())
    if name.isupper() and isinstance(value, int) and name.startswith(("GET_", "SET_", "RESET_"))
}

# Header flags: version 1 in bits 0-1, bit 2 reply, bit 3 need-reply.
VERSION = 0x1
FLAG_REPLY = 0x4
FLAG_NEED_REPLY = 0x8
HEADER = struct.Struct("<III")
MAX_PAYLOAD = 4096  # the largest message we accept (a full memory table is 8 * 32 + 8 bytes)
MAX_FDS = 8  # VHOST_MEMORY_BASELINE_NREGIONS: at most one fd per region

# Protocol feature bits.
PROTOCOL_F_REPLY_ACK = 3
# The back end's own channel to the front end (now called BACKEND_REQ). We never send on
# it, but UML's virtio_uml allocates a device's interrupt number only when it sets this
# channel up: without it the device's IRQ stays 0 and i2c-virtio's probe fails with -EBUSY
# against the timer (linux-kernel-notes.md, "User-mode Linux", fix 3).
PROTOCOL_F_SLAVE_REQ = 5
PROTOCOL_F_CONFIG = 9
# Kicks as VRING_KICK messages and calls as SLAVE_VRING_CALL messages on the SLAVE_REQ
# channel, each answered: what UML's time travel needs, since then the guest learns of a
# completion as an event of the calendar (arch/um/drivers/virtio_uml.c), not as a signal
# that may come at any instant. Offered only by a device told to (``inband``).
PROTOCOL_F_INBAND_NOTIFICATIONS = 14
# Back-end requests (the spec's "back-end message types")
SLAVE_VRING_CALL = 4

# Virtio feature bits (virtio 1.x, 6 "Reserved Feature Bits") and vhost-user's own bit 30.
VIRTIO_RING_F_INDIRECT_DESC = 28
VIRTIO_RING_F_EVENT_IDX = 29
VHOST_USER_F_PROTOCOL_FEATURES = 30
VIRTIO_F_VERSION_1 = 32

VRING_FD_INVALID = 0x100  # bit 8 of the u64 of SET_VRING_KICK/CALL/ERR: no fd passed

U64 = struct.Struct("<Q")  # a u64 payload (features, status)
_HEADER = struct.Struct("<III")  # request, flags, size (as HEADER; here for the back end's own)
_CALL_HEAD = _HEADER.pack(SLAVE_VRING_CALL, VERSION | FLAG_NEED_REPLY, 8)  # + vring state
_STATE = struct.Struct("<II")  # vring index, number
_ADDR = struct.Struct("<IIQQQQ")  # index, flags, descriptor, used, available, log addresses
_CONFIG_HEAD = struct.Struct("<III")  # offset, size, flags


class VhostUserDevice:
    """A virtio device type served over vhost-user. Subclasses set ``num_queues``,
    ``device_features`` and ``config``, and implement :meth:`process` for a kicked queue."""

    num_queues = 1
    device_features = 0
    config = b""
    name = "vhost-user"

    def __init__(self) -> None:
        self.memory = GuestMemory()
        self.rings = [Vring(i) for i in range(self.num_queues)]
        self.queues: list[VirtQueue | None] = [None] * self.num_queues
        self.features = 0
        self.protocol_features = 0
        self.owner = False
        self.slave_req_fd: int | None = None  # SET_SLAVE_REQ_FD's socket (in-band calls)
        self.on_fds_changed: Callable[[], None] | None = None  # the server re-reads kick fds
        # in-band notifications (time travel): offered when set; a call then waits for the
        # front end's answer through ``wait_readable`` (the calendar serves UML meanwhile)
        self.inband = False
        self.wait_readable: Callable[[int], None] | None = None
        self.inband_calls = 0
        self.kicking = False  # inside a VRING_KICK message: UML waits for its reply
        self._calls_owed = 0  # in-band calls whose answer is not read yet

    # ---------------------------------------------------------------- feature words

    @property
    def offered_features(self) -> int:
        return (self.device_features | 1 << VIRTIO_F_VERSION_1
                | 1 << VHOST_USER_F_PROTOCOL_FEATURES
                | 1 << VIRTIO_RING_F_INDIRECT_DESC | 1 << VIRTIO_RING_F_EVENT_IDX)

    @property
    def offered_protocol_features(self) -> int:
        features = 1 << PROTOCOL_F_REPLY_ACK | 1 << PROTOCOL_F_SLAVE_REQ
        if self.config:
            features |= 1 << PROTOCOL_F_CONFIG
        if self.inband:
            features |= 1 << PROTOCOL_F_INBAND_NOTIFICATIONS
        return features

    @property
    def _inband_active(self) -> bool:
        return bool(self.protocol_features >> PROTOCOL_F_INBAND_NOTIFICATIONS & 1)

    # ---------------------------------------------------------------- to override

    def process(self, queue: VirtQueue) -> None:
        """Take every available chain of ``queue``, answer it, push it used."""
        raise NotImplementedError

    def answered(self, index: int) -> None:
        """The driver has been told about the chains just used: work that can wait for
        that (it is off the guest's round trip) goes here."""

    def ring_started(self, index: int) -> None:
        """A ring became ready (kick fd received and enabled)."""

    def ring_stopped(self, index: int) -> None:
        """A ring was stopped (GET_VRING_BASE, reset or disconnect)."""

    # ---------------------------------------------------------------- ring service

    def kick(self, index: int) -> None:
        """The driver kicked ``index`` (or the server polls it): serve the queue."""
        queue = self.queues[index]
        if queue is None or not self.rings[index].ready:
            return
        old_used = queue.ring.used_idx
        self.process(queue)
        while queue.settle():  # looked again after avail_event: no kick can be lost
            self.process(queue)
        queue.notify(old_used)  # one call for all the kick's chains
        self.answered(index)

    def kick_fds(self) -> dict[int, int]:
        """{kick fd: ring index} of the rings that are started."""
        return {r.kick_fd: r.index for r in self.rings if r.kick_fd is not None and r.started}

    def reset(self) -> None:
        for ring in self.rings:
            if ring.started:
                self.ring_stopped(ring.index)
            ring.close_fds()
        self.rings = [Vring(i) for i in range(self.num_queues)]
        self.queues = [None] * self.num_queues
        self.memory.close()
        self._close_slave_req()
        self.features = 0
        self.protocol_features = 0
        self.owner = False

    def _close_slave_req(self) -> None:
        self._calls_owed = 0
        if self.slave_req_fd is not None:
            os.close(self.slave_req_fd)
            self.slave_req_fd = None

    # ---------------------------------------------------------------- messages

    def _ring(self, index: int) -> Vring:
        if not 0 <= index < self.num_queues:
            raise VhostUserError(f"{self.name}: no queue {index} (it has {self.num_queues})")
        return self.rings[index]

    def _setup_queue(self, ring: Vring) -> None:
        if self._inband_active:
            ring.call = lambda index=ring.index: self._call_inband(index)
        self.queues[ring.index] = VirtQueue(
            ring, self.memory,
            event_idx=bool(self.features >> VIRTIO_RING_F_EVENT_IDX & 1),
            indirect=bool(self.features >> VIRTIO_RING_F_INDIRECT_DESC & 1),
        )

    def handle(self, request: int, payload: bytes, fds: list[int]) -> bytes | None:
        """Answer one message: its reply payload, or None when it has none. An int result
        for REPLY_ACK is given by raising OSError (non-zero) or returning normally (zero)."""
        if request == GET_FEATURES:
            return U64.pack(self.offered_features)
        if request == SET_FEATURES:
            self.features = _u64(payload)
            for ring in self.rings:
                if self.queues[ring.index] is not None:
                    self._setup_queue(ring)
            return None
        if request == GET_PROTOCOL_FEATURES:
            return U64.pack(self.offered_protocol_features)
        if request == SET_PROTOCOL_FEATURES:
            self.protocol_features = _u64(payload) & self.offered_protocol_features
            return None
        if request == SET_OWNER:
            self.owner = True
            return None
        if request in (RESET_OWNER, RESET_DEVICE):
            self.reset()
            return None
        if request == SET_MEM_TABLE:
            self.memory.set_table(payload, fds)
            # the ring addresses keep their QEMU addresses: translate them again
            for ring in self.rings:
                if "addr" in ring.extra:
                    self._map_ring(ring, *ring.extra["addr"])
            return None
        if request == SET_VRING_NUM:
            index, num = _STATE.unpack_from(payload)
            if num == 0 or num > 32768 or num & (num - 1):
                raise VhostUserError(f"queue size {num} is not a power of 2 up to 32768")
            ring = self._ring(index)
            if num != ring.num and ring.desc is not None:
                # the queue's areas were mapped for the old size: SET_VRING_ADDR maps again
                ring.desc = ring.avail = ring.used = None
                self.queues[index] = None
            ring.num = num
            return None
        if request == SET_VRING_ADDR:
            index, _flags, desc, used, avail, _log = _ADDR.unpack_from(payload)
            ring = self._ring(index)
            ring.extra["addr"] = (desc, used, avail)
            self._map_ring(ring, desc, used, avail)
            return None
        if request == SET_VRING_BASE:
            index, base = _STATE.unpack_from(payload)
            ring = self._ring(index)
            ring.last_avail = ring.used_idx = base & 0xFFFF
            return None
        if request == GET_VRING_BASE:
            index, _ = _STATE.unpack_from(payload)
            ring = self._ring(index)
            if ring.started:
                self.ring_stopped(index)
            ring.started = False
            if ring.kick_fd is not None:
                os.close(ring.kick_fd)
                ring.kick_fd = None
            self._fds_changed()
            return _STATE.pack(index, ring.last_avail)
        if request in (SET_VRING_KICK, SET_VRING_CALL, SET_VRING_ERR):
            self._set_vring_fd(request, payload, fds)
            return None
        if request == SET_VRING_ENABLE:
            index, enable = _STATE.unpack_from(payload)
            ring = self._ring(index)
            ring.enabled = bool(enable)
            if self._inband_active and ring.kick_fd is None:
                ring.started = ring.enabled  # no SET_VRING_KICK comes: kicks are messages
            if ring.ready:
                self.ring_started(index)
                self.kick(index)  # entries added before the ring was enabled
            return None
        if request == SET_SLAVE_REQ_FD:
            # QEMU sends no payload, UML none or a u64; the fd is what counts
            if len(fds) != 1:
                for fd in fds:
                    os.close(fd)
                raise VhostUserError(f"SET_SLAVE_REQ_FD with {len(fds)} file descriptors")
            self._close_slave_req()
            self.slave_req_fd = fds[0]
            return None
        if request == VRING_KICK:
            index, _ = _STATE.unpack_from(payload)
            self.kicking = True
            try:
                self.kick(self._ring(index).index)
            finally:
                self.kicking = False
            return None
        if request == GET_QUEUE_NUM:
            return U64.pack(self.num_queues)
        if request == GET_CONFIG:
            offset, size, flags = _CONFIG_HEAD.unpack_from(payload)
            data = self.config[offset:offset + size].ljust(size, b"\0")
            return _CONFIG_HEAD.pack(offset, size, flags) + data
        if request in (SET_CONFIG, SET_VRING_ENDIAN):
            return None  # read-only configuration; little-endian rings only
        raise OSError(errno.ENOSYS, f"message {MESSAGE_NAMES.get(request, request)} unsupported")

    def _map_ring(self, ring: Vring, desc: int, used: int, avail: int) -> None:
        if not ring.num:
            raise VhostUserError(f"SET_VRING_ADDR for queue {ring.index} before SET_VRING_NUM")
        if not self.memory.regions:
            return  # mapped when the memory table arrives
        ring.desc = self.memory.user(desc, 16 * ring.num)
        ring.avail = self.memory.user(avail, 6 + 2 * ring.num)
        ring.used = self.memory.user(used, 6 + 8 * ring.num)
        self._setup_queue(ring)

    def _set_vring_fd(self, request: int, payload: bytes, fds: list[int]) -> None:
        value = _u64(payload)
        ring = self._ring(value & 0xFF)
        fd = None
        if not value & VRING_FD_INVALID:
            if len(fds) != 1:
                raise VhostUserError(f"{MESSAGE_NAMES[request]} without its file descriptor")
            fd = fds[0]
        name = {SET_VRING_KICK: "kick_fd", SET_VRING_CALL: "call_fd", SET_VRING_ERR: "err_fd"}
        old = getattr(ring, name[request])
        if old is not None:
            os.close(old)
        setattr(ring, name[request], fd)  # the latest call fd is the one the guest listens on
        if request == SET_VRING_KICK:
            if fd is None and not self._inband_active:
                raise VhostUserError("polling rings (no kick fd) are not supported")
            if fd is not None:
                os.set_blocking(fd, False)
            ring.started = True
            if not self.features >> VHOST_USER_F_PROTOCOL_FEATURES & 1:
                ring.enabled = True  # without PROTOCOL_FEATURES a ring starts enabled
            self._fds_changed()
            if ring.ready:
                self.ring_started(ring.index)
                self.kick(ring.index)

    def _call_inband(self, index: int) -> None:
        """Call the driver with a SLAVE_VRING_CALL message. UML's interrupt handler makes
        the completion an event of its calendar (it asks the calendar for the time, then
        answers: vu_req_read_message). Inside a kick the answer is not waited for: UML waits
        for the kick's reply, and takes the call (a signal) before it, so the kick's reply
        may follow at once (two hand-overs between the processes per transfer fewer);
        anywhere else it is waited for, the calendar served meanwhile."""
        fd = self.slave_req_fd
        if fd is None:
            raise VhostUserError("in-band call without the SLAVE_REQ channel")
        self.settle_calls()  # an answer still owed on this channel is read first
        os.write(fd, _CALL_HEAD + _STATE.pack(index, 0))
        self._calls_owed += 1
        self.inband_calls += 1
        if not self.kicking:
            self.settle_calls()

    def settle_calls(self) -> None:
        """Read the answers UML owes to our in-band calls (waiting for them, the calendar
        served meanwhile: UML asks it for the time before it answers)."""
        fd = self.slave_req_fd
        while self._calls_owed and fd is not None:
            if self.wait_readable is not None:
                self.wait_readable(fd)
            reply = b""
            while len(reply) < _HEADER.size + 8:
                chunk = os.read(fd, _HEADER.size + 8 - len(reply))
                if not chunk:
                    self._calls_owed = 0
                    raise VhostUserError("the front end closed the SLAVE_REQ channel")
                reply += chunk
            self._calls_owed -= 1

    def _fds_changed(self) -> None:
        if self.on_fds_changed is not None:
            self.on_fds_changed()


def _u64(payload: bytes) -> int:
    if len(payload) < 8:
        raise VhostUserError("message payload shorter than its u64")
    return U64.unpack_from(payload)[0]
