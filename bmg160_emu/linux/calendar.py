"""The guest's clock in virtual time: the calendar of UML's external time travel, whose time
is the chips' ``VirtualClock``.

Why: a guest that runs against the host's clock sees what the host's speed allows (a
loaded host drops data-ready edges, a capture of N seconds costs N seconds), and the same
test gives other counts on every run. Under ``time-travel=ext`` UML asks this calendar for
every instant it wants to run at (include/uapi/linux/um_timetravel.h); between its
requests it runs as if its CPU were infinitely fast. The calendar grants them in time
order with the chips' own events (data-ready edges, the instants their samples are made:
:meth:`~bmg160_emu.linux.virtio_gpio.VirtioGPIODevice.next_event_ns`) and the host's
(:meth:`at`), so a capture of N samples costs N samples of work and the same seed and
guest command give the same counts on any host.

The protocol as UML 6.1 speaks it (arch/um/kernel/time.c): 16-byte messages (op, seq,
time); UML's START, REQUEST, WAIT, GET, UPDATE and GET_TOD each get an ACK (GET and GET_TOD
with the time); the calendar sends RUN when UML may run at the instant it asked for, and
FREE_UNTIL before it: UML may then run up to that instant without asking. Device
completions reach UML in band (VRING_KICK and SLAVE_VRING_CALL, vhost_user.py): UML's
interrupt handler asks the calendar for the time (GET) and for a turn at it (REQUEST)
before it answers the call, so :meth:`wait_readable` serves the calendar while a device
waits for that answer.

Rules that keep the guest's time deterministic:

- messages to UML go only as answers to its requests, as RUN while it waits, or as
  FREE_UNTIL just before a RUN or before a kick's reply (when UML reads nothing else);
- a device interrupt reaches UML either inside a kick (its time is the kick's) or while
  UML waits (the calendar's time, which is then at least UML's);
- between the host's requests (:meth:`hold`) the guest's time does not go past the last
  horizon it was given: the host's next request (:meth:`release`) comes at that instant,
  however long the host took to send it.
"""

from __future__ import annotations

import heapq
import logging
import os
import select
import socket
import struct
import time
from collections.abc import Callable
from typing import Protocol

from bmg160_emu.clock import NS_PER_S, VirtualClock

log = logging.getLogger(__name__)

# enum um_timetravel_ops (include/uapi/linux/um_timetravel.h)
ACK, START, REQUEST, WAIT, GET, UPDATE, RUN, FREE_UNTIL, GET_TOD = range(9)
OP_NAMES = ("ACK", "START", "REQUEST", "WAIT", "GET", "UPDATE", "RUN", "FREE_UNTIL", "GET_TOD")
MESSAGE = struct.Struct("<IIQ")  # struct um_timetravel_msg: op, seq, time (ns)
NEVER = (1 << 63) - 1  # S64_MAX: what UML asks for when it has nothing to do
# How far past the instant it runs at UML may go without asking, when nothing of the chips
# or the host comes sooner: bounds how far the guest's time runs on between two requests of
# the host (the next request comes at that horizon). 1 ms is a few thousand clock reads.
QUANTUM_NS = 1_000_000


class EventSource(Protocol):
    """A device with instants of its own (a chip's samples): asked for the next one,
    told when the calendar's time reaches it."""

    def next_event_ns(self) -> int | None: ...

    def fire(self, now_ns: int) -> None: ...


class Watcher(Protocol):
    def watch(self, fd: int, handler: Callable[[], None]) -> None: ...

    def unwatch(self, fd: int) -> None: ...

    def call_soon(self, action: Callable[[], None]) -> None: ...


