"""The output low-pass run block-wise on three axes: the chip's filter of a BW code, on the
true rate (device/datapath.py) and on the sensing element's noise (sensor_noise.py).

The filter acts on deviations from a reference level, so a constant input equal to the
reference passes bit-exactly (unity DC gain without rounding error) and the filter starts
at steady state: a constant rate reads exactly from the first sample (spec 5.3, 6.1).

Design and filtering use numpy only, so that building a chip does not import scipy (about
0.6 s of start-up). The design (``butterworth.py``, shared with identification and a
profile's own filter) is the one ``scipy.signal.butter`` computes (analog Butterworth poles,
cut-off prewarped, bilinear transform at fs = 2), so the coefficients agree with it (bit for
bit for the table's eight BW codes; a test compares them). The filter is the direct-form-II-transposed
state space of ``scipy.signal.lfilter`` run in sub-blocks of ``SUB_BLOCK`` samples with
matrix products instead of a per-sample loop; its output and states agree with lfilter's to
rounding (about 1e-15 of the signal; a test asserts 1e-12), not bit for bit. Streams changed
within rounding when this replaced lfilter: a count can differ from an earlier release only
where ``rate * sensitivity`` lay within about 1e-11 LSB (4e-16 of full scale) of a
rounding boundary; 64,000 reads over all BW codes with a moving true rate and noise gave the
same bytes as before.
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np

from bmg160_emu.noise.bandwidths import LOWPASS_ORDER
from bmg160_emu.noise.butterworth import Butterworth

SUB_BLOCK = 32  # samples per matrix product: big enough to amortise numpy calls, H stays small
SUB_BLOCKS = 32  # sub-blocks solved together (one chunk of SUB_BLOCK * SUB_BLOCKS samples)


def _state_space(b: np.ndarray, a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(A, B, C, D) of lfilter's direct form II transposed: z' = A z + B x, y = C z + D x."""
    b = b / a[0]
    a = a / a[0]
    n = len(a) - 1
    big_a = np.zeros((n, n))
    big_a[:, 0] = -a[1:]
    big_a[: n - 1, 1:] = np.eye(n - 1)
    big_b = b[1:] - a[1:] * b[0]
    big_c = np.zeros(n)
    big_c[0] = 1.0
    return big_a, big_b, big_c, float(b[0])


