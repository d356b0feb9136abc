"""Split virtqueues in the guest's RAM, as a vhost-user back end sees them (virtio 1.x, 2.7).

Why a module of its own: the ring operations are every transfer's hot path, apart from the
vhost-user messages that set them up (vhost_user.py). The guest's RAM arrives as file
descriptors (SET_MEM_TABLE) and is read and written in place through ``mmap``; a driver adds
chains of descriptors to the available ring, the device takes them, answers, and puts used
elements on the used ring. Indirect descriptors (2.7.5.3) and EVENT_IDX (2.7.10) are
handled because QEMU negotiates both with the guest whatever the back end offers
(linux-kernel-notes.md).

Ordering: the stores rely on x86-TSO (the used element is stored before the used index);
where a store must be seen before a later load (avail_event before the avail index is
looked at again, the used index before used_event), :func:`fence` stands between them. The
x86-64 hosts QEMU and UML run this on give both.
"""

from __future__ import annotations

import mmap
import os
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

# Split virtqueue descriptor and ring flags (virtio 1.x, 2.7.5 and 2.7.6).
VRING_DESC_F_NEXT = 1
VRING_DESC_F_WRITE = 2
VRING_DESC_F_INDIRECT = 4
VRING_AVAIL_F_NO_INTERRUPT = 1
MAX_REGIONS = 8  # VHOST_MEMORY_BASELINE_NREGIONS: the regions of one memory table

_REGION = struct.Struct("<QQQQ")  # guest address, size, user (QEMU) address, mmap offset
_DESC = struct.Struct("<QIHH")  # address, length, flags, next
_U16 = struct.Struct("<H")
_USED_ELEM = struct.Struct("<II")
_USED_PAIR = struct.Struct("<IIII")
_TABLE_MAX = 16  # indirect tables up to this many entries are read with one unpack
_TABLES = [struct.Struct("<" + "QIHH" * n) for n in range(_TABLE_MAX + 1)]
_U16S = [struct.Struct(f"<{n}H") for n in range(9)]  # 1..8 heads taken at once
_FENCE = threading.Lock()  # see fence()


def _u16s(count: int) -> struct.Struct:
    return _U16S[count] if count < len(_U16S) else struct.Struct(f"<{count}H")


def fence() -> None:
    """Make our stores to the ring visible before our next load from it. The driver stores
    its index, then loads ours (avail_event, the used index); we store ours, then load its
    (the available index, used_event): x86 may pass a load ahead of an older store, never
    across a locked instruction (the barrier of virtio 1.x 2.7.10). An uncontended lock is
    one."""
    _FENCE.acquire()
    _FENCE.release()


class VhostUserError(Exception):
    """The front end sent something the protocol does not allow; the connection ends."""


@dataclass
class MemoryRegion:
    guest_addr: int
    size: int
    user_addr: int
    mapping: mmap.mmap
    offset: int  # where the region starts inside the mapping (the message's mmap offset)


