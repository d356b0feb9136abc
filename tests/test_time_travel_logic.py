"""Virtual time and the agent's channel without a kernel: the calendar against a fake UML
speaking the time-travel protocol (um_timetravel.h), the virtio-gpio device's agent lines
and its data-ready edges looked at twice at one instant, as virtual time does.

The calendar runs on a real :class:`Server` loop in a thread; the fake UML is a socket that
sends what UML 6.1 sends (arch/um/kernel/time.c) and reads what the calendar answers.
"""

from __future__ import annotations

import socket
import struct
import threading

import pytest
from _vhost_front_end import FakeFrontEnd

from bmg160_emu.clock import VirtualClock
from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux import calendar as cal
from bmg160_emu.linux import virtio_gpio as vg
from bmg160_emu.linux import virtio_gpio_spec as gpio_spec
from bmg160_emu.linux.agent_lines import AgentLines
from bmg160_emu.linux.vhost_user_server import Connection, Server


class FakeUml:
    """UML's side of the calendar's socket: requests answered in order."""

    def __init__(self, path: str) -> None:
        self.sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.sock.connect(path)
        self.sock.settimeout(5)
        self.seq = 0

    def receive(self) -> tuple[int, int, int]:
        data = b""
        while len(data) < cal.MESSAGE.size:
            data += self.sock.recv(cal.MESSAGE.size - len(data))
        return cal.MESSAGE.unpack(data)

    def ask(self, op: int, at: int = 0) -> int:
        """Send a request; the time the ACK carries (messages before it are returned by
        :meth:`wait`'s caller: here none may come)."""
        self.seq += 1
        self.sock.sendall(cal.MESSAGE.pack(op, self.seq, at))
        reply = self.receive()
        assert reply[:2] == (cal.ACK, self.seq), reply
        return reply[2]

    def wait(self) -> tuple[int, int]:
        """WAIT, then what the calendar grants: (free until, run at), each acknowledged."""
        self.ask(cal.WAIT)
        free_until = run_at = None
        while run_at is None:
            op, seq, at = self.receive()
            self.sock.sendall(cal.MESSAGE.pack(cal.ACK, seq, 0))
            if op == cal.FREE_UNTIL:
                free_until = at
            elif op == cal.RUN:
                run_at = at
        assert free_until is not None
        return free_until, run_at

    def nothing_within(self, seconds: float) -> bool:
        self.sock.settimeout(seconds)
        try:
            self.sock.recv(1, socket.MSG_PEEK)
        except TimeoutError:
            return True
        finally:
            self.sock.settimeout(5)
        return False


class Ticks:
    """An event source firing every ``period`` ns from ``first``."""

    def __init__(self, first: int, period: int) -> None:
        self.next, self.period, self.fired = first, period, []

    def next_event_ns(self) -> int:
        return self.next

    def fire(self, now_ns: int) -> None:
        if now_ns >= self.next:
            self.fired.append(now_ns)
            self.next += self.period


def _settled(calendar) -> None:
    """Until the loop has run what was handed to it (its calls run in order)."""
    done = threading.Event()
    calendar.server.call_soon(done.set)
    assert done.wait(5)


@pytest.fixture
def calendar(tmp_path):
    server = Server()
    clock = VirtualClock()
    calendar = cal.Calendar(server, str(tmp_path / "s" / "time.sock"), clock)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    uml = FakeUml(calendar.path)
    assert uml.ask(cal.START, 7) == 0
    yield calendar, uml, clock
    server.stop()
    thread.join(timeout=5)
    calendar.close()
    server.close()


def test_uml_runs_at_the_instant_it_asks_for_and_may_run_on_a_quantum(calendar):
    calendar, uml, clock = calendar
    assert uml.ask(cal.GET) == 0
    assert uml.ask(cal.GET_TOD) > 1_600_000_000 * 10**9  # the guest's wall clock: now
    uml.ask(cal.REQUEST, 2_500_000)
    assert uml.wait() == (2_500_000 + cal.QUANTUM_NS, 2_500_000)
    assert clock.ns == 2_500_000
    # running, UML tells the calendar its time before it kicks a device (UPDATE)
    uml.ask(cal.UPDATE, 2_600_000)
    assert clock.ns == 2_600_000 and uml.ask(cal.GET) == 2_600_000