class Calendar:
    """UML's time-travel scheduler, served on the back end's event loop (``server``)."""

    def __init__(self, server: Watcher, path: str, clock: VirtualClock | None) -> None:
        if not isinstance(clock, VirtualClock):
            raise TypeError("the calendar's time is the chips' VirtualClock")
        from bmg160_emu.linux.vhost_user_server import listen

        self.server = server
        self.clock = clock
        self.sources: list[EventSource] = []
        self.listener = listen(path)
        self.path = path
        server.watch(self.listener.fileno(), self._accept)
        self.sock: socket.socket | None = None
        self._partial = b""  # a message read in part (the socket is non-blocking)
        self.waiting = False  # UML waits for a RUN
        self.requested = NEVER  # the instant UML asked for last
        self.horizon = 0  # UML may run up to (not at) this instant without asking
        self.holding = False  # between the host's requests: time stands still
        self._ring: Callable[[], None] | None = None  # the host's next request, to deliver
        self._events: list[tuple[int, int, Callable[[], None]]] = []  # host events (heap)
        self._seq = 0
        self._nested = 0  # inside wait_readable: answer, do not dispatch

        self._tod_ns = time.time_ns() - clock.ns  # the guest's wall clock at time 0
        self.messages = 0
        self.runs = 0

    # ---------------------------------------------------------------- the host's side

    def hold(self) -> None:
        """The host has its reply and prepares its next request (on the loop's thread)."""
        self.holding = True

    def run_free(self) -> None:
        """The host will send nothing more (the agent was told to stop): the guest's time
        goes on as it asks, so that its power-off finishes (from any thread)."""
        def free() -> None:
            self.holding = False
            self.dispatch()

        self.server.call_soon(free)

    def release(self, ring: Callable[[], None]) -> None:
        """Deliver the host's next request with ``ring`` (from any thread)."""
        def arm() -> None:
            self._ring = ring
            self.dispatch()

        self.server.call_soon(arm)

    def at(self, delay_s: float, action: Callable[[], None]) -> None:
        """Run ``action`` when the calendar's time is ``delay_s`` past now (any thread)."""
        delay_ns = round(delay_s * NS_PER_S)
        if delay_ns < 0:
            raise ValueError("an event cannot be in the past")

        def add() -> None:
            self._seq += 1
            heapq.heappush(self._events, (self.clock.ns + delay_ns, self._seq, action))
            self.dispatch()

        self.server.call_soon(add)

    def describe(self) -> str:
        """The calendar's state in one line (for a report of a guest that hangs)."""
        uml = ("gone" if self.sock is None else
               f"waiting for {self.requested} ns" if self.waiting else
               f"running (free until {self.horizon} ns)")
        return (f"time travel at {self.clock.ns} ns: UML {uml}; next event "
                f"{self.next_event_ns()} ns; host {'holding' if self.holding else 'waiting'}"
                f"{', its request not yet delivered' if self._ring else ''}; "
                f"{self.messages} messages, {self.runs} runs"
                f"{'; inside a device call' if self._nested else ''}")

    # ---------------------------------------------------------------- the socket

    def _accept(self) -> None:
        sock, _ = self.listener.accept()
        if self.sock is not None:
            log.warning("time travel: a second client; refused")
            sock.close()
            return
        sock.setblocking(False)
        self.sock = sock
        self.server.watch(sock.fileno(), self._readable)

    def _readable(self) -> None:
        # (the message epoll saw may have been read already, by a device waiting for a
        # call's answer earlier in the same turn: then there is nothing to do)
        while self._receive():
            pass
        self.dispatch()

    def _receive(self) -> bool:
        """Read and answer one message; False when there is none (or UML has gone)."""
        if self.sock is None:
            return False
        while len(self._partial) < MESSAGE.size:
            try:
                chunk = self.sock.recv(MESSAGE.size - len(self._partial))
            except BlockingIOError:
                return False
            except ConnectionResetError:
                chunk = b""
            if not chunk:
                self._closed()
                return False
            self._partial += chunk
        data, self._partial = self._partial, b""
        op, seq, at = MESSAGE.unpack(data)
        self.messages += 1
        if op == ACK:
            return True  # to our RUN or FREE_UNTIL
        answer = 0
        if op == REQUEST:
            self.requested = at
        elif op == WAIT:
            self.waiting = True
        elif op == GET:
            answer = self.clock.ns
        elif op == UPDATE:
            self._advance(at)
        elif op == GET_TOD:
            answer = self._tod_ns + self.clock.ns
        elif op != START:
            log.warning("time travel: unexpected message %r", data)
        self._send(ACK, seq, answer)
        return True

    def _send(self, op: int, seq: int, at: int) -> None:
        assert self.sock is not None
        data = MESSAGE.pack(op, seq, at)
        try:
            sent = self.sock.send(data)  # (UML reads each message as it waits for it:
        except BlockingIOError:          # the socket's buffer is never full)
            sent = 0
        if sent < len(data):
            self.sock.setblocking(True)
            try:
                self.sock.sendall(data[sent:])
            finally:
                self.sock.setblocking(False)

    def _closed(self) -> None:
        if self.sock is not None:
            self.server.unwatch(self.sock.fileno())
            self.sock.close()
        self.sock = None
        self.waiting = False

    def close(self) -> None:
        self._closed()
        self.server.unwatch(self.listener.fileno())
        self.listener.close()
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass

    def wait_readable(self, fd: int) -> None:
        """Until ``fd`` (a device's channel to UML) can be read, answering the calendar's
        messages meanwhile (UML asks for the time before it answers a device's call)."""
        self._nested += 1
        try:
            while True:
                watched = [fd] if self.sock is None else [fd, self.sock.fileno()]
                ready, _, _ = select.select(watched, [], [])
                if fd in ready:
                    return
                while self._receive():
                    pass
        finally:
            self._nested -= 1

    # ---------------------------------------------------------------- time

    def _advance(self, at: int) -> None:
        now = self.clock.ns
        if at > now:
            self.clock.advance_ns(at - now)
        elif at < now:
            log.warning("time travel: UML's time %d ns is behind the calendar's %d", at, now)

    def next_event_ns(self) -> int:
        """The earliest instant of the chips or the host (NEVER if none)."""
        best = self._events[0][0] if self._events else NEVER
        for source in self.sources:
            at = source.next_event_ns()
            if at is not None and at < best:
                best = at
        return best

    def _fire(self, at: int) -> None:
        """Everything due at ``at`` (the calendar's time now)."""
        for source in self.sources:
            source.fire(at)  # (asking first would make the chip's sample, and hide it)
        while self._events and self._events[0][0] <= at:
            heapq.heappop(self._events)[2]()

    def tighten(self, settle: Callable[[], None] = lambda: None) -> None:
        """Before a kick's reply: if an event now comes before UML's horizon (a driver just
        enabled an interrupt), tell UML to ask again by then. ``settle`` first reads the
        devices' calls UML still owes an answer to (UML reads our word as it waits for the
        kick's reply, and must not find it while its interrupt handler talks to us)."""
        if self.sock is None or self._nested:
            return
        due = self.next_event_ns()
        if self.clock.ns < due < self.horizon:
            settle()
            self.horizon = due
            self._seq += 1
            self._send(FREE_UNTIL, self._seq, due)

    def dispatch(self) -> None:
        """While UML waits: fire what is due before its instant, or let it run."""
        if self._nested:
            return
        while self.sock is not None and self.waiting:
            if self.holding:
                if self._ring is None:
                    return
                # the host's request at the horizon UML was given (UML's time is at most
                # that): an instant the host's speed has no say in
                at = max(self.clock.ns, min(self.requested, self.horizon, self.next_event_ns()))
                self._advance(at)
                ring, self._ring = self._ring, None
                self.holding = False
                ring()
                continue
            event = self.next_event_ns()
            if event <= self.requested:
                if event == NEVER:
                    return  # nothing to do until the host asks for something
                self._advance(event)
                self._fire(event)
                continue
            self._advance(self.requested)
            now = self.clock.ns
            self.horizon = min(self.next_event_ns(), now + QUANTUM_NS)
            self._seq += 1
            self._send(FREE_UNTIL, self._seq, self.horizon)
            self._seq += 1
            self.waiting = False
            self.runs += 1
            self._send(RUN, self._seq, now)