class _Blocks:
    """The matrices that run up to ``SUB_BLOCKS`` sub-blocks of ``SUB_BLOCK`` samples at once.

    Within a sub-block, y = H x + G s with H the lower-triangular Toeplitz matrix of the
    impulse response and s the state at the sub-block's start; the state after it is
    A^L s + K x. The states at the starts of all sub-blocks of a chunk follow from the first
    one and the K x of the earlier sub-blocks by one product with a block-Toeplitz matrix of
    powers of A^L, so there is no Python loop over sub-blocks. Sub-blocks sit side by side as
    columns (sample in sub-block, sub-block x axis) so that every product is one 2-D GEMM."""

    def __init__(self, b: np.ndarray, a: np.ndarray) -> None:
        big_a, big_b, big_c, d = _state_space(b, a)
        n, length = len(big_b), SUB_BLOCK
        powers = np.empty((length + 1, n, n))  # A^0 .. A^L
        powers[0] = np.eye(n)
        for k in range(1, length + 1):
            powers[k] = big_a @ powers[k - 1]
        impulse = np.empty(length)  # h[0] = D, h[k] = C A^(k-1) B
        impulse[0] = d
        impulse[1:] = big_c @ (powers[:-2] @ big_b).T
        lag = np.arange(length)[:, None] - np.arange(length)[None, :]
        self.h = np.where(lag >= 0, impulse[np.clip(lag, 0, None)], 0.0)  # (L, L)
        self.g = big_c @ powers[:-1]  # (L, n): row k is C A^k
        self.k = (powers[length - 1 :: -1] @ big_b).T.copy()  # (n, L): column j is A^(L-1-j) B
        self.powers = powers
        self.order = n
        self.d = float(d)  # h[0]: the one-sample step of LowPass.step
        self.b_list = big_b.tolist()  # B, the last column of K
        self.a_step = powers[1]  # A (LowPass.step's product; the same array as powers[1])
        self._step = powers[length]  # A^L: from one sub-block start to the next
        self._starts: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def _start_matrices(self, count: int) -> tuple[np.ndarray, np.ndarray]:
        """(F, M) with starts = F s0 + M (K x), rows and columns ordered (state, sub-block):
        the start state of sub-block j is (A^L)^j s0 + sum over i < j of (A^L)^(j-1-i) K x_i."""
        cached = self._starts.get(count)
        if cached is not None:
            return cached
        n = self.order
        steps = np.empty((count, n, n))  # (A^L)^0 .. (A^L)^(count-1)
        steps[0] = np.eye(n)
        for j in range(1, count):
            steps[j] = self._step @ steps[j - 1]
        first = steps.transpose(1, 0, 2).reshape(n * count, n)
        carry = np.zeros((n, count, n, count))
        for j in range(1, count):
            for i in range(j):
                carry[:, j, :, i] = steps[j - 1 - i]
        self._starts[count] = first, carry.reshape(n * count, n * count)
        return self._starts[count]

    def run(self, x: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Filter ``x`` (n, axes) from ``state`` (order, axes); return (y, final state)."""
        total = len(x)
        if total == 0:
            return np.empty_like(x), state.copy()
        chunk = SUB_BLOCK * SUB_BLOCKS
        if total <= chunk:
            return self._run_chunk(x, state)
        pieces = []
        for start in range(0, total, chunk):
            y, state = self._run_chunk(x[start : start + chunk], state)
            pieces.append(y)
        return np.concatenate(pieces), state

    def _run_chunk(self, x: np.ndarray, state: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        total, axes = x.shape
        length, n = SUB_BLOCK, self.order
        count = -(-total // length)
        if count * length == total:
            padded = x
        else:
            padded = np.zeros((count * length, axes))
            padded[:total] = x
        if count == 1:  # one sub-block (a closed loop's few due samples): the same products
            # on the same arrays, without the layout steps below (each a no-op on one block)
            first, carry = self._start_matrices(1)
            starts = first @ state + carry @ (self.k @ padded)
            y = (self.h @ padded + self.g @ starts)[:total]
            final = self.powers[total] @ starts + self.k[:, length - total:] @ padded[:total]
            return y, final
        # rows: sample within the sub-block; columns: (sub-block, axis)
        xs = padded.reshape(count, length, axes).transpose(1, 0, 2).reshape(length, count * axes)
        first, carry = self._start_matrices(count)
        into_state = (self.k @ xs).reshape(n * count, axes)  # K x_j, rows (state, sub-block)
        starts = (first @ state + carry @ into_state).reshape(n, count * axes)
        y = (self.h @ xs + self.g @ starts).reshape(length, count, axes)
        y = y.transpose(1, 0, 2).reshape(count * length, axes)[:total]
        rest = total - (count - 1) * length  # samples in the last sub-block, 1..L
        last_start = starts.reshape(n, count, axes)[:, -1]
        last_x = padded[(count - 1) * length : total]
        final = self.powers[rest] @ last_start + self.k[:, length - rest :] @ last_x
        return y, final


@cache
def coefficients(odr_hz: float, bandwidth_hz: float, order: int = LOWPASS_ORDER
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(b, a, steady-state state per unit input) of the Butterworth low-pass (the chip's
    order unless another is named: a profile's own filter, butterworth.py)."""
    b, a = Butterworth(int(order), float(bandwidth_hz), float(odr_hz)).coefficients()
    big_a, big_b, _, _ = _state_space(b, a)
    # the state a constant unit input holds: z = A z + B (what lfilter_zi solves)
    zi = np.linalg.solve(np.eye(len(big_b)) - big_a, big_b)
    return b, a, zi


@cache
def _blocks(odr_hz: float, bandwidth_hz: float, order: int) -> _Blocks:
    b, a, _ = coefficients(odr_hz, bandwidth_hz, order)
    return _Blocks(b, a)


REFERENCE_ROWS_KEPT = 4096  # the largest block whose reference rows a filter keeps (96 kB)
REFERENCE_SHAPES_KEPT = 4  # and how many block shapes at most


class LowPass:
    """Three-axis low-pass with state ``(order, 3)`` carried between blocks."""

    def __init__(self, odr_hz: float, bandwidth_hz: float,
                 order: int = LOWPASS_ORDER) -> None:
        self.design = Butterworth(int(order), float(bandwidth_hz), float(odr_hz))
        self.b, self.a, self._zi_unit = coefficients(float(odr_hz), float(bandwidth_hz),
                                                     int(order))
        self._blocks = _blocks(float(odr_hz), float(bandwidth_hz), int(order))
        self._zi = self._zi_unit.tolist()
        self._rows: list[list[float]] = []  # the state as rows, while ``state`` is _rows_of
        self._rows_of: np.ndarray | None = None
        self.restart(np.zeros(3))  # level the filter rests at (reference)
        self.started = False

    def restart(self, level: Any) -> None:
        """Rest at ``level``: the next input equal to it comes out unchanged."""
        self.reference = np.array(level, dtype=float)
        self._ref = self.reference.tolist()  # the same, as floats (step, rebase_if_settled)
        self._reference_rows: dict[tuple[int, ...], np.ndarray] = {}  # (run)
        self.state = np.zeros((len(self.a) - 1, 3))
        self.started = True

    def _state_rows(self) -> list[list[float]]:
        """``state.tolist()``: the rows ``step`` made the state from while it is that state
        (a closed loop's step and re-reference test read them at every sample)."""
        state = self.state
        return self._rows if state is self._rows_of else state.tolist()

    def rebase_if_settled(self, level: Any) -> None:
        """Re-reference at a constant input once the transient has died out: every state
        within 1e-12 x max(1, |level - reference|) of the state that input settles at.
        (In Python floats on the six states: the test of ``np.allclose(rtol=0)`` at a tenth
        of its cost, which a closed loop pays at every sample.)"""
        if not self.started:
            self.restart(level)
            return
        values = level.tolist() if isinstance(level, np.ndarray) else list(level)
        dev = [a - r for a, r in zip(values, self._ref)]
        rows = self._state_rows()
        if not any(dev) and not any(any(row) for row in rows):
            return
        atol = 1e-12 * max(1.0, *map(abs, dev))
        for row, z in zip(rows, self._zi):
            for s, d in zip(row, dev):
                if not abs(s - z * d) <= atol:  # isclose's test with rtol = 0 (NaN: False)
                    return
        self.restart(level)

    def step(self, x: list[float]) -> list[float]:
        """Filter one sample ``x`` (3 floats) from the current state, which moves on; the
        output as 3 floats. Bit for bit the first row of ``run`` (a closed loop's one-sample
        piece) at a fraction of its cost: in lfilter's state space y = D dev + s[0] and
        s' = A s + B dev, and ``run``'s sub-block products only add exact zeros to these
        (the first rows of H and G hold D and C = (1, 0); the start-state matrices are the
        identity and zeros); A s is the same 2-D product as there, the rest elementwise."""
        blocks = self._blocks
        ref = self._ref
        dev = [a - r for a, r in zip(x, ref)]
        state = self.state
        d = blocks.d
        y = [(d * v + s) + r for v, s, r in zip(dev, self._state_rows()[0], ref)]
        moved = (blocks.a_step @ state).tolist()
        rows = [[a + b * v for a, v in zip(row, dev)] for row, b in zip(moved, blocks.b_list)]
        self.state = self._rows_of = np.array(rows)
        self._rows = rows
        return y

    def settle_on(self, x: np.ndarray) -> None:
        """Rest at 0 in the state the filter holds after ``x`` (n, 3), started at rest at
        x[0]: a noise filter started settled (sensor_noise.SensorNoise). By linearity that
        state is the one of the deviations from x[0] plus the settled state of x[0]; with
        the reference at 0, ``run_pieces`` needs no reference arithmetic."""
        level = np.array(x[0], dtype=float)
        _, final = self._blocks.run(x - level, np.zeros((len(self.a) - 1, x.shape[1])))
        self.restart(np.zeros(x.shape[1]))
        self.state = final + np.outer(self._zi_unit, level)

    def run_pieces(self, x: np.ndarray, state: np.ndarray, every: int
                   ) -> tuple[np.ndarray, np.ndarray]:
        """Filter ``x`` (n, axes) about the reference 0 from ``state`` in pieces of ``every``
        samples counted from x[0] (a multiple of the block chunk): the same bits whatever
        the length of x, as long as it starts on a piece boundary; return (y, final state)."""
        blocks = self._blocks
        if len(x) <= every:
            return blocks.run(x, state)
        y = np.empty_like(x)
        for start in range(0, len(x), every):
            y[start:start + every], state = blocks.run(x[start:start + every], state)
        return y, state

    def run(self, x: np.ndarray, state: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Filter ``x`` (n, 3) from ``state`` (default: current); return (y, final state)."""
        state = self.state if state is None else state
        reference = self._rows_like(x)
        dev = x - reference
        if not np.count_nonzero(dev) and not np.count_nonzero(state):  # (.any(): 5x the cost)
            return (reference.copy() if reference.shape == x.shape
                    else np.broadcast_to(reference, x.shape).copy()), state
        y, final = self._blocks.run(dev, state)
        return y + reference, final

    def _rows_like(self, x: np.ndarray) -> np.ndarray:
        """The reference as x's rows (x's shape): the same operands elementwise as the
        reference broadcast, at a third of the cost (numpy's broadcast of 3 values over
        1024 rows runs an inner loop of 3: 4.3 against 1 us for x - reference, 5.7 against
        0.4 us for the copy); kept for a few shapes of up to REFERENCE_ROWS_KEPT rows until
        the reference changes (a chip's blocks come in few sizes)."""
        shape = x.shape
        rows = self._reference_rows.get(shape)
        if rows is None:
            if x.ndim != 2 or shape[1] != self.reference.shape[0]:
                return self.reference  # (any other shape: broadcast as it comes)
            rows = np.broadcast_to(self.reference, shape).copy()
            if shape[0] <= REFERENCE_ROWS_KEPT:
                if len(self._reference_rows) >= REFERENCE_SHAPES_KEPT:
                    self._reference_rows.clear()
                self._reference_rows[shape] = rows
        return rows