def test_the_chips_instants_and_the_hosts_come_first_in_time_order(calendar):
    calendar, uml, _clock = calendar
    ticks = Ticks(1_000_000, 1_000_000)
    calendar.server.call_soon(lambda: calendar.sources.append(ticks))
    calendar.at(0.0025, lambda: ticks.fired.append(-1))  # a host event at 2.5 ms
    _settled(calendar)
    uml.ask(cal.REQUEST, 3_200_000)
    free_until, run_at = uml.wait()
    assert ticks.fired == [1_000_000, 2_000_000, -1, 3_000_000]
    # the next instant of the chips bounds how far UML may run without asking
    assert (free_until, run_at) == (4_000_000, 3_200_000)


def test_between_the_hosts_requests_time_stands_still_and_the_next_comes_at_the_horizon(
        calendar):
    calendar, uml, clock = calendar
    uml.ask(cal.REQUEST, 1_000_000)
    horizon, _ = uml.wait()
    calendar.server.call_soon(calendar.hold)  # the agent replied: the host prepares
    _settled(calendar)
    uml.ask(cal.REQUEST, 50_000_000)  # UML idles until a timer far ahead ...
    uml.ask(cal.WAIT)
    assert uml.nothing_within(0.3)  # ... and is not let run while the host holds
    delivered = []
    calendar.release(lambda: delivered.append(clock.ns))
    op, seq, at = uml.receive()  # the ring (a device's call in the real thing) came first
    assert delivered == [horizon]
    # (a real UML asks for the ring's instant in its interrupt handler; this one keeps its
    # request, and runs at it once the host's request is delivered)
    assert (op, at) == (cal.FREE_UNTIL, 50_000_000 + cal.QUANTUM_NS)
    uml.sock.sendall(cal.MESSAGE.pack(cal.ACK, seq, 0))
    op, seq, at = uml.receive()
    assert (op, at) == (cal.RUN, 50_000_000)


def test_a_horizon_that_an_earlier_event_now_beats_is_told_before_a_kicks_reply(calendar):
    calendar, uml, _clock = calendar
    uml.ask(cal.REQUEST, 0)
    assert uml.wait() == (cal.QUANTUM_NS, 0)
    ticks = Ticks(300_000, 1_000_000)  # a driver just enabled an interrupt at 0.3 ms
    done = threading.Event()

    def enable_and_tighten() -> None:
        calendar.sources.append(ticks)
        calendar.tighten()
        done.set()

    calendar.server.call_soon(enable_and_tighten)
    op, _seq, at = uml.receive()
    assert (op, at) == (cal.FREE_UNTIL, 300_000) and done.wait(5)


# ---------------------------------------------------------------- the GPIO device


@pytest.fixture
def gpio_with_agent():
    clock = VirtualClock()
    chips = {0x68: BMG160(seed=5, clock=clock)}
    lines = AgentLines()
    replies = []
    lines.on_reply = lambda: replies.append(lines.reply_value)
    device = vg.VirtioGPIODevice(chips, agent=lines)
    front, back = socket.socketpair()
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake(num_queues=2)
    yield fe, device, chips, clock, replies
    connection.close()
    fe.close()


def _request(fe, device, kind, line, value=0, size=2):
    head = fe.add(0, [struct.pack("<HHI", kind, line, value)], [size])
    device.kick(0)
    return fe.read_back(0, head, [size])[0]


