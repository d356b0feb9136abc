"""Guest pacing: the chips' time waits for a slow guest's driver, then catches up.

Wall time is a fake ``time.monotonic`` the tests move by hand, so every hold, guard, timeout
and catch-up is checked exactly. The GPIO device is driven by the in-process fake front end
(tests/_vhost_front_end.py), as in test_vhost_user_gpio_and_sockets.py.
"""

from __future__ import annotations

import socket
import struct
import time

import pytest
from _vhost_front_end import FakeFrontEnd

from bmg160_emu.device.chip import BMG160
from bmg160_emu.linux import virtio_gpio as vg
from bmg160_emu.linux import virtio_gpio_spec as gpio_spec
from bmg160_emu.linux.guest_pace import NEVER, GuestPacedClock
from bmg160_emu.linux.vhost_user_server import Connection

MS = 1_000_000  # ns
PERIOD = 10 * MS  # ODR 100 Hz


class Wall:
    """A fake monotonic clock (ns) for ``time.monotonic`` and ``time.monotonic_ns``."""

    def __init__(self) -> None:
        self.ns = 1_000 * MS

    def move(self, ns: int) -> float:
        self.ns += ns
        return self.ns / 1e9


@pytest.fixture
def wall(monkeypatch):
    w = Wall()
    monkeypatch.setattr(time, "monotonic_ns", lambda: w.ns)
    monkeypatch.setattr(time, "monotonic", lambda: w.ns / 1e9)
    return w


def test_free_clock_is_wall_time(wall):
    clock = GuestPacedClock()
    wall.move(7 * MS)
    assert clock.now_ns() == 7 * MS and clock.lag_s == 0


def test_held_clock_waits_then_catches_up_and_never_runs_ahead(wall):
    clock = GuestPacedClock(catch_up=2.0)
    clock.limit_ns = 3 * MS
    wall.move(10 * MS)
    assert clock.now_ns() == 3 * MS - 1  # held just before the limit
    assert clock.lag_s == pytest.approx(7e-3, abs=1e-8)
    assert clock.max_lag_ns == 7 * MS + 1
    clock.limit_ns = NEVER
    # the lag (7 ms) is made up at twice wall speed: 7 ms of wall, 14 ms of chip time
    assert clock.wall_s_until(clock.now_ns() + 14 * MS) == pytest.approx(7e-3, abs=1e-8)
    wall.move(2 * MS)
    assert clock.now_ns() == 7 * MS - 1
    wall.move(5 * MS + 1)
    assert clock.now_ns() == 17 * MS + 1  # the lag is made up: wall time exactly
    wall.move(3 * MS)
    assert clock.now_ns() == 20 * MS + 1  # then wall time, never ahead of it
    assert clock.lag_s == 0


def test_catch_up_must_be_faster_than_wall_time():
    with pytest.raises(ValueError, match="catch_up"):
        GuestPacedClock(catch_up=1.0)


@pytest.fixture
def paced(wall):
    clock = GuestPacedClock()
    chip = BMG160(seed=5, clock=clock)
    taken = {"yes": True}
    device = vg.VirtioGPIODevice({0x68: chip}, {}, clock, lambda _address: taken["yes"])
    front, back = socket.socketpair()
    connection = Connection(back, device)
    fe = FakeFrontEnd(front, connection.receive)
    fe.handshake(num_queues=2)
    chip.write(0x10, b"\x07")  # ODR 100 Hz
    chip.write(0x18, b"\x01")  # INT_MAP_1: data-ready on INT1
    chip.write(0x15, b"\x80")  # INT_EN_0: data_en
    head = fe.add(0, [struct.pack("<HHI", gpio_spec.MSG_IRQ_TYPE, 0, gpio_spec.IRQ_TYPE_EDGE_RISING)], [2])
    device.kick(0)
    assert fe.used(0) == [(head, 2)]
    device.poll(wall.move(MS))  # past the reset's data-ready pulse; the first sample at 10 ms
    yield fe, device, chip, clock, taken
    connection.close()
    fe.close()