class GuestMemory:
    """The guest's RAM as the front end shared it: guest-physical and front-end-virtual
    (QEMU's or UML's) address lookups."""

    def __init__(self) -> None:
        self.regions: list[MemoryRegion] = []
        # (guest start, guest end, mapping, mapping offset - guest start) per region: the
        # descriptor lookups of every request go through this (no attribute walks)
        self._spans: list[tuple[int, int, mmap.mmap, int]] = []

    def set_table(self, payload: bytes, fds: list[int]) -> None:
        """Map the regions of a SET_MEM_TABLE message (each fd once; it is closed after)."""
        if len(payload) < 8:
            raise VhostUserError("SET_MEM_TABLE payload too short")
        count = struct.unpack_from("<I", payload)[0]
        if count != len(fds) or count > MAX_REGIONS or len(payload) < 8 + count * _REGION.size:
            raise VhostUserError(f"SET_MEM_TABLE with {count} regions and {len(fds)} fds")
        self.close()
        try:
            for i in range(count):
                gpa, size, uva, offset = _REGION.unpack_from(payload, 8 + i * _REGION.size)
                mapping = mmap.mmap(fds[i], size + offset, mmap.MAP_SHARED,
                                    mmap.PROT_READ | mmap.PROT_WRITE)
                self.regions.append(MemoryRegion(gpa, size, uva, mapping, offset))
            self._spans = [(r.guest_addr, r.guest_addr + r.size, r.mapping,
                            r.offset - r.guest_addr) for r in self.regions]
        finally:
            for fd in fds:
                os.close(fd)

    def close(self) -> None:
        for region in self.regions:
            region.mapping.close()
        self.regions = []
        self._spans = []

    def _find(self, address: int, length: int, user: bool) -> tuple[mmap.mmap, int]:
        for region in self.regions:
            base = region.user_addr if user else region.guest_addr
            if base <= address and address + length <= base + region.size:
                return region.mapping, region.offset + address - base
        kind = "QEMU address" if user else "guest address"
        raise VhostUserError(f"{kind} 0x{address:x}+{length} is outside the memory table")

    def locate(self, address: int, length: int) -> tuple[mmap.mmap, int] | None:
        """(mapping, offset) of a guest-physical range inside one region, or None."""
        end = address + length
        for start, stop, mapping, delta in self._spans:
            if start <= address and end <= stop:
                return mapping, address + delta
        return None

    def guest(self, address: int, length: int) -> tuple[mmap.mmap, int]:
        """(mapping, offset) of a guest-physical range (descriptor buffers)."""
        located = self.locate(address, length)
        return located if located is not None else self._find(address, length, user=False)

    def user(self, address: int, length: int) -> tuple[mmap.mmap, int]:
        """(mapping, offset) of a QEMU-virtual range (the ring addresses of SET_VRING_ADDR)."""
        return self._find(address, length, user=True)

    def read(self, address: int, length: int) -> bytes:
        mapping, offset = self.guest(address, length)
        return mapping[offset:offset + length]

    def write(self, address: int, data: bytes) -> None:
        mapping, offset = self.guest(address, len(data))
        mapping[offset:offset + len(data)] = data


@dataclass(slots=True)
class Chain:
    """One descriptor chain taken from the available ring: its head and its buffers as
    (guest address, length) lists, device-readable first, then device-writable."""

    head: int
    readable: list[tuple[int, int]]
    writable: list[tuple[int, int]]


@dataclass
class Vring:
    """A split virtqueue as the back end sees it."""

    index: int
    num: int = 0
    desc: tuple[mmap.mmap, int] | None = None
    avail: tuple[mmap.mmap, int] | None = None
    used: tuple[mmap.mmap, int] | None = None
    last_avail: int = 0
    used_idx: int = 0
    kick_fd: int | None = None
    call_fd: int | None = None
    err_fd: int | None = None
    call: Callable[[], None] | None = None  # in-band notifications: the call as a message
    enabled: bool = False
    started: bool = False
    signalled_used: int = 0  # used index at the last call (EVENT_IDX suppression)
    signalled_valid: bool = False
    notifications: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def ready(self) -> bool:
        return self.started and self.enabled and self.desc is not None

    def close_fds(self) -> None:
        for name in ("kick_fd", "call_fd", "err_fd"):
            fd = getattr(self, name)
            if fd is not None:
                os.close(fd)
                setattr(self, name, None)