def test_the_agent_lines_follow_the_chips_and_carry_requests_and_replies(gpio_with_agent):
    fe, device, _chips, _clock, replies = gpio_with_agent
    names = _request(fe, device, gpio_spec.MSG_GET_NAMES, 0, size=128)[1:].split(b"\0")
    assert names[:4] == [b"bmg160-0x68-INT1", b"bmg160-0x68-INT2",
                         b"bmg160-emu-agent-request", b"bmg160-emu-agent-reply"]
    # the reply line: an output of the guest; gpio-virtio sets the value before the
    # direction (virtio_gpio_direction_output), which is no reply
    assert _request(fe, device, gpio_spec.MSG_SET_VALUE, 3, 0) == b"\x00\x00"
    assert _request(fe, device, gpio_spec.MSG_SET_DIRECTION, 3, gpio_spec.DIRECTION_OUT) == b"\x00\x00"
    assert replies == []
    for value in (1, 0, 1):
        _request(fe, device, gpio_spec.MSG_SET_VALUE, 3, value)
    assert replies == [1, 0, 1]
    # the request line: an input the host pulses; an edge per pulse, held until the
    # guest's event buffer is there
    assert _request(fe, device, gpio_spec.MSG_SET_DIRECTION, 2, gpio_spec.DIRECTION_OUT) == b"\x01\x00"
    _request(fe, device, gpio_spec.MSG_IRQ_TYPE, 2, gpio_spec.IRQ_TYPE_EDGE_RISING)
    device.pulse_agent_request()
    head = fe.add(1, [struct.pack("<H", 2)], [1])
    device.kick(1)
    assert fe.used(1) == [(head, 1)] and fe.read_back(1, head, [1])[0] == b"\x01"
    head = fe.add(1, [struct.pack("<H", 2)], [1])
    device.kick(1)
    assert fe.used(1) == []
    device.pulse_agent_request()
    assert fe.used(1) == [(head, 1)]


def test_each_data_ready_pulse_is_one_edge_however_often_its_instant_is_looked_at(
        gpio_with_agent):
    """Virtual time looks at a line at a sample's instant and again after each transfer at
    that instant: the pulse still under way is the same pulse, not a level that stayed
    asserted (which swallowed every other edge of a capture before)."""
    fe, device, chips, clock, _ = gpio_with_agent
    chip = chips[0x68]
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")  # int1_data
    chip.write(0x15, b"\x80")  # data_en
    clock.advance(0.05)  # past the chip's start-up (30 ms): it samples at 100 Hz
    _request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING)
    fe.add(1, [struct.pack("<H", 0)], [1])
    device.kick(1)
    fired = 0
    for _ in range(20):
        due = device.next_event_ns()
        assert due is not None and due > clock.ns
        clock.advance_ns(due - clock.ns)  # the calendar's time reaches the sample
        device.fire(clock.ns)
        device.look()  # a transfer at the same instant (the driver's read)
        device.look()
        if fe.used(1):
            fired += 1
            fe.add(1, [struct.pack("<H", 0)], [1])
            device.kick(1)
    assert fired == 20


def test_a_trigger_on_both_edges_is_also_called_at_the_end_of_each_pulse(gpio_with_agent):
    """A rising-edge line needs only the sample instants; one on both edges needs the
    instant each 300 us data-ready pulse ends too (the chip's next_pin_change_ns)."""
    from bmg160_emu.device.spec_choices import DATA_READY_PULSE_NS

    fe, device, chips, clock, _ = gpio_with_agent
    chip = chips[0x68]
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")  # int1_data
    chip.write(0x15, b"\x80")  # data_en
    clock.advance(0.05)
    _request(fe, device, gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_BOTH)
    edges = []
    for _ in range(6):
        head = fe.add(1, [struct.pack("<H", 0)], [1])
        device.kick(1)
        due = device.next_event_ns()
        clock.advance_ns(due - clock.ns)
        device.fire(clock.ns)
        if fe.used(1) == [(head, 1)]:
            edges.append((clock.ns, chip.int1))
        else:  # (the buffer stays queued for the next one)
            fe.used(1)
    rises = [t for t, level in edges if level]
    falls = [t for t, level in edges if not level]
    assert len(rises) == 3 and len(falls) == 3  # (armed in a pulse: its end came first)
    ends = [min(f for f in falls if f > r) - r for r in rises if any(f > r for f in falls)]
    assert ends == [DATA_READY_PULSE_NS] * 2
