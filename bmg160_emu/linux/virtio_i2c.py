"""A virtio-i2c device (virtio 1.2, 5.19) whose requests reach the emulated chips' I2CBus.

Why: through QEMU's ``vhost-user-i2c-pci`` the guest kernel's own i2c-virtio adapter
carries every transfer of i2c-tools, i2c-dev programs and kernel drivers (bmg160_i2c) to
the model the moment it is made, so FIFO pops, clear-on-read and MSB shadowing behave as on
a real bus. Requests go through the same :class:`~bmg160_emu.bus.i2c.I2CBus` as every other
front end: NACK for absent addresses, transaction hooks (faults), the transaction log and
its trace sinks.

Request layout (5.19.6): a device-readable header (le16 address = 7-bit address << 1, le16
padding, le32 flags: bit 0 FAIL_NEXT, bit 1 M_RD), the message buffer (readable for a
write, writable for a read; absent for a zero-length message), then one writable status
byte (0 OK, 1 error). Requests linked by FAIL_NEXT form one I2C transfer (one stop at its
end): once a request fails, the rest of its group fails too, and the guest sees a short
message count, as a NACK mid-transfer gives on a real adapter.
"""

from __future__ import annotations

import logging
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from operator import itemgetter

from bmg160_emu.bus.i2c import I2C_SMBUS_BLOCK_MAX, I2CBus, I2CMessage
from bmg160_emu.device.registers import address_of
from bmg160_emu.linux.vhost_user import VhostUserDevice
from bmg160_emu.linux.virtqueue import (
    VRING_DESC_F_NEXT,
    VRING_DESC_F_WRITE,
    Chain,
    VhostUserError,
    VirtQueue,
)

log = logging.getLogger(__name__)

VIRTIO_I2C_F_ZERO_LENGTH_REQUEST = 0  # 5.19.3; the Linux driver refuses to probe without it
FLAG_FAIL_NEXT = 1
FLAG_M_RD = 2
MSG_OK = 0
MSG_ERR = 1
_HEADER = struct.Struct("<HHI")
_STATUS = (bytes([MSG_OK]), bytes([MSG_ERR]))
# The indirect tables of a register read as Linux's driver lays them out, by (length,
# flags, next) of each entry but the read's buffer length: header (8, readable), register
# (1, readable) or buffer (writable), status (1, writable, the chain's end)
_WRITE_SHAPE = itemgetter(1, 2, 3, 5, 6, 7, 9, 10)
_WRITE_1 = (_HEADER.size, VRING_DESC_F_NEXT, 1, 1, VRING_DESC_F_NEXT, 2, 1, VRING_DESC_F_WRITE)
_READ_SHAPE = itemgetter(1, 2, 3, 6, 7, 9, 10)
_READ_N = (_HEADER.size, VRING_DESC_F_NEXT, 1, VRING_DESC_F_NEXT | VRING_DESC_F_WRITE, 2, 1,
           VRING_DESC_F_WRITE)
RATE_FIRST = address_of("RATE_X_LSB")  # a read touching these is a read of the rates
RATE_LAST = address_of("RATE_Z_MSB")


@dataclass
class _Request:
    chain: Chain
    message: I2CMessage | None  # None: malformed, answered with the error status
    flags: int


@dataclass
class I2CStats:
    """What the device served: requests, transfers, failed requests, time in the model."""

    requests: int = 0
    transfers: int = 0
    failed: int = 0
    busy_s: float = 0.0

    def as_dict(self) -> dict[str, float]:
        per = self.busy_s / self.requests * 1e6 if self.requests else 0.0
        return {"requests": self.requests, "transfers": self.transfers,
                "failed": self.failed, "busy_s": round(self.busy_s, 6),
                "us_per_request": round(per, 2)}


