"""Real data as the chip's output: a user's recording played through the register interface.

A recording (CSV or NPZ: a time column and x, y, z in deg/s or raw counts), read and checked
line by line by io/replay_data.py, is attached to a chip as a sample hook, so every output sample the chip produces
carries the recorded rate at that moment and a driver reads flight or lab data through the
RATE registers, the FIFO and the interrupt engines. The method (``docs/replay.md``):

* time: the first output sample after :meth:`ReplaySource.attach` is the recording's first
  time stamp; later output samples keep the chip's own spacing (``1/ODR``), so a recording
  plays at its own time stamps whatever its sample rate;
* resampling to the chip's ODR: linear interpolation between the two recorded samples that
  bracket each output time; when the recording is at least twice as fast as the ODR, the
  mean of the recorded samples inside each output period instead (a boxcar decimator, so
  fast data is not aliased by picking every n-th sample);
* after the last recorded sample the last value is held (or, with ``loop=True``, the
  recording starts over);
* the recorded value replaces the chip's own sample after noise and offset (it already is
  what a chip measured), and the chip scales it to counts with its current range.
"""

from __future__ import annotations

import numpy as np

from bmg160_emu.io.replay_data import ReplayData
from bmg160_emu.session.record import chip_odr_hz

TIME_RESOLUTION_S = 0.5e-9  # half the chip clock's 1 ns step (bmg160_emu.clock)


class ReplaySource:
    """Plays :class:`ReplayData` as a chip's output samples (see the module docstring)."""

    def __init__(self, data: ReplayData, loop: bool = False):
        self.data = data
        self.loop = loop
        self._origin_chip_s: float | None = None
        self.samples_played = 0

    def recording_time(self, chip_time_s: float) -> float:
        """The recording's time stamp that plays at chip time ``chip_time_s``."""
        if self._origin_chip_s is None:
            self._origin_chip_s = chip_time_s
        tau = self.data.t_s[0] + (chip_time_s - self._origin_chip_s)
        if self.loop and tau > self.data.t_s[-1]:
            span = self.data.duration_s + self.data.median_step_s
            tau = self.data.t_s[0] + (tau - self.data.t_s[0]) % span
        return tau

    def value_at(self, tau: float, period_s: float | None) -> np.ndarray:
        """The recorded rate at recording time ``tau`` (deg/s), resampled as documented."""
        t, rate = self.data.t_s, self.data.rate_dps
        res = TIME_RESOLUTION_S
        if period_s is not None and period_s + res >= 2 * self.data.median_step_s:
            lo = np.searchsorted(t, tau - period_s + res, side="right")
            hi = np.searchsorted(t, tau + res, side="right")
            if hi > lo:
                return rate[lo:hi].mean(axis=0)
        if tau <= t[0]:
            return rate[0].copy()
        if tau >= t[-1]:
            return rate[-1].copy()
        i = int(np.searchsorted(t, tau, side="right"))
        # A time stamp within clock resolution of a recorded one plays that sample exactly.
        if tau - t[i - 1] <= TIME_RESOLUTION_S:
            return rate[i - 1].copy()
        if t[i] - tau <= TIME_RESOLUTION_S:
            return rate[i].copy()
        w = (tau - t[i - 1]) / (t[i] - t[i - 1])
        return rate[i - 1] + w * (rate[i] - rate[i - 1])

    def __call__(self, chip, t: float, rate_dps) -> np.ndarray:
        """The sample hook: replace the chip's sample with the recorded one."""
        tau = self.recording_time(float(t))
        self.samples_played += 1
        return self.value_at(tau, 1.0 / chip_odr_hz(chip))

    def attach(self, chip) -> ReplaySource:
        """Start playing on ``chip`` from its next output sample."""
        self._origin_chip_s = None
        chip.sample_hooks.append(self)
        return self

    def detach(self, chip) -> None:
        if self in chip.sample_hooks:
            chip.sample_hooks.remove(self)
