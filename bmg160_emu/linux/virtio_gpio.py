"""A virtio-gpio device (virtio 1.2, 5.18) whose input lines are the chips' INT1/INT2 pins.

Why: the kernel's bmg160 driver registers its own data-ready trigger, and reports
any-motion events, only with an interrupt line. Served through QEMU's
``vhost-user-gpio-pci``, each line's level follows the model: data-ready pulses, FIFO
watermark/full, any-motion, high-rate and the offset engines, latched or not, routed by
INT_MAP_0..2 and enabled by INT_EN_0, with the polarity of INT_EN_1 (spec 4.14-4.19).

Lines: two per chip, in address order: line 2i is INT1 of chip i, line 2i+1 its INT2
(named ``bmg160-0x68-INT1`` ...). They are inputs: setting a direction other than input,
or a value, fails with the error status.

Interrupts (5.18.6.2): the driver sets a line's trigger type (IRQ_TYPE) and queues one
buffer per line on the event queue; the device answers the buffer when the trigger fires.
An edge that comes while no buffer is queued is held and reported when the next buffer
comes (edges are not lost while the guest handles the previous one; several edges in that
time coalesce into one, as a real edge-triggered input does); a level trigger fires
whenever a buffer is queued and the level is active. Setting the type to NONE returns the
queued buffer with status INVALID.

How the level is followed: the model computes samples when it is touched, so the device
polls every chip just after each expected sample (the server's pollers) and after every I2C
transfer (a read can clear a latched status). A data-ready pulse (300 us, spec_choices)
between two polls is known from the chip's per-sample hook, so no pulse is missed however
late the poll runs.

Pacing (with a :class:`~bmg160_emu.linux.guest_pace.GuestPacedClock`): while a chip's
data-ready interrupt reaches a line with a trigger, the chips' time is held just before
that chip's next sample until the driver has read the rate registers after the last one
(and a guard has passed, so the next edge does not find the driver's handler still
running), then it catches up. A guest stalled by its host thus loses no sample; an edge the
guest never answers (its handler dropped it) is given up ``HOLD_TIMEOUT_S`` after the
guest handled the interrupt.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bmg160_emu.clock import NS_PER_S
from bmg160_emu.device.registers import address_of
from bmg160_emu.linux import agent_lines
from bmg160_emu.linux.agent_lines import AgentLines, RequestLine
from bmg160_emu.linux.guest_pace import NEVER, GuestPacedClock
from bmg160_emu.linux.vhost_user import VhostUserDevice
from bmg160_emu.linux.virtio_gpio_spec import (
    DIRECTION_IN,
    DIRECTION_NONE,
    IRQ_STATUS_INVALID,
    IRQ_STATUS_VALID,
    IRQ_TYPE_EDGE_BOTH,
    IRQ_TYPE_EDGE_FALLING,
    IRQ_TYPE_EDGE_RISING,
    IRQ_TYPE_LEVEL_HIGH,
    IRQ_TYPE_NONE,
    IRQ_TYPES,
    MSG_GET_DIRECTION,
    MSG_GET_NAMES,
    MSG_GET_VALUE,
    MSG_IRQ_TYPE,
    MSG_SET_DIRECTION,
    STATUS_ERR,
    STATUS_OK,
    VIRTIO_GPIO_F_IRQ,
)
from bmg160_emu.linux.virtqueue import Chain, VhostUserError, VirtQueue, fence

REQUEST_QUEUE = 0
EVENT_QUEUE = 1
_REQUEST = struct.Struct("<HHI")
_IRQ_REQUEST = struct.Struct("<H")

INT_EN_0 = address_of("INT_EN_0")
INT_EN_1 = address_of("INT_EN_1")
INT_MAP_1 = address_of("INT_MAP_1")
DATA_EN = 0x80  # INT_EN_0 bit 7: data_en (4.14)
INT1_DATA, INT2_DATA = 0x01, 0x80  # INT_MAP_1 bits 0 and 7 (4.16)
# Every status routed to a pin (4.16): INT_MAP_0 bits 1 and 3 (any-motion, high-rate to
# INT1), INT_MAP_1 bits 0-3 to INT1 and 4-7 to INT2, INT_MAP_2 bits 1 and 3 (to INT2)
PIN_ROUTES = {1: ((address_of("INT_MAP_0"), 0x0A), (INT_MAP_1, 0x0F)),
              2: ((INT_MAP_1, 0xF0), (address_of("INT_MAP_2"), 0x0A))}
POLL_IDLE_S = 0.005  # no sample expected (suspend, no ODR): look again this often
POLL_MARGIN_S = 50e-6  # wake just after the sample is due
# Pacing. The driver's read is over for the guest when it has taken the transfer's answer
# (EVENT_IDX shows it); its handler then still pushes the frame and re-arms the trigger, and
# an edge before that is dropped by IIO: the guard. That is tens of us of guest code, but
# the host may stall the guest's vCPU just then: with 0.3 ms, 1.1 % of the 200 Hz edges
# were dropped on a loaded host. At most a quarter period (a 2000 Hz chip keeps its ODR).
GUARD_S = 1e-3
TAKE_POLL_S = 0.2e-3  # while held: how often to look whether the guest took the answer
# An edge unanswered this long after the guest handled the interrupt (its buffer is back)
# was dropped by IIO (or the driver reads no data): the sample is given up and the chip
# runs on wall time until the driver reads again. A guest that does not even handle the
# interrupt is waited for up to STALL_LIMIT_S.
HOLD_TIMEOUT_S = 0.05
STALL_LIMIT_S = 1.0


class _SampleCounter:
    """A truth hook counting the chip's samples (one call per output sample)."""

    def __init__(self) -> None:
        self.count = 0
        self.last_t_s: float | None = None
        self.last_ns: int | None = None

    def __call__(self, _chip: Any, t_s: float, _rate: Any) -> None:
        self.count += 1
        self.last_t_s = t_s
        self.last_ns = round(t_s * NS_PER_S)