def queue_event(fe, device) -> int:
    head = fe.add(1, [struct.pack("<H", 0)], [1])
    device.kick(1)
    return head


def driver_reads(device, chip) -> None:
    """What VirtioI2CDevice records when the driver reads the rate registers."""
    chip.read(0x02, 6)
    device.rate_reads[0x68] = chip.time


def test_the_next_sample_waits_for_the_drivers_read_of_the_last(paced, wall):
    fe, device, chip, clock, taken = paced
    head = queue_event(fe, device)
    device.poll(wall.move(PERIOD - MS))
    assert [h for h, _ in fe.used(1)] == [head]  # the edge of the sample due
    last = device.lines[0].counter.last_ns
    assert clock.limit_ns == last + PERIOD  # the next sample waits
    head = queue_event(fe, device)
    device.poll(wall.move(3 * PERIOD))  # the guest is stalled: no sample meanwhile
    assert clock.now_ns() == last + PERIOD - 1 and fe.used(1) == []
    assert device.held_samples == 1
    # the driver reads, but the guest has not taken the answer yet: still held
    taken["yes"] = False
    driver_reads(device, chip)
    device.poll(wall.move(MS // 10))
    assert clock.limit_ns == last + PERIOD
    # taken: the guard runs, then the chip may go on (two samples ahead at most)
    taken["yes"] = True
    device.poll(wall.move(MS // 10))
    assert clock.limit_ns == last + PERIOD
    deadline = device.poll(wall.move(MS // 10))
    assert deadline is not None and deadline <= wall.ns / 1e9 + vg.GUARD_S
    device.poll(wall.move(vg.GUARD_S * 1e9))
    assert clock.limit_ns == last + 2 * PERIOD
    # catching up at twice wall speed, the next sample comes half a period later
    device.poll(wall.move(PERIOD // 2 + MS // 10))
    assert [h for h, _ in fe.used(1)] == [head]
    assert device.lines[0].counter.last_ns == last + PERIOD
    assert device.given_up == 0 and device.stale_edges == 0


def test_a_guest_that_has_not_handled_the_interrupt_is_waited_for(paced, wall):
    fe, device, _, clock, _ = paced
    queue_event(fe, device)
    device.poll(wall.move(PERIOD - MS))
    last = device.lines[0].counter.last_ns
    device.poll(wall.move(round(vg.HOLD_TIMEOUT_S * 4e9)))  # no buffer back: stalled
    assert device.given_up == 0 and clock.limit_ns == last + PERIOD
    device.poll(wall.move(round(vg.STALL_LIMIT_S * 1e9)))
    assert device.given_up == 1


def test_an_edge_never_answered_is_given_up(paced, wall):
    fe, device, chip, clock, _ = paced
    queue_event(fe, device)
    device.poll(wall.move(PERIOD - MS))
    last = device.lines[0].counter.last_ns
    queue_event(fe, device)  # the guest handled the interrupt, and its driver reads nothing
    device.poll(wall.move(round(vg.HOLD_TIMEOUT_S * 1e9) - MS))
    assert clock.limit_ns == last + PERIOD and device.given_up == 0
    device.poll(wall.move(2 * MS))
    assert device.given_up == 1
    assert clock.limit_ns == last + 2 * PERIOD  # on wall time again, one sample at a time
    # a read of the newest sample the back end has seen resumes pacing
    device.poll(wall.move(PERIOD))
    device.poll(wall.move(MS // 10))  # the sample due now, and its edge
    assert device._pace[0x68].suspended
    driver_reads(device, chip)
    device.poll(wall.move(MS // 10))
    assert not device._pace[0x68].suspended and device._pace[0x68].read_s is not None


def test_no_pacing_without_data_ready_on_a_triggered_line(paced, wall):
    fe, device, chip, clock, _ = paced
    chip.write(0x15, b"\x00")  # data_en off: the driver's buffer is off
    queue_event(fe, device)
    device.poll(wall.move(PERIOD))
    assert clock.limit_ns == NEVER
    device.poll(wall.move(5 * PERIOD))
    assert clock.lag_s == 0