class VirtQueue:
    """Operations on one ring in guest memory: take chains, put used elements, notify.

    The ring's three areas are looked up once (a new queue is made whenever they move), and
    the hot operations do one ``struct`` call per ring access: a register read through
    virtio-i2c is two chains taken, two used elements and one call per kick.
    """

    def __init__(self, ring: Vring, memory: GuestMemory, event_idx: bool, indirect: bool) -> None:
        self.ring = ring
        self.memory = memory
        self.event_idx = event_idx
        self.indirect = indirect
        self.num = ring.num
        self._desc_map, self._desc_base = ring.desc  # type: ignore[misc]
        self._avail_map, self._avail_base = ring.avail  # type: ignore[misc]
        self._used_map, self._used_base = ring.used  # type: ignore[misc]

    def take(self) -> list[int]:
        """The heads of every chain the driver has added since the last look, in ring
        order; they are the device's from now on (answer each with a used element)."""
        ring = self.ring
        start = ring.last_avail
        idx = _U16.unpack_from(self._avail_map, self._avail_base + 2)[0]
        count = (idx - start) & 0xFFFF
        if not count:
            return []
        num = self.num
        if count > num:
            raise VhostUserError(f"queue {ring.index}: {count} entries added to a ring of {num}")
        slot = start & (num - 1)
        base = self._avail_base + 4
        if slot + count <= num:
            heads = list(_u16s(count).unpack_from(self._avail_map, base + 2 * slot))
        else:  # the entries wrap round the end of the ring
            first = num - slot
            heads = [*_u16s(first).unpack_from(self._avail_map, base + 2 * slot),
                     *_u16s(count - first).unpack_from(self._avail_map, base)]
        ring.last_avail = idx
        if max(heads) >= num:
            raise VhostUserError(f"queue {ring.index}: descriptor head {max(heads)} >= size {num}")
        return heads

    def pop(self) -> Chain | None:
        """The next available chain, or None when the driver has added nothing new."""
        ring = self.ring
        mapping, base = self._avail_map, self._avail_base
        if _U16.unpack_from(mapping, base + 2)[0] == ring.last_avail:
            return None
        head = _U16.unpack_from(mapping, base + 4 + 2 * (ring.last_avail & (self.num - 1)))[0]
        ring.last_avail = (ring.last_avail + 1) & 0xFFFF
        if head >= self.num:
            raise VhostUserError(f"queue {ring.index}: descriptor head {head} >= size {self.num}")
        return self.chain(head)

    def table(self, head: int, count: int) -> tuple[int, ...] | None:
        """The entries of ``head``'s indirect table, flat (address, length, flags, next,
        ...), when ``head`` is a lone indirect descriptor (how Linux adds a request of two
        buffers or more) of exactly ``count`` entries in guest memory; None otherwise. The
        caller checks the entries' flags and links; :meth:`chain` walks any chain."""
        addr, length, flags, _ = _DESC.unpack_from(self._desc_map, self._desc_base + 16 * head)
        if flags != VRING_DESC_F_INDIRECT or length != 16 * count or count > _TABLE_MAX:
            return None
        located = self.memory.locate(addr, length)
        if located is None:
            return None
        return _TABLES[count].unpack_from(*located)

    def chain(self, head: int) -> Chain:
        """Walk the chain of ``head`` (direct descriptors, then at most one indirect table:
        virtio 1.x 2.7.5.3) into its device-readable and device-writable buffers."""
        readable: list[tuple[int, int]] = []
        writable: list[tuple[int, int]] = []
        table, table_base = self._desc_map, self._desc_base
        size = self.num
        index = head
        seen = 0
        while True:
            addr, length, flags, nxt = _DESC.unpack_from(table, table_base + 16 * index)
            if flags & VRING_DESC_F_INDIRECT:
                # 2.7.5.3: an indirect table replaces the rest; it cannot chain on
                if flags & VRING_DESC_F_NEXT or length % 16 or not length:
                    raise VhostUserError(f"queue {self.ring.index}: bad indirect descriptor")
                self._walk_table(addr, length, readable, writable)
                return Chain(head, readable, writable)
            if flags & VRING_DESC_F_WRITE:
                writable.append((addr, length))
            elif writable:
                raise VhostUserError(f"queue {self.ring.index}: readable after writable")
            else:
                readable.append((addr, length))
            seen += 1
            if not flags & VRING_DESC_F_NEXT:
                return Chain(head, readable, writable)
            if nxt >= size or seen >= size:
                raise VhostUserError(f"queue {self.ring.index}: descriptor chain loops or ends")
            index = nxt

    def _walk_table(self, addr: int, length: int, readable: list[tuple[int, int]],
                    writable: list[tuple[int, int]]) -> None:
        """The chain inside an indirect table (read with one unpack when it is small)."""
        mapping, offset = self.memory.guest(addr, length)
        size = length // 16
        if size <= _TABLE_MAX:
            entries = _TABLES[size].unpack_from(mapping, offset)
        else:
            entries = tuple(value for entry in _DESC.iter_unpack(mapping[offset:offset + length])
                            for value in entry)
        index = seen = 0
        while True:
            at = 4 * index
            flags = entries[at + 2]
            if flags & VRING_DESC_F_INDIRECT:  # no nesting
                raise VhostUserError(f"queue {self.ring.index}: bad indirect descriptor")
            if flags & VRING_DESC_F_WRITE:
                writable.append((entries[at], entries[at + 1]))
            elif writable:
                raise VhostUserError(f"queue {self.ring.index}: readable after writable")
            else:
                readable.append((entries[at], entries[at + 1]))
            seen += 1
            if not flags & VRING_DESC_F_NEXT:
                return
            index = entries[at + 3]
            if index >= size or seen >= size:
                raise VhostUserError(f"queue {self.ring.index}: descriptor chain loops or ends")

    def push(self, head: int, written: int) -> None:
        """Put a used element (chain head, bytes written) on the used ring."""
        ring = self.ring
        mapping, base = self._used_map, self._used_base
        _USED_ELEM.pack_into(mapping, base + 4 + 8 * (ring.used_idx & (self.num - 1)),
                             head, written)
        ring.used_idx = (ring.used_idx + 1) & 0xFFFF
        _U16.pack_into(mapping, base + 2, ring.used_idx)

    def push2(self, head1: int, written1: int, head2: int, written2: int) -> None:
        """Two used elements, then one store of the used index (the driver sees both)."""
        ring = self.ring
        mapping, base = self._used_map, self._used_base
        used = ring.used_idx
        slot = used & (self.num - 1)
        if slot + 1 < self.num:
            _USED_PAIR.pack_into(mapping, base + 4 + 8 * slot, head1, written1, head2, written2)
        else:
            _USED_ELEM.pack_into(mapping, base + 4 + 8 * slot, head1, written1)
            _USED_ELEM.pack_into(mapping, base + 4, head2, written2)
        ring.used_idx = used = (used + 2) & 0xFFFF
        _U16.pack_into(mapping, base + 2, used)

    def settle(self) -> bool:
        """After taking entries: publish avail_event (EVENT_IDX), then look again; True when
        the driver added more meanwhile (it may not have kicked for them)."""
        ring = self.ring
        if self.event_idx:
            _U16.pack_into(self._used_map, self._used_base + 4 + 8 * self.num, ring.last_avail)
        fence()  # the used index and avail_event out before the available index comes in
        return _U16.unpack_from(self._avail_map, self._avail_base + 2)[0] != ring.last_avail

    def used_event(self) -> int:
        """EVENT_IDX: the used index the driver has consumed up to (it writes it as it takes
        used buffers, when it wants interrupts)."""
        return _U16.unpack_from(self._avail_map, self._avail_base + 4 + 2 * self.num)[0]

    def notify(self, old_used: int) -> None:
        """Call the driver if it wants an interrupt for the entries used since ``old_used``
        (after :meth:`settle` or :func:`fence`: the used index out before used_event in)."""
        ring = self.ring
        if (ring.call_fd is None and ring.call is None) or ring.used_idx == old_used:
            return
        if self.event_idx:
            used_event = _U16.unpack_from(self._avail_map,
                                          self._avail_base + 4 + 2 * self.num)[0]
            # vring_need_event (2.7.10): did new_idx pass used_event since old_idx?
            if (ring.used_idx - used_event - 1) & 0xFFFF >= (ring.used_idx - old_used) & 0xFFFF:
                return
        elif _U16.unpack_from(self._avail_map, self._avail_base)[0] & VRING_AVAIL_F_NO_INTERRUPT:
            return
        if ring.call_fd is not None:
            os.eventfd_write(ring.call_fd, 1)
        else:
            ring.call()  # type: ignore[misc]
        ring.notifications += 1