@dataclass
class _Pace:
    """Pacing state of one chip: its last sample seen and whether the driver read it."""

    last_ns: int = -1
    seen_s: float = 0.0  # wall time (monotonic) the back end saw that sample
    ready_s: float = 0.0  # since when the guest has had its interrupt buffer back
    read_s: float | None = None  # wall time the driver's read of it was seen
    suspended: bool = False  # given up: wall time until the driver reads again
    held: bool = False  # the chips' time waited at this sample


@dataclass
class GpioLine:
    """One input line: a pin of a chip and its interrupt state."""

    chip: Any
    pin: int  # 1 or 2
    name: str
    counter: _SampleCounter
    irq_type: int = IRQ_TYPE_NONE
    buffer: Chain | None = None
    pending: bool = False  # an edge seen while no buffer was queued
    last_active: bool = False
    last_was_pulse: bool = False
    seen_samples: int = 0
    interrupts: int = 0  # buffers answered with VALID

    @property
    def level(self) -> int:
        return self.chip.int_pin_level(self.pin)


class VirtioGPIODevice(VhostUserDevice):
    """The INT1/INT2 lines of ``chips`` ({address: chip}) as a virtio-gpio controller."""

    num_queues = 2
    device_features = 1 << VIRTIO_GPIO_F_IRQ
    name = "virtio-gpio"

    def __init__(self, chips: dict[int, Any], rate_reads: dict[int, float] | None = None,
                 clock: Any = None, read_taken: Callable[[int], bool] | None = None,
                 agent: AgentLines | None = None) -> None:
        super().__init__()
        self.agent = agent  # two more lines after the chips': the guest agent's channel
        self.lines: list[GpioLine] = []
        # {address: chip time of the last rate read} (VirtioI2CDevice.rate_reads)
        self.rate_reads: dict[int, float] = rate_reads if rate_reads is not None else {}
        self.stale_edges = 0  # data-ready edges dropped: the driver had read their sample
        # pacing only when the chips run on a GuestPacedClock
        self.clock = clock if isinstance(clock, GuestPacedClock) else None
        # read_taken(address): the guest has the answer to its last rate read (virtio-i2c)
        self.read_taken = read_taken
        # could the last transfers have changed a pin (virtio-i2c); None: always look
        self.pins_may_have_changed: Callable[[], bool] | None = None
        self._pace: dict[int, _Pace] = {}
        self._armed = False  # a line has a trigger type set
        self.given_up = 0  # samples whose edge the guest never answered (paced)
        self.held_samples = 0  # samples the chips' time waited for (paced)
        # the server's "look again at" (monotonic s); set by whoever runs the loop
        self.wake: Callable[[float | None], None] | None = None
        for address in sorted(chips):
            chip = chips[address]
            counter = _SampleCounter()  # hooked in while a line of the chip has a trigger
            for pin in (1, 2):
                self.lines.append(GpioLine(chip, pin, f"bmg160-0x{address:02x}-INT{pin}", counter))
        extra = agent_lines.NAMES if agent is not None else ()
        names = b"".join(n.encode() + b"\0" for n in [*(line.name for line in self.lines), *extra])
        self.names = names
        self.config = struct.pack("<HxxI", len(self.lines) + len(extra), len(names))

    def ring_stopped(self, index: int) -> None:
        if index == EVENT_QUEUE:
            for line in self.lines:
                line.buffer = None  # the front end takes the ring back as it stands
            if self.agent is not None:
                self.agent.request.buffer = None
            if self.clock is not None:
                self.clock.limit_ns = NEVER  # no guest to wait for
                self._pace.clear()

    # ---------------------------------------------------------------- requests

    def process(self, queue: VirtQueue) -> None:
        if queue.ring.index == EVENT_QUEUE:
            while (chain := queue.pop()) is not None:
                self._queue_event_buffer(chain)
            self.look()
            return
        while (chain := queue.pop()) is not None:
            request = b"".join(self.memory.read(a, n) for a, n in chain.readable)
            if len(request) < _REQUEST.size or not chain.writable:
                raise VhostUserError("virtio-gpio request without its header or response")
            kind, gpio, value = _REQUEST.unpack_from(request)
            response = self._answer(kind, gpio, value)
            queue.push(chain.head, self._scatter(chain, response))
        self.look()  # a trigger type may have changed

    def _answer(self, kind: int, gpio: int, value: int) -> bytes:
        if kind == MSG_GET_NAMES:
            return bytes([STATUS_OK]) + self.names
        if gpio >= len(self.lines):
            offset = gpio - len(self.lines)
            if self.agent is None or offset > 1:
                return bytes([STATUS_ERR, 0])
            return self.agent.answer(offset, kind, value, self._set_request_irq_type)
        line = self.lines[gpio]
        if kind == MSG_GET_DIRECTION:
            return bytes([STATUS_OK, DIRECTION_IN])
        if kind == MSG_SET_DIRECTION:
            ok = value in (DIRECTION_IN, DIRECTION_NONE)  # the chip drives the line
            return bytes([STATUS_OK if ok else STATUS_ERR, 0])
        if kind == MSG_GET_VALUE:
            return bytes([STATUS_OK, line.level])
        if kind == MSG_IRQ_TYPE:
            if value not in IRQ_TYPES:
                return bytes([STATUS_ERR, 0])
            self._set_irq_type(line, value)
            return bytes([STATUS_OK, 0])
        return bytes([STATUS_ERR, 0])  # SET_VALUE on an input, or an unknown request

    def _scatter(self, chain: Chain, response: bytes) -> int:
        rest = response
        written = 0
        for addr, length in chain.writable:
            if not rest:
                break
            self.memory.write(addr, rest[:length])
            written += min(length, len(rest))
            rest = rest[length:]
        return written

    # ---------------------------------------------------------------- interrupts

    def _set_request_irq_type(self, line: RequestLine, irq_type: int) -> None:
        line.irq_type = irq_type
        line.pending = False
        if irq_type == IRQ_TYPE_NONE and line.buffer is not None:
            self._answer_event(line, IRQ_STATUS_INVALID)

    def pulse_agent_request(self) -> None:
        """A rising edge on the agent's request line (on the back end's thread): its
        interrupt now, or when the guest queues its next event buffer."""
        if self.agent is None:
            raise RuntimeError("this virtio-gpio device has no agent lines")
        line = self.agent.request
        if line.irq_type == IRQ_TYPE_NONE:
            line.pending = True  # the agent has not asked for edges yet: kept for it
        elif line.buffer is not None:
            self._answer_event(line, IRQ_STATUS_VALID)
        else:
            line.pending = True

    def _set_irq_type(self, line: GpioLine, irq_type: int) -> None:
        line.irq_type = irq_type
        self._armed = any(o.irq_type != IRQ_TYPE_NONE for o in self.lines)
        # The per-sample hook costs the model its block fast path: only while needed.
        wanted = any(o.irq_type != IRQ_TYPE_NONE for o in self.lines if o.chip is line.chip)
        hooks = line.chip.truth_hooks
        if wanted and line.counter not in hooks:
            _ = line.chip.int1  # produce the samples due first: they were not watched
            hooks.append(line.counter)
        elif not wanted and line.counter in hooks:
            hooks.remove(line.counter)
        line.pending = False
        line.last_active = self._active(line)
        # armed at a sample's instant (as virtual time often does), an active line is that
        # sample's data-ready pulse when data-ready reaches the pin: the next sample's
        # pulse is then a new edge, not the same level still asserted
        data_bit = INT1_DATA if line.pin == 1 else INT2_DATA
        line.last_was_pulse = line.last_active and bool(
            line.chip.peek(INT_EN_0) & DATA_EN and line.chip.peek(INT_MAP_1) & data_bit)
        line.seen_samples = line.counter.count
        if irq_type == IRQ_TYPE_NONE and line.buffer is not None:
            self._answer_event(line, IRQ_STATUS_INVALID)

    def _queue_event_buffer(self, chain: Chain) -> None:
        request = b"".join(self.memory.read(a, n) for a, n in chain.readable)
        if len(request) < _IRQ_REQUEST.size or not chain.writable:
            raise VhostUserError("virtio-gpio event buffer without its line or status")
        gpio = _IRQ_REQUEST.unpack_from(request)[0]
        if self.agent is not None and gpio == len(self.lines):
            request_line = self.agent.request
            if request_line.buffer is not None:
                raise VhostUserError(f"virtio-gpio line {gpio}: a second event buffer")
            request_line.buffer = chain
            if request_line.irq_type == IRQ_TYPE_NONE:
                self._answer_event(request_line, IRQ_STATUS_INVALID)
            elif request_line.pending:
                request_line.pending = False
                self._answer_event(request_line, IRQ_STATUS_VALID)
            return
        if gpio >= len(self.lines):
            raise VhostUserError(f"virtio-gpio event buffer for line {gpio} of {len(self.lines)}")
        line = self.lines[gpio]
        if line.buffer is not None:
            raise VhostUserError(f"virtio-gpio line {gpio}: a second event buffer")
        line.buffer = chain
        if line.irq_type == IRQ_TYPE_NONE:
            self._answer_event(line, IRQ_STATUS_INVALID)

    def _answer_event(self, line: GpioLine | RequestLine, status: int) -> None:
        chain, line.buffer = line.buffer, None
        queue = self.queues[EVENT_QUEUE]
        if chain is None or queue is None:
            return
        addr, _ = chain.writable[0]
        self.memory.write(addr, bytes([status]))
        old = queue.ring.used_idx
        queue.push(chain.head, 1)
        fence()
        queue.notify(old)
        if status == IRQ_STATUS_VALID:
            line.interrupts += 1

    @staticmethod
    def _active(line: GpioLine) -> bool:
        return bool(line.chip.int1 if line.pin == 1 else line.chip.int2)

    def _update(self, line: GpioLine) -> None:
        """Follow the line since the last poll; fire its trigger if it should."""
        chip = line.chip
        active = self._active(line)  # first: this makes the chip produce the samples due
        new_samples = line.counter.count - line.seen_samples
        line.seen_samples = line.counter.count
        data_bit = INT1_DATA if line.pin == 1 else INT2_DATA
        pulses = bool(new_samples and chip.peek(INT_EN_0) & DATA_EN
                      and chip.peek(INT_MAP_1) & data_bit)
        read_t = self.rate_reads.get(chip.address)
        last_t = line.counter.last_t_s
        stale = bool(pulses and read_t is not None and last_t is not None and last_t <= read_t)
        if stale:
            # The model makes a sample when it is touched: a driver reading late (after the
            # next sample was due) made it, and only then does this look see its pulse. On
            # the chip that pulse came while the driver's handler still ran, and IIO drops
            # a trigger that fires then; delivering it now would read the sample twice.
            self.stale_edges += 1
        # the logical (active = asserted) transitions since the last poll, in order
        edges: list[bool] = []  # True = became active
        if stale:
            pass
        elif not line.last_active:
            if active:
                edges = [True]
            elif pulses:
                edges = [True, False]  # a whole data-ready pulse fell between two polls
        elif not active:
            # the pulse seen last time ended (and maybe a whole new one came and went)
            edges = [False, True, False] if pulses and line.last_was_pulse else [False]
        elif pulses and line.last_was_pulse:
            edges = [False, True]  # the last pulse ended, a new one is under way
        line.last_active = active
        # still the same pulse when no sample came since (a second look at one instant, as
        # virtual time gives after a transfer): it is not a level that stayed asserted
        line.last_was_pulse = active and (pulses or (line.last_was_pulse and not new_samples))
        active_high = chip.peek(INT_EN_1) >> (0 if line.pin == 1 else 2) & 1
        kind = line.irq_type
        fire = False
        if kind & IRQ_TYPE_EDGE_BOTH:
            for became_active in edges:
                rising = became_active == bool(active_high)
                if (rising and kind & IRQ_TYPE_EDGE_RISING) or (
                        not rising and kind & IRQ_TYPE_EDGE_FALLING):
                    fire = True
            if fire:
                line.pending = True
        elif kind:
            want = 1 if kind == IRQ_TYPE_LEVEL_HIGH else 0
            seen_levels = {int(b == bool(active_high)) for b in edges} | {line.level}
            line.pending = want in seen_levels
        if line.pending and line.buffer is not None:
            line.pending = False
            self._answer_event(line, IRQ_STATUS_VALID)

    def poll(self, now_s: float) -> float | None:
        """Update every line with a trigger set; the monotonic time of the next look."""
        deadline: float | None = None
        clock = self.clock
        for line in self.lines:
            if line.irq_type == IRQ_TYPE_NONE:
                continue
            self._update(line)
            chip = line.chip
            last = line.counter.last_ns
            odr = chip.odr_hz
            wait = POLL_IDLE_S
            if last is not None and odr and chip.power_mode == "normal":
                due = last + NS_PER_S // odr
                until = (clock.wall_s_until(due) if clock is not None
                         else max(due / NS_PER_S - chip.time, 0.0))
                wait = min(until + POLL_MARGIN_S, POLL_IDLE_S)
            candidate = now_s + wait
            deadline = candidate if deadline is None else min(deadline, candidate)
        if clock is not None:
            held = self._pace_chips(now_s)
            if held is not None:
                deadline = held if deadline is None else min(deadline, held)
        return deadline

    # ---------------------------------------------------------------- virtual time

    def next_event_ns(self) -> int | None:
        """Virtual time (the calendar's source): the earliest instant (ns, the chips' clock)
        at which a line with a trigger may fire. A rising edge of an active-high pin (what
        data-ready, FIFO and motion interrupts raise) comes only with a sample: the sample
        instants while a status is routed to the pin or the line is active. Any other
        trigger also follows the ends of pulses and latches: the chip's own
        ``next_pin_change_ns``. None when no line can fire."""
        best: int | None = None
        for line in self.lines:
            if line.irq_type == IRQ_TYPE_NONE:
                continue
            chip = line.chip
            active_high = chip.peek(INT_EN_1) >> (0 if line.pin == 1 else 2) & 1
            if line.irq_type != IRQ_TYPE_EDGE_RISING or not active_high:
                due = chip.next_pin_change_ns()
            else:
                due = self._next_sample_ns(line)
            if due is not None:
                best = due if best is None else min(best, due)
        return best

    def _next_sample_ns(self, line: GpioLine) -> int | None:
        chip = line.chip
        odr = chip.odr_hz
        if not odr or chip.power_mode != "normal":
            return None
        if not (line.last_active or any(chip.peek(register) & bits
                                        for register, bits in PIN_ROUTES[line.pin])):
            return None
        period = NS_PER_S // odr
        now = chip.clock.now_ns()
        last = line.counter.last_ns
        # the sample after the last one the line saw (until it has seen one, a period from
        # now: no later than the chip's next sample)
        due = last + period if last is not None else now + period
        if due <= now:
            due = now + period - (now - due) % period  # (samples the line has not seen)
        return due

    def fire(self, now_ns: int) -> None:
        """Virtual time: the calendar's time is a sample instant: follow the lines."""
        for line in self.lines:
            if line.irq_type != IRQ_TYPE_NONE:
                self._update(line)

    def look(self) -> None:
        """Poll now and tell the server when to look next (after a transfer or a kick)."""
        if not self.rings[EVENT_QUEUE].ready:
            if self.clock is not None:
                self.clock.limit_ns = NEVER  # no guest to wait for
            return
        deadline = self.poll(time.monotonic())
        if self.wake is not None:
            self.wake(deadline)

    def _paced_lines(self) -> dict[int, GpioLine]:
        """{address: a line} of the chips whose data-ready reaches a line with a trigger."""
        paced: dict[int, GpioLine] = {}
        for line in self.lines:
            chip = line.chip
            if line.irq_type == IRQ_TYPE_NONE or chip.address in paced:
                continue
            data_bit = INT1_DATA if line.pin == 1 else INT2_DATA
            if (chip.peek(INT_EN_0) & DATA_EN and chip.peek(INT_MAP_1) & data_bit
                    and chip.odr_hz and chip.power_mode == "normal"):
                paced[chip.address] = line
        return paced

    def _pace_chips(self, now_s: float) -> float | None:
        """Set the clock's limit from every paced chip; the time a hold expires, if any."""
        clock = self.clock
        assert clock is not None
        limit = NEVER
        deadline: float | None = None
        paced = self._paced_lines()
        for address in [a for a in self._pace if a not in paced]:
            del self._pace[address]
        for address, line in paced.items():
            last = line.counter.last_ns
            if last is None:
                continue
            state = self._pace.setdefault(address, _Pace())
            if state.last_ns != last:
                state.last_ns, state.seen_s, state.read_s, state.held = last, now_s, None, False
                state.ready_s = now_s
            if line.buffer is None:
                # the guest has not handled the interrupt yet (it re-queues the buffer when
                # it does): stalled, not deaf; the timeout counts from when it is back
                state.ready_s = now_s
            period = NS_PER_S // line.chip.odr_hz
            read_t = self.rate_reads.get(address)
            read = read_t is not None and round(read_t * NS_PER_S) >= last
            if read:
                state.suspended = False
                if state.read_s is None and (self.read_taken is None
                                             or self.read_taken(address)):
                    state.read_s = now_s
            guard = min(GUARD_S, period / 4e9)
            held = clock.now_ns() >= last + period - 1
            # never past a sample the back end has not looked at (no two at once) ...
            hold = last + 2 * period
            expires = None
            if state.read_s is None and not state.suspended:
                # ... nor past the next one until the driver has this one
                expires = min(state.ready_s + HOLD_TIMEOUT_S, state.seen_s + STALL_LIMIT_S)
                if now_s >= expires:
                    state.suspended = True
                    self.given_up += 1
                    expires = None
                elif read and held:
                    expires = min(expires, now_s + TAKE_POLL_S)
            elif state.read_s is not None and now_s < state.read_s + guard:
                expires = state.read_s + guard
            if expires is not None:
                hold = last + period
                if held and not state.held:
                    state.held = True
                    self.held_samples += 1
                deadline = expires if deadline is None else min(deadline, expires)
            limit = min(limit, hold)
        clock.limit_ns = limit
        return deadline

    def after_transfer(self) -> None:
        """Hook for the I2C device: a transfer may have changed a line (clear-on-read...).
        With no trigger on any line there is nothing to follow and nothing to pace (the
        look after the request that cleared the last one left it so): no look. Unpaced
        (virtual time), none either after transfers that cannot have changed a pin
        (``pins_may_have_changed``, the I2C device's answer); paced, each rate read is
        what the pacing waits for."""
        if self._armed and (self.clock is not None or self.pins_may_have_changed is None
                            or self.pins_may_have_changed()):
            self.look()

    def line_summary(self) -> list[dict[str, Any]]:
        return [{"line": i, "name": line.name, "irq_type": line.irq_type,
                 "interrupts": line.interrupts} for i, line in enumerate(self.lines)]
