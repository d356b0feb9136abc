"""The chip's rate low-pass filter for a BW code, run block-wise on three axes.

The filter acts on deviations from a reference level, so a constant input equal to the
reference passes bit-exactly (unity DC gain without rounding error) and the filter starts
at steady state: a constant rate reads exactly from the first sample (spec 5.3, 6.1).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from scipy import signal

from bmg160_emu.device import spec_choices


@cache
def coefficients(odr_hz: float, bandwidth_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, a, steady-state state per unit input) of the Butterworth low-pass."""
    nyquist = odr_hz / 2.0
    b, a = signal.butter(spec_choices.LOWPASS_ORDER, min(bandwidth_hz / nyquist, 0.99))
    return b, a, signal.lfilter_zi(b, a)


class LowPass:
    """Three-axis low-pass with state ``(order, 3)`` carried between blocks."""

    def __init__(self, odr_hz: float, bandwidth_hz: float) -> None:
        self.b, self.a, self._zi_unit = coefficients(float(odr_hz), float(bandwidth_hz))
        self.reference = np.zeros(3)  # level the filter rests at; set by restart()
        self.started = False
        self.state = np.zeros((len(self.a) - 1, 3))

    def restart(self, level: np.ndarray) -> None:
        """Rest at ``level``: the next input equal to it comes out unchanged."""
        self.reference = np.array(level, dtype=float)
        self.state = np.zeros_like(self.state)
        self.started = True

    def rebase_if_settled(self, level: np.ndarray) -> None:
        """Re-reference at a constant input once the transient has died out."""
        if not self.started:
            self.restart(level)
            return
        deviation = np.asarray(level, dtype=float) - self.reference
        if not deviation.any() and not self.state.any():
            return
        settled = np.outer(self._zi_unit, deviation)
        if np.allclose(self.state, settled, rtol=0.0, atol=1e-12 * max(1.0, np.abs(deviation).max())):
            self.restart(level)

    def run(self, x: np.ndarray, state: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Filter ``x`` (n, 3) from ``state`` (default: current); return (y, final state)."""
        state = self.state if state is None else state
        dev = x - self.reference
        if not dev.any() and not state.any():
            return np.broadcast_to(self.reference, x.shape).copy(), state
        y, final = signal.lfilter(self.b, self.a, dev, axis=0, zi=state)
        return y + self.reference, final
