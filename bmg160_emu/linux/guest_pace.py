"""A real-time clock that waits for a slow guest: the chips' time under ``vhost-user-i2c``.

Why: a QEMU guest under software emulation (TCG) on a busy host stalls for milliseconds at
a time; a chip on wall time goes on producing samples meanwhile, so the guest's driver
misses data-ready interrupts a real machine would have served (86 % of the frames kept at
200 Hz on this project's loaded 2-core host, docs/virtio-i2c.md). These losses belong to
the emulation, not to the chip. This clock runs at wall time while the guest keeps up; a
pacer (:class:`~bmg160_emu.linux.virtio_gpio.VirtioGPIODevice`) may hold it just before a
chip's next sample while the guest has not yet read the previous one, and afterwards it
runs ``catch_up`` times faster than wall time until the lag is made up. Every sample is
then produced at its own time on the chips' time axis (noise and filter unchanged), one
data-ready interrupt each, and the count over a capture matches ODR x wall time as long as
the guest keeps up on average (the lag it cannot make up is reported).
"""

from __future__ import annotations

import time

from bmg160_emu.clock import NS_PER_S, RealTimeClock

NEVER = 1 << 62  # no limit


class GuestPacedClock(RealTimeClock):
    """Wall time since construction, held below :attr:`limit_ns` and then caught up.

    ``now_ns()`` never goes backwards; the chips read it at each access, as they read a
    :class:`~bmg160_emu.clock.RealTimeClock`, whose waiting ``advance``/``sleep`` it keeps
    (wall time cannot be pushed).
    """

    def __init__(self, catch_up: float = 2.0) -> None:
        if not catch_up > 1.0:
            raise ValueError("catch_up must be > 1 (the lag is made up at that speed)")
        super().__init__()
        self.catch_up = catch_up
        self.limit_ns = NEVER  # the chips' time stays below this (set by the pacer)
        self._real_ns = 0  # wall time at the last look (since the origin)
        self._ns = 0  # the chips' time at the last look
        self.max_lag_ns = 0

    def now_ns(self) -> int:
        real = time.monotonic_ns() - self._origin_ns
        dt = real - self._real_ns
        if dt <= 0:
            return self._ns
        self._real_ns = real
        ns = self._ns
        lag = real - dt - ns  # behind wall time at the last look
        step = dt if lag <= 0 else min(int(dt * self.catch_up), lag + dt)
        new = ns + step
        if new >= self.limit_ns:
            new = max(ns, self.limit_ns - 1)
            self.max_lag_ns = max(self.max_lag_ns, real - new)
        self._ns = new
        return new

    @property
    def lag_s(self) -> float:
        """How far the chips' time is behind wall time (s), as of the last look."""
        return (self._real_ns - self._ns) / NS_PER_S

    def wall_s_until(self, ns: int) -> float:
        """Wall seconds until the chips' time reaches ``ns`` if nothing holds it."""
        now = self.now_ns()
        if ns <= now:
            return 0.0
        lag = self._real_ns - now
        fast = min(ns - now, lag * self.catch_up / (self.catch_up - 1.0)) if lag > 0 else 0.0
        # while catching up the chips' time moves catch_up x wall time, then 1 x
        return (fast / self.catch_up + (ns - now - fast)) / NS_PER_S

    def __repr__(self) -> str:
        return f"GuestPacedClock(t={self._ns / NS_PER_S:.6f} s, lag={self.lag_s:.6f} s)"