class VirtioI2CDevice(VhostUserDevice):
    """The virtio-i2c request queue served from ``bus``."""

    num_queues = 1
    device_features = 1 << VIRTIO_I2C_F_ZERO_LENGTH_REQUEST
    name = "virtio-i2c"

    def __init__(self, bus: I2CBus) -> None:
        super().__init__()
        self.bus = bus
        self.stats = I2CStats()
        # run after the guest has been told its transfers are done (off its round trip):
        # e.g. the GPIO lines' update, the trace file
        self.after_transfer: list[Callable[[], None]] = []
        self._served = False
        # {address: chip time of the last read of the rate registers}: the GPIO device drops
        # a data-ready edge whose sample the driver has already read (see virtio_gpio)
        self.rate_reads: dict[int, float] = {}
        self._rate_read_used: dict[int, int] = {}  # {address: used index after that read}
        self._group: list[_Request] = []
        # the transfers answered since the hooks last ran were all reads of the rate
        # registers and nothing else (see pins_may_have_changed)
        self._rate_reads_only = True
        self._hold_data_int = any(getattr(c, "hold_data_int", False)
                                  for c in bus.devices.values())

    def pins_may_have_changed(self) -> bool:
        """Could the transfers just answered have changed an INT pin? Not when they only
        read RATE_X..RATE_Z (no status is cleared by that read, unless a chip holds
        data_int until it): what lets virtual time skip the GPIO lines' look after a
        driver's plain read (issue 32: that look cost more than the read)."""
        return not self._rate_reads_only or self._hold_data_int

    def reset(self) -> None:
        super().reset()
        self._group = []
        self._rate_read_used.clear()

    def process(self, queue: VirtQueue) -> None:
        started = time.perf_counter()
        served = False
        heads = queue.take()
        count = len(heads)
        bus = self.bus
        i = 0
        while i < count:
            if (i + 1 < count and not self._group and not bus.transaction_hooks
                    and self._register_read(queue, heads[i], heads[i + 1])):
                served = True
                i += 2
                continue
            request = self._parse(queue.chain(heads[i]))
            i += 1
            self._rate_reads_only = False
            self._group.append(request)
            if not request.flags & FLAG_FAIL_NEXT:
                self._transfer(queue, self._group)
                self._group = []
                served = True
        if served:
            self.stats.busy_s += time.perf_counter() - started
            self._served = True

    def answered(self, index: int) -> None:
        if self._served:
            self._served = False
            for hook in self.after_transfer:
                hook()
            self._rate_reads_only = True

    def _register_read(self, queue: VirtQueue, first: int, second: int) -> bool:
        """The drivers' most common transfer, served straight from the two chains' indirect
        tables (how the Linux driver queues them): write [register] with FAIL_NEXT, then a
        read of 1..32 bytes from the same present address, both well formed, in one region
        of guest memory. False (nothing taken) for anything else: the general path serves
        it, with the same result, errors included. The caller checks no fault hook is armed."""
        w = queue.table(first, 3)
        if w is None or _WRITE_SHAPE(w) != _WRITE_1:
            return False
        r = queue.table(second, 3)
        if r is None or _READ_SHAPE(r) != _READ_N:
            return False
        length = r[5]
        if not 0 < length <= I2C_SMBUS_BLOCK_MAX:
            return False
        # every buffer of both requests through one lookup (they lie in one region)
        low = min(w[0], w[4], w[8], r[0], r[4], r[8])
        located = self.memory.locate(low, max(w[0] + 8, w[4] + 1, w[8] + 1, r[0] + 8,
                                              r[4] + length, r[8] + 1) - low)
        if located is None:
            return False
        mapping, offset = located
        delta = offset - low
        raw_address, _, flags = _HEADER.unpack_from(mapping, w[0] + delta)
        if flags != FLAG_FAIL_NEXT or _HEADER.unpack_from(mapping, r[0] + delta) != (
                raw_address, 0, FLAG_M_RD):
            return False
        address = raw_address >> 1
        bus = self.bus
        chip = bus.devices.get(address)
        if chip is None:  # a NACK: the general path fails the group and logs it
            return False
        register = mapping[w[4] + delta]
        # on the wire the SMBus I2C block read, and logged as one (as from i2c-dev)
        data = bus.read_i2c_block_data(address, register, length)
        at = r[4] + delta
        mapping[at:at + length] = data
        mapping[w[8] + delta] = mapping[r[8] + delta] = MSG_OK
        queue.push2(first, 1, second, length + 1)
        stats = self.stats
        stats.transfers += 1
        stats.requests += 2
        if register <= RATE_LAST and register + length > RATE_FIRST:
            self.rate_reads[address] = chip.time
            self._rate_read_used[address] = queue.ring.used_idx
            if register < RATE_FIRST or register + length - 1 > RATE_LAST:
                self._rate_reads_only = False
        else:
            self._rate_reads_only = False
        return True

    def _parse(self, chain: Chain) -> _Request:
        """The request of a chain; a malformed one (5.19.6.2: a header, then the buffer in
        the direction M_RD says, then the status) is failed, not executed."""
        memory = self.memory
        readable = chain.readable
        if len(readable) == 1:
            out = memory.read(*readable[0])
        else:
            out = b"".join([memory.read(a, n) for a, n in readable])
        writable = chain.writable
        room = writable[0][1] if len(writable) == 1 else sum(n for _, n in writable)
        if room < 1:
            raise VhostUserError("virtio-i2c request without a status byte")
        if len(out) < _HEADER.size:
            log.warning("virtio-i2c: request without its header: failed")
            return _Request(chain, None, 0)
        raw_address, _, flags = _HEADER.unpack_from(out)
        address = raw_address >> 1
        if flags & FLAG_M_RD:
            if len(out) != _HEADER.size:
                log.warning("virtio-i2c: read request with a device-readable buffer: failed")
                return _Request(chain, None, flags)
            return _Request(chain, I2CMessage.read_message(address, room - 1), flags)
        if room != 1:
            log.warning("virtio-i2c: write request with a device-writable buffer: failed")
            return _Request(chain, None, flags)
        return _Request(chain, I2CMessage.write(address, out[_HEADER.size:]), flags)

    def _transfer(self, queue: VirtQueue, group: list[_Request]) -> None:
        """One I2C transfer: the group's messages under the chips' locks, in order."""
        bus = self.bus
        self.stats.transfers += 1
        self.stats.requests += len(group)
        messages = [r.message for r in group if r.message is not None]
        ok = [False] * len(group)
        if len(messages) < len(group):
            messages = messages[:0]  # a malformed request fails its whole transfer
        elif (len(messages) == 2 and not bus.transaction_hooks
              and not (w := messages[0]).read and len(w.data) == 1
              and (r := messages[1]).read and r.address == w.address
              and 0 < r.length <= I2C_SMBUS_BLOCK_MAX and w.address in bus.devices):
            # A register read: write [register], repeated start, read n, stop. On the wire
            # this is the SMBus I2C block read, and the bus's hot path serves it (logged as
            # read_i2c_block_data, as the same transfer from i2c-dev is)
            r.data = bus.read_i2c_block_data(w.address, w.data[0], r.length)
            ok = [True, True]
            if w.data[0] <= RATE_LAST and w.data[0] + r.length > RATE_FIRST:
                self.rate_reads[w.address] = bus.devices[w.address].time
                self._rate_read_used[w.address] = (queue.ring.used_idx + 2) & 0xFFFF
        elif not bus.transaction_hooks and all(m.address in bus.devices for m in messages):
            try:  # the common case: every address answers and no fault is armed
                bus.i2c_transfer(messages)
                ok = [True] * len(group)
            except OSError:
                pass  # e.g. a message longer than i2c-dev allows: all fail
        else:  # one transfer, as the fault hooks must see it (a register read is one)
            try:
                bus.i2c_transfer(messages)
                ok = [True] * len(group)
            except OSError as exc:  # FAIL_NEXT: the rest of the group fails unexecuted
                done = getattr(exc, "messages_done", 0)
                ok = [i < done for i in range(len(group))]
        for request, good in zip(group, ok):
            if not good:
                self.stats.failed += 1
            parsed = request.message
            data = parsed.data if good and parsed is not None and parsed.read else b""
            written = self._scatter(request.chain, data, MSG_OK if good else MSG_ERR)
            queue.push(request.chain.head, written)

    def guest_took_rate_read(self, address: int) -> bool:
        """Has the guest's driver taken the answer to its last rate read of ``address``?
        With EVENT_IDX it writes, as it takes used buffers, how far it has taken them."""
        mark = self._rate_read_used.get(address)
        queue = self.queues[0]
        if mark is None or queue is None or not queue.event_idx or not self.rings[0].ready:
            return True
        return (queue.used_event() - mark) & 0xFFFF < 0x8000

    def _scatter(self, chain: Chain, data: bytes, status: int) -> int:
        """Write read data (may be empty) and the status byte; return the bytes written."""
        memory = self.memory
        segments = chain.writable
        if len(segments) == 2 and segments[0][1] == len(data):  # the driver's read: data, status
            memory.write(segments[0][0], data)
            memory.write(segments[1][0] + segments[1][1] - 1, _STATUS[status])
            return len(data) + 1
        rest = data
        for i, (addr, length) in enumerate(segments):
            last = i == len(segments) - 1
            room = length - 1 if last else length
            if rest and room:
                memory.write(addr, rest[:room])
                rest = rest[room:]
            if last:
                memory.write(addr + length - 1, _STATUS[status])
        return len(data) + 1
